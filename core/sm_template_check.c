/* Whether a surface can be a template's boundary (sm_template_mesh.h):
 * closed, manifold, consistently oriented, not crossing itself, with a
 * positive enclosed volume.  Everything here is bounded by the facet
 * count (sorts and a uniform grid), since it is what hostile uploads
 * reach first (tests/fuzz/fuzz_template_surface.c). */
#include "shapematch/sm_template_mesh.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* An edge of a facet: its two vertices sorted, and whether the facet
 * goes lo -> hi (1) or hi -> lo (0). */
typedef struct edge_use {
    int32_t lo, hi;
    int32_t facet;
    int32_t forward;
} edge_use;

static int edge_cmp(const void *a, const void *b)
{
    const edge_use *x = a, *y = b;
    if (x->lo != y->lo)
        return x->lo < y->lo ? -1 : 1;
    if (x->hi != y->hi)
        return x->hi < y->hi ? -1 : 1;
    return (x->facet > y->facet) - (x->facet < y->facet);
}

static void vertex_text(const sm_surface *s, int32_t v, char *buf, size_t cap)
{
    const double *p = s->coords + (size_t)v * (size_t)s->dim;
    if (s->dim == 3)
        snprintf(buf, cap, "(%.6g, %.6g, %.6g)", p[0], p[1], p[2]);
    else
        snprintf(buf, cap, "(%.6g, %.6g)", p[0], p[1]);
}

/* 3D: every edge on exactly two triangles, in opposite directions. */
static sm_status check_edges(const sm_surface *s, sm_error *err)
{
    size_t n = (size_t)s->nfacets * 3;
    edge_use *e = malloc(n * sizeof *e);
    if (!e)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory checking the surface's edges");
    for (int32_t f = 0; f < s->nfacets; f++)
        for (int k = 0; k < 3; k++) {
            int32_t a = s->facets[3 * (size_t)f + k], b = s->facets[3 * (size_t)f + (k + 1) % 3];
            e[3 * (size_t)f + k] = (edge_use){a < b ? a : b, a < b ? b : a, f, a < b};
        }
    qsort(e, n, sizeof *e, edge_cmp);
    int64_t open = 0, nonmanifold = 0, flipped = 0;
    size_t open_at = 0, nm_at = 0, flip_at = 0;
    for (size_t i = 0; i < n;) {
        size_t j = i + 1;
        while (j < n && e[j].lo == e[i].lo && e[j].hi == e[i].hi)
            j++;
        if (j - i == 1 && open++ == 0)
            open_at = i;
        if (j - i > 2 && nonmanifold++ == 0)
            nm_at = i;
        if (j - i == 2 && e[i].forward == e[i + 1].forward && flipped++ == 0)
            flip_at = i;
        i = j;
    }
    char a[96], b[96];
    sm_status st = SM_OK;
    if (nonmanifold) {
        vertex_text(s, e[nm_at].lo, a, sizeof a);
        vertex_text(s, e[nm_at].hi, b, sizeof b);
        st = sm_error_set(err, SM_ERR_INVALID,
                          "non-manifold: %lld edges on three triangles or more, e.g. between %s "
                          "and %s; a template's boundary must be a closed manifold surface",
                          (long long)nonmanifold, a, b);
    } else if (open) {
        vertex_text(s, e[open_at].lo, a, sizeof a);
        vertex_text(s, e[open_at].hi, b, sizeof b);
        st = sm_error_set(err, SM_ERR_INVALID,
                          "open: %lld edges on one triangle only (holes), e.g. between %s and "
                          "%s; a template's boundary must be closed",
                          (long long)open, a, b);
    } else if (flipped) {
        vertex_text(s, e[flip_at].lo, a, sizeof a);
        vertex_text(s, e[flip_at].hi, b, sizeof b);
        st = sm_error_set(err, SM_ERR_INVALID,
                          "inconsistent orientation: %lld edges run the same way in both of "
                          "their triangles, e.g. between %s and %s",
                          (long long)flipped, a, b);
    }
    free(e);
    return st;
}

