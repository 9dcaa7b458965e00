/* The signed distance to a label map's boundary (sm_image.h,
 * sm_image_target_*): the image cropped to the padded box of the
 * selected voxels; a lightly smoothed mask (a Gaussian of sigma
 * `smooth` voxels: a binary mask's staircase is what the voxel-centre EDT
 * measures to, the smoothed level set is close to the shape it was
 * sampled from) or a float image's values; its level set at `level` as a
 * triangle surface by marching tetrahedra (sm_image_march.c); the signed
 * distance at the crop's voxel centres, exact at the voxels next to the
 * surface and through the nearest of those (sm_edt.h's nearest-site
 * transform) beyond, for the far field (sm_image_grid.c); within `band`
 * voxels of the boundary the exact signed distance to the surface at
 * any point.  The target's fields: sm_image_target.h. */
#include "shapematch/sm_image.h"

#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

#include "shapematch/sm_sdf.h"
#include "sm_alloc.h"
#include "sm_bvh.h"
#include "sm_edt.h"
#include "sm_image_march.h"
#include "sm_image_target.h"

/* ---- the field on the crop ---- */

/* One line; the same sums in the same order everywhere, only the bounds
 * test is left out where the whole window is inside. */
static void gauss1d(float *line, float *tmp, int64_t len, const double *w, int r)
{
    for (int64_t q = 0; q < len; q++) {
        double s = 0;
        if (q >= r && q + r < len) {
            const float *x = line + q - r;
            for (int t = 0; t <= 2 * r; t++)
                s += w[t] * x[t];
        } else {
            for (int t = -r; t <= r; t++) {
                int64_t p = q + t;
                if (p >= 0 && p < len)
                    s += w[t + r] * line[p];
            }
        }
        tmp[q] = (float)s;
    }
    memcpy(line, tmp, (size_t)len * sizeof *line);
}

/* Rows out[x] = sum over the window's rows of w[t] in[t][x] (x < len),
 * t from t0 to t1 in order, in double: per voxel the sums of gauss1d,
 * the voxels of a row at once. */
static void gauss_rows(float *out, const float *const *in, const double *w, int t0, int t1,
                       int64_t len, double *acc)
{
    for (int64_t x = 0; x < len; x++)
        acc[x] = 0;
    for (int t = t0; t <= t1; t++) {
        const float *row = in[t];
        double wt = w[t];
#pragma omp simd
        for (int64_t x = 0; x < len; x++)
            acc[x] += wt * row[x];
    }
    for (int64_t x = 0; x < len; x++)
        out[x] = (float)acc[x];
}

/* Separable Gaussian blur of f (n voxels) with sigma voxels, zero beyond;
 * f is zero outside the box lo..hi (inclusive) and is blurred there
 * only: the box reaches the Gaussian's radius beyond every nonzero
 * voxel, and a segment of a line summed with zero beyond it is the whole
 * line's sum (the same terms in the same order, zeros left out).  Along
 * x a line at a time; along y and z a plane of rows at a time (a copy
 * of the box's rows across the other axis), each output row the
 * weighted sum of its window's rows: the same sums, many voxels at once. */
