/* solver_bench: the elastic solvers alone on one template, the figures
 * `auto`'s cost model is fitted on (docs/solvers.md).
 *
 *   solver_bench TEMPLATE X,Y,Z,R SOLVER [SOLVES [FACTOR]]
 *
 * SOLVER is cholmod, amg or auto (auto prints the choice the cost model
 * makes and its predicted figures); FACTOR (cholmod only) is auto,
 * simplicial or supernodal.  Builds the operator with the clamp ball,
 * factorizes (or sets the AMG hierarchy up) and solves SOLVES times
 * (default 20) for loads that change from one solve to the next as a
 * descent's do: AMG's warm-started solves then take ~4 PCG steps, as in
 * the descent on examples/3d (bench/scale.sh: 3.9).
 * Prints one line: the template's size, the set-up split into pattern and
 * analysis / factorization, the mean solve, the factor's entries and
 * flops, PCG steps per solve, wall and CPU seconds, and the peak RSS the
 * solver added to the template's.  One solver per process, so that each
 * peak RSS is its own. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench_util.h"
#include "shapematch/sm_clamp.h"
#include "shapematch/sm_clock.h"
#include "shapematch/sm_io.h"
#include "shapematch/sm_mesh.h"
#include "sm_elasticity.h"

int main(int argc, char **argv)
{
    if (argc < 4) {
        fprintf(stderr, "usage: %s TEMPLATE X,Y,Z,R cholmod|amg|auto [SOLVES [auto|simplicial|supernodal]]\n",
                argv[0]);
        return 1;
    }
    sm_params p;
    sm_params_default(&p);
    if (sscanf(argv[2], "%lf,%lf,%lf,%lf", &p.clamp_center[0], &p.clamp_center[1],
               &p.clamp_center[2], &p.clamp_radius) != 4) {
        fprintf(stderr, "clamp: X,Y,Z,R\n");
        return 1;
    }
    p.clamp = SM_CLAMP_BALL;
    sm_elasticity_opts eo = {.young = p.young, .poisson = p.poisson};
    if (sm_solver_kind_from_name(argv[3], &eo.solver) != 0) {
        fprintf(stderr, "solver must be auto, cholmod or amg (got %s)\n", argv[3]);
        return 1;
    }
    int solves = argc > 4 ? atoi(argv[4]) : 20;
    if (argc > 5)
        eo.factor = strcmp(argv[5], "simplicial") == 0   ? SM_FACTOR_SIMPLICIAL
                    : strcmp(argv[5], "supernodal") == 0 ? SM_FACTOR_SUPERNODAL
                                                         : SM_FACTOR_AUTO;
    sm_error err;
    sm_mesh *m = NULL;
    if (sm_mesh_read(argv[1], &m, &err) != SM_OK) {
        fprintf(stderr, "%s\n", err.msg);
        return 1;
    }
    const size_t ndof = (size_t)m->nverts * 3;
    uint8_t *clamped = malloc((size_t)m->nverts + 1);
    double *load = malloc(ndof * sizeof *load), *u = malloc(ndof * sizeof *u);
    if (m->dim != 3 || !clamped || !load || !u) {
        fprintf(stderr, "a 3D template is needed\n");
        return 1;
    }
    sm_clamp_mark(m, &p, clamped);
    double rss0 = bench_peak_rss_mib();
    double c0 = bench_cpu_seconds(), t0 = sm_clock_seconds();
    sm_elasticity *el = NULL;
    if (sm__elasticity_new(m, clamped, &eo, &el, &err) != SM_OK) {
        fprintf(stderr, "%s\n", err.msg);
        return 1;
    }
    double t1 = sm_clock_seconds();
    if (sm__elasticity_factorize(el, m->coords, &err) != SM_OK) {
        fprintf(stderr, "%s\n", err.msg);
        return 1;
    }
    double t2 = sm_clock_seconds(), c2 = bench_cpu_seconds();
    long pcg = 0;
    double checksum = 0;
    for (int k = 0; k < solves; k++) {
        /* a load away from the clamp's centre, its pattern moving with k */
        for (int32_t v = 0; v < m->nverts; v++) {
            const double *x = m->coords + (size_t)v * 3;
            double s = 1 + 0.5 * sin(1.3 * k + 7 * x[0] + 3 * x[1]);
            for (int c = 0; c < 3; c++)
                load[(size_t)v * 3 + c] = 1e-4 * s * (x[c] - p.clamp_center[c]);
        }
        if (sm__elasticity_solve(el, load, NULL, u, &err) != SM_OK) {
            fprintf(stderr, "%s\n", err.msg);
            return 1;
        }
        sm_elasticity_info in;
        sm__elasticity_get_info(el, &in);
        pcg += in.amg_iterations;
        checksum += u[ndof / 2];
    }
    double t3 = sm_clock_seconds(), c3 = bench_cpu_seconds();
    sm_elasticity_info info;
    sm__elasticity_get_info(el, &info);
    sm_solver_estimate est;
    sm__elasticity_estimate(el, &est);
    printf("SOLVER tets=%d unknowns=%d nnz=%ld solver=%s factor=%s analyse=%.4f factorize=%.4f "
           "solve=%.5f pcg=%.2f lnz=%.0f flops=%.4g cpu_setup=%.3f cpu_solve=%.5f rss_mib=%.1f "
           "est_chol_s=%.3f est_amg_s=%.3f est_chol_mib=%.0f est_amg_mib=%.0f check=%.6g\n",
           m->nelems, info.nfree, (long)info.nnz, sm_solver_kind_name(info.solver),
           info.solver == SM_SOLVER_CHOLMOD ? (info.supernodal ? "supernodal" : "simplicial") : "-",
           t1 - t0, t2 - t1, solves > 0 ? (t3 - t2) / solves : 0.0,
           solves > 0 ? (double)pcg / solves : 0.0, est.lnz, est.flops, c2 - c0,
           solves > 0 ? (c3 - c2) / solves : 0.0, bench_peak_rss_mib() - rss0, est.cholmod_seconds,
           est.amg_seconds, est.cholmod_bytes / 1048576.0, est.amg_bytes / 1048576.0, checksum);
    sm__elasticity_free(el);
    sm_mesh_free(m);
    free(clamped);
    free(load);
    free(u);
    return 0;
}
