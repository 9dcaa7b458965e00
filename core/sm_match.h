/* Elastic shape matching (de Buhan, Dapogny, Frey, Nardoni 2016): deform
 * a template mesh by a sequence of linear-elastic displacements that
 * decrease J(Omega) = int_Omega d, d the target's signed distance. */
#ifndef SM_MATCH_H
#define SM_MATCH_H

#include <stdint.h>

#include "sm_error.h"
#include "sm_mesh.h"

#define SM_MAX_REFS 64

typedef enum sm_clamp_kind {
    SM_CLAMP_BALL = 0,     /* vertices inside a disk/ball */
    SM_CLAMP_ELEMENTS = 1, /* vertices of elements with given references */
    SM_CLAMP_VERTICES = 2, /* vertices with given references */
    SM_CLAMP_NONE = 3      /* no clamp: 0th-order term alpha int u.v */
} sm_clamp_kind;

typedef struct sm_params {
    sm_clamp_kind clamp;
    double clamp_center[3];
    double clamp_radius;
    int32_t clamp_refs[SM_MAX_REFS];
    int n_clamp_refs;
    double alpha;            /* 0th-order coefficient (clamp none); default 1e-2 */

    /* boundary facet references excluded from the load ("bref") */
    int32_t free_refs[SM_MAX_REFS];
    int n_free_refs;

    double young;            /* default 1 */
    double poisson;          /* default 0.3 */

    int max_iter;            /* default 500 */
    double tol_step;         /* stop when step < tol_step*diameter; 1e-6 */
    double tol_boundary;     /* stop when ||d||_L2(boundary) <= this; 0=off */
    double min_quality;      /* quality floor for accepted steps; 0.02 */
    int save_every;          /* snapshot callback period (0 = never) */
    double step_initial;     /* first step as a fraction of the diameter; 0.01 */
    double step_max;         /* largest step as a fraction of the diameter; 0.1 */
    int refactor_every;      /* refactorize the elastic operator on the current
                              * mesh every k iterations (1 = every iteration,
                              * as in the paper); 100 */
} sm_params;

void sm_params_default(sm_params *p);
/* Checks ranges; message names the offending parameter. */
sm_status sm_params_validate(const sm_params *p, int dim, sm_error *err);

typedef struct sm_progress {
    int iteration;           /* accepted iterations so far (0 = initial) */
    double J;                /* current J(Omega_k) */
    double step;             /* last accepted step (a length) */
    double boundary_l2;      /* ||d||_L2(dOmega_k) */
    double boundary_max;     /* max |d| on dOmega_k */
    double min_quality;
    double elapsed;          /* seconds since the start of the run */
    int accepted, rejected;  /* trial steps in total */
} sm_progress;

typedef enum sm_stop_reason {
    SM_STOP_STEP = 0,        /* step below tol_step * diameter */
    SM_STOP_BOUNDARY = 1,    /* boundary error reached tol_boundary */
    SM_STOP_MAX_ITER = 2,
    SM_STOP_CANCELLED = 3
} sm_stop_reason;
const char *sm_stop_reason_name(sm_stop_reason r);

typedef struct sm_timings {
    double setup;            /* wall time before the first iteration: topology,
                              * the target's search structures and initial
                              * samples, and, side by side, the elastic
                              * analysis and first factorization; the other
                              * fields count the iterations only */
    double sample;           /* sampling d (load, boundary error, J) */
    double assembly;
    double factor;
    double solve;
    double step;             /* step search (validity, quality, dJ) */
    double total;
} sm_timings;

typedef struct sm_result {
    sm_stop_reason stop;
    int iterations;
    double J_initial, J;
    double boundary_l2, boundary_max, min_quality;
    int accepted, rejected;
    int factorizations;      /* numeric factorizations of the elastic operator */
    sm_timings time;
} sm_result;

/* Called after each iteration (and once for the initial state with
 * iteration 0).  coords is the current mesh (nverts*dim).  Return nonzero
 * to cancel the run. */
typedef int (*sm_progress_fn)(const sm_progress *p, const double *coords,
                              void *user);

/* Runs a matching job.  template and background need not have their
 * boundary built (copies are made as needed; inputs are not modified).
 * d has background->nverts values.  coords_out (template->nverts*dim)
 * receives the final vertex positions; the cumulative displacement is
 * coords_out - template->coords.  cancel (may be NULL) is polled between
 * iterations.  On SM_ERR_CANCELLED-free return, result->stop says why
 * the descent ended.  progress may be NULL. */
sm_status sm_match_run(const sm_mesh *template_mesh,
                       const sm_mesh *background, const double *d,
                       const sm_params *params, sm_progress_fn progress,
                       void *user, const volatile int *cancel,
                       double *coords_out, sm_result *result,
                       sm_error *err);

#endif
