/* Generated-background benchmark (make bench): is the graded background
 * (sm_background_graded_new) as good a carrier of the distance as the
 * hand-made backgrounds of examples/?  For each background the exact
 * signed distance is sampled at its vertices (sm_sdf) and interpolated
 * P1 (sm_field) at random points of the band |d| < BAND * H around the
 * surface, against the exact distance there.
 *   bg_bench SURFACE HANDMADE_BG H [NPOINTS [BAND]]
 * The graded background covers HANDMADE_BG's box with near-surface size
 * H; the uniform grid of the same size is counted, not built.  Prints
 * max and RMS errors and vertex counts, and one RESULT line. */
#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "shapematch/sm_field.h"
#include "shapematch/sm_io.h"
#include "shapematch/sm_sdf.h"
#include "shapematch/sm_surface.h"

typedef struct errs {
    double max, rms;
} errs;

/* n random points of the box with |d| < band, and their exact d. */
static int band_points(const sm_sdf *d, int dim, const double *lo, const double *hi, double band,
                       long n, double *pts, double *exact)
{
    long have = 0, batch = 65536;
    double *cand = malloc((size_t)batch * dim * sizeof *cand), *cd = malloc((size_t)batch * sizeof *cd);
    unsigned long long s = 88172645463325252ull;
    sm_error err;
    sm_error_clear(&err);
    int rc = cand && cd ? 0 : -1;
    for (int round = 0; rc == 0 && have < n && round < 10000; round++) {
        for (long i = 0; i < batch * dim; i++) {
            s ^= s << 13, s ^= s >> 7, s ^= s << 17;
            cand[i] = lo[i % dim] + (hi[i % dim] - lo[i % dim]) * (double)(s >> 11) / 9007199254740992.0;
        }
        if (sm_sdf_signed(d, batch, cand, cd, &err) != SM_OK) {
            fprintf(stderr, "bg_bench: %s\n", err.msg);
            rc = -1;
        }
        for (long i = 0; rc == 0 && i < batch && have < n; i++)
            if (fabs(cd[i]) < band) {
                memcpy(pts + have * dim, cand + i * dim, dim * sizeof *pts);
                exact[have++] = cd[i];
            }
    }
    free(cand);
    free(cd);
    return rc == 0 && have == n ? 0 : -1;
}

/* The P1 error on bg of the exact distance sampled at its vertices. */
static int measure(const sm_sdf *d, sm_mesh *bg, long n, const double *pts, const double *exact,
                   errs *e)
{
    sm_error err;
    sm_error_clear(&err);
    double *val = malloc((size_t)bg->nverts * sizeof *val), *got = malloc((size_t)n * sizeof *got);
    sm_field *f = NULL;
    int rc = -1;
    if (val && got && sm_sdf_signed(d, bg->nverts, bg->coords, val, &err) == SM_OK &&
        sm_mesh_build_boundary(bg, &err) == SM_OK && sm_field_new(bg, val, &f, &err) == SM_OK) {
        sm_field_eval_many(f, n, pts, NULL, got);
        double s2 = 0;
        e->max = 0;
        for (long i = 0; i < n; i++) {
            double x = fabs(got[i] - exact[i]);
            e->max = fmax(e->max, x);
            s2 += x * x;
        }
        e->rms = sqrt(s2 / (double)n);
        rc = 0;
    } else {
        fprintf(stderr, "bg_bench: %s\n", err.msg[0] ? err.msg : "out of memory");
    }
    sm_field_free(f);
    free(val);
    free(got);
    return rc;
}

static double uniform_count(int dim, const double *lo, const double *hi, double h)
{
    double c = 1;
    for (int k = 0; k < dim; k++)
        c *= ceil((hi[k] - lo[k]) / h) + 1;
    return c;
}

int main(int argc, char **argv)
{
    if (argc < 4) {
        fprintf(stderr, "usage: bg_bench SURFACE HANDMADE_BG H [NPOINTS [BAND]]\n");
        return 2;
    }
    double h = atof(argv[3]), band = argc > 5 ? atof(argv[5]) : 3;
    long n = argc > 4 ? atol(argv[4]) : 20000;
    sm_surface *s = NULL;
    sm_mesh *hand = NULL, *gen = NULL;
    sm_sdf *d = NULL;
    sm_error err;
    sm_error_clear(&err);
    if (sm_surface_read(argv[1], &s, &err) != SM_OK || sm_surface_repair(s, NULL, &err) != SM_OK ||
        sm_sdf_new(s, &d, &err) != SM_OK || sm_mesh_read(argv[2], &hand, &err) != SM_OK) {
        fprintf(stderr, "bg_bench: %s\n", err.msg);
        return 1;
    }
    int dim = s->dim;
    double lo[3], hi[3];
    sm_mesh_bbox(hand, hand->coords, lo, hi);
    double t0 = omp_get_wtime();
    if (sm_background_graded_new(dim, lo, hi, h, d, &gen, &err) != SM_OK) {
        fprintf(stderr, "bg_bench: %s\n", err.msg);
        return 1;
    }
    double t_gen = omp_get_wtime() - t0;
    double *pts = malloc((size_t)n * dim * sizeof *pts), *exact = malloc((size_t)n * sizeof *exact);
    errs eh, eg;
    if (!pts || !exact || band_points(d, dim, lo, hi, band * h, n, pts, exact) != 0 ||
        measure(d, hand, n, pts, exact, &eh) != 0 || measure(d, gen, n, pts, exact, &eg) != 0)
        return 1;
    printf("%s (%dD, %d facets), %ld points with |d| < %g:\n", argv[1], dim, s->nfacets, n,
           band * h);
    printf("  hand-made %s: %d vertices, P1 error of d max %.3g rms %.3g\n", argv[2], hand->nverts,
           eh.max, eh.rms);
    printf("  graded, size %g: %d vertices (uniform grid of that size: %.0f), built in %.3f s, "
           "max %.3g rms %.3g\n", h, gen->nverts, uniform_count(dim, lo, hi, h), t_gen, eg.max,
           eg.rms);
    printf("RESULT dim=%d h=%g hand_verts=%d hand_max=%.3g hand_rms=%.3g graded_verts=%d "
           "uniform_verts=%.0f graded_max=%.3g graded_rms=%.3g\n", dim, h, hand->nverts, eh.max,
           eh.rms, gen->nverts, uniform_count(dim, lo, hi, h), eg.max, eg.rms);
    free(pts);
    free(exact);
    sm_mesh_free(gen);
    sm_mesh_free(hand);
    sm_sdf_free(d);
    sm_surface_free(s);
    return 0;
}
