/* The parameter table of sm_params, and the defaults and range checks
 * read from it (see sm_params.h). */
#include "shapematch/sm_params.h"

#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define REAL(field) SM_PARAM_REAL, offsetof(sm_params, field), 0
#define INT(field) SM_PARAM_INT, offsetof(sm_params, field), 0
/* no bound on that side (an infinite bound is open: values are finite) */
#define NO_MIN -INFINITY, 1
#define NO_MAX INFINITY, 1
/* The struct holds min, max, min_open, max_open; a row reads "lower
 * bound, upper bound" (the extra level expands NO_MIN/NO_MAX first). */
#define RANGE_(lo, lo_open, hi, hi_open) lo, hi, lo_open, hi_open
#define RANGE(...) RANGE_(__VA_ARGS__)
#define CLOSED 0
#define OPEN 1

/* One row a parameter, in the order of the params document (the encoder
 * writes them in this order).  Why a default is what it is stays beside
 * its row. */
static const sm_param_info table[] = {
    /* auto: a new user's first run needs no clamp option; a ball at the
     * deepest point holds the template without touching its boundary */
    {"clamp", SM_PARAM_CLAMP, offsetof(sm_params, clamp), 0, RANGE(0, CLOSED, 0, CLOSED),
     SM_CLAMP_AUTO, "a ball at the deepest point", 0, NULL, NULL,
     "the clamp set where the displacement is 0 (the paper's omega), at most one option; "
     "without one, a ball at the template's deepest interior point, of a quarter of its "
     "inradius (at least dim+2 vertices); with --no-clamp nothing is fixed and the term "
     "alpha*int u.v makes the problem well posed (paper, Remark 1)", "clamp"},
    /* 0 = from the problem's scale: E / diameter^2 (sm_match.c), which
     * converges with --no-clamp on both examples (2D: relative boundary
     * error 1e-3 after 19 iterations, 3D: after 21), where the former
     * fixed 0.01 did not (2D: 9.1e-3 after 500 iterations). */
    {"alpha", REAL(alpha), RANGE(0, CLOSED, NO_MAX), 0.0, NULL, 1, "--alpha", "A",
     "0th-order term alpha*int u.v of the unclamped problem (only with --no-clamp; "
     "0: from the scale, E/diameter^2)", "clamp"},
    {"free_boundary", SM_PARAM_REFS, offsetof(sm_params, free_refs),
     offsetof(sm_params, n_free_refs), RANGE(0, CLOSED, SM_MAX_REFS, CLOSED), 0, NULL, 0,
     "--free-boundary", "REFS",
     "boundary facet references excluded from the load (they count neither in J nor in the "
     "boundary error)", "clamp"},
    {"young", REAL(young), RANGE(0, OPEN, NO_MAX), 1.0, NULL, 0, "--young", "E",
     "Young's modulus of the elastic model", "advanced"},
    {"poisson", REAL(poisson), RANGE(-1, OPEN, 0.5, OPEN), 0.3, NULL, 0, "--poisson", "NU",
     "Poisson ratio of the elastic model", "advanced"},
    /* 1e9: far beyond any run (a default run stops after ~200), and an
     * int on every platform */
    {"max_iter", INT(max_iter), RANGE(1, CLOSED, 1e9, CLOSED), 500, NULL, 0, "--max-iter", "N",
     "stop after N iterations", "stop"},
    {"tol_step", REAL(tol_step), RANGE(0, OPEN, 1, OPEN), 1e-6, NULL, 0, "--tol-step", "EPS",
     "stop when the step falls below EPS times the template diameter (the paper's "
     "criterion)", "stop"},
    {"tol_boundary", REAL(tol_boundary), RANGE(0, CLOSED, NO_MAX), 0.0, NULL, 0,
     "--tol-boundary", "TOL",
     "stop when the boundary error ||d||_L2 is <= TOL (0: off; absolute: scales like L^1.5 "
     "in 2D, L^2 in 3D with the template's size L)", "stop"},
    {"tol_boundary_rel", REAL(tol_boundary_rel), RANGE(0, CLOSED, NO_MAX), 0.0, NULL, 0,
     "--tol-boundary-rel", "R",
     "stop when the RMS boundary error ||d||_L2/sqrt(|boundary|) is <= R times the template "
     "diameter (0: off; unit-free)", "stop"},
    /* The stall rule ends converged runs, which the step rule alone does
     * not (the step stays well above tol_step while the error creeps down
     * by less than the background's resolution).  Measured with 500
     * iterations as the reference, "needed" = first iteration within 10%
     * of the best error of those 500: 2D example needs 163, stops at 210;
     * 3D example needs 266, stops at 281 (docs/user-guide.md, "Stop rules",
     * has the Gmsh cases).  Shorter windows or larger fractions stop too early on
     * the 3D case's plateaus (K 10 / 2%: 109 < 266). */
    {"tol_stall", REAL(tol_stall), RANGE(0, CLOSED, 1, OPEN), 0.01, NULL, 0, "--tol-stall", "F",
     "stop (stalled) when the best boundary error improved by < F over the stall window "
     "(0: off)", "stop"},
    {"stall_window", INT(stall_window), RANGE(1, CLOSED, 100000, CLOSED), 15, NULL, 0,
     "--stall-window", "K", "iterations of the stall rule's window", "stop"},
    /* 1: the term's force per unit of the target's area, 2 dist, is then
     * of the order of J's per unit of boundary, |d| (both are lengths
     * times measures), so neither side dominates where both act.
     * docs/method.md has the measures (the protrusion and handle cases,
     * the examples unchanged within their tolerance). */
    {"coverage_weight", REAL(coverage_weight), RANGE(0, CLOSED, NO_MAX), 1.0, NULL, 0,
     "--coverage-weight", "W",
     "weight of the target-side term sum_y w_y dist(y, boundary)^2 over the target surface's "
     "samples, which pulls the boundary toward the parts of the target it does not reach "
     "(0: the paper's J alone)", "advanced"},
    {"min_quality", REAL(min_quality), RANGE(0, CLOSED, 1, OPEN), 0.02, NULL, 0, "--min-quality",
     "Q",
     "element quality floor for an accepted step (or the template's own worst quality, if "
     "lower)", "advanced"},
    {"save_every", INT(save_every), RANGE(0, CLOSED, INT_MAX, CLOSED), 0, NULL, 0,
     "--save-every", "K",
     "also write OUTDIR/iter-NNNNN.mesh and .vtu (with the displacement and d) of the first "
     "state, every K iterations and the final state, the .vtu listed in snapshots.pvd (0: "
     "never)", "advanced"},
    {"step_initial", REAL(step_initial), RANGE(0, OPEN, 1, CLOSED), 0.01, NULL, 0,
     "--step-initial", "S", "first step length, as a fraction of the template diameter",
     "advanced"},
    {"step_max", REAL(step_max), RANGE(0, OPEN, 1, CLOSED), 0.1, NULL, 0, "--step-max", "S",
     "largest step length, as a fraction of the template diameter", "advanced"},
    /* Why the elastic operator is not refactorized at every iteration by
     * default: any SPD operator gives a descent direction (the gradient in
     * the elastic metric of a slightly older configuration), the
     * stationary points are the same, and on the bundled examples the
     * descent needs no more iterations (2D: 18 vs 21 to reach 3e-4; 3D: 16
     * vs 19) with a minimum quality as good, while the numeric
     * factorization is 80-90% of the cost of an iteration in 3D.
     * refactor_every = 1 gives the paper's exact scheme. */
    {"refactor_every", INT(refactor_every), RANGE(1, CLOSED, INT_MAX, CLOSED), 100, NULL, 0,
     "--refactor-every", "K",
     "refactorize the elasticity matrix every K iterations (1: every iteration, as in the "
     "paper)", "advanced"},
    {"live_every", INT(live_every), RANGE(0, CLOSED, INT_MAX, CLOSED), 0, NULL, 0,
     NULL, NULL,
     "daemon only: publish the current shape (mesh/latest) every K iterations, and at least "
     "every 0.5 s (0: by time only)", "advanced"},
    /* 0: warm starts do not pay on the populations measured
     * (docs/performance.md, bench/batch.sh): a start 3x nearer the
     * target saves the descent's first ~10 iterations, and the ~130 that
     * creep to the stall rule remain (3D example onto ellipsoids: 619
     * iterations warm against 611 cold for 4 targets; 2D ellipses: 288
     * against 313).  0 is also today's batch, bit for bit separate runs. */
    {"warm_start", INT(warm_start), RANGE(0, CLOSED, 1, CLOSED), 0, NULL, 0, "--warm-start",
     "N",
     "batches, 1: start each target's descent from the finished target's map nearest to it "
     "(the RMS of its distance at the boundary), when nearer than the template (0: every "
     "target from the template, as separate runs)", "advanced"},
    {"solver", SM_PARAM_SOLVER, offsetof(sm_params, solver), 0,
     RANGE(SM_SOLVER_AUTO, CLOSED, SM_SOLVER_AMG, CLOSED), SM_SOLVER_AUTO, NULL, 0, "--solver",
     "NAME",
     "elastic solver: cholmod (sparse Cholesky), amg (PCG + BoomerAMG: less memory, for large "
     "3D templates) or auto (3D: the one a cost model predicts faster, within the memory "
     "limit; 2D: cholmod)", "advanced"},
    /* none: the paper's assumption (shapes given aligned) and today's
     * runs bit for bit; an alignment costs a second or so (bench/align.sh) */
    {"align", SM_PARAM_ALIGN, offsetof(sm_params, align), 0,
     RANGE(SM_ALIGN_NONE, CLOSED, SM_ALIGN_AFFINE, CLOSED), SM_ALIGN_NONE, NULL, 0, "--align",
     "MODE",
     "move the template onto the target before the descent: none, rigid (rotation and "
     "translation), similarity (and a uniform scale) or affine, found from the target's distance "
     "(or started from --landmarks); the result and displacement.sol are then the whole map",
     "inputs"},
    /* The label-map target's rows (only with a target image).  0 as "every
     * nonzero voxel": label 0 is a segmentation's background, never the
     * shape; labels are the non-negative values Slicer, ITK-SNAP and
     * nnU-Net write. */
    {"label", INT(label), RANGE(0, CLOSED, INT_MAX, CLOSED), 0, NULL, 0, "--label", "N",
     "with a target image: the label whose voxels are the target (0: every nonzero voxel)",
     "inputs"},
    /* 0.5: the midpoint of a 0/1 mask or a probability map */
    {"level", REAL(level), RANGE(NO_MIN, NO_MAX), 0.5, NULL, 0, "--level", "L",
     "with a float target image and no label: the voxels of value >= L are the target", "inputs"},
    /* 1 voxel: a label's staircase rounded off without thinning a
     * structure a few voxels thick (docs/user-guide.md, --smooth) */
    {"smooth", REAL(smooth), RANGE(0, CLOSED, 16, CLOSED), 1.0, NULL, 0, "--smooth", "S",
     "with a target image: the Gaussian (in voxels) that smooths the label's mask before its "
     "boundary is taken (0: none; float images without a label are never smoothed)", "inputs"},
    /* LPS: the frame of ITK, Slicer and NRRD's left-posterior-superior,
     * the tools that make most templates */
    {"image_space", SM_PARAM_SPACE, offsetof(sm_params, image_space), 0,
     RANGE(SM_IMAGE_SPACE_LPS, CLOSED, SM_IMAGE_SPACE_RAS, CLOSED), SM_IMAGE_SPACE_LPS, NULL, 0,
     "--image-space", "S",
     "with a target image: the frame of the template's coordinates, lps (ITK, Slicer) or ras "
     "(NIfTI's world); the image is mapped into it", "inputs"},
};
#define N_TABLE (sizeof table / sizeof table[0])

