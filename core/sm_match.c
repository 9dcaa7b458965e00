#include "shapematch/sm_match.h"

#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "shapematch/sm_clock.h"
#include "shapematch/sm_clamp.h"
#include "sm_alloc.h"
#include "sm_coverage_internal.h"
#include "sm_elasticity.h"
#include "sm_relax.h"
#include "shapematch/sm_field.h"
#include "sm_shape.h"

/* Sufficient-decrease constant of the Armijo test. */
#define ARMIJO_C 1e-4
/* Step growth after an accepted trial, and the bounds of a reduction. */
#define STEP_GROW 1.6
#define STEP_SHRINK_MIN 0.1
#define STEP_SHRINK_MAX 0.5

/* Keeping element quality through large deformations.  The elastic
 * operator is re-assembled on the current mesh (besides every
 * refactor_every iterations) when the worst quality approaches the floor
 * (below REFACTOR_QUALITY_NEAR times it) and has fallen below
 * REFACTOR_QUALITY_DROP times the worst quality of the mesh the operator
 * was assembled on, and when a step search fails with an operator of an
 * older mesh; each re-assembly multiplies an element's Lame coefficients
 * by (q_template / q_now)^STIFFEN_EXPONENT when it has lost quality, so
 * that the next directions spare the distorted elements (the
 * distortion-based variant of the Jacobian-based stiffening of ALE mesh
 * motion).  Measured (bench/robust.sh, Gmsh unit ball clamped at its
 * centre, radius 0.2): onto the ellipsoid grown x2 the boundary RMS went
 * from 0.60 (quality floor hit at iteration 13) to 5.1e-3, shrunk x0.5
 * from 0.115 to 2.7e-4, better than unclamped CHOLMOD (7.3e-3, 4.7e-4).
 * Without the gate near the floor the 2D example re-assembled after 5
 * iterations at quality 0.56 (harmless) and needed 40% more iterations
 * to the same error.  Exponent 0 (re-assembly alone): grown 7.3e-3 in
 * 495 iterations, shrunk quality_blocked at 4.8e-3; 1: 5.1e-3 in 378 and
 * 2.7e-4 in 118; 2: 5.2e-3 in 345 and 2.8e-4 in 121, but on the cube of
 * side 0.4 onto a ball (bench/stall_cases.py) 2.5e-4 after 341 where 1
 * reaches 1.9e-4 after 346 (min quality 0.11) and the former scheme
 * 2.1e-4 after 56 at the floor (0.02).  Far from the floor (worst
 * quality above REFACTOR_QUALITY_NEAR times it: a re-assembly after a
 * failed step search) nothing is stiffened: there it changed the path of
 * the square onto a disk of bench/stall_cases.py (6.27e-3 after 203
 * iterations instead of 5.91e-3 after 202) and of the examples. */
#define REFACTOR_QUALITY_NEAR 10.0
#define REFACTOR_QUALITY_DROP 0.7
#define STIFFEN_EXPONENT 1.0
#define STIFFEN_MAX 1e4
/* Rings of the boundary the target-side term's point loads are spread
 * over for the direction (sm__coverage_spread).  Measured on a Gmsh
 * ball (mesh size 0.15) onto a ball with a finger 0.5 wide
 * (tests/cli/coverage.sh): unspread, a spike one or two vertices wide
 * grows along the finger's axis and the target side's p99 stays at 0.2;
 * three rings (about the finger's radius) grow the finger, p99 0.098. */
#define SPREAD_PASSES 3
/* Interior relaxation (sm_relax.h) after an accepted step whose worst
 * quality fell below RELAX_NEAR times the floor: the free interior
 * vertices of the elements below RELAX_BELOW times the floor are moved
 * to better quality (RELAX_SWEEPS passes), which changes neither J nor
 * T.  Measured on issue 33's ball onto a bent capsule (an L;
 * tests/cli/stall.sh), --align affine: quality_blocked after 143
 * iterations, target side p99 0.178 (twice the resolution: 0.143),
 * became covered, p99 0.068 after 473; --align similarity 0.136
 * quality_blocked after 127 became 0.025; a ball onto a dumbbell (bar
 * 0.5 wide) 0.086 quality_blocked after 139 became 0.019.  Below 10 x
 * the floor and 3 passes ended the same to 5% at twice the CPU time
 * (the relaxation was then 3/4 of an iteration's); 20 x and 10 passes
 * too.  The gate keeps every run that stays above 5 x the floor (both
 * examples: 0.49 and 0.30; bench/robust.sh but its torus) bit for bit
 * as it was. */
#define RELAX_NEAR 5.0
#define RELAX_BELOW 6.0
#define RELAX_SWEEPS 1


const char *sm_stop_reason_name(sm_stop_reason r)
{
    switch (r) {
    case SM_STOP_STEP: return "step_tolerance";
    case SM_STOP_BOUNDARY: return "boundary_tolerance";
    case SM_STOP_MAX_ITER: return "max_iterations";
    case SM_STOP_CANCELLED: return "cancelled";
    case SM_STOP_STALLED: return "stalled";
    case SM_STOP_QUALITY: return "quality_blocked";
    }
    return "unknown";
}

