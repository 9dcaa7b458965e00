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
