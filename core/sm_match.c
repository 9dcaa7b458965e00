#include "sm_match.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "sm_clamp.h"
#include "sm_elasticity.h"
#include "sm_field.h"
#include "sm_shape.h"

/* Sufficient-decrease constant of the Armijo test. */
#define ARMIJO_C 1e-4
/* Step growth after an accepted trial, and the bounds of a reduction. */
#define STEP_GROW 1.6
#define STEP_SHRINK_MIN 0.1
#define STEP_SHRINK_MAX 0.5
/* Why the elastic operator is not refactorized at every iteration by
 * default: any SPD operator gives a descent direction (the gradient in the
 * elastic metric of a slightly older configuration), the stationary points
 * are the same, and on the bundled examples the descent needs no more
 * iterations (2D: 18 vs 21 to reach 3e-4; 3D: 16 vs 19) with a minimum
 * quality as good, while the numeric factorization is 80-90% of the cost of
 * an iteration in 3D.  refactor_every = 1 gives the paper's exact scheme. */

void sm_params_default(sm_params *p)
{
    memset(p, 0, sizeof *p);
    p->clamp = SM_CLAMP_NONE;
    p->alpha = 1e-2;
    p->young = 1.0;
    p->poisson = 0.3;
    p->max_iter = 500;
    p->tol_step = 1e-6;
    p->tol_boundary = 0.0;
    p->min_quality = 0.02;
    p->save_every = 0;
    p->step_initial = 0.01;
    p->step_max = 0.1;
    p->refactor_every = 100;
}

sm_status sm_params_validate(const sm_params *p, int dim, sm_error *err)
{
    if (p->clamp < SM_CLAMP_BALL || p->clamp > SM_CLAMP_NONE)
        return sm_error_set(err, SM_ERR_INVALID, "clamp: unknown kind %d", (int)p->clamp);
    if (p->clamp == SM_CLAMP_BALL) {
        for (int c = 0; c < (dim ? dim : 3); c++)
            if (!isfinite(p->clamp_center[c]))
                return sm_error_set(err, SM_ERR_INVALID, "clamp center: coordinate %d is not finite", c + 1);
        if (!(p->clamp_radius > 0) || !isfinite(p->clamp_radius))
            return sm_error_set(err, SM_ERR_INVALID, "clamp radius must be > 0 (got %g)", p->clamp_radius);
    }
    if ((p->clamp == SM_CLAMP_ELEMENTS || p->clamp == SM_CLAMP_VERTICES) &&
        (p->n_clamp_refs < 1 || p->n_clamp_refs > SM_MAX_REFS))
        return sm_error_set(err, SM_ERR_INVALID, "clamp references: give 1 to %d references", SM_MAX_REFS);
    if (p->clamp == SM_CLAMP_NONE && !(p->alpha > 0 && isfinite(p->alpha)))
        return sm_error_set(err, SM_ERR_INVALID, "alpha must be > 0 when nothing is clamped (got %g)", p->alpha);
    if (p->n_free_refs < 0 || p->n_free_refs > SM_MAX_REFS)
        return sm_error_set(err, SM_ERR_INVALID, "free boundary: at most %d references", SM_MAX_REFS);
    if (!(p->young > 0) || !isfinite(p->young))
        return sm_error_set(err, SM_ERR_INVALID, "young modulus must be > 0 (got %g)", p->young);
    if (!(p->poisson > -1.0 && p->poisson < 0.5))
        return sm_error_set(err, SM_ERR_INVALID, "poisson ratio must be in (-1, 0.5) (got %g)", p->poisson);
    if (p->max_iter < 1)
        return sm_error_set(err, SM_ERR_INVALID, "max iterations must be >= 1 (got %d)", p->max_iter);
    if (!(p->tol_step > 0 && p->tol_step < 1))
        return sm_error_set(err, SM_ERR_INVALID, "step tolerance must be in (0, 1) (got %g)", p->tol_step);
    if (!(p->tol_boundary >= 0) || !isfinite(p->tol_boundary))
        return sm_error_set(err, SM_ERR_INVALID, "boundary tolerance must be >= 0 (got %g)", p->tol_boundary);
    if (!(p->min_quality >= 0 && p->min_quality < 1))
        return sm_error_set(err, SM_ERR_INVALID, "minimum quality must be in [0, 1) (got %g)", p->min_quality);
    if (p->save_every < 0)
        return sm_error_set(err, SM_ERR_INVALID, "save-every must be >= 0 (got %d)", p->save_every);
    if (!(p->step_initial > 0 && p->step_initial <= 1))
        return sm_error_set(err, SM_ERR_INVALID, "initial step must be in (0, 1] (got %g)", p->step_initial);
    if (!(p->step_max >= p->step_initial && p->step_max <= 1))
        return sm_error_set(err, SM_ERR_INVALID,
                            "maximum step must be in [initial step, 1] (got %g)", p->step_max);
    if (p->refactor_every < 1)
        return sm_error_set(err, SM_ERR_INVALID, "refactor-every must be >= 1 (got %d)", p->refactor_every);
    return SM_OK;
}