/* 2D: every vertex used starts one segment and ends one. */
static sm_status check_ends(const sm_surface *s, sm_error *err)
{
    int32_t *in = calloc((size_t)s->nverts, sizeof *in), *out = calloc((size_t)s->nverts, sizeof *out);
    if (!in || !out) {
        free(in);
        free(out);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory checking the curve's ends");
    }
    for (int32_t f = 0; f < s->nfacets; f++) {
        out[s->facets[2 * (size_t)f]]++;
        in[s->facets[2 * (size_t)f + 1]]++;
    }
    int64_t open = 0, branch = 0, flipped = 0;
    int32_t open_at = 0, branch_at = 0, flip_at = 0;
    for (int32_t v = 0; v < s->nverts; v++) {
        int32_t deg = in[v] + out[v];
        if (deg == 0)
            continue;
        if (deg == 1 && open++ == 0)
            open_at = v;
        else if (deg > 2 && branch++ == 0)
            branch_at = v;
        else if (deg == 2 && in[v] != 1 && flipped++ == 0)
            flip_at = v;
    }
    free(in);
    free(out);
    char a[96];
    if (branch) {
        vertex_text(s, branch_at, a, sizeof a);
        return sm_error_set(err, SM_ERR_INVALID,
                            "non-manifold: %lld vertices on three segments or more, e.g. %s; a "
                            "template's boundary must be closed curves that do not branch",
                            (long long)branch, a);
    }
    if (open) {
        vertex_text(s, open_at, a, sizeof a);
        return sm_error_set(err, SM_ERR_INVALID,
                            "open: %lld curve ends on one segment only, e.g. %s; a template's "
                            "boundary must be closed",
                            (long long)open, a);
    }
    if (flipped) {
        vertex_text(s, flip_at, a, sizeof a);
        return sm_error_set(err, SM_ERR_INVALID,
                            "inconsistent orientation: %lld vertices where two segments meet "
                            "head to head, e.g. %s",
                            (long long)flipped, a);
    }
    return SM_OK;
}

/* ------------------------------------------------------ self-intersection */

static double orient3(const double *a, const double *b, const double *c, const double *d)
{
    double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    double v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    double w[3] = {d[0] - a[0], d[1] - a[1], d[2] - a[2]};
    return u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0]) +
           u[2] * (v[0] * w[1] - v[1] * w[0]);
}

static double orient2(const double *a, const double *b, const double *c)
{
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
}

/* The sign of an orientation beyond tol (0 within): near-coplanar
 * facets of a flat region (a label map's surface has many) would
 * otherwise cross by rounding noise. */
static int sgn(double x, double tol)
{
    return (x > tol) - (x < -tol);
}

/* Longest edge of the two facets f and g: the scale of the tolerances. */
static double pair_scale(const sm_surface *s, int32_t f, int32_t g)
{
    int d = s->dim;
    double L = 0;
    const int32_t *F[2] = {s->facets + (size_t)d * f, s->facets + (size_t)d * g};
    for (int q = 0; q < 2; q++)
        for (int i = 0; i < d; i++)
            for (int j = i + 1; j < d; j++) {
                const double *a = s->coords + (size_t)d * F[q][i], *b = s->coords + (size_t)d * F[q][j];
                double l = 0;
                for (int c = 0; c < d; c++)
                    l += (a[c] - b[c]) * (a[c] - b[c]);
                L = fmax(L, sqrt(l));
            }
    return L;
}

/* Segment pq through the inside of triangle abc: a proper crossing (the
 * end points strictly on both sides, the line strictly inside the three
 * edges).  Touching and coplanar overlaps are not reported: a closed
 * manifold surface that crosses itself does so properly somewhere. */
static int segment_hits_triangle(const double *p, const double *q, const double *a,
                                 const double *b, const double *c, double tol)
{
    int sp = sgn(orient3(a, b, c, p), tol), sq = sgn(orient3(a, b, c, q), tol);
    if (sp == 0 || sq == 0 || sp == sq)
        return 0;
    int s1 = sgn(orient3(p, q, a, b), tol), s2 = sgn(orient3(p, q, b, c), tol),
        s3 = sgn(orient3(p, q, c, a), tol);
    return s1 != 0 && s1 == s2 && s2 == s3;
}

static int triangles_cross(const sm_surface *s, int32_t f, int32_t g)
{
    const double *A[3], *B[3];
    for (int k = 0; k < 3; k++) {
        A[k] = s->coords + 3 * (size_t)s->facets[3 * (size_t)f + k];
        B[k] = s->coords + 3 * (size_t)s->facets[3 * (size_t)g + k];
    }
    double L = pair_scale(s, f, g), tol = 1e-10 * L * L * L;
    for (int k = 0; k < 3; k++)
        if (segment_hits_triangle(A[k], A[(k + 1) % 3], B[0], B[1], B[2], tol) ||
            segment_hits_triangle(B[k], B[(k + 1) % 3], A[0], A[1], A[2], tol))
            return 1;
    return 0;
}