int sm_stop_reason_from_name(const char *name, sm_stop_reason *out)
{
    /* every value the name function knows, so the two cannot drift */
    for (int r = 0; name && strcmp(sm_stop_reason_name((sm_stop_reason)r), "unknown") != 0; r++)
        if (strcmp(name, sm_stop_reason_name((sm_stop_reason)r)) == 0) {
            *out = (sm_stop_reason)r;
            return 0;
        }
    return -1;
}

/* Everything one run owns or tracks; freed in one place.  The set-up,
 * the direction and the line search below read and update it.  An
 * sm_match (sm_match_new) is one whose template side is set up. */
typedef struct sm_match run_state;
struct sm_match {
    const sm_params *params;
    sm_params own_params;     /* the params with a clamp of kind auto made
                               * the default ball (sm_clamp_resolve) */
    const sm_mesh *mesh;      /* the template with its boundary built:
                               * opts->prepared, or own_mesh */
    sm_mesh *own_mesh;        /* private copy when nothing was prepared */
    sm_shape *shape;
    sm_elasticity *elasticity;
    sm_relax *relax;          /* interior relaxation (relax_interior) */
    uint8_t *clamped;
    double *x, *trial, *load, *u, *step;
    double *tload;            /* the target-side term's part of load */
    double *dirload;          /* the load the direction is solved for:
                               * load with the term's part spread */
    double *q_template;       /* nelems: each element's quality in the template */
    double *stiffness;        /* nelems: the operator's stiffening factors */
    double q_factor;          /* min quality of the mesh the operator was
                               * assembled on */
    int refactor_now;         /* assemble on the current mesh before the
                               * next direction */
    int quality_limited;      /* the last step search ended on a trial the
                               * quality floor (or an inversion) rejected */
    int dim;
    size_t ndof;
    double t_start;
    double diameter, step_min, step_max;
    double floor_q;           /* quality floor of accepted steps */
    double alpha;             /* effective 0th-order coefficient (no clamp) */
    double J, qmin;
    sm_boundary_error be;
    /* the target-side term (sm_coverage_internal.h): T at x, its weight,
     * and the target side's figures there */
    sm_coverage *coverage;    /* opts->coverage or own_coverage */
    sm_coverage *own_coverage;
    double weight, T;
    sm_distance_side cover;
    int corresponded;         /* the coverage's correspondences, T and
                               * cover were found at x by the step search */
    double coverage_seconds;
    double last_step;         /* the last accepted step (a length) */
    double tau;               /* current trial step (a length) */
    double slope;             /* -dJ/dtau along the normalized direction */
    int since_factor;         /* accepted iterations since the last factorization */
    int iteration, accepted, rejected;
    double *best;             /* stall rule: best ||d||_L2 up to iteration
                               * i, at best[i % (stall_window + 1)] */
    double elastic_seconds;   /* sm_match_new: its elastic set-up's time */
    int executed;             /* sm_match_execute ran (once only) */
    int warm;                 /* the descent starts from a given
                               * displacement (sm_match_set_start), with
                               * the operator of the template */
};

static void run_state_free(run_state *rs)
{
    sm__elasticity_free(rs->elasticity);
    sm__relax_free(rs->relax);
    sm__shape_free(rs->shape);
    sm_mesh_free(rs->own_mesh);
    free(rs->clamped);
    free(rs->x);
    free(rs->trial);
    free(rs->load);
    free(rs->tload);
    free(rs->dirload);
    free(rs->u);
    free(rs->step);
    free(rs->q_template);
    free(rs->stiffness);
    free(rs->best);
    sm_coverage_free(rs->own_coverage);
}

/* A trial mesh is valid when no element is inverted and its worst quality
 * stays above the floor.  Returns the worst quality (or -1 if inverted). */
static double trial_quality(const sm_mesh *m, const double *coords, double floor_q, int *ok)
{
    double qmin = sm_mesh_min_quality(m, coords, NULL);
    *ok = qmin > 0.0 && qmin >= floor_q;
    return qmin > 0.0 ? qmin : -1.0;
}

/* The template with its boundary (borrowed or a private copy), the work
 * arrays, the clamp set and the step bounds. */
