/* Numerical verification of the functional J, its change between meshes
 * (swept-region quadrature) and the load (its derivative): exactness for
 * affine d, agreement with an independent volume quadrature and with
 * finite differences, and analytic values for a circle. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "shapematch/sm_field.h"
#include "sm_shape.h"
#include "util_mesh.h"

typedef struct fixture {
    sm_mesh *bg;
    double *d;
    sm_field *field;
    sm_mesh *tm;
    sm_shape *shape;
} fixture;

typedef double (*scalar_fn)(const double *x, int dim);

static double affine_d(const double *x, int dim)
{
    return 0.3 * x[0] - 0.7 * x[1] + (dim == 3 ? 0.2 * x[2] : 0.0) - 0.1;
}

/* signed distance to the circle/sphere of center 0.5 and radius 0.3 */
static double circle_d(const double *x, int dim)
{
    double s = 0.0;
    for (int c = 0; c < dim; c++)
        s += (x[c] - 0.5) * (x[c] - 0.5);
    return sqrt(s) - 0.3;
}

static void setup(fixture *fx, int dim, int bg_cells, scalar_fn fn, int rings_or_cells)
{
    sm_error err;
    const double lo[3] = {0, 0, 0}, hi[3] = {1, 1, 1};
    fx->bg = util_box_mesh(dim, bg_cells, lo, hi, 7);
    assert_non_null(fx->bg);
    fx->d = malloc(sizeof(double) * fx->bg->nverts);
    for (int32_t v = 0; v < fx->bg->nverts; v++)
        fx->d[v] = fn(fx->bg->coords + v * dim, dim);
    assert_int_equal(sm_field_new(fx->bg, fx->d, &fx->field, &err), SM_OK);
    if (dim == 2) {
        const double c[2] = {0.5, 0.5};
        fx->tm = util_disk_mesh(c, 0.2, rings_or_cells);
    } else {
        const double tlo[3] = {0.35, 0.35, 0.35}, thi[3] = {0.65, 0.65, 0.65};
        fx->tm = util_box_mesh(3, rings_or_cells, tlo, thi, 3);
    }
    assert_non_null(fx->tm);
    assert_int_equal(sm_mesh_build_boundary(fx->tm, &err), SM_OK);
    assert_int_equal(sm__shape_new(fx->tm, fx->field, NULL, 0, &fx->shape, &err), SM_OK);
}

static void teardown(fixture *fx)
{
    sm__shape_free(fx->shape);
    sm_mesh_free(fx->tm);
    sm_field_free(fx->field);
    sm_mesh_free(fx->bg);
    free(fx->d);
}

/* smooth displacement field, interior vertices included */
static void displacement(const sm_mesh *m, double amp, double *u)
{
    for (int32_t v = 0; v < m->nverts; v++) {
        const double *x = m->coords + v * m->dim;
        u[v * m->dim] = amp * (0.3 + sin(7 * x[1]) + 0.5 * x[0]);
        u[v * m->dim + 1] = amp * (-0.2 + cos(5 * x[0]) * x[1]);
        if (m->dim == 3)
            u[v * m->dim + 2] = amp * (0.1 + sin(3 * x[0] + 2 * x[2]));
    }
}

/* For affine d the volume rule and the swept rule are both exact. */
static void check_delta_exact_for_affine(int dim, int n)
{
    fixture fx;
    setup(&fx, dim, 12, affine_d, n);
    size_t ndof = (size_t)fx.tm->nverts * dim;
    double *u = malloc(sizeof(double) * ndof), *x1 = malloc(sizeof(double) * ndof);
    displacement(fx.tm, 0.02, u);
    for (size_t i = 0; i < ndof; i++)
        x1[i] = fx.tm->coords[i] + u[i];
    double j0 = sm__shape_volume_j(fx.shape, fx.tm->coords);
    double j1 = sm__shape_volume_j(fx.shape, x1);
    double dj = sm__shape_delta_j(fx.shape, fx.tm->coords, u);
    assert_true(fabs(j1 - j0) > 1e-4); /* the test moves something */
    assert_true(fabs(dj - (j1 - j0)) < 1e-13);
    free(u);
    free(x1);
    teardown(&fx);
}

static void test_delta_exact_affine_2d(void **s) { (void)s; check_delta_exact_for_affine(2, 8); }
static void test_delta_exact_affine_3d(void **s) { (void)s; check_delta_exact_for_affine(3, 4); }