const sm_param_info *sm_params_table(size_t *count)
{
    *count = N_TABLE;
    return table;
}

const sm_param_info *sm_params_lookup(const char *name)
{
    for (size_t i = 0; name && i < N_TABLE; i++)
        if (strcmp(table[i].name, name) == 0)
            return &table[i];
    return NULL;
}

int sm_param_in_range(const sm_param_info *f, double x)
{
    int above_min = f->min_open ? x > f->min : x >= f->min;
    int below_max = f->max_open ? x < f->max : x <= f->max;
    return above_min && below_max && isfinite(x);
}

int sm_param_describe_range(const sm_param_info *f, char *buf, size_t cap)
{
    char lo[SM_NUMBER_TEXT_LEN], hi[SM_NUMBER_TEXT_LEN];
    int int_like = f->type != SM_PARAM_REAL;
    int no_max = isinf(f->max) || (int_like && f->max >= INT_MAX);
    sm_number_text(lo, f->min);
    sm_number_text(hi, f->max);
    if (no_max)
        return snprintf(buf, cap, "%s %s", f->min_open ? ">" : ">=", lo);
    if (isinf(f->min))
        return snprintf(buf, cap, "%s %s", f->max_open ? "<" : "<=", hi);
    return snprintf(buf, cap, "in %c%s, %s%c", f->min_open ? '(' : '[', lo, hi,
                    f->max_open ? ')' : ']');
}

