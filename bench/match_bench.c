/* match_bench: runs one matching case and prints where the time goes.
 *
 *   match_bench DIR CLAMP_X,CLAMP_Y[,CLAMP_Z],R [MAX_ITER [REFACTOR_EVERY [SOLVER
 *               [COVERAGE_WEIGHT]]]]
 *
 * DIR holds template.mesh, background.mesh(.gz) and background.sol(.gz).
 * Prints reading time, iterations, seconds per iteration split into
 * sampling / assembly / factorization / solve / step search, the wall
 * time until ||d||_L2(boundary) <= 3e-4 and 1.5e-4 first held, the best
 * error reached, the target-side term's and figures' share (issue 33:
 * COVERAGE_WEIGHT 0 is the paper's J; the figures are computed all the
 * same), and the peak resident set size. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

#include "bench_util.h"
#include "shapematch/sm_clock.h"
#include "shapematch/sm_io.h"
#include "shapematch/sm_field.h"
#include "shapematch/sm_match.h"

typedef struct watch {
    double t_start;     /* before reading the files */
    double t_3e4, t_29e5, t_15e5;
    int it_3e4, it_29e5, it_15e5;
    double best;
    double cpu_setup;   /* process CPU seconds until the first progress call */
} watch;

static int on_progress(const sm_progress *p, const double *coords, void *user)
{
    (void)coords;
    watch *w = user;
    double t = sm_clock_seconds() - w->t_start;
    if (p->iteration == 0)
        w->cpu_setup = bench_cpu_seconds();
    if (p->boundary_l2 < w->best)
        w->best = p->boundary_l2;
    if (w->t_3e4 < 0 && p->boundary_l2 <= 3e-4) {
        w->t_3e4 = t;
        w->it_3e4 = p->iteration;
    }
    if (w->t_29e5 < 0 && p->boundary_l2 <= 2.9e-4) { /* the paper's best error */
        w->t_29e5 = t;
        w->it_29e5 = p->iteration;
    }
    if (w->t_15e5 < 0 && p->boundary_l2 <= 1.5e-4) {
        w->t_15e5 = t;
        w->it_15e5 = p->iteration;
    }
    return 0;
}

