/* The exact Euclidean distance transform of Felzenszwalb & Huttenlocher
 * ("Distance transforms of sampled functions", Theory of Computing 2012):
 * the squared distance is separable, d2(x,y,z) = min over the feature of
 * dx2 + dy2 + dz2, so three passes of a 1D transform — the lower envelope
 * of parabolas (q h)^2 + f(q) — along x, then y, then z give it exactly,
 * each line in linear time, lines in parallel (OpenMP).  Spacing h per
 * axis enters the parabolas, so anisotropic grids are exact.
 *
 * The signed transform needs the distance to the inside for outside
 * voxels and to the outside for inside voxels.  One array holds both:
 * each voxel keeps its distance to the other class, and a pass reads a
 * voxel of the same class as 0 for the other class's transform (it IS of
 * that class), so both transforms run in the same passes over one float
 * array — memory: the mask and one float per voxel. */
#include "shapematch/sm_image.h"

#include <math.h>
#include <omp.h>
#include <stdlib.h>

#include "sm_edt.h"

typedef struct line_scratch {
    double *f, *d, *z;
    int64_t *v;
} line_scratch;

/* 1D: d[q] = min over p of ((q - p) h)^2 + f[p]; f INFINITY where p has
 * no feature.  All INFINITY when f is. */
static void dt1d(const double *f, int64_t n, double h, double *d, int64_t *v, double *z)
{
    int64_t k = -1;
    for (int64_t q = 0; q < n; q++) {
        if (f[q] == INFINITY)
            continue;
        double fq = f[q] + (double)q * (double)q * h * h, s = -INFINITY;
        while (k >= 0) {
            double p = (double)v[k];
            s = (fq - (f[v[k]] + p * p * h * h)) / (2 * h * h * ((double)q - p));
            if (s > z[k])
                break;
            k--;
        }
        k++;
        v[k] = q;
        z[k] = k == 0 ? -INFINITY : s;
        z[k + 1] = INFINITY;
    }
    if (k < 0) {
        for (int64_t q = 0; q < n; q++)
            d[q] = INFINITY;
        return;
    }
    k = 0;
    for (int64_t q = 0; q < n; q++) {
        while (z[k + 1] < (double)q)
            k++;
        double dq = ((double)q - (double)v[k]) * h;
        d[q] = dq * dq + f[v[k]];
    }
}

/* One pass along axis a: for each line, each class's transform; cls NULL
 * for the unsigned transform (feature = mask nonzero). */
static void pass(const int64_t n[3], const double h[3], int a, const uint8_t *mask, int first,
                 int sign, float *d2, line_scratch *sc)
{
    int64_t stride = a == 0 ? 1 : a == 1 ? n[0] : n[0] * n[1];
    int b = a == 0 ? 1 : 0, c = a == 2 ? 1 : 2;
    int64_t lines = n[b] * n[c], len = n[a];
#pragma omp parallel for schedule(dynamic, 16)
    for (int64_t l = 0; l < lines; l++) {
        int t = omp_get_thread_num();
        line_scratch *s = sc + t;
        int64_t ib = l % n[b], ic = l / n[b];
        int64_t strides[3] = {1, n[0], n[0] * n[1]};
        int64_t base = ib * strides[b] + ic * strides[c];
        for (int cls = 0; cls < (sign ? 2 : 1); cls++) {
            /* cls 0: distance to the mask (for voxels outside it); cls 1:
             * distance to the outside (for voxels inside) */
            for (int64_t q = 0; q < len; q++) {
                int64_t at = base + q * stride;
                int feature = cls == 0 ? mask[at] != 0 : mask[at] == 0;
                s->f[q] = feature ? 0 : first ? INFINITY : (double)d2[at];
            }
            dt1d(s->f, len, h[a], s->d, s->v, s->z);
            for (int64_t q = 0; q < len; q++) {
                int64_t at = base + q * stride;
                int mine = cls == 0 ? mask[at] == 0 : mask[at] != 0;
                if (!sign || mine)
                    d2[at] = (float)s->d[q];
            }
        }
    }
}