void sm_params_default(sm_params *p)
{
    memset(p, 0, sizeof *p);
    for (size_t i = 0; i < N_TABLE; i++) {
        char *at = (char *)p + table[i].offset;
        switch (table[i].type) {
        case SM_PARAM_REAL: *(double *)at = table[i].def; break;
        case SM_PARAM_INT: *(int *)at = (int)table[i].def; break;
        case SM_PARAM_SOLVER:
        case SM_PARAM_ALIGN:
        case SM_PARAM_SPACE: sm_param_set_value(&table[i], p, (int)table[i].def); break;
        case SM_PARAM_CLAMP: *(sm_clamp_kind *)at = (sm_clamp_kind)table[i].def; break;
        case SM_PARAM_REFS: break; /* empty list: the memset */
        }
    }
}

/* The clamp kind and the members it requires: not one field each. */
static sm_status check_clamp(const sm_params *p, int dim, sm_error *err)
{
    if (p->clamp < SM_CLAMP_BALL || p->clamp > SM_CLAMP_AUTO)
        return sm_error_set(err, SM_ERR_INVALID, "clamp: unknown kind %d", (int)p->clamp);
    if (p->clamp == SM_CLAMP_BALL) {
        for (int c = 0; c < (dim ? dim : 3); c++)
            if (!isfinite(p->clamp_center[c]))
                return sm_error_set(err, SM_ERR_INVALID, "clamp center: coordinate %d is not finite", c + 1);
        char got[SM_NUMBER_TEXT_LEN];
        if (!(p->clamp_radius > 0) || !isfinite(p->clamp_radius))
            return sm_error_set(err, SM_ERR_INVALID, "clamp radius must be > 0 (got %s)",
                                sm_number_text(got, p->clamp_radius));
    }
    if ((p->clamp == SM_CLAMP_ELEMENTS || p->clamp == SM_CLAMP_VERTICES) &&
        (p->n_clamp_refs < 1 || p->n_clamp_refs > SM_MAX_REFS))
        return sm_error_set(err, SM_ERR_INVALID, "clamp references: give 1 to %d references", SM_MAX_REFS);
    return SM_OK;
}

