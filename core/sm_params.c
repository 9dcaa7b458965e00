/* Defaults and range checks of sm_params (see sm_params.h). */
#include "shapematch/sm_params.h"

#include <math.h>
#include <string.h>

void sm_params_default(sm_params *p)
{
    memset(p, 0, sizeof *p);
    p->clamp = SM_CLAMP_NONE;
    /* 0 = from the problem's scale: E / diameter^2 (sm_match.c), which
     * converges with --no-clamp on both examples (2D: relative boundary
     * error 1e-3 after 19 iterations, 3D: after 21), where the former
     * fixed 0.01 did not (2D: 9.1e-3 after 500 iterations). */
    p->alpha = 0.0;
    p->young = 1.0;
    p->poisson = 0.3;
    p->max_iter = 500;
    p->tol_step = 1e-6;
    p->tol_boundary = 0.0;
    p->tol_boundary_rel = 0.0;
    /* The stall rule ends converged runs, which the step rule alone does not
     * (the step stays well above tol_step while the error creeps down by
     * less than the background's resolution).  Measured with 500 iterations
     * as the reference, "needed" = first iteration within 10% of the best
     * error of those 500: 2D example needs 163, stops at 210; 3D example
     * needs 266, stops at 281 (README.md, "Stop rules", has the Gmsh cases).
     * Shorter windows or larger fractions stop too early on the 3D case's
     * plateaus (K 10 / 2%: 109 < 266). */
    p->tol_stall = 0.01;
    p->stall_window = 15;
    p->min_quality = 0.02;
    p->save_every = 0;
    p->step_initial = 0.01;
    p->step_max = 0.1;
    /* Why the elastic operator is not refactorized at every iteration by
     * default: any SPD operator gives a descent direction (the gradient in the
     * elastic metric of a slightly older configuration), the stationary points
     * are the same, and on the bundled examples the descent needs no more
     * iterations (2D: 18 vs 21 to reach 3e-4; 3D: 16 vs 19) with a minimum
     * quality as good, while the numeric factorization is 80-90% of the cost of
     * an iteration in 3D.  refactor_every = 1 gives the paper's exact scheme. */
    p->refactor_every = 100;
    p->live_every = 0;
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
    if (p->clamp == SM_CLAMP_NONE && !(p->alpha >= 0 && isfinite(p->alpha)))
        return sm_error_set(err, SM_ERR_INVALID,
                            "alpha must be >= 0 when nothing is clamped (0: from the scale; got %g)",
                            p->alpha);
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
    if (!(p->tol_boundary_rel >= 0) || !isfinite(p->tol_boundary_rel))
        return sm_error_set(err, SM_ERR_INVALID, "relative boundary tolerance must be >= 0 (got %g)",
                            p->tol_boundary_rel);
    if (!(p->tol_stall >= 0 && p->tol_stall < 1))
        return sm_error_set(err, SM_ERR_INVALID, "stall tolerance must be in [0, 1) (got %g)", p->tol_stall);
    if (p->stall_window < 1 || p->stall_window > 100000)
        return sm_error_set(err, SM_ERR_INVALID, "stall window must be in [1, 100000] (got %d)",
                            p->stall_window);
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
    if (!sm_solver_kind_name(p->solver))
        return sm_error_set(err, SM_ERR_INVALID, "solver must be auto, cholmod or amg (got %d)",
                            (int)p->solver);
    if (p->live_every < 0)
        return sm_error_set(err, SM_ERR_INVALID, "live-every must be >= 0 (got %d)", p->live_every);
    return SM_OK;
}

static const char *const solver_names[] = {"auto", "cholmod", "amg"};

const char *sm_solver_kind_name(sm_solver_kind kind)
{
    if ((int)kind < 0 || (size_t)kind >= sizeof solver_names / sizeof solver_names[0])
        return NULL;
    return solver_names[kind];
}

int sm_solver_kind_from_name(const char *name, sm_solver_kind *out)
{
    for (size_t i = 0; name && i < sizeof solver_names / sizeof solver_names[0]; i++) {
        if (strcmp(name, solver_names[i]) == 0) {
            *out = (sm_solver_kind)i;
            return 0;
        }
    }
    return -1;
}

sm_solver_kind sm_solver_resolve(sm_solver_kind kind, int dim, int64_t nelems)
{
    if (kind != SM_SOLVER_AUTO)
        return kind;
    return dim == 3 && nelems >= SM_SOLVER_AMG_MIN_TETS ? SM_SOLVER_AMG : SM_SOLVER_CHOLMOD;
}