static sm_status setup_mesh(run_state *rs, const sm_match_opts *opts, sm_error *err)
{
    sm_status st;
    const sm_params *params = rs->params;
    if (opts->prepared) {
        rs->mesh = opts->prepared;
    } else {
        if ((st = sm_mesh_clone(opts->template_mesh, &rs->own_mesh, err)) != SM_OK)
            return st;
        if ((st = sm_mesh_build_boundary(rs->own_mesh, err)) != SM_OK) {
            sm_error_prefix(err, "template");
            return st;
        }
        rs->mesh = rs->own_mesh;
    }
    if (params->clamp == SM_CLAMP_AUTO) { /* the default clamp, on the boundary just built */
        rs->own_params = *params;
        if ((st = sm_clamp_resolve(rs->mesh, &rs->own_params, NULL, err)) != SM_OK)
            return st;
        rs->params = params = &rs->own_params;
    }
    const size_t ndof = rs->ndof;
    rs->clamped = malloc((size_t)rs->mesh->nverts + 1);
    /* written at once by the set-up and the first iteration: prefaulted
     * or huge pages (sm_alloc.h) */
    rs->x = sm__alloc_huge(ndof * sizeof(double));
    rs->trial = sm__alloc_huge(ndof * sizeof(double));
    rs->load = sm__alloc_huge(ndof * sizeof(double));
    rs->tload = malloc((ndof + 1) * sizeof(double));
    rs->dirload = malloc((ndof + 1) * sizeof(double));
    rs->u = sm__alloc_huge(ndof * sizeof(double));
    rs->step = sm__alloc_huge(ndof * sizeof(double));
    rs->best = malloc(((size_t)params->stall_window + 1) * sizeof(double));
    rs->q_template = malloc(((size_t)rs->mesh->nelems + 1) * sizeof(double));
    rs->stiffness = malloc(((size_t)rs->mesh->nelems + 1) * sizeof(double));
    if (!rs->clamped || !rs->x || !rs->trial || !rs->load || !rs->u || !rs->step || !rs->best ||
        !rs->tload || !rs->dirload ||
        !rs->q_template || !rs->stiffness)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for a mesh of %ld vertices",
                            (long)rs->mesh->nverts);
    if ((st = sm_clamp_check(rs->mesh, params, NULL, err)) != SM_OK)
        return st;
    sm_clamp_mark(rs->mesh, params, rs->clamped);
    if ((st = sm__relax_new(rs->mesh, rs->clamped, &rs->relax, err)) != SM_OK)
        return st;

    memcpy(rs->x, rs->mesh->coords, ndof * sizeof(double));
    rs->diameter = sm_mesh_diameter(rs->mesh, rs->x);
    rs->step_min = params->tol_step * rs->diameter;
    rs->step_max = params->step_max * rs->diameter;
    /* alpha int u.v against E int eps:eps: the two balance at E / L^2 */
    rs->alpha = params->alpha > 0 ? params->alpha : params->young / (rs->diameter * rs->diameter);

    sm_quality_stats qs;
    sm_mesh_quality(rs->mesh, rs->x, &qs);
    /* A template already worse than the floor may not get worse still. */
    rs->floor_q = qs.min < params->min_quality ? qs.min : params->min_quality;
    rs->qmin = qs.min;
    rs->q_factor = qs.min;
#pragma omp parallel for schedule(static)
    for (int32_t e = 0; e < rs->mesh->nelems; e++) {
        rs->q_template[e] = sm_elem_quality(rs->mesh, rs->x, e);
        rs->stiffness[e] = 1.0;
    }
    return SM_OK;
}

/* CHOLMOD's supernodal factorization opens OpenMP regions of a fixed
 * width of its own (num_threads(4) in CHOLMOD 3), which the thread limit
 * does not cap; outside an active region they would start 4 threads
 * where one is allowed (and spin for it: 5x the set-up CPU time on the
 * busy machine).  With one thread allowed, every region is made inactive
 * for the call instead (max-active-levels 0: they run on the calling
 * thread).  Returns the previous level, for omp_set_max_active_levels. */
static int one_thread_regions(void)
{
    int levels = omp_get_max_active_levels();
    if (omp_get_max_threads() == 1)
        omp_set_max_active_levels(0);
    return levels;
}

/* The target-side term at x: the closest points of the target's samples
 * on the current boundary, T and the figures, and the term's load added
 * to the load of J. */
static sm_status add_coverage_load(run_state *rs, sm_error *err)
{
    double t0 = sm_clock_seconds();
    sm_status st = SM_OK;
    if (!rs->corresponded) /* else the step search found them at x */
        st = sm__coverage_correspond(rs->coverage, rs->x, &rs->cover, &rs->T, err);
    rs->corresponded = 0;
    memcpy(rs->dirload, rs->load, rs->ndof * sizeof *rs->dirload);
    if (st == SM_OK && rs->weight > 0 && rs->T > 0) {
        memset(rs->tload, 0, rs->ndof * sizeof *rs->tload);
        sm__coverage_add_load(rs->coverage, rs->x, rs->weight, rs->tload);
        sm__coverage_spread(rs->coverage, rs->tload, rs->step, SPREAD_PASSES);
        for (size_t i = 0; i < rs->ndof; i++) {
            rs->load[i] += rs->tload[i];
            rs->dirload[i] += rs->step[i];
        }
    }
    rs->coverage_seconds += sm_clock_seconds() - t0;
    return st;
}

/* The target side of the set-up: the boundary functional on the
 * (prebuilt) target field with the initial samples. */