/* d/dtau dJ(tau u) at 0 equals -load.u (same facet quadrature): central
 * finite differences agree with it to a relative 1e-4. */
static void check_load_is_derivative(int dim, int n)
{
    fixture fx;
    setup(&fx, dim, 40, circle_d, n);
    size_t ndof = (size_t)fx.tm->nverts * dim;
    double *u = malloc(sizeof(double) * ndof), *load = malloc(sizeof(double) * ndof);
    double *su = malloc(sizeof(double) * ndof);
    displacement(fx.tm, 1.0, u);
    sm_boundary_error be;
    sm__shape_load(fx.shape, fx.tm->coords, load, &be);
    double predicted = 0.0;
    for (size_t i = 0; i < ndof; i++)
        predicted -= load[i] * u[i];
    for (double eps = 1e-3; eps >= 2.4e-4; eps /= 2) {
        for (size_t i = 0; i < ndof; i++)
            su[i] = eps * u[i];
        double plus = sm__shape_delta_j(fx.shape, fx.tm->coords, su);
        for (size_t i = 0; i < ndof; i++)
            su[i] = -eps * u[i];
        double minus = sm__shape_delta_j(fx.shape, fx.tm->coords, su);
        double fd = (plus - minus) / (2 * eps);
        double e = fabs(fd - predicted);
        if (getenv("SM_DEBUG")) print_message("eps %g fd %.12g pred %.12g err %.3g\n", eps, fd, predicted, e);
        /* kinks of the P1 background keep this from being a clean
         * O(eps^2) sequence; a wrong load (factor, sign, rule) is off by
         * orders of magnitude more */
        assert_true(e < 1e-4 * fabs(predicted));
    }
    free(u);
    free(su);
    free(load);
    teardown(&fx);
}

static void test_load_derivative_2d(void **s) { (void)s; check_load_is_derivative(2, 10); }
static void test_load_derivative_3d(void **s) { (void)s; check_load_is_derivative(3, 4); }

/* J of a disk of radius r=0.2 for the distance to a circle of radius
 * R=0.3 with the same center: 2 pi (r^3/3 - R r^2/2); the inscribed
 * polygon and the P1 background converge to it. */
static void test_volume_j_analytic(void **s)
{
    (void)s;
    double prev = INFINITY;
    const double r = 0.2, R = 0.3, exact = 2 * M_PI * (r * r * r / 3 - R * r * r / 2);
    for (int rings = 4; rings <= 16; rings *= 2) {
        fixture fx;
        setup(&fx, 2, 16 * rings, circle_d, rings);
        double j = sm__shape_volume_j(fx.shape, fx.tm->coords);
        double e = fabs(j - exact);
        if (getenv("SM_DEBUG")) print_message("rings %d J %.10g exact %.10g err %.3g\n", rings, j, exact, e);
        assert_true(e < prev / 3.0); /* second order: about /4 per halving */
        prev = e;
        teardown(&fx);
    }
    assert_true(prev < 1e-3 * fabs(exact));
}

/* The boundary error of a polygon inscribed in the target circle is the
 * chordal error, O(h^2); the load at such a mesh is small accordingly. */
static void test_boundary_error_on_target(void **s)
{
    (void)s;
    sm_error err;
    const double lo[2] = {0, 0}, hi[2] = {1, 1}, c[2] = {0.5, 0.5};
    sm_mesh *bg = util_box_mesh(2, 200, lo, hi, 0);
    double *d = malloc(sizeof(double) * bg->nverts);
    for (int32_t v = 0; v < bg->nverts; v++)
        d[v] = circle_d(bg->coords + 2 * v, 2);
    sm_field *field;
    assert_int_equal(sm_field_new(bg, d, &field, &err), SM_OK);
    double prev = INFINITY;
    for (int rings = 8; rings <= 32; rings *= 2) {
        sm_mesh *tm = util_disk_mesh(c, 0.3, rings);
        assert_int_equal(sm_mesh_build_boundary(tm, &err), SM_OK);
        sm_shape *sh;
        assert_int_equal(sm__shape_new(tm, field, NULL, 0, &sh, &err), SM_OK);
        double *load = malloc(sizeof(double) * tm->nverts * 2);
        sm_boundary_error be;
        sm__shape_load(sh, tm->coords, load, &be);
        double hb = 2 * M_PI * 0.3 / (6 * rings);
        /* chord sagitta h^2/(8R), plus the background interpolation error */
        assert_true(be.max < hb * hb / (8 * 0.3) * 1.2 + 5e-5);
        assert_true(be.l2 < prev);
        prev = be.l2;
        free(load);
        sm__shape_free(sh);
        sm_mesh_free(tm);
    }
    sm_field_free(field);
    sm_mesh_free(bg);
    free(d);
}