static sm_status blur(float *f, const int64_t n[3], double sigma, const int64_t lo[3],
                      const int64_t hi[3], sm_error *err)
{
    int r = (int)ceil(3 * sigma);
    double w[64];
    if (r > 31)
        r = 31;
    double sum = 0;
    for (int t = -r; t <= r; t++)
        sum += w[t + r] = exp(-0.5 * t * t / (sigma * sigma));
    for (int t = 0; t <= 2 * r; t++)
        w[t] /= sum;
    int64_t m[3] = {hi[0] - lo[0] + 1, hi[1] - lo[1] + 1, hi[2] - lo[2] + 1};
    int64_t len = m[0] > m[1] ? m[0] : m[1];
    len = len > m[2] ? len : m[2];
    int64_t strides[3] = {1, n[0], n[0] * n[1]};
    int fail = 0;
    /* along x: lines */
#pragma omp parallel reduction(| : fail)
    {
        float *line = malloc((size_t)len * 2 * sizeof *line);
        fail |= !line;
#pragma omp for schedule(dynamic, 64)
        for (int64_t l = 0; l < m[1] * m[2]; l++) {
            if (!line)
                continue;
            float *at = f + lo[0] + (lo[1] + l % m[1]) * strides[1] + (lo[2] + l / m[1]) * strides[2];
            int nonzero = 0;
            for (int64_t q = 0; q < m[0]; q++)
                nonzero |= (line[q] = at[q]) != 0.0f;
            if (!nonzero) /* zero beyond too: it stays zero */
                continue;
            gauss1d(line, line + len, m[0], w, r);
            memcpy(at, line, (size_t)m[0] * sizeof *at);
        }
        free(line);
    }
    /* along y, then z: for each slice (y) or row of slices (z), the
     * box's rows along that axis copied, then summed back in place */
    for (int a = 1; a <= 2 && !fail; a++) {
        int c = a == 1 ? 2 : 1; /* the axis the planes are taken across */
#pragma omp parallel reduction(| : fail)
        {
            float *rows = malloc((size_t)(m[a] * m[0]) * sizeof *rows);
            double *acc = malloc((size_t)m[0] * sizeof *acc);
            const float **win = malloc((size_t)(2 * r + 1) * sizeof *win);
            fail |= !rows || !acc || !win;
#pragma omp for schedule(dynamic, 1)
            for (int64_t l = 0; l < m[c]; l++) {
                if (!rows || !acc || !win)
                    continue;
                float *base = f + lo[0] + (lo[c] + l) * strides[c] + lo[a] * strides[a];
                int nonzero = 0;
                for (int64_t q = 0; q < m[a]; q++) {
                    const float *src = base + q * strides[a];
                    float *dst = rows + q * m[0];
                    for (int64_t x = 0; x < m[0]; x++)
                        nonzero |= (dst[x] = src[x]) != 0.0f;
                }
                if (!nonzero)
                    continue;
                for (int64_t q = 0; q < m[a]; q++) {
                    /* the window's rows inside the box, in order */
                    int t0 = q >= r ? 0 : (int)(r - q), t1 = q + r < m[a] ? 2 * r : (int)(m[a] - 1 - q + r);
                    for (int t = t0; t <= t1; t++)
                        win[t] = rows + (q - r + t) * m[0];
                    gauss_rows(base + q * strides[a], win, w, t0, t1, m[0], acc);
                }
            }
            free(rows);
            free(acc);
            free(win);
        }
    }
    return fail ? sm_error_set(err, SM_ERR_NOMEM, "out of memory for the smoothing") : SM_OK;
}

/* ---- the target ---- */

static void invert(const double *m, double *inv)
{
    double a = m[0], b = m[1], c = m[2], d = m[4], e = m[5], f = m[6], g = m[8], h = m[9], i = m[10];
    double det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g);
    double r[9] = {(e * i - f * h) / det, (c * h - b * i) / det, (b * f - c * e) / det,
                   (f * g - d * i) / det, (a * i - c * g) / det, (c * d - a * f) / det,
                   (d * h - e * g) / det, (b * g - a * h) / det, (a * e - b * d) / det};
    for (int row = 0; row < 3; row++) {
        for (int col = 0; col < 3; col++)
            inv[4 * row + col] = r[3 * row + col];
        inv[4 * row + 3] = -(r[3 * row] * m[3] + r[3 * row + 1] * m[7] + r[3 * row + 2] * m[11]);
    }
}

void sm_image_target_free(sm_image_target *t)
{
    if (!t)
        return;
    free(t->edt);
    free(t->field);
    free(t->cells);
    free(t->slice_cells);
    free(t->ckeys);
    free(t->crun);
    free(t->cbits);
    sm_sdf_free(t->sdf);
    sm_surface_free(t->surface);
    free(t);
}