int main(int argc, char **argv)
{
    if (argc < 3) {
        fprintf(stderr, "usage: %s DIR X,Y[,Z],R [MAX_ITER [REFACTOR_EVERY [SOLVER [COVERAGE_WEIGHT]]]]\n",
                argv[0]);
        return 1;
    }
    sm_params p;
    sm_params_default(&p);
    double v[4];
    int nv = sscanf(argv[2], "%lf,%lf,%lf,%lf", &v[0], &v[1], &v[2], &v[3]);
    p.clamp = SM_CLAMP_BALL;
    for (int c = 0; c < nv - 1; c++)
        p.clamp_center[c] = v[c];
    p.clamp_radius = v[nv - 1];
    p.max_iter = argc > 3 ? atoi(argv[3]) : 300;
    p.tol_stall = 0.0; /* the fixed-length descent the figures below compare */
    if (argc > 4)
        p.refactor_every = atoi(argv[4]);
    if (argc > 6)
        p.coverage_weight = atof(argv[6]);
    if (argc > 5 && sm_solver_kind_from_name(argv[5], &p.solver) != 0) {
        fprintf(stderr, "solver must be auto, cholmod or amg (got %s)\n", argv[5]);
        return 1;
    }

    char tpath[4096], bpath[4096], spath[4096];
    if (!bench_first_existing(argv[1], "template.mesh", tpath, sizeof tpath) ||
        !bench_first_existing(argv[1], "background.mesh", bpath, sizeof bpath) ||
        !bench_first_existing(argv[1], "background.sol", spath, sizeof spath)) {
        fprintf(stderr, "%s: missing template/background files\n", argv[1]);
        return 1;
    }
    watch w = {sm_clock_seconds(), -1, -1, -1, -1, -1, -1, INFINITY, 0.0};
    sm_error err;
    sm_mesh *tm = NULL, *bg = NULL;
    sm_sol *sol = NULL;
    if (sm_mesh_read(tpath, &tm, &err) || sm_mesh_read(bpath, &bg, &err) ||
        sm_sol_read(spath, &sol, &err)) {
        fprintf(stderr, "%s\n", err.msg);
        return 1;
    }
    double t_read = sm_clock_seconds() - w.t_start;
    double rss_read = bench_peak_rss_mib();
    double *out = malloc(sizeof(double) * (size_t)tm->nverts * (size_t)tm->dim);
    sm_result r;
    /* the field is built before the run (once per process, as the job
     * runner does) and counted in the wall time like the run's set-up */
    sm_field *field = NULL;
    if (sm_field_new(bg, sol->values, &field, &err)) {
        fprintf(stderr, "%s\n", err.msg);
        return 1;
    }
    double t_field = sm_clock_seconds() - w.t_start - t_read;
    double rss_field = bench_peak_rss_mib();
    sm_match_opts opts = {.template_mesh = tm, .target = field, .params = &p};
    sm_match_callbacks cb = {.progress = on_progress, .user = &w};
    if (sm_match_run(&opts, &cb, out, &r, &err)) {
        fprintf(stderr, "%s\n", err.msg);
        return 1;
    }
    double wall = sm_clock_seconds() - w.t_start;
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    int it = r.iterations > 0 ? r.iterations : 1;
    printf("case %s: %dD, template %d vertices / %d elements, background %d vertices / %d elements\n",
           argv[1], tm->dim, tm->nverts, tm->nelems, bg->nverts, bg->nelems);
    printf("  read inputs          %8.3f s\n", t_read);
    printf("  field build          %8.3f s\n", t_field);
    printf("  setup                %8.3f s\n", r.time.setup);
    printf("  iterations           %8d   (stop: %s, %d accepted / %d rejected trials, %d factorizations)\n",
           r.iterations, sm_stop_reason_name(r.stop), r.accepted, r.rejected, r.factorizations);
    printf("  per iteration        %8.2f ms = sampling %.2f + assembly %.2f + factorization %.2f"
           " + solve %.2f + step search %.2f\n",
           1e3 * (r.time.total - r.time.setup) / it, 1e3 * r.time.sample / it,
           1e3 * r.time.assembly / it, 1e3 * r.time.factor / it, 1e3 * r.time.solve / it,
           1e3 * r.time.step / it);
    printf("  target-side term     %8.2f ms an iteration (weight %g: correspondences, load, "
           "figures; the final two-sided measure included)\n",
           1e3 * r.coverage_seconds / it, p.coverage_weight);
    if (r.solver_iterations > 0)
        printf("  PCG iterations       %8ld   (%.1f per solve)\n", r.solver_iterations,
               (double)r.solver_iterations / it);
    printf("  boundary error       final %.3g, best %.3g, min quality %.3f\n", r.boundary_l2,
           w.best, r.min_quality);
    if (w.t_3e4 >= 0)
        printf("  reached 3e-4         %8.3f s wall incl. reading (iteration %d)\n", w.t_3e4, w.it_3e4);
    else
        printf("  reached 3e-4         never\n");
    if (w.t_29e5 >= 0)
        printf("  reached 2.9e-4       %8.3f s wall incl. reading (iteration %d)\n", w.t_29e5, w.it_29e5);
    else
        printf("  reached 2.9e-4       never\n");
    if (w.t_15e5 >= 0)
        printf("  reached 1.5e-4       %8.3f s wall incl. reading (iteration %d)\n", w.t_15e5, w.it_15e5);
    else
        printf("  reached 1.5e-4       never\n");
    /* CPU time too: on a shared machine the wall time also counts the
     * time the other processes held the cores */
    double cpu = (double)ru.ru_utime.tv_sec + 1e-6 * (double)ru.ru_utime.tv_usec +
                 (double)ru.ru_stime.tv_sec + 1e-6 * (double)ru.ru_stime.tv_usec;
    printf("  total wall           %8.3f s (CPU %.3f s), peak RSS %.1f MiB (after reading %.1f, after the field %.1f)\n",
           wall, cpu, ru.ru_maxrss / 1024.0, rss_read, rss_field);
    printf("  cpu time             %8.3f s: set-up incl. reading %.3f s, per iteration %.5f s\n", cpu,
           w.cpu_setup, (cpu - w.cpu_setup) / it);
    /* machine-readable line for scripts */
    printf("RESULT dim=%d iters=%d read=%.4f field=%.4f setup=%.4f per_iter=%.5f t3e4=%.4f t29e5=%.4f"
           " t15e5=%.4f best=%.4g rss_mib=%.1f cpu=%.3f\n",
           tm->dim, r.iterations, t_read, t_field, r.time.setup, (r.time.total - r.time.setup) / it,
           w.t_3e4, w.t_29e5, w.t_15e5, w.best, ru.ru_maxrss / 1024.0, cpu);
    free(out);
    sm_field_free(field);
    sm_sol_free(sol);
    sm_mesh_free(tm);
    sm_mesh_free(bg);
    return 0;
}