/* One row's own bounds. */
static sm_status check_row(const sm_param_info *f, const sm_params *p, sm_error *err)
{
    const char *at = (const char *)p + f->offset;
    double x;
    switch (f->type) {
    case SM_PARAM_REAL: x = *(const double *)at; break;
    case SM_PARAM_INT: x = *(const int *)at; break;
    case SM_PARAM_REFS: x = *(const int *)((const char *)p + f->count_offset); break;
    case SM_PARAM_SOLVER:
    case SM_PARAM_ALIGN:
    case SM_PARAM_SPACE: x = sm_param_get_value(f, p); break;
    default: return SM_OK; /* the clamp: check_clamp */
    }
    if (sm_param_in_range(f, x))
        return SM_OK;
    char range[80];
    sm_param_describe_range(f, range, sizeof range);
    if (f->type == SM_PARAM_REFS)
        return sm_error_set(err, SM_ERR_INVALID, "%s: the number of references must be %s (got %d)",
                            f->name, range, (int)x);
    if (sm_param_is_named(f)) {
        char names[96];
        sm_param_names_text(f, names, sizeof names);
        return sm_error_set(err, SM_ERR_INVALID, "%s: must be %s (got %d)", f->name, names, (int)x);
    }
    char got[SM_NUMBER_TEXT_LEN];
    return sm_error_set(err, SM_ERR_INVALID, "%s: must be %s (got %s)", f->name, range,
                        sm_number_text(got, x));
}