/* The crop (index box lo..hi of the selection, padded) and its field. */
static sm_status crop_field(const sm_image *im, const uint8_t *mask, const sm_image_select *sel,
                            const sm_image_target_opts *o, sm_image_target *t, float **field,
                            double *level, sm_error *err)
{
    const int64_t *n = im->dims;
    int64_t lo0 = n[0], lo1 = n[1], lo2 = n[2], hi0 = -1, hi1 = -1, hi2 = -1;
#pragma omp parallel for schedule(static) reduction(min : lo0, lo1, lo2) reduction(max : hi0, hi1, hi2)
    for (int64_t r = 0; r < n[1] * n[2]; r++) {
        const uint8_t *row = mask + r * n[0];
        int64_t first = -1, last = -1;
        for (int64_t i = 0; i < n[0]; i++)
            if (row[i]) {
                first = first < 0 ? i : first;
                last = i;
            }
        if (first < 0)
            continue;
        int64_t j = r % n[1], k = r / n[1];
        lo0 = first < lo0 ? first : lo0;
        hi0 = last > hi0 ? last : hi0;
        lo1 = j < lo1 ? j : lo1;
        hi1 = j > hi1 ? j : hi1;
        lo2 = k < lo2 ? k : lo2;
        hi2 = k > hi2 ? k : hi2;
    }
    int64_t lo[3] = {lo0, lo1, lo2}, hi[3] = {hi0, hi1, hi2};
    if (hi[0] < 0)
        return sm_error_set(err, SM_ERR_INVALID, "the selected label is empty");
    int raw = !sel->has_label && (im->type == SM_VOXEL_F32 || im->type == SM_VOXEL_F64);
    double smooth = raw ? 0 : o->smooth;
    int64_t pad = (int64_t)ceil(3 * smooth) + 2 + (int64_t)ceil(o->pad_voxels);
    int64_t reach = smooth > 0 ? (int64_t)fmin(31, ceil(3 * smooth)) : 0, llo[3], lhi[3];
    memcpy(llo, lo, sizeof llo);
    memcpy(lhi, hi, sizeof lhi);
    int64_t total = 1;
    for (int c = 0; c < 3; c++) {
        lo[c] -= pad;
        hi[c] += pad;
        if (o->whole_image) {
            lo[c] = lo[c] < 0 ? lo[c] : 0;
            hi[c] = hi[c] > n[c] - 1 ? hi[c] : n[c] - 1;
        }
        t->n[c] = hi[c] - lo[c] + 1;
        total *= t->n[c];
    }
    if (total > SM_IMAGE_MAX_VOXELS / 4)
        return sm_error_set(err, SM_ERR_INVALID, "the padded label box has too many voxels");
    float *f = sm__alloc_huge((size_t)total * sizeof *f); /* written at once */
    if (!f)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the label's field");
    for (int c = 0; c < 3; c++) {
        t->act_lo[c] = llo[c] - reach - lo[c] > 0 ? llo[c] - reach - lo[c] : 0;
        t->act_hi[c] = lhi[c] + reach - lo[c] < t->n[c] - 1 ? lhi[c] + reach - lo[c] : t->n[c] - 1;
    }
    /* a row at a time; outside the image: background (0, below any level) */
    float outside = raw ? (float)fmin(0, sel->level - 1) : 0.0f;
#pragma omp parallel for schedule(static)
    for (int64_t r = 0; r < t->n[1] * t->n[2]; r++) {
        int64_t j = lo[1] + r % t->n[1], k = lo[2] + r / t->n[1];
        float *row = f + r * t->n[0];
        int in = j >= 0 && k >= 0 && j < n[1] && k < n[2];
        if (in && !raw && lo[0] >= 0 && lo[0] + t->n[0] <= n[0]) { /* the whole row inside */
            const uint8_t *from = mask + lo[0] + n[0] * (j + n[1] * k);
            for (int64_t v = 0; v < t->n[0]; v++)
                row[v] = (float)from[v];
            continue;
        }
        for (int64_t v = 0; v < t->n[0]; v++) {
            int64_t i = lo[0] + v;
            int64_t at = i + n[0] * (j + n[1] * k);
            row[v] = !in || i < 0 || i >= n[0] ? outside
                     : raw ? (float)sm_image_value(im, at) : (float)mask[at];
        }
    }
    *level = raw ? sel->level : 0.5;
    sm_status st = smooth > 0 ? blur(f, t->n, smooth, t->act_lo, t->act_hi, err) : SM_OK;
    if (st != SM_OK) {
        free(f);
        return st;
    }
    const double *m = im->ijk_to_lps;
    for (int row = 0; row < 3; row++) {
        for (int col = 0; col < 3; col++)
            t->map[4 * row + col] = m[4 * row + col];
        t->map[4 * row + 3] = m[4 * row + 3] + m[4 * row] * (double)lo[0] +
                              m[4 * row + 1] * (double)lo[1] + m[4 * row + 2] * (double)lo[2];
    }
    for (int col = 0; col < 3; col++)
        t->h[col] = sqrt(m[col] * m[col] + m[4 + col] * m[4 + col] + m[8 + col] * m[8 + col]);
    *field = f;
    return SM_OK;
}