/* Boundary facets with a free reference carry no load. */
static void test_free_boundary(void **s)
{
    (void)s;
    fixture fx;
    setup(&fx, 2, 20, circle_d, 6);
    sm_error err;
    int32_t refs[1] = {1};
    sm_shape *free_all;
    assert_int_equal(sm__shape_new(fx.tm, fx.field, refs, 1, &free_all, &err), SM_OK);
    assert_int_equal(sm__shape_active_facets(free_all), 0);
    assert_int_equal(sm__shape_active_facets(fx.shape), fx.tm->nbfacets);
    double *load = malloc(sizeof(double) * fx.tm->nverts * 2);
    sm_boundary_error be;
    sm__shape_load(free_all, fx.tm->coords, load, &be);
    for (int32_t i = 0; i < fx.tm->nverts * 2; i++)
        assert_true(load[i] == 0.0);
    free(load);
    sm__shape_free(free_all);
    teardown(&fx);
}

/* The samples a trial step and the mesh it leads to share: a load after
 * sm__shape_delta_j(x, u) at x + u takes the step's end samples, and a
 * step from the current mesh takes its samples; either way bit for bit
 * what a fresh shape computes, and for a mesh that is not the step's end
 * the samples are computed anew. */
static void check_samples_reused(int dim, int n)
{
    fixture fx, fresh;
    setup(&fx, dim, 30, circle_d, n);
    setup(&fresh, dim, 30, circle_d, n);
    size_t ndof = (size_t)fx.tm->nverts * dim;
    double *u = malloc(sizeof(double) * ndof), *x1 = malloc(sizeof(double) * ndof);
    double *l1 = malloc(sizeof(double) * ndof), *l2 = malloc(sizeof(double) * ndof);
    displacement(fx.tm, 0.01, u);
    for (size_t i = 0; i < ndof; i++)
        x1[i] = fx.tm->coords[i] + u[i];
    sm_boundary_error b1, b2;
    sm__shape_load(fx.shape, fx.tm->coords, l1, &b1);
    double dj = sm__shape_delta_j(fx.shape, fx.tm->coords, u); /* reuses the load's */
    double dj_fresh = sm__shape_delta_j(fresh.shape, fresh.tm->coords, u);
    assert_true(dj == dj_fresh);
    sm__shape_load(fx.shape, x1, l1, &b1);       /* reuses the step's end */
    sm__shape_load(fresh.shape, x1, l2, &b2);    /* evaluates */
    assert_memory_equal(l1, l2, sizeof(double) * ndof);
    assert_true(b1.l2 == b2.l2 && b1.max == b2.max && b1.measure == b2.measure);
    /* another mesh than the step's end: evaluated, not taken */
    x1[0] += 1e-3;
    sm__shape_load(fx.shape, x1, l1, &b1);
    sm__shape_load(fresh.shape, x1, l2, &b2);
    assert_memory_equal(l1, l2, sizeof(double) * ndof);
    assert_true(b1.l2 == b2.l2);
    free(u);
    free(x1);
    free(l1);
    free(l2);
    teardown(&fx);
    teardown(&fresh);
}

static void test_samples_reused_2d(void **s) { (void)s; check_samples_reused(2, 10); }
static void test_samples_reused_3d(void **s) { (void)s; check_samples_reused(3, 4); }

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_delta_exact_affine_2d),
        cmocka_unit_test(test_delta_exact_affine_3d),
        cmocka_unit_test(test_load_derivative_2d),
        cmocka_unit_test(test_load_derivative_3d),
        cmocka_unit_test(test_volume_j_analytic),
        cmocka_unit_test(test_boundary_error_on_target),
        cmocka_unit_test(test_free_boundary),
        cmocka_unit_test(test_samples_reused_2d),
        cmocka_unit_test(test_samples_reused_3d),
    };
    return cmocka_run_group_tests_name("shape", tests, NULL, NULL);
}
