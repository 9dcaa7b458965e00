/* The boundary of a 2D label map's selection as a closed curve (see
 * sm_image.h, sm_image_contour_2d). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "shapematch/sm_image.h"

typedef struct contour {
    int64_t w, h;        /* the padded crop's nodes (voxel centres) */
    int64_t i0, j0;      /* image index of node (0, 0) */
    double *f;           /* w*h values of the smoothed mask */
    int32_t *id[3];      /* vertex on edge (a,b)-(a+1,b), (a,b)-(a,b+1),
                          * (a,b)-(a+1,b+1), -1: none yet */
    const double *m;     /* ijk_to_lps */
    double *xy;          /* 2 per vertex */
    int32_t nv, capv;
    int32_t *seg;        /* 2 per segment */
    int32_t ns, caps;
} contour;

static int grow(void **a, int32_t *cap, int32_t need, size_t item)
{
    if (need <= *cap)
        return 0;
    int64_t n = *cap ? 2 * (int64_t)*cap : 256;
    while (n < need)
        n *= 2;
    if (n > SM_MAX_ENTITIES)
        n = SM_MAX_ENTITIES;
    if (need > n)
        return -1;
    void *p = realloc(*a, (size_t)n * item);
    if (!p)
        return -1;
    *a = p;
    *cap = (int32_t)n;
    return 0;
}

/* The vertex where the level 0.5 crosses the edge from node (a, b) to
 * node (a + da, b + db) (one end inside, f > 0.5, the other not), made
 * once per edge: the segments of both sides share it. */
static int32_t edge_vertex(contour *c, int64_t a, int64_t b, int da, int db)
{
    int kind = da && db ? 2 : da ? 0 : 1;
    int32_t *slot = &c->id[kind][b * c->w + a];
    if (*slot >= 0)
        return *slot;
    if (grow((void **)&c->xy, &c->capv, c->nv + 1, 2 * sizeof(double)) != 0)
        return -1;
    double fp = c->f[b * c->w + a], fq = c->f[(b + db) * c->w + a + da];
    double t = (0.5 - fp) / (fq - fp);
    double i = (double)(c->i0 + a) + t * da, j = (double)(c->j0 + b) + t * db;
    c->xy[2 * c->nv] = c->m[0] * i + c->m[1] * j + c->m[3];
    c->xy[2 * c->nv + 1] = c->m[4] * i + c->m[5] * j + c->m[7];
    *slot = c->nv;
    return c->nv++;
}

static int add_segment(contour *c, int32_t p, int32_t q)
{
    if (p < 0 || q < 0 || grow((void **)&c->seg, &c->caps, c->ns + 1, 2 * sizeof(int32_t)) != 0)
        return -1;
    c->seg[2 * c->ns] = p;
    c->seg[2 * c->ns + 1] = q;
    c->ns++;
    return 0;
}

/* One triangle of nodes (x[k], y[k]), counterclockwise in index space:
 * a segment with the inside on its left (flip: on its right, for a map
 * that mirrors). */
static int triangle(contour *c, const int64_t x[3], const int64_t y[3], int flip)
{
    int in[3], count = 0;
    for (int k = 0; k < 3; k++)
        count += in[k] = c->f[y[k] * c->w + x[k]] > 0.5;
    if (count == 0 || count == 3)
        return 0;
    /* the odd one out: the inside vertex of one, the outside of two */
    int v = 0;
    while (in[v] != (count == 1))
        v++;
    int n = (v + 1) % 3, p = (v + 2) % 3;
    int32_t a = edge_vertex(c, x[v] < x[n] || (x[v] == x[n] && y[v] < y[n]) ? x[v] : x[n],
                            x[v] < x[n] || (x[v] == x[n] && y[v] < y[n]) ? y[v] : y[n],
                            (int)llabs(x[n] - x[v]), (int)llabs(y[n] - y[v]));
    int32_t b = edge_vertex(c, x[v] < x[p] || (x[v] == x[p] && y[v] < y[p]) ? x[v] : x[p],
                            x[v] < x[p] || (x[v] == x[p] && y[v] < y[p]) ? y[v] : y[p],
                            (int)llabs(x[p] - x[v]), (int)llabs(y[p] - y[v]));
    /* one inside vertex v: from its edge to n, to its edge to p, has v on
     * the left; one outside vertex: the other way */
    int forward = (count == 1) != flip;
    return forward ? add_segment(c, a, b) : add_segment(c, b, a);
}