static sm_status setup_target(run_state *rs, const sm_field *target, sm_error *err)
{
    const sm_params *params = rs->params;
    sm_status st = sm__shape_new(rs->mesh, target, params->free_refs, params->n_free_refs,
                                &rs->shape, err);
    if (st == SM_OK && sm__shape_active_facets(rs->shape) == 0)
        st = sm_error_set(err, SM_ERR_INVALID,
                          "no boundary facet carries the load (all are in the free boundary)");
    if (st != SM_OK)
        return st;
    if (!rs->coverage) {
        st = sm_coverage_new(target, NULL, rs->mesh, params->free_refs, params->n_free_refs,
                             &rs->own_coverage, err);
        if (st != SM_OK) {
            sm_error_prefix(err, "target");
            return st;
        }
        rs->coverage = rs->own_coverage;
    }
    rs->weight = params->coverage_weight;
    sm__shape_load(rs->shape, rs->x, rs->load, &rs->be);
    rs->J = sm__shape_volume_j(rs->shape, rs->x);
    return add_coverage_load(rs, err);
}

/* The elastic side: the operator's symbolic analysis and its first
 * factorization (or AMG hierarchy), which need the template only. */
static sm_status setup_elastic(run_state *rs, sm_error *err)
{
    const sm_params *params = rs->params;
    sm_elasticity_opts eopts = {
        .young = params->young, .poisson = params->poisson,
        .alpha = params->clamp == SM_CLAMP_NONE ? rs->alpha : 0.0,
        .solver = params->solver};
    sm_status st = sm__elasticity_new(rs->mesh, rs->clamped, &eopts, &rs->elasticity, err);
    if (st == SM_OK) /* on the template, also under a warm start */
        st = sm__elasticity_factorize(rs->elasticity, rs->mesh->coords, err);
    return st;
}

/* The two expensive set-up tasks are independent, so sm_match_run runs
 * them side by side when more than one thread is allowed (the thread
 * policy, proto/job/sm_job_threads.h, allows one for small templates). */
static sm_status setup_both(run_state *rs, const sm_field *target, sm_error *err)
{
    sm_status st_target = SM_OK, st_elastic = SM_OK;
    sm_error err_target, err_elastic;
    sm_error_clear(&err_target);
    sm_error_clear(&err_elastic);
    int levels = one_thread_regions();
#pragma omp parallel sections num_threads(omp_get_max_threads() > 1 ? 2 : 1)
    {
#pragma omp section
        st_target = setup_target(rs, target, &err_target);
#pragma omp section
        st_elastic = setup_elastic(rs, &err_elastic);
    }
    omp_set_max_active_levels(levels);
    if (st_target != SM_OK || st_elastic != SM_OK) {
        if (err)
            *err = st_target != SM_OK ? err_target : err_elastic;
        return st_target != SM_OK ? st_target : st_elastic;
    }
    return SM_OK;
}

/* The stiffening factors of the current mesh (see STIFFEN_EXPONENT),
 * handed to the operator for its next assembly. */
static void stiffen(run_state *rs)
{
    const sm_mesh *m = rs->mesh;
    if (rs->qmin >= REFACTOR_QUALITY_NEAR * rs->floor_q) {
        /* far from the floor: the plain operator of the current mesh */
        sm__elasticity_set_stiffness(rs->elasticity, NULL);
        return;
    }
#pragma omp parallel for schedule(static)
    for (int32_t e = 0; e < m->nelems; e++) {
        double q = sm_elem_quality(m, rs->x, e), w = 1.0;
        if (q > 0 && q < rs->q_template[e]) {
            w = pow(rs->q_template[e] / q, STIFFEN_EXPONENT);
            if (w > STIFFEN_MAX)
                w = STIFFEN_MAX;
        }
        rs->stiffness[e] = w;
    }
    sm__elasticity_set_stiffness(rs->elasticity, rs->stiffness);
}

/* The descent direction: elasticity with the shape derivative as load,
 * refactorized on the current mesh every refactor_every iterations, then
 * normalized so that tau is the largest vertex displacement.  *found = 0
 * when no descent direction is left. */