static int segments_cross(const sm_surface *s, int32_t f, int32_t g)
{
    const double *a = s->coords + 2 * (size_t)s->facets[2 * (size_t)f];
    const double *b = s->coords + 2 * (size_t)s->facets[2 * (size_t)f + 1];
    const double *c = s->coords + 2 * (size_t)s->facets[2 * (size_t)g];
    const double *d = s->coords + 2 * (size_t)s->facets[2 * (size_t)g + 1];
    double L = pair_scale(s, f, g), tol = 1e-10 * L * L;
    int s1 = sgn(orient2(a, b, c), tol), s2 = sgn(orient2(a, b, d), tol);
    int s3 = sgn(orient2(c, d, a), tol), s4 = sgn(orient2(c, d, b), tol);
    return s1 && s2 && s3 && s4 && s1 != s2 && s3 != s4;
}

static int share_vertex(const sm_surface *s, int32_t f, int32_t g)
{
    int d = s->dim;
    for (int i = 0; i < d; i++)
        for (int j = 0; j < d; j++)
            if (s->facets[(size_t)d * f + i] == s->facets[(size_t)d * g + j])
                return 1;
    return 0;
}

/* Facet boxes (lo then hi, dim each). */
static void facet_box(const sm_surface *s, int32_t f, double *lo, double *hi)
{
    int d = s->dim;
    for (int c = 0; c < d; c++) {
        lo[c] = INFINITY;
        hi[c] = -INFINITY;
    }
    for (int k = 0; k < d; k++) {
        const double *p = s->coords + (size_t)d * s->facets[(size_t)d * f + k];
        for (int c = 0; c < d; c++) {
            lo[c] = fmin(lo[c], p[c]);
            hi[c] = fmax(hi[c], p[c]);
        }
    }
}

/* Entries of the grid beyond which the test gives up (facets of very
 * uneven sizes, each large one in many cells): a bound on its memory,
 * 32 cells a facet on average (a facet of about the mean size covers 1
 * to 8), plus a constant for small surfaces. */
#define GRID_MAX_ENTRIES(nf) (32 * (int64_t)(nf) + (1 << 20))

typedef struct grid {
    int d;
    double lo[3], cell;
    int64_t n[3];
} grid;

static void cell_range(const grid *G, const double *lo, const double *hi, int64_t *a, int64_t *b)
{
    for (int c = 0; c < G->d; c++) {
        a[c] = (int64_t)floor((lo[c] - G->lo[c]) / G->cell);
        b[c] = (int64_t)floor((hi[c] - G->lo[c]) / G->cell);
        a[c] = a[c] < 0 ? 0 : a[c] >= G->n[c] ? G->n[c] - 1 : a[c];
        b[c] = b[c] < 0 ? 0 : b[c] >= G->n[c] ? G->n[c] - 1 : b[c];
    }
    for (int c = G->d; c < 3; c++)
        a[c] = b[c] = 0;
}

static int64_t cell_id(const grid *G, int64_t i, int64_t j, int64_t k)
{
    return (k * G->n[1] + j) * G->n[0] + i;
}

/* The cells a box covers. */
static int64_t box_cells(const grid *G, const double *lo, const double *hi)
{
    int64_t a[3], b[3];
    cell_range(G, lo, hi, a, b);
    return (b[0] - a[0] + 1) * (b[1] - a[1] + 1) * (b[2] - a[2] + 1);
}

/* The facets' boxes (lo then hi, dim each, into box) and a grid over
 * them: cells about twice the mean facet extent, not more cells than
 * facets times 8. */
static void grid_setup(const sm_surface *s, double *box, grid *G)
{
    int d = s->dim;
    int32_t nf = s->nfacets;
    double hi[3] = {-INFINITY, -INFINITY, -INFINITY}, ext = 0;
    G->d = d;
    for (int c = 0; c < 3; c++)
        G->lo[c] = c < d ? INFINITY : 0;
    for (int32_t f = 0; f < nf; f++) {
        double *lo = box + (size_t)f * 2 * d, *h = lo + d;
        facet_box(s, f, lo, h);
        for (int c = 0; c < d; c++) {
            G->lo[c] = fmin(G->lo[c], lo[c]);
            hi[c] = fmax(hi[c], h[c]);
            ext += h[c] - lo[c];
        }
    }
    double span = 0;
    for (int c = 0; c < d; c++)
        span = fmax(span, hi[c] - G->lo[c]);
    G->cell = fmax(2 * ext / ((double)nf * d), span * 1e-9);
    double cells = 1;
    for (int c = 0; c < d; c++)
        cells *= floor((hi[c] - G->lo[c]) / G->cell) + 1;
    if (cells > 8.0 * nf + 64)
        G->cell *= pow(cells / (8.0 * nf + 64), 1.0 / d) * 1.01;
    for (int c = 0; c < 3; c++)
        G->n[c] = c < d ? (int64_t)floor((hi[c] - G->lo[c]) / G->cell) + 1 : 1;
}