/* The smallest singular value of the 3x3 part of the 3x4 map m: the
 * square root of the smallest eigenvalue of m^T m (symmetric: the
 * trigonometric closed form), less a relative 1e-9 so that it bounds
 * from below; the larger of it and 1 / ||m^-1||_F (a bound of its own,
 * for a rounding-spoiled case). */
static double smallest_singular(const double *m)
{
    double a[3][3];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            a[i][j] = m[i] * m[j] + m[4 + i] * m[4 + j] + m[8 + i] * m[8 + j];
    double p1 = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
    double q = (a[0][0] + a[1][1] + a[2][2]) / 3, lmin;
    if (p1 == 0) {
        lmin = fmin(a[0][0], fmin(a[1][1], a[2][2]));
    } else {
        double p2 = (a[0][0] - q) * (a[0][0] - q) + (a[1][1] - q) * (a[1][1] - q) +
                    (a[2][2] - q) * (a[2][2] - q) + 2 * p1;
        double p = sqrt(p2 / 6), b[3][3];
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++)
                b[i][j] = (a[i][j] - (i == j ? q : 0)) / p;
        double r = (b[0][0] * (b[1][1] * b[2][2] - b[1][2] * b[2][1]) -
                    b[0][1] * (b[1][0] * b[2][2] - b[1][2] * b[2][0]) +
                    b[0][2] * (b[1][0] * b[2][1] - b[1][1] * b[2][0])) / 2;
        double phi = r <= -1 ? M_PI / 3 : r >= 1 ? 0 : acos(r) / 3;
        lmin = q + 2 * p * cos(phi + 2 * M_PI / 3);
    }
    double inv[12], fro = 0;
    invert(m, inv);
    for (int row = 0; row < 3; row++)
        for (int col = 0; col < 3; col++)
            fro += inv[4 * row + col] * inv[4 * row + col];
    return fmax(lmin > 0 ? sqrt(lmin) * (1 - 1e-9) : 0, 1 / sqrt(fro));
}

/* t->step from t->map and t->smin: the spacing (less a relative 1e-9)
 * on an orthogonal grid, where an index gap g is sqrt(sum (g h)^2) long
 * in the world; smin on every axis otherwise. */
static void grid_steps(sm_image_target *t)
{
    const double *m = t->map;
    int orthogonal = 1;
    for (int a = 0; a < 3; a++)
        for (int b = a + 1; b < 3; b++) {
            double dot = m[a] * m[b] + m[4 + a] * m[4 + b] + m[8 + a] * m[8 + b];
            orthogonal &= fabs(dot) <= 1e-12 * t->h[a] * t->h[b];
        }
    for (int a = 0; a < 3; a++)
        t->step[a] = orthogonal ? fmax(t->h[a] * (1 - 1e-9), t->smin) : t->smin;
}

static float float_below(double x)
{
    float f = (float)x;
    return (double)f > x ? nextafterf(f, -INFINITY) : f;
}

static float float_above(double x)
{
    float f = (float)x;
    return (double)f < x ? nextafterf(f, INFINITY) : f;
}

