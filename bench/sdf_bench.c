/* Distance-to-surface benchmark (make bench): exact signed distances per
 * second through sm_sdf (hierarchy + hierarchical winding number), side
 * by side with brute force (every point against every facet) on a
 * sample, whose result must agree to 1e-12.
 *   sdf_bench SURFACE MESH [NSAMPLE]         query points: MESH's vertices
 *   sdf_bench SURFACE random:N:LO:HI [NSAMPLE] N random points in [LO,HI]^dim
 * Prints one RESULT line of key=value pairs. */
#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "bench_util.h"
#include "shapematch/sm_io.h"
#include "shapematch/sm_sdf.h"
#include "shapematch/sm_surface.h"

static double *points(const char *spec, int dim, long *n)
{
    if (strncmp(spec, "random:", 7) == 0) {
        double lo, hi;
        if (sscanf(spec + 7, "%ld:%lf:%lf", n, &lo, &hi) != 3)
            return NULL;
        double *p = malloc((size_t)*n * dim * sizeof *p);
        unsigned long long s = 88172645463325252ull;
        for (long i = 0; p && i < *n * dim; i++) {
            s ^= s << 13, s ^= s >> 7, s ^= s << 17;
            p[i] = lo + (hi - lo) * (double)(s >> 11) / 9007199254740992.0;
        }
        return p;
    }
    sm_mesh *m;
    sm_error err;
    sm_error_clear(&err);
    if (sm_mesh_read(spec, &m, &err) != SM_OK || m->dim != dim) {
        fprintf(stderr, "sdf_bench: %s\n", err.msg[0] ? err.msg : "dimension mismatch");
        return NULL;
    }
    double *p = malloc((size_t)m->nverts * dim * sizeof *p);
    memcpy(p, m->coords, (size_t)m->nverts * dim * sizeof *p);
    *n = m->nverts;
    sm_mesh_free(m);
    return p;
}

static double brute(const sm_surface *s, const double *p)
{
    double best = INFINITY;
    for (int32_t f = 0; f < s->nfacets; f++) {
        const int32_t *v = s->facets + (size_t)f * s->dim;
        double d2 = s->dim == 3 ? sm_sdf_point_triangle2(p, s->coords + 3 * v[0], s->coords + 3 * v[1],
                                                        s->coords + 3 * v[2])
                                : sm_sdf_point_segment2(p, s->coords + 2 * v[0], s->coords + 2 * v[1]);
        best = fmin(best, d2);
    }
    return sqrt(best);
}

int main(int argc, char **argv)
{
    if (argc < 3) {
        fprintf(stderr, "usage: sdf_bench SURFACE MESH|random:N:LO:HI [NSAMPLE]\n");
        return 2;
    }
    long nsample = argc > 3 ? atol(argv[3]) : 2000;
    sm_surface *s;
    sm_error err;
    sm_error_clear(&err);
    double t0 = omp_get_wtime();
    if (sm_surface_read(argv[1], &s, &err) != SM_OK || sm_surface_repair(s, NULL, &err) != SM_OK) {
        fprintf(stderr, "sdf_bench: %s\n", err.msg);
        return 1;
    }
    double t_read = omp_get_wtime() - t0;
    long n;
    double *p = points(argv[2], s->dim, &n);
    if (!p)
        return 1;
    sm_sdf *d;
    t0 = omp_get_wtime();
    if (sm_sdf_new(s, &d, &err) != SM_OK) {
        fprintf(stderr, "sdf_bench: %s\n", err.msg);
        return 1;
    }
    double t_build = omp_get_wtime() - t0;
    double *dist = malloc((size_t)n * sizeof *dist), *sd = malloc((size_t)n * sizeof *sd);
    t0 = omp_get_wtime();
    sm_sdf_distance(d, n, p, dist, NULL);
    double t_dist = omp_get_wtime() - t0;
    t0 = omp_get_wtime();
    double c0 = bench_cpu_seconds();
    int64_t wound = 0;
    sm_status st = sm_sdf_signed_stats(d, n, p, sd, &wound, &err);
    double t_signed = omp_get_wtime() - t0, c_signed = bench_cpu_seconds() - c0;
    if (st != SM_OK)
        fprintf(stderr, "sdf_bench: %s\n", err.msg);
    /* the signs against the winding number at every sampled point */
    long differ = 0, nw = nsample < n ? nsample : n;
    double *w = malloc((size_t)(nw + 1) * sizeof *w), *wp = malloc((size_t)(nw + 1) * s->dim * sizeof *wp);
    for (long k = 0; k < nw; k++)
        memcpy(wp + k * s->dim, p + (size_t)(k * (n / (nw ? nw : 1))) * s->dim, s->dim * sizeof *wp);
    sm_sdf_winding(d, nw, wp, w);
    for (long k = 0; k < nw; k++) {
        long i = k * (n / (nw ? nw : 1));
        differ += (sd[i] < 0) != (w[k] > 0.5) || fabs(sd[i]) != dist[i];
    }
    free(w);
    free(wp);
    if (nsample > n)
        nsample = n;
    long stride = nsample ? n / nsample : 1;
    double worst = 0;
    c0 = bench_cpu_seconds();
    for (long k = 0; k < nsample; k++)
        worst = fmax(worst, fabs(brute(s, p + (size_t)(k * stride) * s->dim) - dist[k * stride]));
    double t_brute = (bench_cpu_seconds() - c0) * (double)n / (double)(nsample ? nsample : 1);
    printf("%s: %d %s, %ld points, %d threads\n", argv[1], s->nfacets,
           s->dim == 3 ? "triangles" : "segments", n, omp_get_max_threads());
    printf("  read+repair %.3f s, hierarchy %.3f s, distance %.3f s, signed (distance + "
           "winding) %.3f s = %.3g points/s\n", t_read, t_build, t_dist, t_signed,
           n / (t_signed > 0 ? t_signed : 1e-9));
    printf("  signed: %.3f CPU s (%.3f s on %d idle cores), winding number at %lld of %ld "
           "points; %ld of %ld sampled signs differ from the winding number's\n", c_signed,
           c_signed / omp_get_max_threads(), omp_get_max_threads(), (long long)wound, n, differ,
           nw);
    printf("  brute force (1 thread, CPU s, extrapolated from %ld points) %.3g s: %.0fx the "
           "signed distance's CPU time; max |diff| %.2g\n", nsample, t_brute, t_brute / c_signed,
           worst);
    printf("RESULT dim=%d facets=%d points=%ld signed=%.4f signed_cpu=%.4f build=%.4f brute=%.4g "
           "diff=%.3g wound=%lld sign_differ=%ld\n", s->dim, s->nfacets, n, t_signed, c_signed,
           t_build, t_brute, worst, (long long)wound, differ);
    free(p);
    free(dist);
    free(sd);
    sm_sdf_free(d);
    sm_surface_free(s);
    return worst <= 1e-12 && st == SM_OK && differ == 0 ? 0 : 1;
}
