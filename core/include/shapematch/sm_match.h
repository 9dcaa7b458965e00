/* Elastic shape matching (de Buhan, Dapogny, Frey, Nardoni 2016): deform
 * a template mesh by a sequence of linear-elastic displacements that
 * decrease E(Omega) = J(Omega) + coverage_weight * T(Omega), where
 * J(Omega) = int_Omega d (the paper's functional, d the target's signed
 * distance) and T(Omega) = sum_y w_y dist(y, dOmega)^2 over the samples
 * y of the target's surface (sm_coverage.h): the target-side term that
 * pulls the boundary toward the parts of the target it does not reach
 * (docs/method.md).  coverage_weight 0 is the paper's J alone. */
#ifndef SM_MATCH_H
#define SM_MATCH_H

#include <stdint.h>

#include "sm_coverage.h"
#include "sm_error.h"
#include "sm_field.h"
#include "sm_mesh.h"
#include "sm_params.h"

typedef struct sm_progress {
    int iteration;           /* accepted iterations so far (0 = initial) */
    double J;                /* current J(Omega_k) */
    double step;             /* last accepted step (a length) */
    double boundary_l2;      /* ||d||_L2(dOmega_k) */
    double boundary_max;     /* max |d| on dOmega_k */
    double boundary_rms;     /* boundary_l2 / sqrt(|dOmega_k|): a length */
    double boundary_relative; /* boundary_rms / the template's diameter:
                              * unit-free */
    double min_quality;
    double elapsed;          /* seconds since the start of the run */
    int accepted, rejected;  /* trial steps in total */
    /* Both sides at this iteration, from the descent's own samples:
     * result_to_target's rms and max are boundary_rms and boundary_max
     * (d sampled on the field at the boundary's quadrature points; its
     * mean and p99 are not computed: NAN); target_to_result is exact to
     * the current boundary from the descent's samples of the target (its
     * samples merged per cell of a grid of the template boundary's mean
     * edge, each with its cell's area: sm_coverage.c), the ones the
     * target-side term uses (the events send rms, max, p99). */
    sm_distance distance;
    double energy;           /* E = J + coverage_weight * T */
} sm_progress;

typedef enum sm_stop_reason {
    SM_STOP_STEP = 0,        /* step below tol_step * diameter */
    SM_STOP_BOUNDARY = 1,    /* boundary error reached tol_boundary
                              * or tol_boundary_rel */
    SM_STOP_MAX_ITER = 2,
    SM_STOP_CANCELLED = 3,
    SM_STOP_STALLED = 4,     /* boundary error stalled (tol_stall) */
    SM_STOP_QUALITY = 5      /* quality_blocked: every trial step down to
                              * tol_step * diameter was rejected by the
                              * quality floor (or inverted an element),
                              * even with the operator assembled on the
                              * current mesh: the descent cannot move
                              * without degrading the mesh */
} sm_stop_reason;
const char *sm_stop_reason_name(sm_stop_reason r);
/* Its inverse ("step_tolerance" ... "quality_blocked"): 0 and *out set
 * for a known name, -1 otherwise (NULL included). */
int sm_stop_reason_from_name(const char *name, sm_stop_reason *out);

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
    double step;             /* step search (validity, quality, dJ) and the
                              * interior relaxation after it */
    double total;
} sm_timings;

typedef struct sm_result {
    sm_stop_reason stop;
    int converged;           /* 1 when the run reached a match: sm_match_run
                              * sets 0 for quality_blocked and cancelled;
                              * the job runner (sm_job_runner.h) also sets 0
                              * when the boundary error ends far above what
                              * the background resolves */
    int iterations;
    double J_initial, J;
    double boundary_l2, boundary_max, min_quality;
    double boundary_rms;     /* boundary_l2 / sqrt(|dOmega|), a length */
    double diameter;         /* of the template: boundary_rms / diameter is
                              * the unit-free relative error */
    double alpha;            /* the 0th-order coefficient used (no clamp;
                              * params alpha, or young / diameter^2 for 0) */
    int accepted, rejected;
    int factorizations;      /* numeric factorizations of the elastic operator */
    long solver_iterations;  /* AMG: PCG iterations over all solves (0 with CHOLMOD) */
    sm_timings time;
    /* Both sides at the end, exact and dense (sm_coverage_measure): what
     * the summary reports as "distance". */
    sm_distance distance;
    double energy_initial, energy; /* E = J + coverage_weight * T */
    double coverage_seconds;  /* the target-side term and figures, all
                               * iterations (included in the others) */
} sm_result;

/* Called after each iteration (and once for the initial state with
 * iteration 0).  coords is the current mesh (nverts*dim).  Return nonzero
 * to cancel the run. */