static sm_status index_cells(sm_image_target *t, const int64_t *tcell, int64_t nt, sm_error *err)
{
    int64_t runs = 0;
    for (int64_t i = 0; i < nt; i++)
        runs += i == 0 || tcell[i] != tcell[i - 1];
    int64_t cap = 1024;
    while (cap < 2 * runs)
        cap *= 2;
    t->ccap = cap;
    t->ncells = runs;
    t->cells = malloc((size_t)runs * sizeof *t->cells);
    t->slice_cells = malloc((size_t)(t->n[2] + 1) * sizeof *t->slice_cells);
    t->ckeys = calloc((size_t)cap, sizeof *t->ckeys);
    t->crun = malloc((size_t)cap * sizeof *t->crun);
    int64_t ncells = t->n[0] * t->n[1] * t->n[2], plane = t->n[0] * t->n[1];
    t->cbits = calloc((size_t)(ncells / 64 + 1), sizeof *t->cbits);
    if (!t->cells || !t->slice_cells || !t->ckeys || !t->crun || !t->cbits)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the label's surface");
    int64_t r = 0, k = 0;
    for (int64_t i = 0; i < nt; r++) {
        int64_t j = i;
        while (j < nt && tcell[j] == tcell[i])
            j++;
        while (k <= tcell[i] / plane)
            t->slice_cells[k++] = r;
        t->cells[r] = (cell_tris){.cell = (int32_t)tcell[i], .first = (int32_t)i,
                                  .count = (int32_t)(j - i)};
        uint64_t s = sm__cell_hash(tcell[i] + 1, cap);
        while (t->ckeys[s])
            s = (s + 1) & (uint64_t)(cap - 1);
        t->ckeys[s] = (int32_t)(tcell[i] + 1);
        t->crun[s] = (int32_t)r;
        t->cbits[tcell[i] >> 6] |= (uint64_t)1 << (tcell[i] & 63);
        i = j;
    }
    while (k <= t->n[2])
        t->slice_cells[k++] = runs;
    const sm_surface *sf = t->surface;
#pragma omp parallel for schedule(static)
    for (int64_t q = 0; q < runs; q++) {
        cell_tris *c = t->cells + q;
        double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (int32_t f = c->first; f < c->first + c->count; f++)
            for (int v = 0; v < 3; v++) {
                const double *x = sf->coords + 3 * sf->facets[3 * f + v];
                for (int a = 0; a < 3; a++) {
                    lo[a] = x[a] < lo[a] ? x[a] : lo[a];
                    hi[a] = x[a] > hi[a] ? x[a] : hi[a];
                }
            }
        for (int a = 0; a < 3; a++) {
            c->lo[a] = float_below(lo[a]);
            c->hi[a] = float_above(hi[a]);
        }
    }
    return SM_OK;
}

/* (sm_image_target.h) */
const cell_tris *sm__image_triangle_cell(const sm_image_target *t, int32_t f)
{
    int64_t lo = 0, hi = t->ncells - 1;
    while (lo < hi) {
        int64_t mid = (lo + hi + 1) / 2;
        if (t->cells[mid].first <= f)
            lo = mid;
        else
            hi = mid - 1;
    }
    return t->cells + lo;
}

/* The squared distance from p to the bounding box of triangle abc: a
 * lower bound of the distance to the triangle. */
static inline double triangle_box2(const double *p, const double *a, const double *b,
                                   const double *c)
{
    double box2 = 0;
    for (int r = 0; r < 3; r++) {
        double lo = a[r] < b[r] ? a[r] : b[r], hi = a[r] < b[r] ? b[r] : a[r];
        lo = c[r] < lo ? c[r] : lo;
        hi = c[r] > hi ? c[r] : hi;
        double g = p[r] < lo ? lo - p[r] : p[r] > hi ? p[r] - hi : 0;
        box2 += g * g;
    }
    return box2;
}

/* The squared distance from p to the plane of triangle abc, a lower
 * bound of the distance to the triangle (less a relative 1e-9 for its
 * rounding; 0 for a degenerate triangle). */
static inline double triangle_plane2(const double *p, const double *a, const double *b,
                                     const double *c)
{
    double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    double w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    double nrm[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
    double nn = nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2];
    double h = nrm[0] * (p[0] - a[0]) + nrm[1] * (p[1] - a[1]) + nrm[2] * (p[2] - a[2]);
    return nn > 0 ? h * h / nn * (1 - 1e-9) : 0;
}

/* (sm_image_target.h) Triangles whose box or plane is not nearer are
 * skipped: most of them, the exact test costs several times the two
 * bounds. */
void sm__image_range_nearest(const sm_image_target *t, int32_t first, int32_t count,
                             const double *p, double *best2, int32_t *bestf)
{
    const sm_surface *s = t->surface;
    double w[3];
    for (int32_t f = first; f < first + count; f++) {
        const int32_t *v = s->facets + 3 * f;
        const double *a = s->coords + 3 * v[0], *b = s->coords + 3 * v[1], *c = s->coords + 3 * v[2];
        if (triangle_box2(p, a, b, c) >= *best2 || triangle_plane2(p, a, b, c) >= *best2)
            continue;
        double d2 = sm__triangle_closest(p, a, b, c, w);
        if (d2 < *best2) {
            *best2 = d2;
            *bestf = f;
        }
    }
}

/* How far index q lies from the cell [c, c + 1] along one axis. */
static inline double gap(double c, double q)
{
    return q < c ? c - q : q > c + 1 ? q - (c + 1) : 0;
}