/* Each cell's facets (those whose box meets it), by a counting sort:
 * list[start[c] .. start[c+1]).  -1: out of memory. */
static int grid_fill(const grid *G, const double *box, int32_t nf, int64_t entries,
                     int64_t **start_out, int32_t **list_out)
{
    int d = G->d;
    int64_t ncells = G->n[0] * G->n[1] * G->n[2];
    int64_t *start = calloc((size_t)ncells + 1, sizeof *start);
    int64_t *cursor = malloc((size_t)ncells * sizeof *cursor);
    int32_t *list = malloc((size_t)(entries ? entries : 1) * sizeof *list);
    if (!start || !cursor || !list) {
        free(start);
        free(cursor);
        free(list);
        return -1;
    }
    for (int pass = 0; pass < 2; pass++) {
        for (int32_t f = 0; f < nf; f++) {
            const double *lo = box + (size_t)f * 2 * d;
            int64_t a[3], b[3];
            cell_range(G, lo, lo + d, a, b);
            for (int64_t k = a[2]; k <= b[2]; k++)
                for (int64_t j = a[1]; j <= b[1]; j++)
                    for (int64_t i = a[0]; i <= b[0]; i++) {
                        int64_t c = cell_id(G, i, j, k);
                        if (pass == 0)
                            start[c + 1]++;
                        else
                            list[cursor[c]++] = f;
                    }
        }
        if (pass == 0) {
            for (int64_t c = 0; c < ncells; c++)
                start[c + 1] += start[c];
            memcpy(cursor, start, (size_t)ncells * sizeof *cursor);
        }
    }
    free(cursor);
    *start_out = start;
    *list_out = list;
    return 0;
}

/* Facets f and g of cell c cross; a pair is tested in one cell only, the
 * one holding the low corner of the boxes' intersection. */
static int pair_crosses(const sm_surface *s, const grid *G, const double *box, int64_t c,
                        int32_t f, int32_t g)
{
    int d = s->dim;
    const double *fl = box + (size_t)f * 2 * d, *fh = fl + d;
    const double *gl = box + (size_t)g * 2 * d, *gh = gl + d;
    double corner[3] = {0, 0, 0};
    for (int q = 0; q < d; q++) {
        if (fl[q] > gh[q] || gl[q] > fh[q])
            return 0;
        corner[q] = fmax(fl[q], gl[q]);
    }
    int64_t a[3], b[3];
    cell_range(G, corner, corner, a, b);
    if (cell_id(G, a[0], a[1], a[2]) != c || share_vertex(s, f, g))
        return 0;
    return d == 3 ? triangles_cross(s, f, g) : segments_cross(s, f, g);
}

static sm_status check_crossings(const sm_surface *s, sm_error *err)
{
    int d = s->dim;
    int32_t nf = s->nfacets;
    double *box = malloc((size_t)nf * 2 * (size_t)d * sizeof *box);
    if (!box)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory checking self-intersections");
    grid G;
    grid_setup(s, box, &G);
    int64_t entries = 0;
    for (int32_t f = 0; f < nf; f++) {
        const double *lo = box + (size_t)f * 2 * d;
        entries += box_cells(&G, lo, lo + d);
        if (entries > GRID_MAX_ENTRIES(nf)) {
            free(box);
            return sm_error_set(err, SM_ERR_INVALID,
                                "facets of very uneven sizes (over %lld grid entries to test "
                                "for self-intersection): remesh the surface more uniformly",
                                (long long)GRID_MAX_ENTRIES(nf));
        }
    }
    int64_t *start;
    int32_t *list;
    if (grid_fill(&G, box, nf, entries, &start, &list) != 0) {
        free(box);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory checking self-intersections");
    }
    int64_t crossings = 0, ncells = G.n[0] * G.n[1] * G.n[2];
    int32_t first_f = -1, first_g = -1;
    for (int64_t c = 0; c < ncells; c++)
        for (int64_t x = start[c]; x < start[c + 1]; x++)
            for (int64_t y = x + 1; y < start[c + 1]; y++)
                if (pair_crosses(s, &G, box, c, list[x], list[y]) && crossings++ == 0) {
                    first_f = list[x];
                    first_g = list[y];
                }
    free(box);
    free(start);
    free(list);
    if (crossings) {
        char a[96];
        vertex_text(s, s->facets[(size_t)d * first_f], a, sizeof a);
        const char *what = d == 3 ? "triangles" : "segments";
        return sm_error_set(err, SM_ERR_INVALID,
                            "self-intersecting: %lld pairs of %s cross, e.g. %s %d and %d "
                            "(near %s); a template's boundary must not cross itself",
                            (long long)crossings, what, what, (int)first_f + 1,
                            (int)first_g + 1, a);
    }
    return SM_OK;
}