/* Separable Gaussian of sigma (in nodes) on the w x h values. */
static int blur(double *f, int64_t w, int64_t h, double sigma)
{
    int r = (int)ceil(3 * sigma);
    double *k = malloc((size_t)(2 * r + 1) * sizeof *k);
    double *line = malloc((size_t)(w > h ? w : h) * sizeof *line);
    if (!k || !line) {
        free(k);
        free(line);
        return -1;
    }
    double sum = 0;
    for (int d = -r; d <= r; d++)
        sum += k[d + r] = exp(-0.5 * d * d / (sigma * sigma));
    for (int d = 0; d <= 2 * r; d++)
        k[d] /= sum;
    for (int pass = 0; pass < 2; pass++) {
        int64_t n = pass ? h : w, lines = pass ? w : h;
        int64_t step = pass ? w : 1, stride = pass ? 1 : w;
        for (int64_t l = 0; l < lines; l++) {
            double *base = f + l * stride;
            for (int64_t s = 0; s < n; s++) {
                double v = 0;
                for (int d = -r; d <= r; d++) {
                    int64_t t = s + d;
                    if (t >= 0 && t < n) /* zero beyond the padded crop */
                        v += k[d + r] * base[t * step];
                }
                line[s] = v;
            }
            for (int64_t s = 0; s < n; s++)
                base[s * step] = line[s];
        }
    }
    free(k);
    free(line);
    return 0;
}

sm_status sm_image_contour_2d(const sm_image *im, const uint8_t *mask, double smooth,
                              sm_surface **out, sm_error *err)
{
    *out = NULL;
    const double *m = im->ijk_to_lps;
    if (im->dims[2] != 1)
        return sm_error_set(err, SM_ERR_INVALID, "a 2D image has one slice (this one has %lld)",
                            (long long)im->dims[2]);
    if (m[8] != 0 || m[9] != 0)
        return sm_error_set(err, SM_ERR_INVALID, "the image's plane is not z = constant (its "
                            "axes have z components %g and %g): a 2D target lies in the plane "
                            "of the 2D template", m[8], m[9]);
    int64_t nx = im->dims[0], ny = im->dims[1];
    int64_t lo[2] = {nx, ny}, hi[2] = {-1, -1};
    for (int64_t j = 0; j < ny; j++)
        for (int64_t i = 0; i < nx; i++)
            if (mask[j * nx + i]) {
                lo[0] = i < lo[0] ? i : lo[0];
                hi[0] = i > hi[0] ? i : hi[0];
                lo[1] = j < lo[1] ? j : lo[1];
                hi[1] = j > hi[1] ? j : hi[1];
            }
    if (hi[0] < 0)
        return sm_error_set(err, SM_ERR_INVALID, "the selection is empty");
    /* outside the image is background: padded so that the smoothed mask
     * is below the level on the crop's rim and every curve closes */
    int64_t pad = 2 + (int64_t)ceil(3 * (smooth > 0 ? smooth : 0));
    contour c;
    memset(&c, 0, sizeof c);
    c.m = m;
    c.i0 = lo[0] - pad;
    c.j0 = lo[1] - pad;
    c.w = hi[0] - lo[0] + 1 + 2 * pad;
    c.h = hi[1] - lo[1] + 1 + 2 * pad;
    size_t n = (size_t)(c.w * c.h);
    sm_status st = SM_OK;
    c.f = calloc(n, sizeof *c.f);
    for (int k = 0; k < 3; k++)
        c.id[k] = malloc(n * sizeof(int32_t));
    if (!c.f || !c.id[0] || !c.id[1] || !c.id[2]) {
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory for the label's contour (%zu nodes)",
                          n);
        goto done;
    }
    for (int k = 0; k < 3; k++)
        memset(c.id[k], 0xff, n * sizeof(int32_t));
    for (int64_t j = lo[1]; j <= hi[1]; j++)
        for (int64_t i = lo[0]; i <= hi[0]; i++)
            c.f[(j - c.j0) * c.w + (i - c.i0)] = mask[j * nx + i] ? 1.0 : 0.0;
    if (smooth > 0 && blur(c.f, c.w, c.h, smooth) != 0) {
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory smoothing the label");
        goto done;
    }
    /* a map that mirrors (negative determinant of the in-plane axes)
     * turns the index space's counterclockwise around */
    int flip = m[0] * m[5] - m[1] * m[4] < 0;
    for (int64_t b = 0; b + 1 < c.h; b++)
        for (int64_t a = 0; a + 1 < c.w; a++) {
            const int64_t x1[3] = {a, a + 1, a + 1}, y1[3] = {b, b, b + 1};
            const int64_t x2[3] = {a, a + 1, a}, y2[3] = {b, b + 1, b + 1};
            if (triangle(&c, x1, y1, flip) != 0 || triangle(&c, x2, y2, flip) != 0) {
                st = sm_error_set(err, SM_ERR_NOMEM, "out of memory for the label's contour "
                                  "(%ld segments)", (long)c.ns);
                goto done;
            }
        }
    if (c.ns == 0) {
        st = sm_error_set(err, SM_ERR_INVALID, "the smoothed label has no boundary at level 0.5 "
                          "(a selection thinner than the smoothing)");
        goto done;
    }
    sm_surface *s;
    if ((st = sm_surface_alloc(&s, 2, c.nv, c.ns, err)) != SM_OK)
        goto done;
    memcpy(s->coords, c.xy, (size_t)c.nv * 2 * sizeof(double));
    memcpy(s->facets, c.seg, (size_t)c.ns * 2 * sizeof(int32_t));
    *out = s;
done:
    free(c.f);
    for (int k = 0; k < 3; k++)
        free(c.id[k]);
    free(c.xy);
    free(c.seg);
    return st;
}