/* Distance from world point p to the surface, exactly: the cells in
 * Chebyshev rings around the cell of p's crop index (clamped into the
 * crop: for a point outside it, the clamped index is its projection on
 * the crop's box, no farther in index space from any cell than p), ring
 * by ring until the next ring's cells (>= k index steps away, each at
 * least smin long) cannot be nearer than the nearest triangle found. */
static double surface_distance(const sm_image_target *t, const double *p, double *closest)
{
    return sm__image_surface_distance_from(t, p, INFINITY, -1, closest, NULL);
}

/* (sm_image_target.h) */
double sm__image_surface_distance_from(const sm_image_target *t, const double *p, double best2,
                                       int32_t bestf, double *closest, int32_t *nearest)
{
    int64_t c0[3], m[3];
    double qc[3]; /* p's index, clamped into the crop */
    for (int row = 0; row < 3; row++) {
        double q = t->inv[4 * row] * p[0] + t->inv[4 * row + 1] * p[1] + t->inv[4 * row + 2] * p[2] +
                   t->inv[4 * row + 3];
        m[row] = t->n[row] - 1; /* cells per axis */
        qc[row] = !(q >= 0) ? 0 : q > (double)m[row] ? (double)m[row] : q;
        double cl = floor(qc[row]);
        c0[row] = cl >= (double)(m[row] - 1) ? m[row] - 1 : (int64_t)cl;
    }
    double s2 = t->smin * t->smin;
    const sm_surface *s = t->surface;
    int64_t kmax = m[0] > m[1] ? m[0] : m[1];
    kmax = kmax > m[2] ? kmax : m[2];
    for (int64_t k = 0; k <= kmax; k++) {
        for (int64_t dz = -k; dz <= k; dz++) {
            int64_t z = c0[2] + dz;
            if (z < 0 || z >= m[2])
                continue;
            double gz = gap((double)z, qc[2]);
            for (int64_t dy = -k; dy <= k; dy++) {
                int64_t y = c0[1] + dy;
                if (y < 0 || y >= m[1])
                    continue;
                double gy = gap((double)y, qc[1]);
                int face = dz == -k || dz == k || dy == -k || dy == k;
                for (int64_t dx = -k; dx <= k; dx += face ? 1 : 2 * k) {
                    int64_t x = c0[0] + dx;
                    double gx = gap((double)x, qc[0]);
                    /* the cell's box is at least this far (index gaps,
                     * each index unit at least smin long) */
                    if (x >= 0 && x < m[0] && s2 * (gx * gx + gy * gy + gz * gz) < best2)
                        sm__cell_nearest(t, sm__cell_triangles(t, x + t->n[0] * (y + t->n[1] * z)),
                                         p, &best2, &bestf);
                    if (k == 0)
                        break;
                }
            }
        }
        double reach = (double)k * t->smin;
        if (reach * reach >= best2)
            break;
    }
    if (nearest)
        *nearest = bestf;
    if (closest && bestf >= 0) {
        const int32_t *v = s->facets + 3 * bestf;
        const double *a = s->coords + 3 * v[0], *b = s->coords + 3 * v[1], *c = s->coords + 3 * v[2];
        double w[3];
        sm__triangle_closest(p, a, b, c, w);
        for (int row = 0; row < 3; row++)
            closest[row] = w[0] * a[row] + w[1] * b[row] + w[2] * c[row];
    }
    return sqrt(best2);
}

/* The field's value at p as the marching's piecewise-linear field: the
 * Kuhn tetrahedron of p's cell that holds it (axes by decreasing
 * fraction), linear there; so >= level exactly on the surface's inside.
 * -INFINITY outside the crop. */
