/* warp_bench: points per second through a result's map (core/sm_warp.c).
 *
 *   warp_bench RESULT_DIR [NPOINTS]
 *
 * RESULT_DIR holds result.mesh and displacement.sol (what `shapematch
 * run` writes; make bench uses the 3D example's).  Prints the set-up
 * time (reading aside: the location structures of both directions) and,
 * best of 3 passes with all the OpenMP threads, the points per second
 * of sm_warp_points:
 *   forward   NPOINTS random points inside the template (a random
 *             element, random barycentric coordinates), in random order;
 *   inverse   their images, back;
 *   box       NPOINTS random points of the template's bounding box
 *             (forward; about half outside a ball, each of those a
 *             nearest-point search);
 * and max |inverse(forward(x)) - x| relative to the diameter. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench_util.h"
#include "shapematch/sm_clock.h"
#include "shapematch/sm_io.h"
#include "shapematch/sm_mesh.h"
#include "shapematch/sm_warp.h"

#include <omp.h>

static int bench_threads(void)
{
    return omp_get_max_threads();
}

static double urand(uint64_t *s)
{
    *s ^= *s << 13;
    *s ^= *s >> 7;
    *s ^= *s << 17;
    return (double)(*s >> 11) * (1.0 / 9007199254740992.0);
}

/* Points per CPU second of the best of 3 passes (all threads' CPU time:
 * on a shared machine the wall time also counts the waits for a core). */
static double cpu_rate;

/* Best of 3 wall times of one batch; returns points per second, and the
 * points per CPU second of the pass with the least CPU in cpu_rate. */
static double rate(const sm_warp *w, sm_warp_direction dir, int64_t n, const double *in,
                   double *out, uint8_t *inside, int64_t *nout)
{
    double best = INFINITY, best_cpu = INFINITY;
    for (int pass = 0; pass < 3; pass++) {
        sm_error err;
        double c0 = bench_cpu_seconds();
        double t0 = sm_clock_seconds();
        if (sm_warp_points(w, dir, 0, n, in, out, inside, nout, &err) != SM_OK) {
            fprintf(stderr, "warp_bench: %s\n", err.msg);
            exit(1);
        }
        double t = sm_clock_seconds() - t0, c = bench_cpu_seconds() - c0;
        best = fmin(best, t);
        best_cpu = fmin(best_cpu, c);
    }
    cpu_rate = (double)n / best_cpu;
    return (double)n / best;
}

int main(int argc, char **argv)
{
    if (argc < 2) {
        fprintf(stderr, "usage: warp_bench RESULT_DIR [NPOINTS]\n");
        return 2;
    }
    int64_t n = argc > 2 ? atoll(argv[2]) : 1000000;
    char pm[4096], ps[4096];
    snprintf(pm, sizeof pm, "%s/result.mesh", argv[1]);
    snprintf(ps, sizeof ps, "%s/displacement.sol", argv[1]);
    sm_mesh *m;
    sm_sol *d;
    sm_error err;
    if (sm_mesh_read(pm, &m, &err) != SM_OK || sm_sol_read(ps, &d, &err) != SM_OK) {
        fprintf(stderr, "warp_bench: %s\n", err.msg);
        return 1;
    }
    const int D = m->dim;
    size_t nc = (size_t)m->nverts * (size_t)D;
    double *Y = malloc(nc * sizeof *Y);
    memcpy(Y, m->coords, nc * sizeof *Y);
    for (size_t i = 0; i < nc; i++)
        m->coords[i] -= d->values[i];
    double t0 = sm_clock_seconds();
    sm_warp *w;
    if (sm_warp_new(m, Y, SM_WARP_LOCATE_FORWARD | SM_WARP_LOCATE_INVERSE, &w, &err) != SM_OK) {
        fprintf(stderr, "warp_bench: %s\n", err.msg);
        return 1;
    }
    double setup = sm_clock_seconds() - t0;
    double *x = malloc((size_t)n * D * sizeof *x), *y = malloc((size_t)n * D * sizeof *y);
    double *back = malloc((size_t)n * D * sizeof *back);
    uint8_t *inside = malloc((size_t)n);
    uint64_t seed = 12345;
    for (int64_t p = 0; p < n; p++) {
        const int32_t *ev = m->elems + (size_t)(urand(&seed) * m->nelems) * (size_t)(D + 1);
        double lam[4], s = 0;
        for (int k = 0; k <= D; k++)
            s += lam[k] = -log(1.0 - urand(&seed)); /* uniform on the simplex */
        for (int i = 0; i < D; i++) {
            double v = 0;
            for (int k = 0; k <= D; k++)
                v += lam[k] / s * m->coords[(size_t)ev[k] * D + i];
            x[(size_t)p * D + i] = v;
        }
    }
    int64_t nout;
    double fwd = rate(w, SM_WARP_FORWARD, n, x, y, inside, &nout), fwd_cpu = cpu_rate;
    int64_t fwd_out = nout;
    double inv = rate(w, SM_WARP_INVERSE, n, y, back, inside, &nout), inv_cpu = cpu_rate;
    double diam = sm_mesh_diameter(m, m->coords), worst = 0;
    for (size_t i = 0; i < (size_t)n * D; i++)
        worst = fmax(worst, fabs(back[i] - x[i]));
    double lo[3], hi[3];
    sm_mesh_bbox(m, m->coords, lo, hi);
    for (int64_t p = 0; p < n; p++)
        for (int i = 0; i < D; i++)
            x[(size_t)p * D + i] = lo[i] + urand(&seed) * (hi[i] - lo[i]);
    double box = rate(w, SM_WARP_FORWARD, n, x, y, inside, &nout), box_cpu = cpu_rate;
    printf("map: %dD, %ld vertices, %ld elements; set-up (both directions) %.3f s\n", D,
           (long)m->nverts, (long)m->nelems, setup);
    printf("(points/s of wall time with %d threads; per CPU second: what one core does)\n",
           bench_threads());
    printf("forward: %.3g points/s, %.3g per CPU s (%lld points inside the template, %lld "
           "flagged outside)\n", fwd, fwd_cpu, (long long)n, (long long)fwd_out);
    printf("inverse: %.3g points/s, %.3g per CPU s (their images); max |inverse(forward(x)) - x| "
           "= %.2g of the diameter\n", inv, inv_cpu, worst / diam);
    printf("box:     %.3g points/s, %.3g per CPU s forward (random in the bounding box, %lld "
           "outside)\n", box, box_cpu, (long long)nout);
    printf("RESULT forward=%.0f inverse=%.0f box=%.0f forward_cpu=%.0f inverse_cpu=%.0f "
           "roundtrip=%.3g\n", fwd, inv, box, fwd_cpu, inv_cpu, worst / diam);
    sm_warp_free(w);
    free(x);
    free(y);
    free(back);
    free(inside);
    free(Y);
    sm_sol_free(d);
    sm_mesh_free(m);
    return 0;
}