sm_status sm_params_validate(const sm_params *p, int dim, sm_error *err)
{
    sm_status st = check_clamp(p, dim, err);
    for (size_t i = 0; st == SM_OK && i < N_TABLE; i++)
        if (!table[i].in_clamp || p->clamp == SM_CLAMP_NONE) /* alpha: kind none only */
            st = check_row(&table[i], p, err);
    char a[SM_NUMBER_TEXT_LEN], b[SM_NUMBER_TEXT_LEN];
    if (st == SM_OK && p->step_initial > p->step_max)
        st = sm_error_set(err, SM_ERR_INVALID, "step_initial: must be <= step_max (%s > %s)",
                          sm_number_text(a, p->step_initial), sm_number_text(b, p->step_max));
    return st;
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

static const char *const clamp_names[] = {"ball", "elements", "vertices", "none", "auto"};

const char *sm_clamp_kind_name(sm_clamp_kind kind)
{
    if ((int)kind < 0 || (size_t)kind >= sizeof clamp_names / sizeof clamp_names[0])
        return NULL;
    return clamp_names[kind];
}

int sm_clamp_kind_from_name(const char *name, sm_clamp_kind *out)
{
    for (size_t i = 0; name && i < sizeof clamp_names / sizeof clamp_names[0]; i++) {
        if (strcmp(name, clamp_names[i]) == 0) {
            *out = (sm_clamp_kind)i;
            return 0;
        }
    }
    return -1;
}

static const char *const mode_names[] = {"none", "rigid", "similarity", "affine"};

const char *sm_align_mode_name(sm_align_mode mode)
{
    if ((int)mode < 0 || (size_t)mode >= sizeof mode_names / sizeof mode_names[0])
        return NULL;
    return mode_names[mode];
}

int sm_align_mode_from_name(const char *name, sm_align_mode *out)
{
    for (size_t i = 0; name && i < sizeof mode_names / sizeof mode_names[0]; i++)
        if (strcmp(name, mode_names[i]) == 0) {
            *out = (sm_align_mode)i;
            return 0;
        }
    return -1;
}

static const char *const space_names[] = {"lps", "ras"};

const char *sm_image_space_name(sm_image_space space)
{
    if ((int)space < 0 || (size_t)space >= sizeof space_names / sizeof space_names[0])
        return NULL;
    return space_names[space];
}

sm_solver_kind sm_solver_resolve(sm_solver_kind kind, int dim, int64_t nelems)
{
    if (kind != SM_SOLVER_AUTO)
        return kind;
    return dim == 3 && nelems >= SM_SOLVER_AMG_MIN_TETS ? SM_SOLVER_AMG : SM_SOLVER_CHOLMOD;
}

int sm_param_is_named(const sm_param_info *f)
{
    return f->type == SM_PARAM_SOLVER || f->type == SM_PARAM_ALIGN || f->type == SM_PARAM_SPACE;
}

const char *sm_param_value_name(const sm_param_info *f, int k)
{
    if (f->type == SM_PARAM_SOLVER)
        return sm_solver_kind_name((sm_solver_kind)k);
    if (f->type == SM_PARAM_ALIGN)
        return sm_align_mode_name((sm_align_mode)k);
    if (f->type == SM_PARAM_SPACE)
        return sm_image_space_name((sm_image_space)k);
    return NULL;
}

int sm_param_value_from_name(const sm_param_info *f, const char *name)
{
    for (int k = (int)f->min; sm_param_is_named(f) && k <= (int)f->max; k++)
        if (name && strcmp(name, sm_param_value_name(f, k)) == 0)
            return k;
    return -1;
}

int sm_param_get_value(const sm_param_info *f, const void *base)
{
    const char *at = (const char *)base + f->offset;
    if (f->type == SM_PARAM_SOLVER)
        return (int)*(const sm_solver_kind *)at;
    if (f->type == SM_PARAM_ALIGN)
        return (int)*(const sm_align_mode *)at;
    if (f->type == SM_PARAM_SPACE)
        return (int)*(const sm_image_space *)at;
    return -1;
}

void sm_param_set_value(const sm_param_info *f, void *base, int k)
{
    char *at = (char *)base + f->offset;
    if (f->type == SM_PARAM_SOLVER)
        *(sm_solver_kind *)at = (sm_solver_kind)k;
    else if (f->type == SM_PARAM_ALIGN)
        *(sm_align_mode *)at = (sm_align_mode)k;
    else if (f->type == SM_PARAM_SPACE)
        *(sm_image_space *)at = (sm_image_space)k;
}

void sm_param_names_text(const sm_param_info *f, char *buf, size_t cap)
{
    size_t used = 0;
    if (cap)
        buf[0] = '\0';
    for (int k = (int)f->min; sm_param_is_named(f) && k <= (int)f->max && used < cap; k++) {
        int w = snprintf(buf + used, cap - used, "%s%s", k == (int)f->min ? "" : k == (int)f->max ? " or " : ", ",
                         sm_param_value_name(f, k));
        if (w < 0)
            break;
        used += (size_t)w;
    }
}