static double field_at(const sm_image_target *t, const double *p)
{
    double u[3];
    int64_t base[3];
    for (int row = 0; row < 3; row++) {
        double q = t->inv[4 * row] * p[0] + t->inv[4 * row + 1] * p[1] + t->inv[4 * row + 2] * p[2] +
                   t->inv[4 * row + 3];
        if (!(q >= 0) || !(q <= (double)(t->n[row] - 1)))
            return -INFINITY;
        base[row] = (int64_t)floor(q);
        if (base[row] >= t->n[row] - 1)
            base[row] = t->n[row] > 1 ? t->n[row] - 2 : 0;
        u[row] = q - (double)base[row];
    }
    int a[3] = {0, 1, 2};
    for (int i = 0; i < 2; i++) /* sort the axes by decreasing u */
        for (int j = 0; j < 2 - i; j++)
            if (u[a[j]] < u[a[j + 1]]) {
                int s = a[j];
                a[j] = a[j + 1];
                a[j + 1] = s;
            }
    int64_t stride[3] = {1, t->n[0], t->n[0] * t->n[1]};
    int64_t node = base[0] + stride[1] * base[1] + stride[2] * base[2];
    double w[4] = {1 - u[a[0]], u[a[0]] - u[a[1]], u[a[1]] - u[a[2]], u[a[2]]};
    double v = w[0] * t->field[node];
    for (int s = 0; s < 3; s++) {
        node += stride[a[s]] * (t->n[a[s]] > 1 ? 1 : 0);
        v += w[s + 1] * t->field[node];
    }
    return v;
}

/* The voxel-centre signed EDT of the thresholded field (sm_image.h). */
sm_status sm_image_target_voxel_edt(const sm_image_target *t, float **edt, sm_error *err)
{
    int64_t total = t->n[0] * t->n[1] * t->n[2];
    uint8_t *mask = malloc((size_t)total);
    *edt = malloc((size_t)total * sizeof **edt);
    sm_status st = mask && *edt ? SM_OK
                   : sm_error_set(err, SM_ERR_NOMEM, "out of memory for the distance transform");
    if (st == SM_OK) {
#pragma omp parallel for schedule(static)
        for (int64_t v = 0; v < total; v++)
            mask[v] = t->field[v] >= t->level;
        st = sm_edt_signed(t->n, t->h, mask, *edt, err);
    }
    free(mask);
    if (st != SM_OK) {
        free(*edt);
        *edt = NULL;
    }
    return st;
}

sm_status sm_image_target_new(const sm_image *im, const uint8_t *mask, const sm_image_select *sel,
                              const sm_image_target_opts *o, sm_image_target **out, sm_error *err)
{
    *out = NULL;
    sm_image_target *t = calloc(1, sizeof *t);
    if (!t)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    float *f = NULL;
    double level = 0.5;
    sm_status st = crop_field(im, mask, sel, o, t, &f, &level, err);
    if (st != SM_OK)
        goto done;
    invert(t->map, t->inv);
    int64_t total = t->n[0] * t->n[1] * t->n[2];
    t->edt = sm__alloc_huge((size_t)total * sizeof *t->edt); /* written at once */
    if (!t->edt) {
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory for the distance transform");
        goto done;
    }
    mt_builder b = {.f = f, .n = {t->n[0], t->n[1], t->n[2]}, .lo = t->act_lo, .hi = t->act_hi,
                    .level = level, .map = t->map};
    st = sm__image_march(&b, &t->surface, err);
    if (st == SM_ERR_INVALID && o->smooth > 0 && level == 0.5)
        /* a label thinner than about two sigmas is smoothed below 0.5 */
        st = sm_error_set(err, SM_ERR_INVALID, "the label's boundary vanished under the smoothing "
                          "of %g voxels (a structure a few voxels thin): give a smaller smoothing "
                          "(--smooth 0 keeps the mask's own boundary)", o->smooth);
    free(b.coords);
    free(b.tris);
    free(b.keys);
    free(b.vals);
    if (st == SM_OK)
        st = index_cells(t, b.tcell, b.nt, err);
    free(b.tcell);
    if (st == SM_OK) {
        t->band = o->band_voxels * fmax(t->h[0], fmax(t->h[1], t->h[2]));
        t->grid_band = o->whole_image;
        t->smin = smallest_singular(t->map);
        grid_steps(t);
        st = sm__image_distance_field(t, f, level, err);
    }
    if (st != SM_OK)
        goto done;
    t->field = f; /* the sign near the surface */
    t->level = level;
    f = NULL;
    if (o->hierarchy)
        st = sm_sdf_new(t->surface, &t->sdf, err);
done:
    free(f);
    if (st != SM_OK)
        sm_image_target_free(t);
    else
        *out = t;
    return st;
}

const sm_surface *sm_image_target_surface(const sm_image_target *t)
{
    return t->surface;
}

const sm_sdf *sm_image_target_sdf(const sm_image_target *t)
{
    return t->sdf;
}