static sm_status find_direction(run_state *rs, sm_result *result, int *found, sm_error *err)
{
    sm_status st;
    sm_timings *tm = &result->time;
    const int dim = rs->dim;
    double t0, ta, tf;
    if (rs->since_factor >= rs->params->refactor_every || rs->refactor_now) {
        stiffen(rs);
        int levels = one_thread_regions();
        st = sm__elasticity_factorize(rs->elasticity, rs->x, err);
        omp_set_max_active_levels(levels);
        if (st != SM_OK)
            return st;
        rs->since_factor = 0;
        rs->refactor_now = 0;
        rs->q_factor = rs->qmin;
        result->factorizations++;
        sm__elasticity_timings(rs->elasticity, &ta, &tf);
        tm->assembly += ta;
        tm->factor += tf;
    }
    t0 = sm_clock_seconds();
    if ((st = sm__elasticity_solve(rs->elasticity, rs->dirload, NULL, rs->u, err)) != SM_OK)
        return st;
    if (rs->weight > 0 && rs->T > 0) {
        /* the spread load is a preconditioned gradient: the direction must
         * still descend along the true one, else the true load's */
        double s = 0;
        for (size_t i = 0; i < rs->ndof; i++)
            s += rs->load[i] * rs->u[i];
        if (!(s > 0) &&
            (st = sm__elasticity_solve(rs->elasticity, rs->load, NULL, rs->u, err)) != SM_OK)
            return st;
    }
    tm->solve += sm_clock_seconds() - t0;
    sm_elasticity_info info;
    sm__elasticity_get_info(rs->elasticity, &info);
    result->solver_iterations += info.amg_iterations;

    double umax = 0.0;
    for (int32_t v = 0; v < rs->mesh->nverts; v++) {
        double s = 0.0;
        for (int c = 0; c < dim; c++)
            s += rs->u[(size_t)v * (size_t)dim + (size_t)c] * rs->u[(size_t)v * (size_t)dim + (size_t)c];
        if (s > umax)
            umax = s;
    }
    umax = sqrt(umax);
    double slope = 0.0;
    if (umax > 0) {
        for (size_t i = 0; i < rs->ndof; i++) {
            rs->u[i] /= umax;
            slope += rs->load[i] * rs->u[i];
        }
    }
    rs->slope = slope;
    *found = umax > 0 && slope > 0;
    return SM_OK;
}

/* Step search along u: shrink tau until the trial mesh is valid and the
 * energy E = J + weight * T decreases sufficiently (Armijo), the shrink
 * factor from the parabola through E(0), E'(0), E(tau).  T is the true
 * term at the trial: its closest points found again there
 * (sm__coverage_correspond), and on acceptance kept as the next
 * iteration's (add_coverage_load does not search again).  The slope's T
 * part, from the correspondences kept at x, is the true derivative
 * (where the closest points are unique they move smoothly, and the
 * term's derivative along them is 0).  The bound with the
 * correspondences kept instead (never below T) rejected long steps: it
 * charges every sliding of the boundary along the target as if it moved
 * away from it, and a sample inside the dead zone leaves it as soon as
 * its closest point slides by delta.  On examples/3d (tolerance 2.9e-4)
 * a step of 6.8e-2 the true E accepts (dJ -4.1e-6, dT -5.7e-6) had a
 * bound's dT of +1.9e-3: the median accepted step was 5.6e-3 against
 * 2.35e-2, 41 iterations against 23 (17 with J alone).  On success rs->trial
 * holds the accepted mesh, *dJ and *q_trial its change of J and worst
 * quality; *found = 0 when tau fell below the step tolerance first. */
static sm_status line_search(run_state *rs, double *dJ, double *q_trial, int *found,
                             sm_error *err)
{
    const double slope = rs->slope;
    double tau = rs->tau;
    *found = 0;
    *dJ = 0.0;
    *q_trial = rs->qmin;
    rs->quality_limited = 0;
    while (tau >= rs->step_min) {
        for (size_t i = 0; i < rs->ndof; i++) {
            rs->step[i] = tau * rs->u[i];
            rs->trial[i] = rs->x[i] + rs->step[i];
        }
        int ok;
        *q_trial = trial_quality(rs->mesh, rs->trial, rs->floor_q, &ok);
        rs->quality_limited = !ok;
        if (ok) {
            *dJ = sm__shape_delta_j(rs->shape, rs->x, rs->step);
            double dE = *dJ, T_trial = 0;
            sm_distance_side cover_trial = {0};
            if (rs->weight > 0) {
                double t0 = sm_clock_seconds();
                sm_status st = sm__coverage_correspond(rs->coverage, rs->trial, &cover_trial,
                                                       &T_trial, err);
                rs->coverage_seconds += sm_clock_seconds() - t0;
                if (st != SM_OK)
                    return st;
                dE += rs->weight * (T_trial - rs->T);
            }
            if (dE <= -ARMIJO_C * tau * slope) {
                *found = 1;
                rs->accepted++;
                if (rs->weight > 0) {
                    rs->T = T_trial;
                    rs->cover = cover_trial;
                    rs->corresponded = 1;
                }
                break;
            }
            double curvature = dE + tau * slope;
            double shrink = curvature > 0 ? 0.5 * slope * tau / curvature : STEP_SHRINK_MAX;
            if (shrink > STEP_SHRINK_MAX)
                shrink = STEP_SHRINK_MAX;
            if (shrink < STEP_SHRINK_MIN)
                shrink = STEP_SHRINK_MIN;
            tau *= shrink;
        } else {
            tau *= STEP_SHRINK_MAX;
        }
        rs->rejected++;
    }
    rs->tau = tau;
    return SM_OK;
}

static double boundary_rms(const sm_boundary_error *be)
{
    return be->measure > 0 ? be->l2 / sqrt(be->measure) : 0.0;
}

/* The error the stall rule follows: ||d||_L2 on the boundary, and with
 * the target-side term on, the target side's sqrt(T) too (the two-sided
 * L2 distance). */
static double stall_error(const run_state *rs)
{
    return rs->weight > 0 ? sqrt(rs->be.l2 * rs->be.l2 + rs->T) : rs->be.l2;
}

