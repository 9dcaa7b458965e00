/* The parameters of a matching run (sm_match_run): clamp set, material,
 * stopping rules and step control, with their defaults and range checks.
 * A header of its own because the wire codecs (proto), the CLI's option
 * parser and the core all speak it, while only the core runs the descent. */
#ifndef SM_PARAMS_H
#define SM_PARAMS_H

#include <stdint.h>

#include "sm_error.h"

#define SM_MAX_REFS 64

typedef enum sm_clamp_kind {
    SM_CLAMP_BALL = 0,     /* vertices inside a disk/ball */
    SM_CLAMP_ELEMENTS = 1, /* vertices of elements with given references */
    SM_CLAMP_VERTICES = 2, /* vertices with given references */
    SM_CLAMP_NONE = 3      /* no clamp: 0th-order term alpha int u.v */
} sm_clamp_kind;

/* How the elastic system is solved (params "solver").  AUTO picks by the
 * template's size (sm_solver_resolve): CHOLMOD's sparse Cholesky below the
 * crossover measured by bench/scale.sh, PCG + BoomerAMG (hypre) above, where
 * the factor's memory grows like n^1.3 and the AMG hierarchy's like n. */
typedef enum sm_solver_kind {
    SM_SOLVER_AUTO = 0,
    SM_SOLVER_CHOLMOD = 1,
    SM_SOLVER_AMG = 2
} sm_solver_kind;

/* "auto", "cholmod", "amg"; NULL for a value out of range. */
const char *sm_solver_kind_name(sm_solver_kind kind);
/* 0 and *out set for a known name, -1 otherwise. */
int sm_solver_kind_from_name(const char *name, sm_solver_kind *out);
/* The solver AUTO means for a template of dim and nelems elements:
 * AMG from SM_SOLVER_AMG_MIN_TETS tetrahedra on (3D only: 2D templates of
 * any size this project meets factor fast); kind itself if not AUTO.
 * Measured (bench/scale.sh, match_bench, shapematch run; README "Large
 * templates"): the inexact AMG directions need fewer iterations than the
 * exact ones (the 30k-tetrahedron example reaches 2.9e-4 at iteration 13
 * instead of 17, and its default run stops after 213 iterations instead
 * of 272, at a lower error), so AMG is ahead from ~8k tetrahedra (equal
 * at 8.5k) and uses less memory (82 against 134 MiB at 30k); below, the
 * MPI and hierarchy set-up weighs more than the whole run. */
sm_solver_kind sm_solver_resolve(sm_solver_kind kind, int dim, int64_t nelems);
#define SM_SOLVER_AMG_MIN_TETS 20000

typedef struct sm_params {
    sm_clamp_kind clamp;
    double clamp_center[3];
    double clamp_radius;
    int32_t clamp_refs[SM_MAX_REFS];
    int n_clamp_refs;
    double alpha;            /* 0th-order coefficient (clamp none); 0 (default)
                              * = from the scale, young / diameter^2 */

    /* boundary facet references excluded from the load ("bref") */
    int32_t free_refs[SM_MAX_REFS];
    int n_free_refs;

    double young;            /* default 1 */
    double poisson;          /* default 0.3 */

    int max_iter;            /* default 500 */
    double tol_step;         /* stop when step < tol_step*diameter; 1e-6 */
    double tol_boundary;     /* stop when ||d||_L2(boundary) <= this; 0=off.
                              * Absolute: scales like L^1.5 (2D) or L^2 (3D)
                              * with the template's size L */
    double tol_boundary_rel; /* stop when the RMS boundary error
                              * ||d||_L2 / sqrt(|dOmega|) <= this times the
                              * template's diameter: the same number works in
                              * any unit; 0 = off (default) */
    double tol_stall;        /* stall rule: stop when the best ||d||_L2 so far
                              * improved by less than this fraction over the
                              * last stall_window iterations; 0 = off;
                              * default 0.01 (measured in sm_params.c) */
    int stall_window;        /* K of the stall rule; default 15 */
    double min_quality;      /* quality floor for accepted steps; 0.02 */
    int save_every;          /* snapshot callback period (0 = never) */
    double step_initial;     /* first step as a fraction of the diameter; 0.01 */
    double step_max;         /* largest step as a fraction of the diameter; 0.1 */
    int refactor_every;      /* refactorize the elastic operator on the current
                              * mesh every k iterations (1 = every iteration,
                              * as in the paper); 100 */
    sm_solver_kind solver;   /* elastic solver; SM_SOLVER_AUTO (default) */
    int live_every;          /* the daemon's live mesh (mesh/latest): published
                              * every k iterations, and at least every 0.5 s
                              * of a run; 0 = by time only (default) */
} sm_params;

void sm_params_default(sm_params *p);
/* Checks ranges; message names the offending parameter. */
sm_status sm_params_validate(const sm_params *p, int dim, sm_error *err);

#endif
