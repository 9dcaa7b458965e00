/* The signed distance to a label map's boundary (sm_image.h,
 * sm_image_target_*): the image cropped to the padded box of the
 * selected voxels; a lightly smoothed mask (a Gaussian of sigma
 * `smooth` voxels: a binary mask's staircase is what the voxel-centre EDT
 * measures to, the smoothed level set is close to the shape it was
 * sampled from) or a float image's values; its level set at `level` as a
 * triangle surface by marching tetrahedra (sm_image_march.c); the signed
 * distance at the crop's voxel centres, exact at the voxels next to the
 * surface and through the nearest of those (sm_edt.h's nearest-site
 * transform) beyond, for the far field; within `band` voxels of the
 * boundary the exact signed distance to the surface at any point. */
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

/* A crossed cell: its triangles and their box (rounded outward to float:
 * a lower bound of the distance to any of them for one test). */
typedef struct cell_tris {
    int32_t cell, first, count;
    float lo[3], hi[3];
} cell_tris;

struct sm_image_target {
    int64_t n[3];      /* the crop, in voxels */
    int64_t act_lo[3], act_hi[3]; /* the crop's voxels where the field can
                                   * differ from its value far outside:
                                   * the selection's box and the blur's
                                   * reach */
    double map[12];    /* crop index -> world (the image's frame) */
    double inv[12];    /* world -> crop index */
    double h[3];       /* spacing along the crop's axes */
    double smin;       /* a lower bound of the map's smallest singular
                        * value: world length of a unit index step */
    double step[3];    /* per axis, a lower bound of the world distance
                        * of index gap 1 (orthogonal axes: the spacing;
                        * else smin): a gap g is sqrt(sum (g step)^2) */
    float *edt;        /* signed voxel-centre EDT on the crop */
    float *field;      /* the (smoothed) field the surface is a level of */
    double level;
    double band;       /* world units: exact within */
    int grid_band;     /* the grid's band refined (whole_image: the grid
                        * is the output; else points there are exact) */
    sm_surface *surface;
    /* the surface's triangles by the crop cell that made them (marching
     * emits them cell by cell, in order): the crossed cells, and a table
     * from a cell to its place there (open addressing, key cell + 1) */
    cell_tris *cells;
    int64_t ncells;
    int64_t *slice_cells; /* n[2] + 1: the first crossed cell of each slice */
    int32_t *ckeys, *crun;
    int64_t ccap;
    uint64_t *cbits;   /* one bit a crop cell: it has triangles (most
                        * cells a search visits have none) */
    sm_sdf *sdf;       /* opts->hierarchy only */
};

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

/* The crossed cells (tcell: nondecreasing, as march emits them), their
 * triangles' boxes, and the table from a cell to its place. */