/* Records the best error up to the current iteration. */
static void track_best(run_state *rs)
{
    const size_t slots = (size_t)rs->params->stall_window + 1;
    double b = stall_error(rs);
    if (rs->iteration > 0) {
        double prev = rs->best[(size_t)(rs->iteration - 1) % slots];
        if (prev < b)
            b = prev;
    }
    rs->best[(size_t)rs->iteration % slots] = b;
}

/* The stall rule: over the last stall_window iterations the best error
 * so far improved by less than the fraction tol_stall.  The best so far,
 * not the current error, so that one lucky or unlucky iteration neither
 * triggers nor delays it.  A run whose last step was the largest allowed
 * is moving, not stalled: the Armijo test accepted a full-length step,
 * so the energy still falls fast (a converged run's steps shrink), even
 * when the boundary error rises for a while (a template swinging into
 * place after an alignment: issue 33's ball onto a bent capsule). */
static int stalled(const run_state *rs)
{
    const sm_params *p = rs->params;
    if (!(p->tol_stall > 0) || rs->iteration < p->stall_window)
        return 0;
    if (rs->last_step >= rs->step_max)
        return 0;
    const size_t slots = (size_t)p->stall_window + 1;
    double then = rs->best[(size_t)(rs->iteration - p->stall_window) % slots];
    double now = rs->best[(size_t)rs->iteration % slots];
    return then - now < p->tol_stall * then;
}

/* Reports the current state; nonzero when the callback asks to stop. */
static int report(const run_state *rs, const sm_match_callbacks *cb)
{
    if (!cb || !cb->progress)
        return 0;
    sm_progress pg = {0};
    pg.iteration = rs->iteration;
    pg.J = rs->J;
    pg.step = rs->iteration > 0 ? rs->tau : 0.0;
    pg.boundary_l2 = rs->be.l2;
    pg.boundary_max = rs->be.max;
    pg.boundary_rms = boundary_rms(&rs->be);
    pg.boundary_relative = rs->diameter > 0 ? pg.boundary_rms / rs->diameter : 0.0;
    pg.min_quality = rs->qmin;
    pg.elapsed = sm_clock_seconds() - rs->t_start;
    pg.accepted = rs->accepted;
    pg.rejected = rs->rejected;
    pg.distance.method = sm_coverage_method(rs->coverage);
    pg.distance.result_to_target = (sm_distance_side){
        .rms = pg.boundary_rms, .max = rs->be.max, .mean = NAN, .p99 = NAN};
    pg.distance.target_to_result = rs->cover;
    pg.energy = rs->J + rs->weight * rs->T;
    return cb->progress(&pg, rs->x, cb->user);
}

/* Why the loop stops before the next iteration, or -1 to go on. */
static int stop_before_iteration(const run_state *rs, const sm_match_callbacks *cb)
{
    const sm_params *p = rs->params;
    /* with the target-side term on, both sides must be within the
     * tolerance: a boundary on the target that misses a part of it has
     * not arrived */
    int covered_l2 = !(rs->weight > 0) || sqrt(rs->T) <= p->tol_boundary;
    int covered_rms = !(rs->weight > 0) || rs->cover.rms <= p->tol_boundary_rel * rs->diameter;
    if (p->tol_boundary > 0 && rs->be.l2 <= p->tol_boundary && covered_l2)
        return SM_STOP_BOUNDARY;
    if (p->tol_boundary_rel > 0 && boundary_rms(&rs->be) <= p->tol_boundary_rel * rs->diameter &&
        covered_rms)
        return SM_STOP_BOUNDARY;
    if (stalled(rs))
        return SM_STOP_STALLED;
    if (rs->iteration >= rs->params->max_iter)
        return SM_STOP_MAX_ITER;
    if (cb && cb->cancel && *cb->cancel)
        return SM_STOP_CANCELLED;
    return -1;
}

/* After an accepted step that brought the worst quality near the floor:
 * the interior vertices of the degrading elements relaxed to better
 * quality (sm_relax.h).  The boundary does not move, so J, T, the load's
 * samples and the boundary error stay exactly as they are. */
static void relax_interior(run_state *rs)
{
    if (!(rs->qmin < RELAX_NEAR * rs->floor_q))
        return;
    sm__relax_run(rs->relax, rs->x, RELAX_BELOW * rs->floor_q, RELAX_SWEEPS);
    rs->qmin = sm_mesh_min_quality(rs->mesh, rs->x, NULL);
}