typedef int (*sm_progress_fn)(const sm_progress *p, const double *coords,
                              void *user);

/* What a run works on.  Everything is borrowed and only read, so one
 * target field can serve checks, the run and the outputs of a job: the
 * caller builds it once (sm_field_new) and frees it after the run. */
typedef struct sm_match_opts {
    const sm_mesh *template_mesh; /* as read; need not have its boundary */
    const sm_mesh *prepared;      /* optional: a copy of template_mesh with
                                   * its boundary built (sm_mesh_build_boundary),
                                   * as an input check makes it; NULL = the
                                   * run makes its own */
    const sm_field *target;       /* the target's signed distance on its
                                   * background mesh */
    const sm_params *params;
    sm_coverage *coverage;        /* optional: the target's samples for the
                                   * target-side term and the figures, built
                                   * on the same template (sm_coverage_new);
                                   * NULL = the run builds its own from the
                                   * target field's zero level set.  Borrowed;
                                   * the run updates its last measure. */
    const double *start;          /* optional: the displacement the descent
                                   * starts from (nverts*dim, from
                                   * template_mesh's coordinates; checked as
                                   * sm_match_set_start); NULL = the template
                                   * itself, as the paper */
} sm_match_opts;

/* How a run talks back; every member may be NULL (zeroed struct). */
typedef struct sm_match_callbacks {
    sm_progress_fn progress;      /* after each iteration, see above */
    void *user;                   /* passed to progress */
    const volatile int *cancel;   /* polled between iterations */
} sm_match_callbacks;

/* Runs a matching job.  coords_out (template->nverts*dim) receives the
 * final vertex positions; the cumulative displacement is coords_out -
 * template->coords.  cb may be NULL.  A cancel (the flag, or progress
 * returning nonzero) is not an error: the run returns SM_OK with
 * result->stop = SM_STOP_CANCELLED and coords_out and *result describe
 * the state reached (sm_match_run never returns SM_ERR_CANCELLED).  On
 * SM_OK, result->stop says why the descent ended. */
sm_status sm_match_run(const sm_match_opts *opts, const sm_match_callbacks *cb,
                       double *coords_out, sm_result *result, sm_error *err);

/* The same run in two steps, for callers that have other work to do
 * while the template side is set up (the job runner reads the target
 * meanwhile):
 *   sm_match_new      the template side: checks, topology, clamp set (a
 *                     clamp of kind auto made the default ball on the
 *                     template: sm_clamp_resolve),
 *                     the elastic operator and its first factorization
 *                     (or AMG hierarchy).  opts->target is not used; the
 *                     template meshes and params stay borrowed until
 *                     sm_match_free.
 *   sm_match_execute  the target side (the boundary functional and its
 *                     initial samples) and the descent, as sm_match_run;
 *                     once per sm_match (a second call: SM_ERR_INVALID).
 *                     result->time.setup and .total include the
 *                     template side's time; progress's elapsed counts
 *                     from the call.
 * sm_match_free in every case (NULL is fine); after a failed
 * sm_match_new *out is NULL. */
typedef struct sm_match sm_match;
sm_status sm_match_new(const sm_match_opts *opts, sm_match **out, sm_error *err);
sm_status sm_match_execute(sm_match *m, const sm_field *target, const sm_match_callbacks *cb,
                           double *coords_out, sm_result *result, sm_error *err);
/* Before sm_match_execute: the coverage to use (as sm_match_opts.coverage,
 * which sm_match_new does not read); NULL = the run builds its own. */
void sm_match_use_coverage(sm_match *m, sm_coverage *coverage);
/* Before sm_match_execute: a warm start.  The descent's first iteration
 * starts from the template moved by displacement (nverts*dim, from the
 * template's coordinates; copied) instead of from the template: its J,
 * load, boundary error and quality are those of the moved mesh, and the
 * reported and final coordinates are absolute, so coords_out minus the
 * template is still the whole displacement.  The elastic operator stays
 * the template's until the descent re-assembles it (its usual rules, and
 * after a failed step search).  The step lengths, the quality floor and
 * the stall and stop rules are those of a cold run.  SM_ERR_INVALID (and
 * the run unchanged) for a non-finite value, a clamped vertex that moves,
 * an element inverted or flat, or a worst quality below the run's quality
 * floor (min_quality, or the template's own if lower: no step could be
 * accepted from there); the message names the vertex or element (from
 * 1).  Without it the run is the cold one, bit for bit. */
sm_status sm_match_set_start(sm_match *m, const double *displacement, sm_error *err);
void sm_match_free(sm_match *m);

#endif