void sm_image_target_grid(const sm_image_target *t, int64_t n[3], double map[12], const float **edt)
{
    memcpy(n, t->n, 3 * sizeof *n);
    memcpy(map, t->map, 12 * sizeof *map);
    *edt = t->edt;
}

float *sm_image_target_take_grid(sm_image_target *t)
{
    float *d = t->edt;
    t->edt = NULL;
    return d;
}

/* Trilinear EDT at world point x; NAN outside the crop. */
static double edt_at(const sm_image_target *t, const double *x)
{
    double ijk[3];
    int64_t base[3];
    double w[3];
    for (int row = 0; row < 3; row++) {
        ijk[row] = t->inv[4 * row] * x[0] + t->inv[4 * row + 1] * x[1] + t->inv[4 * row + 2] * x[2] +
                   t->inv[4 * row + 3];
        if (!(ijk[row] >= 0) || !(ijk[row] <= (double)(t->n[row] - 1)))
            return NAN;
        base[row] = (int64_t)floor(ijk[row]);
        if (base[row] >= t->n[row] - 1)
            base[row] = t->n[row] > 1 ? t->n[row] - 2 : 0;
        w[row] = ijk[row] - (double)base[row];
    }
    double s = 0;
    for (int corner = 0; corner < 8; corner++) {
        double wt = 1;
        int64_t at = 0, stride = 1;
        for (int a = 0; a < 3; a++) {
            int up = (corner >> a) & 1;
            wt *= up ? w[a] : 1 - w[a];
            int64_t idx = base[a] + up;
            if (idx >= t->n[a])
                idx = t->n[a] - 1;
            at += idx * stride;
            stride *= t->n[a];
        }
        if (wt != 0)
            s += wt * t->edt[at];
    }
    return s;
}

/* The crop point nearest p in index space (p itself inside the crop). */
static void clamp_to_crop(const sm_image_target *t, const double *p, double *q)
{
    double ijk[3];
    for (int row = 0; row < 3; row++) {
        double x = t->inv[4 * row] * p[0] + t->inv[4 * row + 1] * p[1] + t->inv[4 * row + 2] * p[2] +
                   t->inv[4 * row + 3];
        double top = (double)(t->n[row] - 1);
        ijk[row] = !(x >= 0) ? 0 : x > top ? top : x;
    }
    sm__grid_world(t->map, ijk[0], ijk[1], ijk[2], q);
}

/* Signed distance at p; *exact: 1 when computed exactly. */
static double signed_at(const sm_image_target *t, const double *p, int *exact)
{
    double e = edt_at(t, p);
    *exact = 0;
    if (isnan(e)) { /* outside the crop (so outside the label): the way
                     * to the crop plus the EDT there, an upper bound;
                     * exact when that is within twice the band */
        double q[3];
        clamp_to_crop(t, p, q);
        double up = sqrt((p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) +
                         (p[2] - q[2]) * (p[2] - q[2])) + fabs(edt_at(t, q));
        if (up > 2 * t->band)
            return up;
        *exact = 1;
        return surface_distance(t, p, NULL);
    }
    if (fabs(e) > t->band)
        return e;
    *exact = 1;
    double d = surface_distance(t, p, NULL);
    return field_at(t, p) >= t->level ? -d : d;
}

sm_status sm_image_target_signed(const sm_image_target *t, int64_t n, const double *pts, double *out,
                                 int64_t *exact, sm_error *err)
{
    (void)err;
    int64_t near = 0;
#pragma omp parallel for schedule(dynamic, 256) reduction(+ : near)
    for (int64_t p = 0; p < n; p++) {
        int ex;
        out[p] = signed_at(t, pts + 3 * p, &ex);
        near += ex;
    }
    if (exact)
        *exact = near;
    return SM_OK;
}

static void unsigned_fn(void *user, int64_t n, const double *pts, double *dist)
{
    const sm_image_target *t = user;
#pragma omp parallel for schedule(dynamic, 256)
    for (int64_t p = 0; p < n; p++) {
        int ex;
        dist[p] = fabs(signed_at(t, pts + 3 * p, &ex));
    }
}

sm_status sm_image_target_background(const sm_image_target *t, const double lo[3],
                                     const double hi[3], double h, sm_mesh **out, sm_error *err)
{
    return sm_background_graded_fn_new(3, lo, hi, h, unsigned_fn, (void *)t, out, err);
}