static sm_status transform(const int64_t n[3], const double h[3], const uint8_t *mask, float *d,
                           int sign, sm_error *err)
{
    for (int a = 0; a < 3; a++)
        if (n[a] < 1 || !(h[a] > 0) || !isfinite(h[a]))
            return sm_error_set(err, SM_ERR_INVALID, "distance transform: bad grid (axis %d: "
                                "%lld voxels, spacing %g)", a, (long long)n[a], h[a]);
    int threads = omp_get_max_threads();
    int64_t len = n[0] > n[1] ? n[0] : n[1];
    len = len > n[2] ? len : n[2];
    line_scratch *sc = calloc((size_t)threads, sizeof *sc);
    int ok = sc != NULL;
    for (int t = 0; ok && t < threads; t++) {
        sc[t].f = malloc((size_t)len * sizeof(double));
        sc[t].d = malloc((size_t)len * sizeof(double));
        sc[t].z = malloc(((size_t)len + 1) * sizeof(double));
        sc[t].v = malloc((size_t)len * sizeof(int64_t));
        ok = sc[t].f && sc[t].d && sc[t].z && sc[t].v;
    }
    if (ok) {
        for (int a = 0; a < 3; a++)
            pass(n, h, a, mask, a == 0, sign, d, sc);
        int64_t total = n[0] * n[1] * n[2];
#pragma omp parallel for schedule(static)
        for (int64_t v = 0; v < total; v++) {
            float r = sqrtf(d[v]);
            d[v] = sign && mask[v] ? -r : r;
        }
    }
    for (int t = 0; sc && t < threads; t++) {
        free(sc[t].f);
        free(sc[t].d);
        free(sc[t].z);
        free(sc[t].v);
    }
    free(sc);
    return ok ? SM_OK : sm_error_set(err, SM_ERR_NOMEM, "out of memory for the distance transform");
}

sm_status sm_edt(const int64_t n[3], const double h[3], const uint8_t *feature, float *d,
                 sm_error *err)
{
    return transform(n, h, feature, d, 0, err);
}

sm_status sm_edt_signed(const int64_t n[3], const double h[3], const uint8_t *mask, float *d,
                        sm_error *err)
{
    return transform(n, h, mask, d, 1, err);
}

/* ---- the nearest site (sm_edt.h) ---- */

/* 1D with the minimiser: arg[q] = the p minimising (q - p)^2 h^2 + f[p]
 * (f INFINITY: no site), -1 when every f is.  The parabolas scaled by
 * 1/h^2: g[k] = f/h^2 + p^2 of the envelope's k-th. */
static void envelope(const double *f, int64_t n, double h, const double *half_inv, int32_t *arg,
                     int32_t *v, double *z, double *g)
{
    double ih2 = 1 / (h * h);
    int64_t k = -1;
    for (int64_t q = 0; q < n; q++) {
        if (f[q] == INFINITY)
            continue;
        double gq = f[q] * ih2 + (double)q * (double)q, s = -INFINITY;
        while (k >= 0) {
            s = (gq - g[k]) * half_inv[q - v[k]];
            if (s > z[k])
                break;
            k--;
        }
        k++;
        v[k] = (int32_t)q;
        g[k] = gq;
        z[k] = k == 0 ? -INFINITY : s;
        z[k + 1] = INFINITY;
    }
    if (k < 0) {
        for (int64_t q = 0; q < n; q++)
            arg[q] = -1;
        return;
    }
    k = 0;
    for (int64_t q = 0; q < n; q++) {
        while (z[k + 1] < (double)q)
            k++;
        arg[q] = v[k];
    }
}

/* Along x, sites only (f 0 or none): the nearer of the last site at or
 * before q and the first at or after, two sweeps of a row (left: the
 * thread's scratch of n[0]).  Going down, row[p] for p > q is already
 * final and a site keeps its own slot, for p < q still as on entry. */
static void nearest_row(int32_t *row, int64_t len, int32_t *left)
{
    int32_t last = -1;
    for (int64_t q = 0; q < len; q++) {
        if (row[q] >= 0)
            last = (int32_t)q;
        left[q] = last;
    }
    if (last < 0)
        return; /* no site on the row */
    int32_t next = -1;
    for (int64_t q = len - 1; q >= 0; q--) {
        int32_t l = left[q];
        if (l == q)
            next = (int32_t)q;
        int32_t p = l < 0 ? next : next < 0 ? l : q - l <= next - q ? l : next;
        row[q] = row[p];
    }
}

enum { TILE = 16 }; /* lines gathered at once across y and z: 64 bytes of
                     * each row of near per read */

typedef struct tile_scratch {
    double *half_inv; /* 1 / (2 d) at d, 1 <= d < len: the envelope's
                       * divisions, on its critical path */
    double *f, *z, *g;
    int32_t *v, *arg, *old, *out, *left;
} tile_scratch;

/* Along axis a (1 or 2) for the TILE x-adjacent lines from x = i0 at
 * other coordinate c: each voxel's candidate so far is a site level with
 * it along a, at squared distance f; the envelope picks, per voxel, the
 * line's best candidate.  slice_has (along z): the slices holding a site,
 * the others none yet (not read). */
