/* run.sh: seconds 40 */
/* The AMG solves against the exact ones on the problems the descent
 * solves (issue 21): a Gmsh-made ellipse (2D) or ellipsoid (3D)
 * template, a target with asymmetric bumps that pulls with a net torque
 * about the clamp, the loads of the first direction and of later
 * iterations of a descent, every clamp kind (a ball of radius 0.04 at
 * the paper's size, the
 * elements and the vertices of given references, none: the alpha
 * term), at a small size and at the paper's (31k tetrahedra).  For each
 * load the TRUE relative error in the energy norm,
 *   |u_amg - u*|_K / |u*|_K, u* from CHOLMOD on the same matrix,
 * must be within the stated tolerance, SM_ELASTICITY_AMG_RTOL: a bound,
 * not an estimate (sm_solver_amg.c).  Before the V-cycle was balanced
 * with the rigid motions and the stopping test divided by the smallest
 * Ritz value, the 31k case with the ball clamp gave 0.67 on the first
 * direction (cosine 0.34 with the exact one), 0.14-0.18 later. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "sm_elasticity.h"
#include "sm_shape.h"
#include "shapematch/sm_clamp.h"
#include "shapematch/sm_field.h"
#include "shapematch/sm_match.h"
#include "util_gmsh.h"
#include "util_mesh.h"

#define REF_CLAMPED 7

/* Template: an ellipse or ellipsoid about (0.5, 0.5[, 0.5]). */
static sm_mesh *make_template(int dim, double clmax)
{
    const char *geo = dim == 2
        ? "SetFactory(\"OpenCASCADE\");\nDisk(1) = {0.5, 0.5, 0, 0.3, 0.22};\n"
          "Mesh.MeshSizeFromPoints = 0;\n"
        : "SetFactory(\"OpenCASCADE\");\nSphere(1) = {0, 0, 0, 1};\n"
          "Dilate {{0, 0, 0}, {0.3, 0.25, 0.2}} { Volume{1}; }\n"
          "Translate {0.5, 0.5, 0.5} { Volume{1}; }\nMesh.MeshSizeFromPoints = 0;\n";
    sm_mesh *m = NULL;
    char msg[512];
    if (util_gmsh_mesh(geo, dim, clmax, &m, msg, sizeof msg) != SM_OK)
        fail_msg("gmsh: %s", msg);
    sm_error err;
    assert_int_equal(sm_mesh_build_boundary(m, &err), SM_OK);
    /* references for the element and vertex clamps: the elements whose
     * centroid lies within 0.07 of a point off the centre, the vertices
     * at the tip x < 0.23 */
    const int nv = dim + 1;
    for (int32_t e = 0; e < m->nelems; e++) {
        double r2 = 0.0;
        for (int c = 0; c < dim; c++) {
            double x = 0.0;
            for (int i = 0; i < nv; i++)
                x += m->coords[(size_t)m->elems[(size_t)e * nv + i] * dim + c] / nv;
            double off = c == 0 ? 0.62 : 0.5;
            r2 += (x - off) * (x - off);
        }
        m->elem_refs[e] = r2 < 0.07 * 0.07 ? REF_CLAMPED : 1;
    }
    for (int32_t v = 0; v < m->nverts; v++)
        m->vert_refs[v] = m->coords[(size_t)v * dim] < 0.23 ? REF_CLAMPED : 1;
    return m;
}

/* Target: the ellipse or ellipsoid with semi-axes 0.32, 0.26[, 0.21]
 * and three bumps in asymmetric directions, radial distance (a signed
 * distance to within the bumps' slopes, which is all the loads need). */
static double bumped_radius(int dim, const double *u)
{
    static const double dirs[3][3] = {{1, 0.4, 0.3}, {-0.2, 1, -0.5}, {0.3, -0.5, 1}};
    static const double amp[3] = {0.10, 0.07, 0.06}, width[3] = {0.5, 0.45, 0.4};
    const double axes[3] = {0.32, 0.26, 0.21};
    double q = 0.0;
    for (int c = 0; c < dim; c++)
        q += u[c] * u[c] / (axes[c] * axes[c]);
    double r = 1.0 / sqrt(q);
    for (int k = 0; k < 3; k++) {
        double n = 0.0, cosang = 0.0;
        for (int c = 0; c < dim; c++)
            n += dirs[k][c] * dirs[k][c];
        for (int c = 0; c < dim; c++)
            cosang += u[c] * dirs[k][c] / sqrt(n);
        r += amp[k] * exp(-2.0 * (1.0 - cosang) / (width[k] * width[k]));
    }
    return r;
}

typedef struct target {
    sm_mesh *bg;
    double *d;
    sm_field *field;
} target;

