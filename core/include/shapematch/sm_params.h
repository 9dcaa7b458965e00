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
    int live_every;          /* the daemon's live mesh (mesh/latest): published
                              * every k iterations, and at least every 0.5 s
                              * of a run; 0 = by time only (default) */
} sm_params;

void sm_params_default(sm_params *p);
/* Checks ranges; message names the offending parameter. */
sm_status sm_params_validate(const sm_params *p, int dim, sm_error *err);

#endif