/* ------------------------------------------------------------- the check */

static double enclosed_volume(const sm_surface *s)
{
    double v = 0;
    for (int32_t f = 0; f < s->nfacets; f++) {
        if (s->dim == 3) {
            const double *a = s->coords + 3 * (size_t)s->facets[3 * (size_t)f];
            const double *b = s->coords + 3 * (size_t)s->facets[3 * (size_t)f + 1];
            const double *c = s->coords + 3 * (size_t)s->facets[3 * (size_t)f + 2];
            v += (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) +
                  a[2] * (b[0] * c[1] - b[1] * c[0])) / 6.0;
        } else {
            const double *a = s->coords + 2 * (size_t)s->facets[2 * (size_t)f];
            const double *b = s->coords + 2 * (size_t)s->facets[2 * (size_t)f + 1];
            v += (a[0] * b[1] - a[1] * b[0]) / 2.0;
        }
    }
    return v;
}

static int degenerate(const sm_surface *s, int32_t f)
{
    int d = s->dim;
    const double *a = s->coords + (size_t)d * s->facets[(size_t)d * f];
    const double *b = s->coords + (size_t)d * s->facets[(size_t)d * f + 1];
    if (d == 2)
        return a[0] == b[0] && a[1] == b[1];
    const double *c = s->coords + 3 * (size_t)s->facets[3 * (size_t)f + 2];
    double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    double v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    double n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
    return n[0] == 0 && n[1] == 0 && n[2] == 0;
}

sm_status sm_template_surface_check(const sm_surface *s, double *volume, sm_error *err)
{
    if (volume)
        *volume = 0;
    if (!s || (s->dim != 2 && s->dim != 3))
        return sm_error_set(err, SM_ERR_INVALID, "not a surface (dimension 2 or 3)");
    int d = s->dim;
    const char *facet = d == 3 ? "triangles" : "segments";
    if (s->nfacets < d + 1 || s->nverts < d + 1)
        return sm_error_set(err, SM_ERR_INVALID,
                            "empty: %d %s on %d vertices cannot enclose a %s", (int)s->nfacets,
                            facet, (int)s->nverts, d == 3 ? "volume" : "area");
    if (s->nfacets > SM_TEMPLATE_MAX_FACETS)
        return sm_error_set(err, SM_ERR_INVALID,
                            "too large: %d %s (a template surface may have at most %d; "
                            "decimate it first)",
                            (int)s->nfacets, facet, SM_TEMPLATE_MAX_FACETS);
    for (size_t i = 0; i < (size_t)s->nverts * (size_t)d; i++)
        if (!isfinite(s->coords[i]))
            return sm_error_set(err, SM_ERR_INVALID, "a non-finite coordinate at vertex %d",
                                (int)(i / (size_t)d) + 1);
    for (size_t i = 0; i < (size_t)s->nfacets * (size_t)d; i++)
        if (s->facets[i] < 0 || s->facets[i] >= s->nverts)
            return sm_error_set(err, SM_ERR_INVALID, "a facet's vertex index out of range");
    for (int32_t f = 0; f < s->nfacets; f++)
        if (degenerate(s, f))
            return sm_error_set(err, SM_ERR_INVALID,
                                "degenerate: %s %d has zero %s", d == 3 ? "triangle" : "segment",
                                (int)f + 1, d == 3 ? "area" : "length");
    sm_status st = d == 3 ? check_edges(s, err) : check_ends(s, err);
    if (st != SM_OK)
        return st;
    double v = enclosed_volume(s);
    if (!(v > 0))
        return sm_error_set(err, SM_ERR_INVALID,
                            "inside-out: the surface encloses a %s of %g (outward facets "
                            "enclose a positive one)",
                            d == 3 ? "volume" : "area", v);
    if ((st = check_crossings(s, err)) != SM_OK)
        return st;
    if (volume)
        *volume = v;
    return SM_OK;
}