static void make_target(target *t, int dim)
{
    const double lo[3] = {0, 0, 0}, hi[3] = {1, 1, 1};
    t->bg = util_box_mesh(dim, dim == 2 ? 100 : 28, lo, hi, 11);
    assert_non_null(t->bg);
    t->d = malloc(sizeof(double) * t->bg->nverts);
    for (int32_t v = 0; v < t->bg->nverts; v++) {
        double u[3] = {0, 0, 0}, r = 0.0;
        for (int c = 0; c < dim; c++) {
            u[c] = t->bg->coords[(size_t)v * dim + c] - 0.5;
            r += u[c] * u[c];
        }
        r = sqrt(r);
        if (r == 0.0) {
            t->d[v] = -0.2;
            continue;
        }
        for (int c = 0; c < dim; c++)
            u[c] /= r;
        t->d[v] = r - bumped_radius(dim, u);
    }
    sm_error err;
    assert_int_equal(sm_field_new(t->bg, t->d, &t->field, &err), SM_OK);
}

static void free_target(target *t)
{
    sm_field_free(t->field);
    sm_mesh_free(t->bg);
    free(t->d);
}

/* ball: radius 0.04, or twice the mesh size on coarser meshes (the
 * ball must hold 3 non-collinear vertices) */
static void set_clamp(sm_params *p, int dim, sm_clamp_kind kind, double clmax)
{
    p->clamp = kind;
    if (kind == SM_CLAMP_BALL) {
        for (int c = 0; c < dim; c++)
            p->clamp_center[c] = 0.5;
        p->clamp_radius = fmax(0.04, 2.0 * clmax);
    } else if (kind != SM_CLAMP_NONE) {
        p->clamp_refs[0] = REF_CLAMPED;
        p->n_clamp_refs = 1;
    }
}

/* w'Kw over the free DOFs of el (w global, vertex-major). */
static double energy(const sm_elasticity *el, const sm_mesh *m, const double *w)
{
    const int dim = m->dim;
    sm_csr_view a;
    sm__elasticity_matrix(el, &a);
    double *wf = calloc((size_t)a.n, sizeof *wf), e = 0.0;
    for (int32_t v = 0; v < m->nverts; v++)
        for (int c = 0; c < dim; c++) {
            int32_t k = sm__elasticity_dof(el, v, c);
            if (k >= 0)
                wf[k] = w[(size_t)v * dim + c];
        }
    for (int32_t r = 0; r < a.n; r++)
        for (int32_t q = a.rowptr[r]; q < a.rowptr[r + 1]; q++)
            e += wf[r] * a.values[q] * wf[a.colind[q]];
    free(wf);
    return e;
}

/* The meshes of a direct descent at the iterations in snap_at. */
#define NSNAP 3
static const int snap_at[NSNAP] = {0, 4, 12};
typedef struct snaps {
    size_t nd;
    double *x[NSNAP];
} snaps;

static int keep_snapshots(const sm_progress *pg, const double *coords, void *user)
{
    snaps *s = user;
    for (int k = 0; k < NSNAP; k++)
        if (pg->iteration == snap_at[k] && !s->x[k]) {
            s->x[k] = malloc(s->nd * sizeof(double));
            memcpy(s->x[k], coords, s->nd * sizeof(double));
        }
    return 0;
}