const char *sm_stop_reason_name(sm_stop_reason r)
{
    switch (r) {
    case SM_STOP_STEP: return "step_tolerance";
    case SM_STOP_BOUNDARY: return "boundary_tolerance";
    case SM_STOP_MAX_ITER: return "max_iterations";
    case SM_STOP_CANCELLED: return "cancelled";
    }
    return "unknown";
}

static double now_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Everything one run owns; freed in one place. */
typedef struct run_state {
    sm_mesh *mesh;            /* private copy of the template, boundary built */
    sm_field *field;
    sm_shape *shape;
    sm_elasticity *elasticity;
    uint8_t *clamped;
    double *x, *trial, *load, *u, *step;
} run_state;

static void run_state_free(run_state *rs)
{
    sm_elasticity_free(rs->elasticity);
    sm_shape_free(rs->shape);
    sm_field_free(rs->field);
    sm_mesh_free(rs->mesh);
    free(rs->clamped);
    free(rs->x);
    free(rs->trial);
    free(rs->load);
    free(rs->u);
    free(rs->step);
}

/* A trial mesh is valid when no element is inverted and its worst quality
 * stays above the floor.  Returns the worst quality (or -1 if inverted). */
static double trial_quality(const sm_mesh *m, const double *coords, double floor_q, int *ok)
{
    double qmin = INFINITY;
#pragma omp parallel for schedule(static) reduction(min : qmin)
    for (int32_t e = 0; e < m->nelems; e++) {
        double q = sm_elem_quality(m, coords, e);
        if (q < qmin)
            qmin = q;
    }
    *ok = qmin > 0.0 && qmin >= floor_q;
    return qmin > 0.0 ? qmin : -1.0;
}

sm_status sm_match_run(const sm_mesh *template_mesh, const sm_mesh *background, const double *d,
                       const sm_params *params, sm_progress_fn progress, void *user,
                       const volatile int *cancel, double *coords_out, sm_result *result,
                       sm_error *err)
{
    double t_start = now_seconds();
    sm_status st;
    run_state rs;
    memset(&rs, 0, sizeof rs);
    memset(result, 0, sizeof *result);

    if (template_mesh->dim != background->dim)
        return sm_error_set(err, SM_ERR_INVALID,
                            "the template is %dD but the target background mesh is %dD",
                            template_mesh->dim, background->dim);
    if ((st = sm_params_validate(params, template_mesh->dim, err)) != SM_OK)
        return st;

    const int dim = template_mesh->dim;
    const size_t ndof = (size_t)template_mesh->nverts * (size_t)dim;

    if ((st = sm_mesh_clone(template_mesh, &rs.mesh, err)) != SM_OK)
        goto done;
    if ((st = sm_mesh_build_boundary(rs.mesh, err)) != SM_OK) {
        sm_error_prefix(err, "template");
        goto done;
    }
    rs.clamped = malloc((size_t)rs.mesh->nverts + 1);
    rs.x = malloc(ndof * sizeof(double));
    rs.trial = malloc(ndof * sizeof(double));
    rs.load = malloc(ndof * sizeof(double));
    rs.u = malloc(ndof * sizeof(double));
    rs.step = malloc(ndof * sizeof(double));
    if (!rs.clamped || !rs.x || !rs.trial || !rs.load || !rs.u || !rs.step) {
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory for a mesh of %ld vertices",
                          (long)rs.mesh->nverts);
        goto done;
    }
    if ((st = sm_clamp_check(rs.mesh, params, NULL, err)) != SM_OK)
        goto done;
    sm_clamp_mark(rs.mesh, params, rs.clamped);

    memcpy(rs.x, rs.mesh->coords, ndof * sizeof(double));
    const double diameter = sm_mesh_diameter(rs.mesh, rs.x);
    const double step_min = params->tol_step * diameter;
    const double step_max = params->step_max * diameter;

    sm_quality_stats qs;
    sm_mesh_quality(rs.mesh, rs.x, &qs);
    /* A template already worse than the floor may not get worse still. */
    const double floor_q = qs.min < params->min_quality ? qs.min : params->min_quality;
    double qmin = qs.min;

    /* The two expensive set-up tasks are independent: the target's search
     * structures with the initial samples, and the elastic operator's
     * symbolic analysis with its first factorization.  They run side by
     * side (each may use more threads inside). */
    sm_timings *tm = &result->time;
    sm_status st_target = SM_OK, st_elastic = SM_OK;
    sm_error err_target, err_elastic;
    sm_error_clear(&err_target);
    sm_error_clear(&err_elastic);
    sm_boundary_error be = {0, 0};
    double J = 0.0, t0, ta, tf;