/* The descent: direction, step search, accept, report, grow the step. */
static sm_status descend(run_state *rs, const sm_match_callbacks *cb, sm_result *result,
                         sm_error *err)
{
    sm_status st;
    sm_timings *tm = &result->time;
    double t0;
    rs->tau = rs->params->step_initial * rs->diameter;
    /* factorized during the set-up; on the template, an older mesh than
     * a warm start's, which a failed step search may then replace */
    rs->since_factor = rs->warm;
    result->stop = SM_STOP_MAX_ITER;
    for (;;) {
        int why = stop_before_iteration(rs, cb);
        if (why >= 0) {
            result->stop = (sm_stop_reason)why;
            return SM_OK;
        }
        int found;
        if ((st = find_direction(rs, result, &found, err)) != SM_OK)
            return st;
        if (!found) {
            result->stop = SM_STOP_STEP; /* no descent direction left */
            return SM_OK;
        }
        t0 = sm_clock_seconds();
        double dJ, q_trial, tau0 = rs->tau;
        st = line_search(rs, &dJ, &q_trial, &found, err);
        tm->step += sm_clock_seconds() - t0;
        if (st != SM_OK)
            return st;
        if (!found && rs->since_factor > 0) {
            /* an operator of an older mesh: try again with one of this
             * mesh before giving up */
            rs->refactor_now = 1;
            rs->tau = tau0;
            continue;
        }
        if (!found) {
            result->stop = rs->quality_limited ? SM_STOP_QUALITY : SM_STOP_STEP;
            return SM_OK;
        }

        double *tmp = rs->x;
        rs->x = rs->trial;
        rs->trial = tmp;
        rs->since_factor++;
        rs->J += dJ;
        rs->qmin = q_trial;
        rs->last_step = rs->tau;
        rs->iteration++;
        t0 = sm_clock_seconds();
        relax_interior(rs);
        tm->step += sm_clock_seconds() - t0;
        if (rs->qmin < REFACTOR_QUALITY_DROP * rs->q_factor &&
            rs->qmin < REFACTOR_QUALITY_NEAR * rs->floor_q)
            rs->refactor_now = 1;

        t0 = sm_clock_seconds();
        sm__shape_load(rs->shape, rs->x, rs->load, &rs->be);
        st = add_coverage_load(rs, err);
        tm->sample += sm_clock_seconds() - t0;
        if (st != SM_OK)
            return st;
        track_best(rs);

        if (report(rs, cb)) {
            result->stop = SM_STOP_CANCELLED;
            return SM_OK;
        }
        rs->tau *= STEP_GROW;
        if (rs->tau > rs->step_max)
            rs->tau = rs->step_max;
    }
}

/* The checks of a run's template side and the state with its mesh set
 * up (setup_mesh); *out is freed by sm_match_free in every case. */
static sm_status match_alloc(const sm_match_opts *opts, sm_match **out, sm_error *err)
{
    *out = NULL;
    const sm_mesh *template_mesh = opts->template_mesh;
    sm_status st;
    if (!template_mesh || !opts->params)
        return sm_error_set(err, SM_ERR_INVALID, "no template or no parameters");
    if (opts->prepared && (opts->prepared->nverts != template_mesh->nverts ||
                           opts->prepared->dim != template_mesh->dim))
        return sm_error_set(err, SM_ERR_INVALID, "the prepared template is not a copy of the template");
    if ((st = sm_params_validate(opts->params, template_mesh->dim, err)) != SM_OK)
        return st;
    run_state *rs = calloc(1, sizeof *rs);
    if (!rs)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    *out = rs;
    rs->t_start = sm_clock_seconds();
    rs->params = opts->params;
    rs->coverage = opts->coverage;
    rs->dim = template_mesh->dim;
    rs->ndof = (size_t)template_mesh->nverts * (size_t)rs->dim;
    return setup_mesh(rs, opts, err);
}

static sm_status check_target(int dim, const sm_field *target, sm_error *err)
{
    if (!target)
        return sm_error_set(err, SM_ERR_INVALID, "no target field");
    if (dim != sm_field_dim(target))
        return sm_error_set(err, SM_ERR_INVALID,
                            "the template is %dD but the target background mesh is %dD", dim,
                            sm_field_dim(target));
    return SM_OK;
}

sm_status sm_match_new(const sm_match_opts *opts, sm_match **out, sm_error *err)
{
    sm_match *m = NULL;
    sm_status st = match_alloc(opts, &m, err);
    if (st == SM_OK) {
        int levels = one_thread_regions();
        st = setup_elastic(m, err);
        omp_set_max_active_levels(levels);
    }
    if (st != SM_OK) {
        sm_match_free(m);
        *out = NULL;
        return st;
    }
    m->elastic_seconds = sm_clock_seconds() - m->t_start;
    *out = m;
    return SM_OK;
}