static uint64_t cell_hash(int64_t key, int64_t cap)
{
    return ((uint64_t)key * 0x9E3779B97F4A7C15ull >> 20) & (uint64_t)(cap - 1);
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
        uint64_t s = cell_hash(tcell[i] + 1, cap);
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

/* The crossed cell c (crop cell index), NULL when c has no triangles. */
static const cell_tris *cell_triangles(const sm_image_target *t, int64_t c)
{
    if (!(t->cbits[c >> 6] >> (c & 63) & 1))
        return NULL;
    uint64_t s = cell_hash(c + 1, t->ccap);
    while (t->ckeys[s]) {
        if (t->ckeys[s] == c + 1)
            return t->cells + t->crun[s];
        s = (s + 1) & (uint64_t)(t->ccap - 1);
    }
    return NULL;
}

/* The crossed cell whose triangles hold triangle f. */
static const cell_tris *triangle_cell(const sm_image_target *t, int32_t f)
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

/* The squared distance from p to cell c's triangles' box (a lower bound
 * of the distance to each of them). */
static inline double cell_box2(const cell_tris *c, const double *p)
{
    double box2 = 0;
    for (int r = 0; r < 3; r++) {
        double g = p[r] < c->lo[r] ? c->lo[r] - p[r] : p[r] > c->hi[r] ? p[r] - c->hi[r] : 0;
        box2 += g * g;
    }
    return box2;
}

/* *best2, *bestf lowered by cell c's triangles (NULL: none) when its box
 * is nearer. */
static void range_nearest(const sm_image_target *t, int32_t first, int32_t count, const double *p,
                          double *best2, int32_t *bestf);

static inline void cell_nearest(const sm_image_target *t, const cell_tris *c, const double *p,
                                double *best2, int32_t *bestf)
{
    if (c && cell_box2(c, p) < *best2)
        range_nearest(t, c->first, c->count, p, best2, bestf);
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

/* *best2 lowered to the squared distance from p to the triangles first
 * .. first + count - 1 nearer than it, *bestf to the nearest of them
 * (triangles whose box or plane is not nearer are skipped: most of them,
 * the exact test costs several times the two bounds). */
static void range_nearest(const sm_image_target *t, int32_t first, int32_t count, const double *p,
                          double *best2, int32_t *bestf)
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
static double surface_distance_from(const sm_image_target *t, const double *p, double best2,
                                    int32_t bestf, double *closest, int32_t *nearest);

static double surface_distance(const sm_image_target *t, const double *p, double *closest)
{
    return surface_distance_from(t, p, INFINITY, -1, closest, NULL);
}

/* The same, with a triangle bestf at squared distance best2 already
 * known (-1, INFINITY: none); *nearest (when not NULL): the nearest
 * triangle. */
static double surface_distance_from(const sm_image_target *t, const double *p, double best2,
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
                        cell_nearest(t, cell_triangles(t, x + t->n[0] * (y + t->n[1] * z)), p,
                                     &best2, &bestf);
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

/* A triangle's bounds made once for the several corners that test it. */
typedef struct tri_bounds {
    const double *a, *b, *c;
    double lo[3], hi[3], nrm[3];
    double inn; /* (1 - 1e-9) / |nrm|^2, 0 for a degenerate triangle */
} tri_bounds;

static void tri_bounds_make(const sm_surface *s, int32_t f, tri_bounds *tb)
{
    const int32_t *v = s->facets + 3 * f;
    const double *a = s->coords + 3 * v[0], *b = s->coords + 3 * v[1], *c = s->coords + 3 * v[2];
    tb->a = a;
    tb->b = b;
    tb->c = c;
    for (int r = 0; r < 3; r++) {
        double lo = a[r] < b[r] ? a[r] : b[r], hi = a[r] < b[r] ? b[r] : a[r];
        tb->lo[r] = c[r] < lo ? c[r] : lo;
        tb->hi[r] = c[r] > hi ? c[r] : hi;
    }
    double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    double w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    tb->nrm[0] = u[1] * w[2] - u[2] * w[1];
    tb->nrm[1] = u[2] * w[0] - u[0] * w[2];
    tb->nrm[2] = u[0] * w[1] - u[1] * w[0];
    double nn = tb->nrm[0] * tb->nrm[0] + tb->nrm[1] * tb->nrm[1] + tb->nrm[2] * tb->nrm[2];
    tb->inn = nn > 0 ? (1 - 1e-9) / nn : 0;
}

/* *best2, *bestf lowered to triangle f (bounds e) when nearer. */
static inline void tri_nearest(const tri_bounds *e, int32_t f, const double *p, double *best2,
                               int32_t *bestf)
{
    double box2 = 0;
    for (int row = 0; row < 3; row++) {
        double g = p[row] < e->lo[row] ? e->lo[row] - p[row] : p[row] > e->hi[row] ? p[row] - e->hi[row] : 0;
        box2 += g * g;
    }
    if (box2 >= *best2)
        return;
    double h = e->nrm[0] * (p[0] - e->a[0]) + e->nrm[1] * (p[1] - e->a[1]) + e->nrm[2] * (p[2] - e->a[2]);
    if (h * h * e->inn >= *best2)
        return;
    double w[3], d2 = sm__triangle_closest(p, e->a, e->b, e->c, w);
    if (d2 < *best2) {
        *best2 = d2;
        *bestf = f;
    }
}

/* The nearest point of every site among the triangles of the crossed
 * cells it is a corner of (best2, bestf: INFINITY, -1 on entry), cell
 * by cell: node plane z takes the four corners in it of the cells of
 * slices z - 1 and z, planes in parallel (a site is in one plane only),
 * each triangle's bounds made once for its four corners. */
static void corner_nearest(const sm_image_target *t, const int32_t *near, double *best2,
                           int32_t *bestf)
{
    const int64_t *n = t->n;
    const sm_surface *sf = t->surface;
#pragma omp parallel for schedule(dynamic, 1)
    for (int64_t z = 0; z < n[2]; z++) {
        tri_bounds tb[12]; /* a cell's: 6 tetrahedra, at most 2 each */
        for (int up = 0; up < 2; up++) {
            int64_t k = z - up;
            if (k < 0 || k >= n[2] - 1)
                continue;
            for (int64_t r = t->slice_cells[k]; r < t->slice_cells[k + 1]; r++) {
                const cell_tris *ct = t->cells + r;
                int32_t cnt = ct->count < 12 ? ct->count : 12;
                for (int32_t q = 0; q < cnt; q++)
                    tri_bounds_make(sf, ct->first + q, tb + q);
                int64_t i0 = ct->cell % n[0], j0 = (ct->cell / n[0]) % n[1];
                for (int corner = 0; corner < 4; corner++) {
                    int64_t i = i0 + (corner & 1), j = j0 + (corner >> 1);
                    int32_t site = near[i + n[0] * (j + n[1] * z)];
                    double p[3], b2 = best2[site];
                    int32_t bf = bestf[site];
                    for (int row = 0; row < 3; row++)
                        p[row] = t->map[4 * row] * (double)i + t->map[4 * row + 1] * (double)j +
                                 t->map[4 * row + 2] * (double)z + t->map[4 * row + 3];
                    for (int32_t q = 0; q < cnt; q++)
                        tri_nearest(tb + q, ct->first + q, p, &b2, &bf);
                    /* a cell of more triangles than a cell can make: the rest */
                    if (ct->count > cnt)
                        range_nearest(t, ct->first + cnt, ct->count - cnt, p, &b2, &bf);
                    best2[site] = b2;
                    bestf[site] = bf;
                }
            }
        }
    }
}

/* The nearest surface point of the voxel centre at ijk, a corner of a
 * cell the surface passes through, and its triangle *tri, from the
 * nearest among the (up to) 8 cells around it (best2, bestf:
 * corner_nearest's): every other cell is at least one index step away,
 * smin in the world, so a point nearer than that is the nearest; one
 * nearer than 3 smin: the cells within two steps whose gap (t->step)
 * and then whose triangles' box is nearer; else the general search. */
static void site_foot(const sm_image_target *t, const int32_t *ijk, double best2, int32_t bestf,
                      double *foot, int32_t *tri)
{
    double x[3];
    for (int row = 0; row < 3; row++)
        x[row] = t->map[4 * row] * ijk[0] + t->map[4 * row + 1] * ijk[1] +
                 t->map[4 * row + 2] * ijk[2] + t->map[4 * row + 3];
    const sm_surface *s = t->surface;
    double w[3];
    double s2 = t->smin * t->smin, st2[3];
    for (int a = 0; a < 3; a++)
        st2[a] = t->step[a] * t->step[a];
    if (bestf >= 0 && best2 > s2 && best2 <= 9 * s2) {
        /* the cells g = (gx, gy, gz) index steps beyond those 8 (at
         * least sqrt(sum (g step)^2) away, step >= smin) nearer than
         * best2, so |g| <= 2 per axis; a cell whose gap is not nearer
         * cannot be */
        for (int gz = -2; gz <= 2; gz++)
            for (int gy = -2; gy <= 2; gy++)
                for (int gx = -2; gx <= 2; gx++) {
                    if (st2[0] * gx * gx + st2[1] * gy * gy + st2[2] * gz * gz >= best2 ||
                        (!gx && !gy && !gz))
                        continue;
                    /* gap g below the block: cell ijk - 1 + g; above: ijk + g */
                    int64_t c[3] = {ijk[0] + gx - (gx <= 0), ijk[1] + gy - (gy <= 0),
                                    ijk[2] + gz - (gz <= 0)};
                    /* gap 0 on an axis: both cells of the block */
                    for (int d = 0; d < 8; d++) {
                        int64_t e[3] = {c[0] + (gx == 0 && (d & 1)), c[1] + (gy == 0 && (d & 2)),
                                        c[2] + (gz == 0 && (d & 4))};
                        if (((d & 1) && gx) || ((d & 2) && gy) || ((d & 4) && gz))
                            continue;
                        if (e[0] < 0 || e[1] < 0 || e[2] < 0 || e[0] >= t->n[0] - 1 ||
                            e[1] >= t->n[1] - 1 || e[2] >= t->n[2] - 1)
                            continue;
                        cell_nearest(t, cell_triangles(t, e[0] + t->n[0] * (e[1] + t->n[1] * e[2])),
                                     x, &best2, &bestf);
                    }
                }
    } else if (bestf < 0 || best2 > s2) {
        surface_distance_from(t, x, best2, bestf, foot, tri);
        return;
    }
    *tri = bestf;
    const int32_t *v = s->facets + 3 * bestf;
    const double *a = s->coords + 3 * v[0], *b = s->coords + 3 * v[1], *c = s->coords + 3 * v[2];
    sm__triangle_closest(x, a, b, c, w);
    for (int row = 0; row < 3; row++)
        foot[row] = w[0] * a[row] + w[1] * b[row] + w[2] * c[row];
}

/* Whether voxel (i, j, k) is a site: a corner of a crossed cell. */
static int is_site(const sm_image_target *t, int64_t i, int64_t j, int64_t k)
{
    for (int64_t c = k > 0 ? k - 1 : 0; c <= k && c < t->n[2] - 1; c++)
        for (int64_t b = j > 0 ? j - 1 : 0; b <= j && b < t->n[1] - 1; b++)
            for (int64_t a = i > 0 ? i - 1 : 0; a <= i && a < t->n[0] - 1; a++) {
                int64_t cell = a + t->n[0] * (b + t->n[1] * c);
                if (t->cbits[cell >> 6] >> (cell & 63) & 1)
                    return 1;
            }
    return 0;
}

/* The band's voxels to refine: the voxel, its distance squared so far
 * and the crossed cell of its site's point. */
typedef struct band_voxel {
    int64_t v;
    double best2;
    int32_t cell;
} band_voxel;

typedef struct band_list {
    band_voxel *at;
    int64_t n, cap;
    int fail;
} band_list;

static void band_add(band_list *b, int64_t v, double best2, int32_t cell)
{
    if (b->fail || !sm__image_grow((void **)&b->at, &b->cap, b->n + 1, sizeof *b->at)) {
        b->fail = 1;
        return;
    }
    b->at[b->n++] = (band_voxel){v, best2, cell};
}

/* One slice k of the distance from the sites (distance_field): each
 * voxel's own nearest site and its six neighbours' (their sites' surface
 * points are as near, often nearer: the nearest site by voxel centres is
 * not always the one with the nearest point), the nearest of those
 * points; signed as its own site (first_inside: the first inside
 * site).  below/above: slices k - 1 and k + 1 of sites (NULL beyond the
 * grid); cellof: each site's point's crossed cell; the voxels within the
 * band (t->grid_band) added to band for band_refine. */
static void slice_distance(const sm_image_target *t, int32_t first_inside, const double *foot,
                           const int32_t *cellof, const int32_t *below, const int32_t *slice,
                           const int32_t *above, int64_t k, float *out, band_list *band)
{
    /* the target's fields in locals: the band's calls would make the
     * compiler load them again at every voxel */
    const int64_t n0 = t->n[0], n1 = t->n[1];
    const double m0 = t->map[0], m4 = t->map[4], m8 = t->map[8];
    const double band2 = t->grid_band ? t->band * t->band : -1;
    for (int64_t j = 0; j < n1; j++) {
        /* a neighbour beyond the grid: the row itself (the voxel's own site) */
        const int32_t *row = slice + j * n0;
        const int32_t *nb0 = j > 0 ? row - n0 : row, *nb1 = j + 1 < n1 ? row + n0 : row,
                      *nb2 = below ? below + j * n0 : row, *nb3 = above ? above + j * n0 : row;
        double x[3];
        for (int r = 0; r < 3; r++)
            x[r] = t->map[4 * r + 1] * (double)j + t->map[4 * r + 2] * (double)k + t->map[4 * r + 3];
        float *orow = out + j * n0;
        for (int64_t i = 0; i < n0; i++) {
            double p[3] = {x[0] + m0 * (double)i, x[1] + m4 * (double)i, x[2] + m8 * (double)i};
            /* the neighbours' sites, most often the voxel's own */
            int32_t own = row[i], cand[6] = {i > 0 ? row[i - 1] : own, i + 1 < n0 ? row[i + 1] : own,
                                             nb0[i], nb1[i], nb2[i], nb3[i]};
            const double *q = foot + 3 * (int64_t)own;
            double best = (p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) +
                          (p[2] - q[2]) * (p[2] - q[2]);
            /* most often (far from the surface) all the same site */
            int32_t other = (cand[0] ^ own) | (cand[1] ^ own) | (cand[2] ^ own) |
                            (cand[3] ^ own) | (cand[4] ^ own) | (cand[5] ^ own);
            for (int c = 0; other && c < 6; c++) {
                if (cand[c] == own)
                    continue;
                q = foot + 3 * (int64_t)cand[c];
                double d2 = (p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) +
                            (p[2] - q[2]) * (p[2] - q[2]);
                best = d2 < best ? d2 : best;
            }
            if (best <= band2 && cellof[own] >= 0 && !is_site(t, i, j, k))
                /* within the band: the other triangles of the cell holding
                 * the voxel's own site's point too, later (band_refine);
                 * a site's own point is its nearest already */
                band_add(band, (k * n1 + j) * n0 + i, best, cellof[own]);
            float d = sqrtf((float)best); /* as near as sqrt then rounding */
            orow[i] = own >= first_inside ? -d : d;
        }
    }
}

/* The distances from the sites over the sites themselves (t->edt: each
 * voxel's site, int32, becomes its distance, float), in slabs of slices
 * (several a thread, taken in turn, so that a thread the machine holds
 * back delays only its slab): a slab's slices in order, each written back
 * once the next one is done (no slice is needed after its neighbours
 * are); every slab's first and last slices are copied before anyone
 * writes.  band: one list a slab. */
static sm_status site_distances(sm_image_target *t, int32_t first_inside, const double *foot,
                                const int32_t *cellof, int32_t *near, band_list *band,
                                int slabs, sm_error *err)
{
    const int64_t *n = t->n;
    int64_t plane = n[0] * n[1];
    int threads = omp_get_max_threads();
    /* each slab's first and last slice's sites; two slices of output a thread */
    int32_t *edges = malloc((size_t)slabs * 2 * (size_t)plane * sizeof *edges);
    float *bufs = malloc((size_t)threads * 2 * (size_t)plane * sizeof *bufs);
    if (!edges || !bufs) {
        free(edges);
        free(bufs);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the distance's sites");
    }
#pragma omp parallel num_threads(threads)
    {
#pragma omp for schedule(static)
        for (int sl = 0; sl < slabs; sl++) {
            int64_t k0 = n[2] * sl / slabs, k1 = n[2] * (sl + 1) / slabs;
            int32_t *first = edges + (size_t)(2 * sl) * (size_t)plane, *last = first + plane;
            memcpy(first, near + k0 * plane, (size_t)plane * sizeof *first);
            memcpy(last, near + (k1 - 1) * plane, (size_t)plane * sizeof *last);
        }
        int me = omp_get_thread_num();
        float *buf[2] = {bufs + (size_t)(2 * me) * (size_t)plane,
                         bufs + (size_t)(2 * me + 1) * (size_t)plane};
#pragma omp for schedule(dynamic, 1)
        for (int sl = 0; sl < slabs; sl++) {
            int64_t k0 = n[2] * sl / slabs, k1 = n[2] * (sl + 1) / slabs;
            for (int64_t k = k0; k < k1; k++) {
                const int32_t *below = k == 0 ? NULL
                                       : k == k0 ? edges + (size_t)(2 * sl - 1) * (size_t)plane
                                                 : near + (k - 1) * plane;
                const int32_t *above = k + 1 == n[2] ? NULL
                                       : k + 1 == k1 ? edges + (size_t)(2 * sl + 2) * (size_t)plane
                                                     : near + (k + 1) * plane;
                slice_distance(t, first_inside, foot, cellof, below, near + k * plane, above, k,
                               buf[k & 1], band + sl);
                if (k > k0) /* slice k - 1 is no one's neighbour any more */
                    memcpy(t->edt + (k - 1) * plane, buf[(k - 1) & 1],
                           (size_t)plane * sizeof(float));
            }
            memcpy(t->edt + (k1 - 1) * plane, buf[(k1 - 1) & 1], (size_t)plane * sizeof(float));
        }
    }
    free(edges);
    free(bufs);
    return SM_OK;
}

static int node_inside(const sm_image_target *t, const float *f, double level, const int32_t *ijk)
{
    for (int a = 0; a < 3; a++)
        if (ijk[a] < t->act_lo[a] || ijk[a] > t->act_hi[a])
            return 0;
    return f[ijk[0] + t->n[0] * (ijk[1] + t->n[1] * (int64_t)ijk[2])] >= level;
}

/* The sites: every corner of a crossed cell, numbered node plane by node
 * plane (plane z: the corners in it of the cells of slices z - 1 and z),
 * those outside the surface first (*first_inside: the first inside);
 * *ijk their voxels; near (the crop's voxels): each site's number at its
 * voxel, -1 elsewhere.  A node's side is the marching's: the field
 * against the level within the active box, outside beyond it.  Planes
 * in parallel: marked and counted, then numbered. */
static sm_status collect_sites(const sm_image_target *t, const float *f, double level,
                               int32_t *near, int32_t **ijk, int64_t *nsites,
                               int32_t *first_inside, sm_error *err)
{
    const int64_t *n = t->n;
    int64_t plane = n[0] * n[1];
    int64_t *count = calloc((size_t)(2 * n[2] + 1), sizeof *count); /* outside, inside a plane */
    if (!count)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the distance's sites");
    int32_t *at = NULL;
    for (int pass = 0; pass < 2; pass++) {
#pragma omp parallel for schedule(dynamic, 1)
        for (int64_t z = 0; z < n[2]; z++) {
            if (pass == 0)
                memset(near + z * plane, 0xff, (size_t)plane * sizeof *near); /* -1: none */
            int64_t next[2] = {pass ? count[2 * z] : 0, pass ? count[2 * z + 1] : 0};
            for (int up = 0; up < 2; up++) {
                int64_t k = z - up;
                if (k < 0 || k >= n[2] - 1)
                    continue;
                for (int64_t r = t->slice_cells[k]; r < t->slice_cells[k + 1]; r++) {
                    int64_t i0 = t->cells[r].cell % n[0], j0 = (t->cells[r].cell / n[0]) % n[1];
                    for (int corner = 0; corner < 4; corner++) {
                        int32_t x[3] = {(int32_t)(i0 + (corner & 1)), (int32_t)(j0 + (corner >> 1)),
                                        (int32_t)z};
                        int32_t *v = near + x[0] + n[0] * (x[1] + n[1] * z);
                        if (*v != (pass ? -2 : -1))
                            continue;
                        int in = node_inside(t, f, level, x);
                        if (pass == 0) {
                            *v = -2; /* marked */
                            count[2 * z + in]++;
                            continue;
                        }
                        *v = (int32_t)next[in]++;
                        memcpy(at + 3 * *v, x, sizeof x);
                    }
                }
            }
        }
        if (pass == 0) {
            /* each plane's first number outside, and inside after all
             * those outside */
            int64_t out = 0, in = 0;
            for (int64_t z = 0; z < n[2]; z++)
                in += count[2 * z];
            *first_inside = (int32_t)(in < INT32_MAX ? in : 0);
            for (int64_t z = 0; z < n[2]; z++) {
                int64_t o = count[2 * z], i = count[2 * z + 1];
                count[2 * z] = out;
                count[2 * z + 1] = in;
                out += o;
                in += i;
            }
            *nsites = in;
            at = in < INT32_MAX ? malloc((size_t)(in > 0 ? in : 1) * 3 * sizeof *at) : NULL;
            if (!at) {
                free(count);
                return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the distance's sites");
            }
        }
    }
    free(count);
    *ijk = at;
    return SM_OK;
}

/* The band's voxels (the threads' lists) lowered to the nearest of the
 * triangles of the cell holding their site's point (the surface around
 * that point, where a nearer one most often is): each list (a slab's
 * voxels, so cells mostly its own) sorted by cell, lists in parallel,
 * then cell by cell, each triangle's bounds made once for all the
 * cell's voxels. */
static sm_status band_refine(sm_image_target *t, const band_list *band, int lists, sm_error *err)
{
    int fail = 0;
    for (int k = 0; k < lists; k++)
        fail |= band[k].fail;
    if (fail)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the distance's band");
    const int64_t *n = t->n;
    const sm_surface *sf = t->surface;
    /* each thread its own list (its slab's voxels), sorted by cell */
#pragma omp parallel for schedule(dynamic, 1) reduction(| : fail)
    for (int k = 0; k < lists; k++) {
        const band_list *b = band + k;
        int64_t *start = calloc((size_t)t->ncells + 1, sizeof *start);
        band_voxel *by = malloc((size_t)(b->n > 0 ? b->n : 1) * sizeof *by);
        if (!start || !by) {
            fail = 1;
            free(start);
            free(by);
            continue;
        }
        for (int64_t e = 0; e < b->n; e++)
            start[b->at[e].cell + 1]++;
        for (int64_t c = 0; c < t->ncells; c++)
            start[c + 1] += start[c];
        for (int64_t e = 0; e < b->n; e++)
            by[start[b->at[e].cell]++] = b->at[e];
        /* start[c] is now cell c's end */
        for (int64_t e = 0; e < b->n;) {
            const cell_tris *ct = t->cells + by[e].cell;
            int64_t end = start[by[e].cell];
            tri_bounds tb[12];
            int32_t cnt = ct->count < 12 ? ct->count : 12;
            for (int32_t q = 0; q < cnt; q++)
                tri_bounds_make(sf, ct->first + q, tb + q);
            for (; e < end; e++) {
                int64_t v = by[e].v, i = v % n[0], j = (v / n[0]) % n[1], kz = v / (n[0] * n[1]);
                double p[3], b2 = by[e].best2;
                int32_t bf = -1;
                for (int row = 0; row < 3; row++)
                    p[row] = t->map[4 * row] * (double)i + t->map[4 * row + 1] * (double)j +
                             t->map[4 * row + 2] * (double)kz + t->map[4 * row + 3];
                for (int32_t q = 0; q < cnt; q++)
                    tri_nearest(tb + q, ct->first + q, p, &b2, &bf);
                if (ct->count > cnt)
                    range_nearest(t, ct->first + cnt, ct->count - cnt, p, &b2, &bf);
                if (bf >= 0) {
                    float d = sqrtf((float)b2);
                    t->edt[v] = t->edt[v] < 0 ? -d : d;
                }
            }
        }
        free(start);
        free(by);
    }
    return fail ? sm_error_set(err, SM_ERR_NOMEM, "out of memory for the distance's band") : SM_OK;
}

/* The signed distance at every crop voxel centre into t->edt: the sites
 * are the corners of the cells the surface passes through (every voxel
 * within a cell of it), each with its exact nearest surface point; every
 * other voxel takes the nearest site's (sm__edt_nearest, on the grid's
 * axis lengths) and its distance to that point, a point of the surface:
 * an upper bound, off by the square of the sites' sideways offset over
 * twice the distance, so the far field is close to exact where the
 * voxel-centre EDT is off by up to a voxel.  The sign: a site's is its
 * node's side of the level (the marching's); every other voxel's is its
 * nearest site's.  A lattice path from the voxel to that site, each step
 * one index towards it, passes only voxels nearer the voxel than the
 * site, so no other site; two neighbours that are not both sites share
 * no crossed cell, so are on one side; so the whole path is.  (No field
 * read at every voxel.)  t->edt holds the sites (int32) until each
 * voxel's float replaces its own. */
static sm_status distance_field(sm_image_target *t, const float *f, double level, sm_error *err)
{
    const int64_t *n = t->n;
    int32_t *near = (int32_t *)t->edt;
    int32_t *ijk = NULL, first_inside = 0;
    double *foot = NULL;
    int64_t nsites = 0;
    /* the sites outside the surface first: a voxel's sign is its
     * nearest site's (see above) */
    sm_status st = collect_sites(t, f, level, near, &ijk, &nsites, &first_inside, err);
    if (st != SM_OK)
        return st;
    foot = malloc((size_t)nsites * 3 * sizeof *foot);
    int32_t *cellof = malloc((size_t)nsites * sizeof *cellof);
    double *best2 = malloc((size_t)nsites * sizeof *best2);
    int32_t *bestf = malloc((size_t)nsites * sizeof *bestf);
    if (!foot || !cellof || !best2 || !bestf) {
        free(ijk);
        free(foot);
        free(cellof);
        free(best2);
        free(bestf);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the distance's sites");
    }
    for (int64_t k = 0; k < nsites; k++) {
        best2[k] = INFINITY;
        bestf[k] = -1;
    }
    corner_nearest(t, near, best2, bestf);
    /* each foot's cell (the cell that made its triangle), for the band */
#pragma omp parallel for schedule(dynamic, 256)
    for (int64_t k = 0; k < nsites; k++) {
        int32_t tri = -1;
        site_foot(t, ijk + 3 * k, best2[k], bestf[k], foot + 3 * k, &tri);
        cellof[k] = tri < 0 ? -1 : (int32_t)(triangle_cell(t, tri) - t->cells);
    }
    free(best2);
    free(bestf);
    st = sm__edt_nearest(n, t->h, ijk, nsites, near, err);
    free(ijk);
    /* slabs of slices for the distances, four a thread */
    int slabs = 4 * omp_get_max_threads();
    slabs = slabs < n[2] ? slabs : (int)n[2];
    band_list *band = calloc((size_t)slabs, sizeof *band);
    if (st == SM_OK && !band)
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory for the distance's band");
    if (st == SM_OK)
        st = site_distances(t, first_inside, foot, cellof, near, band, slabs, err);
    free(foot);
    free(cellof);
    if (st == SM_OK)
        st = band_refine(t, band, slabs, err);
    for (int k = 0; band && k < slabs; k++)
        free(band[k].at);
    free(band);
    return st;
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
        st = distance_field(t, f, level, err);
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
    for (int row = 0; row < 3; row++)
        q[row] = t->map[4 * row] * ijk[0] + t->map[4 * row + 1] * ijk[1] +
                 t->map[4 * row + 2] * ijk[2] + t->map[4 * row + 3];
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