#pragma omp parallel sections num_threads(2)
    {
#pragma omp section
        {
            st_target = sm_field_new(background, d, &rs.field, &err_target);
            if (st_target != SM_OK)
                sm_error_prefix(&err_target, "target");
            else
                st_target = sm_shape_new(rs.mesh, rs.field, params->free_refs, params->n_free_refs,
                                         &rs.shape, &err_target);
            if (st_target == SM_OK && sm_shape_active_facets(rs.shape) == 0)
                st_target = sm_error_set(&err_target, SM_ERR_INVALID,
                                         "no boundary facet carries the load (all are in the free boundary)");
            if (st_target == SM_OK) {
                sm_shape_load(rs.shape, rs.x, rs.load, &be);
                J = sm_shape_volume_j(rs.shape, rs.x);
            }
        }
#pragma omp section
        {
            sm_elasticity_opts eopts = {
                .young = params->young, .poisson = params->poisson,
                .alpha = params->clamp == SM_CLAMP_NONE ? params->alpha : 0.0};
            st_elastic = sm_elasticity_new(rs.mesh, rs.clamped, &eopts, &rs.elasticity, &err_elastic);
            if (st_elastic == SM_OK)
                st_elastic = sm_elasticity_factorize(rs.elasticity, rs.x, &err_elastic);
        }
    }
    if (st_target != SM_OK || st_elastic != SM_OK) {
        st = st_target != SM_OK ? st_target : st_elastic;
        if (err)
            *err = st_target != SM_OK ? err_target : err_elastic;
        goto done;
    }
    /* set-up is wall time: its parts overlap, so they are not split */
    result->factorizations = 1;
    tm->setup = now_seconds() - t_start;
    result->J_initial = J;

    int iteration = 0, accepted = 0, rejected = 0;
    sm_progress pg = {0};
    pg.J = J;
    pg.boundary_l2 = be.l2;
    pg.boundary_max = be.max;
    pg.min_quality = qmin;
    pg.elapsed = now_seconds() - t_start;
    if (progress && progress(&pg, rs.x, user)) {
        result->stop = SM_STOP_CANCELLED;
        goto finish;
    }

    double tau = params->step_initial * diameter;
    int since_factor = 0; /* factorized during the set-up */
    result->stop = SM_STOP_MAX_ITER;
    for (;;) {
        if (params->tol_boundary > 0 && be.l2 <= params->tol_boundary) {
            result->stop = SM_STOP_BOUNDARY;
            break;
        }
        if (iteration >= params->max_iter) {
            result->stop = SM_STOP_MAX_ITER;
            break;
        }
        if (cancel && *cancel) {
            result->stop = SM_STOP_CANCELLED;
            break;
        }

        /* descent direction: elasticity with the shape derivative as load */
        if (since_factor >= params->refactor_every) {
            if ((st = sm_elasticity_factorize(rs.elasticity, rs.x, err)) != SM_OK)
                goto done;
            since_factor = 0;
            result->factorizations++;
            sm_elasticity_timings(rs.elasticity, &ta, &tf);
            tm->assembly += ta;
            tm->factor += tf;
        }
        t0 = now_seconds();
        if ((st = sm_elasticity_solve(rs.elasticity, rs.load, NULL, rs.u, err)) != SM_OK)
            goto done;
        tm->solve += now_seconds() - t0;

        /* normalize so that tau is the largest vertex displacement */
        double umax = 0.0;
        for (int32_t v = 0; v < rs.mesh->nverts; v++) {
            double s = 0.0;
            for (int c = 0; c < dim; c++)
                s += rs.u[(size_t)v * (size_t)dim + (size_t)c] * rs.u[(size_t)v * (size_t)dim + (size_t)c];
            if (s > umax)
                umax = s;
        }
        umax = sqrt(umax);
        double slope = 0.0; /* -dJ/dtau along the normalized direction */
        if (umax > 0) {
            for (size_t i = 0; i < ndof; i++) {
                rs.u[i] /= umax;
                slope += rs.load[i] * rs.u[i];
            }
        }
        if (!(umax > 0) || !(slope > 0)) {
            result->stop = SM_STOP_STEP; /* no descent direction left */
            break;
        }

        /* step search: shrink until valid and sufficiently decreasing */
        t0 = now_seconds();
        int found = 0;
        double dJ = 0.0, q_trial = qmin;
        while (tau >= step_min) {
            for (size_t i = 0; i < ndof; i++) {
                rs.step[i] = tau * rs.u[i];
                rs.trial[i] = rs.x[i] + rs.step[i];
            }
            int ok;
            q_trial = trial_quality(rs.mesh, rs.trial, floor_q, &ok);
            if (ok) {
                dJ = sm_shape_delta_j(rs.shape, rs.x, rs.step);
                if (dJ <= -ARMIJO_C * tau * slope) {
                    found = 1;
                    accepted++;
                    break;
                }
                /* minimizer of the parabola through J(0), J'(0), J(tau) */
                double curvature = dJ + tau * slope;
                double shrink = curvature > 0 ? 0.5 * slope * tau / curvature : STEP_SHRINK_MAX;
                if (shrink > STEP_SHRINK_MAX)
                    shrink = STEP_SHRINK_MAX;
                if (shrink < STEP_SHRINK_MIN)
                    shrink = STEP_SHRINK_MIN;
                tau *= shrink;
            } else {
                tau *= STEP_SHRINK_MAX;
            }
            rejected++;
        }
        tm->step += now_seconds() - t0;
        if (!found) {
            result->stop = SM_STOP_STEP;
            break;
        }

        double *tmp = rs.x;
        rs.x = rs.trial;
        rs.trial = tmp;
        since_factor++;
        J += dJ;
        qmin = q_trial;
        iteration++;

        t0 = now_seconds();
        sm_shape_load(rs.shape, rs.x, rs.load, &be);
        tm->sample += now_seconds() - t0;

        pg.iteration = iteration;
        pg.J = J;
        pg.step = tau;
        pg.boundary_l2 = be.l2;
        pg.boundary_max = be.max;
        pg.min_quality = qmin;
        pg.elapsed = now_seconds() - t_start;
        pg.accepted = accepted;
        pg.rejected = rejected;
        if (progress && progress(&pg, rs.x, user)) {
            result->stop = SM_STOP_CANCELLED;
            break;
        }
        tau *= STEP_GROW;
        if (tau > step_max)
            tau = step_max;
    }

finish:
    memcpy(coords_out, rs.x, ndof * sizeof(double));
    result->iterations = iteration;
    result->J = J;
    result->boundary_l2 = be.l2;
    result->boundary_max = be.max;
    result->min_quality = qmin;
    result->accepted = accepted;
    result->rejected = rejected;
    tm->total = now_seconds() - t_start;
    st = SM_OK;
done:
    run_state_free(&rs);
    return st;
}