sm_status sm_match_set_start(sm_match *m, const double *displacement, sm_error *err)
{
    if (!m || !displacement)
        return sm_error_set(err, SM_ERR_INVALID, "no run or no start displacement");
    if (m->executed)
        return sm_error_set(err, SM_ERR_INVALID, "the run was already executed");
    const sm_mesh *mesh = m->mesh;
    const int dim = m->dim;
    for (int32_t v = 0; v < mesh->nverts; v++)
        for (int c = 0; c < dim; c++) {
            double u = displacement[(size_t)v * (size_t)dim + (size_t)c];
            if (!isfinite(u))
                return sm_error_set(err, SM_ERR_INVALID,
                                    "start displacement: vertex %ld has a non-finite value",
                                    (long)v + 1);
            if (m->clamped[v] && u != 0.0)
                return sm_error_set(err, SM_ERR_INVALID,
                                    "start displacement: vertex %ld is in the clamp set but "
                                    "moves (the clamp holds it at 0)", (long)v + 1);
        }
    /* built in trial: x keeps the template until the start is accepted */
    for (size_t i = 0; i < m->ndof; i++)
        m->trial[i] = mesh->coords[i] + displacement[i];
    int32_t worst = -1;
    double q = sm_mesh_min_quality(mesh, m->trial, &worst);
    if (!(q > 0.0))
        return sm_error_set(err, SM_ERR_INVALID,
                            "start displacement: element %ld is inverted or flat (quality %.3g): "
                            "a start must keep every element's orientation",
                            (long)worst + 1, q);
    if (q < m->floor_q)
        return sm_error_set(err, SM_ERR_INVALID,
                            "start displacement: element %ld's quality %.3g is below the "
                            "quality floor %.3g (min_quality): no step from it could be accepted",
                            (long)worst + 1, q, m->floor_q);
    memcpy(m->x, m->trial, m->ndof * sizeof *m->x);
    m->qmin = q;
    m->warm = 1;
    return SM_OK;
}

void sm_match_free(sm_match *m)
{
    if (!m)
        return;
    run_state_free(m);
    free(m);
}

/* After the set-up: the initial report, the descent and the result. */
static sm_status finish_run(run_state *rs, const sm_match_callbacks *cb, double *coords_out,
                            sm_result *result, double setup_seconds, sm_error *err)
{
    sm_status st;
    result->factorizations = 1;
    result->time.setup = setup_seconds;
    result->J_initial = rs->J;
    result->energy_initial = rs->J + rs->weight * rs->T;
    track_best(rs);

    if (report(rs, cb))
        result->stop = SM_STOP_CANCELLED;
    else if ((st = descend(rs, cb, result, err)) != SM_OK)
        return st;

    memcpy(coords_out, rs->x, rs->ndof * sizeof(double));
    /* the operator is the descent's only (a run executes once): its
     * factor, 62 MB of the 3D example's, is not held through the final
     * measure's samples */
    sm__elasticity_free(rs->elasticity);
    rs->elasticity = NULL;
    double t0 = sm_clock_seconds();
    if ((st = sm_coverage_measure(rs->coverage, rs->x, &result->distance, err)) != SM_OK)
        return st;
    rs->coverage_seconds += sm_clock_seconds() - t0;
    result->coverage_seconds = rs->coverage_seconds;
    result->energy = rs->J + rs->weight * rs->T;
    result->iterations = rs->iteration;
    result->J = rs->J;
    result->boundary_l2 = rs->be.l2;
    result->boundary_max = rs->be.max;
    result->boundary_rms = boundary_rms(&rs->be);
    result->converged = result->stop != SM_STOP_QUALITY && result->stop != SM_STOP_CANCELLED;
    result->diameter = rs->diameter;
    result->alpha = rs->params->clamp == SM_CLAMP_NONE ? rs->alpha : 0.0;
    result->min_quality = rs->qmin;
    result->accepted = rs->accepted;
    result->rejected = rs->rejected;
    result->time.total = sm_clock_seconds() - rs->t_start + rs->elastic_seconds;
    return SM_OK;
}

void sm_match_use_coverage(sm_match *m, sm_coverage *coverage)
{
    m->coverage = coverage;
}

sm_status sm_match_execute(sm_match *m, const sm_field *target, const sm_match_callbacks *cb,
                           double *coords_out, sm_result *result, sm_error *err)
{
    memset(result, 0, sizeof *result);
    if (m->executed)
        return sm_error_set(err, SM_ERR_INVALID, "this run was already executed");
    m->executed = 1;
    sm_status st = check_target(m->dim, target, err);
    if (st != SM_OK)
        return st;
    /* the run's clock starts now; the elastic set-up done before is
     * added to its set-up and total times */
    m->t_start = sm_clock_seconds();
    if ((st = setup_target(m, target, err)) != SM_OK)
        return st;
    double setup = m->elastic_seconds + sm_clock_seconds() - m->t_start;
    return finish_run(m, cb, coords_out, result, setup, err);
}

sm_status sm_match_run(const sm_match_opts *opts, const sm_match_callbacks *cb,
                       double *coords_out, sm_result *result, sm_error *err)
{
    memset(result, 0, sizeof *result);
    sm_match *m = NULL;
    sm_status st;
    if (opts->template_mesh &&
        (st = check_target(opts->template_mesh->dim, opts->target, err)) != SM_OK)
        return st;
    if ((st = match_alloc(opts, &m, err)) == SM_OK &&
        (!opts->start || (st = sm_match_set_start(m, opts->start, err)) == SM_OK) &&
        (st = setup_both(m, opts->target, err)) == SM_OK)
        /* set-up is wall time: its parts overlap, so they are not split */
        st = finish_run(m, cb, coords_out, result, sm_clock_seconds() - m->t_start, err);
    sm_match_free(m);
    return st;
}