static void check_case(const sm_mesh *m, const target *t, sm_clamp_kind kind, double clmax,
                       sm_amg_modes modes)
{
    const int dim = m->dim;
    const size_t nd = (size_t)m->nverts * dim;
    sm_params p;
    sm_params_default(&p);
    set_clamp(&p, dim, kind, clmax);
    p.solver = SM_SOLVER_CHOLMOD;
    p.tol_stall = 0.0;
    p.max_iter = snap_at[NSNAP - 1];
    sm_error err;
    snaps s = {.nd = nd};
    double *out = malloc(nd * sizeof *out);
    sm_result res;
    sm_match_opts mo = {.template_mesh = m, .target = t->field, .params = &p};
    sm_match_callbacks cb = {.progress = keep_snapshots, .user = &s};
    if (sm_match_run(&mo, &cb, out, &res, &err) != SM_OK)
        fail_msg("descent: %s", err.msg);

    uint8_t *clamped = calloc((size_t)m->nverts + 1, 1);
    sm_clamp_mark(m, &p, clamped);
    double diam = sm_mesh_diameter(m, m->coords);
    sm_elasticity_opts o = {.young = p.young, .poisson = p.poisson,
                            .alpha = kind == SM_CLAMP_NONE ? p.young / (diam * diam) : 0.0,
                            .solver = SM_SOLVER_CHOLMOD};
    sm_elasticity *chol = NULL, *amg = NULL;
    assert_int_equal(sm__elasticity_new(m, clamped, &o, &chol, &err), SM_OK);
    assert_int_equal(sm__elasticity_factorize(chol, m->coords, &err), SM_OK);
    o.solver = SM_SOLVER_AMG; /* default tolerance */
    o.amg_modes = modes;
    assert_int_equal(sm__elasticity_new(m, clamped, &o, &amg, &err), SM_OK);
    assert_int_equal(sm__elasticity_factorize(amg, m->coords, &err), SM_OK);
    sm_shape *shape = NULL;
    assert_int_equal(sm__shape_new(m, t->field, NULL, 0, &shape, &err), SM_OK);
    double *load = malloc(nd * sizeof *load), *u0 = malloc(nd * sizeof *u0),
           *u1 = malloc(nd * sizeof *u1);
    sm_boundary_error be;
    for (int k = 0; k < NSNAP; k++) {
        assert_non_null(s.x[k]); /* the descent got that far */
        /* the load at iteration k on the template's operator, the
         * default --refactor-every; the AMG solves warm-started one
         * from the other as in the descent */
        sm__shape_load(shape, s.x[k], load, &be);
        assert_int_equal(sm__elasticity_solve(chol, load, NULL, u0, &err), SM_OK);
        if (sm__elasticity_solve(amg, load, NULL, u1, &err) != SM_OK)
            fail_msg("AMG solve: %s", err.msg);
        double ref = energy(chol, m, u0);
        for (size_t i = 0; i < nd; i++)
            u1[i] -= u0[i];
        double rel = sqrt(energy(chol, m, u1) / ref);
        sm_elasticity_info info;
        sm__elasticity_get_info(amg, &info);
        if (getenv("SM_DEBUG"))
            print_message("dim %d, %ld elements, clamp %d, modes %d, iteration %d: energy error %.4f"
                          " (%d PCG iterations)\n", dim, (long)m->nelems, (int)kind, (int)modes,
                          snap_at[k], rel, info.amg_iterations);
        assert_true(ref > 0.0);
        assert_true(rel <= SM_ELASTICITY_AMG_RTOL);
    }
    /* the descent's re-assembly: both operators again on the last
     * snapshot's mesh; the AMG's new hierarchy keeps the smallest Ritz
     * value of the one before (its first solve no longer takes
     * FIRST_SOLVE_MIN_ITER steps to learn it), and its solve must still
     * meet the bound */
    const double *moved = s.x[NSNAP - 1];
    assert_int_equal(sm__elasticity_factorize(chol, moved, &err), SM_OK);
    assert_int_equal(sm__elasticity_factorize(amg, moved, &err), SM_OK);
    sm__shape_load(shape, moved, load, &be);
    assert_int_equal(sm__elasticity_solve(chol, load, NULL, u0, &err), SM_OK);
    if (sm__elasticity_solve(amg, load, NULL, u1, &err) != SM_OK)
        fail_msg("AMG solve after a re-assembly: %s", err.msg);
    {
        /* the energy norm of the re-assembled operator: chol's */
        double ref = energy(chol, m, u0);
        for (size_t i = 0; i < nd; i++)
            u1[i] -= u0[i];
        double rel = sqrt(energy(chol, m, u1) / ref);
        sm_elasticity_info info;
        sm__elasticity_get_info(amg, &info);
        if (getenv("SM_DEBUG"))
            print_message("dim %d, clamp %d, modes %d, re-assembled: energy error %.4f (%d PCG "
                          "iterations)\n", dim, (int)kind, (int)modes, rel, info.amg_iterations);
        assert_true(ref > 0.0);
        assert_true(rel <= SM_ELASTICITY_AMG_RTOL);
    }
    for (int k = 0; k < NSNAP; k++)
        free(s.x[k]);
    sm__shape_free(shape);
    sm__elasticity_free(chol);
    sm__elasticity_free(amg);
    free(clamped);
    free(out);
    free(load);
    free(u0);
    free(u1);
}

static void every_clamp(int dim, double clmax)
{
    target t;
    make_target(&t, dim);
    sm_mesh *m = make_template(dim, clmax);
    const sm_clamp_kind kinds[4] = {SM_CLAMP_BALL, SM_CLAMP_ELEMENTS, SM_CLAMP_VERTICES,
                                    SM_CLAMP_NONE};
    for (int k = 0; k < 4; k++)
        check_case(m, &t, kinds[k], clmax, SM_AMG_MODES_AUTO);
    /* without clamp and with the rotations in the hierarchy: the set-up
     * of issue 20's large --no-clamp template (hypre flagged zero coarse
     * rows there, at 210k tetrahedra; bench/solver_maps.sh noclamp) */
    if (dim == 3)
        check_case(m, &t, SM_CLAMP_NONE, clmax, SM_AMG_MODES_ON);
    sm_mesh_free(m);
    free_target(&t);
}

static void test_energy_error_2d(void **state)
{
    (void)state;
    every_clamp(2, 0.006); /* ~11k triangles */
}

static void test_energy_error_3d_small(void **state)
{
    (void)state;
    every_clamp(3, 0.045); /* ~3k tetrahedra */
}

static void test_energy_error_3d_paper_size(void **state)
{
    (void)state;
#if defined(__SANITIZE_ADDRESS__)
    /* the sanitizer build runs the same code on the 2D and small 3D
     * templates; the paper-size one is the release build's (2 min here) */
    skip();
#endif
    every_clamp(3, 0.021); /* 31k tetrahedra, 6.2k vertices */
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_energy_error_2d),
        cmocka_unit_test(test_energy_error_3d_small),
        cmocka_unit_test(test_energy_error_3d_paper_size),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