static void nearest_tile(const int64_t n[3], const double h[3], int a, int64_t i0, int64_t c,
                         const int32_t *site_ijk, const uint8_t *slice_has, int32_t *near,
                         tile_scratch *s)
{
    int64_t len = n[a], stride = a == 1 ? n[0] : n[0] * n[1];
    int64_t base = i0 + (a == 1 ? c * n[0] * n[1] : c * n[0]);
    int cnt = (int)(n[0] - i0 < TILE ? n[0] - i0 : TILE);
    int any = 0;
    for (int64_t q = 0; q < len; q++) {
        if (slice_has && !slice_has[q]) { /* a slice without sites: none yet */
            for (int t = 0; t < cnt; t++)
                s->old[t * len + q] = -1;
            continue;
        }
        for (int t = 0; t < cnt; t++)
            any |= (s->old[t * len + q] = near[base + q * stride + t]) >= 0;
    }
    if (!any)
        return;
    int b = a == 1 ? 2 : 1; /* the other axis than x and a */
    for (int t = 0; t < cnt; t++) {
        const int32_t *old = s->old + t * len;
        double x = (double)(i0 + t), other = (double)c;
        for (int64_t q = 0; q < len; q++) {
            if (old[q] < 0) {
                s->f[q] = INFINITY;
                continue;
            }
            const int32_t *ijk = site_ijk + 3 * (int64_t)old[q];
            double dx = (x - ijk[0]) * h[0], db = (other - ijk[b]) * h[b];
            s->f[q] = dx * dx + db * db;
        }
        envelope(s->f, len, h[a], s->half_inv, s->arg, s->v, s->z, s->g);
        for (int64_t q = 0; q < len; q++)
            s->out[t * len + q] = s->arg[q] < 0 ? -1 : old[s->arg[q]];
    }
    for (int64_t q = 0; q < len; q++)
        for (int t = 0; t < cnt; t++)
            near[base + q * stride + t] = s->out[t * len + q];
}

sm_status sm__edt_nearest(const int64_t n[3], const double h[3], const int32_t *site_ijk,
                          int64_t nsites, int32_t *near, sm_error *err)
{
    int64_t len = n[0] > n[1] ? n[0] : n[1];
    len = len > n[2] ? len : n[2];
    /* has[k]: slice k holds a site; has[n[2] + j + n[1] k]: row (j, k) */
    uint8_t *has = calloc((size_t)(n[2] + n[1] * n[2]), 1);
    if (!has)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the distance transform");
    for (int64_t s = 0; s < nsites; s++) {
        has[site_ijk[3 * s + 2]] = 1;
        has[n[2] + site_ijk[3 * s + 1] + n[1] * site_ijk[3 * s + 2]] = 1;
    }
    int fail = 0;
#pragma omp parallel shared(fail)
    {
        tile_scratch s = {
            .f = malloc((size_t)len * sizeof(double)), .z = malloc((size_t)(len + 1) * sizeof(double)),
            .g = malloc((size_t)len * sizeof(double)),
            .half_inv = malloc((size_t)len * sizeof(double)), .v = malloc((size_t)len * sizeof(int32_t)),
            .arg = malloc((size_t)len * sizeof(int32_t)),
            .old = malloc((size_t)len * TILE * sizeof(int32_t)),
            .out = malloc((size_t)len * TILE * sizeof(int32_t)),
            .left = malloc((size_t)len * sizeof(int32_t))};
        int mine = !s.f || !s.z || !s.g || !s.half_inv || !s.v || !s.arg || !s.old || !s.out ||
                   !s.left;
        for (int64_t d = 1; !mine && d < len; d++)
            s.half_inv[d] = 1 / (2 * (double)d);
        /* every thread must reach the same barriers: a failed one only
         * stops doing work, and all give up after the first pass */
        if (mine) {
#pragma omp atomic write
            fail = 1;
        }
#pragma omp barrier
        int failed;
#pragma omp atomic read
        failed = fail;
        if (!failed) {
            /* rows and slices without a site stay so until the last pass */
            int64_t rows = n[1] * n[2];
#pragma omp for schedule(dynamic, 64)
            for (int64_t r = 0; r < rows; r++)
                if (has[n[2] + r])
                    nearest_row(near + r * n[0], n[0], s.left);
            int64_t tiles = (n[0] + TILE - 1) / TILE;
            for (int a = 1; a <= 2; a++) {
                int64_t others = n[a == 1 ? 2 : 1];
#pragma omp for schedule(dynamic, 4)
                for (int64_t w = 0; w < tiles * others; w++)
                    if (a == 2 || has[w / tiles])
                        nearest_tile(n, h, a, (w % tiles) * TILE, w / tiles, site_ijk,
                                     a == 2 ? has : NULL, near, &s);
            }
        }
        free(s.f);
        free(s.z);
        free(s.g);
        free(s.v);
        free(s.arg);
        free(s.old);
        free(s.out);
        free(s.left);
        free(s.half_inv);
    }
    free(has);
    return fail ? sm_error_set(err, SM_ERR_NOMEM, "out of memory for the distance transform")
                : SM_OK;
}
