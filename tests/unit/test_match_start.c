/* A descent from a given displacement (sm_match_set_start,
 * sm_match_opts.start): the analytic radial map of a disk onto an ellipse
 * as the start (an answer made independently of the descent) starts the
 * descent at its J and boundary error and reaches the cold run's
 * tolerance in fewer iterations, with the final boundary on the exact
 * ellipse; invalid starts (an inverted element, a clamped vertex that
 * moves, a non-finite value, a worst quality below the floor) are refused
 * with their message and leave the run as it was: the cold run bit for
 * bit. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "shapematch/sm_field.h"
#include "shapematch/sm_match.h"
#include "util_mesh.h"

/* run.sh: seconds 2 */

#define A 0.32
#define B 0.22
#define R 0.25 /* the template disk's radius */
#define CLAMP_R 0.05

/* the ellipse's radius along the direction (c, s) */
static double ellipse_radius(double c, double s)
{
    return 1.0 / sqrt(c * c / (A * A) + s * s / (B * B));
}

/* signed radial distance to the ellipse (x-0.5)^2/A^2 + (y-0.5)^2/B^2 = 1
 * (exact on the ellipse, where it is 0) */
static double ellipse_d(const double *x)
{
    double dx = x[0] - 0.5, dy = x[1] - 0.5, r = sqrt(dx * dx + dy * dy);
    return r == 0 ? -B : r - ellipse_radius(dx / r, dy / r);
}

typedef struct fixture {
    sm_mesh *bg, *tm;
    double *d;
    sm_field *field;
    sm_params p;
    size_t n;
} fixture;

static void setup_fixture(fixture *f)
{
    const double lo[2] = {0, 0}, hi[2] = {1, 1}, c[2] = {0.5, 0.5};
    f->bg = util_box_mesh(2, 160, lo, hi, 11);
    f->d = malloc(sizeof(double) * (size_t)f->bg->nverts);
    for (int32_t v = 0; v < f->bg->nverts; v++)
        f->d[v] = ellipse_d(f->bg->coords + 2 * v);
    sm_error err;
    assert_int_equal(sm_field_new(f->bg, f->d, &f->field, &err), SM_OK);
    f->tm = util_disk_mesh(c, R, 12);
    f->n = (size_t)f->tm->nverts * 2;
    sm_params_default(&f->p);
    f->p.clamp = SM_CLAMP_BALL;
    f->p.clamp_center[0] = f->p.clamp_center[1] = 0.5;
    f->p.clamp_radius = CLAMP_R;
    f->p.max_iter = 400;
    f->p.tol_boundary = 2e-4;
}

static void free_fixture(fixture *f)
{
    sm_field_free(f->field);
    sm_mesh_free(f->bg);
    sm_mesh_free(f->tm);
    free(f->d);
}

/* The radial map of the disk onto the ellipse, blended to 0 inside the
 * clamp ball: a vertex at radius r in direction t moves to radius
 * r (1 + (rb(t)/R - 1) w(r)), w = 0 up to the clamp's radius and 1 on
 * the disk's boundary. */
static void radial_start(const fixture *f, double *disp)
{
    for (int32_t v = 0; v < f->tm->nverts; v++) {
        double dx = f->tm->coords[2 * v] - 0.5, dy = f->tm->coords[2 * v + 1] - 0.5;
        double r = sqrt(dx * dx + dy * dy);
        double w = r <= CLAMP_R * (1 + 1e-9) ? 0.0 : (r - CLAMP_R) / (R - CLAMP_R);
        double k = r > 0 ? (ellipse_radius(dx / r, dy / r) / R - 1.0) * w : 0.0;
        disp[2 * v] = k * dx;
        disp[2 * v + 1] = k * dy;
    }
}

static sm_status run_from(const fixture *f, const double *start, double *out, sm_result *res,
                          sm_error *err)
{
    sm_match_opts o = {.template_mesh = f->tm, .target = f->field, .params = &f->p,
                       .start = start};
    return sm_match_run(&o, NULL, out, res, err);
}

/* RMS of the exact ellipse distance over the boundary's vertices at coords. */
static double boundary_rms_exact(const sm_mesh *m, const double *coords)
{
    sm_mesh *b;
    sm_error err;
    assert_int_equal(sm_mesh_clone(m, &b, &err), SM_OK);
    assert_int_equal(sm_mesh_build_boundary(b, &err), SM_OK);
    double s = 0;
    int64_t k = 0;
    for (int32_t fct = 0; fct < b->nbfacets; fct++)
        for (int j = 0; j < 2; j++) {
            double e = ellipse_d(coords + 2 * b->bfacets[2 * fct + j]);
            s += e * e;
            k++;
        }
    sm_mesh_free(b);
    return sqrt(s / (double)k);
}

static void test_warm_start_from_the_analytic_map(void **state)
{
    (void)state;
    fixture f;
    setup_fixture(&f);
    double *cold = malloc(sizeof(double) * f.n), *warm = malloc(sizeof(double) * f.n);
    double *disp = malloc(sizeof(double) * f.n);
    sm_result rc, rw;
    sm_error err;
    assert_int_equal(run_from(&f, NULL, cold, &rc, &err), SM_OK);
    radial_start(&f, disp);
    /* the start itself lies on the ellipse: its vertices exactly */
    double *moved = malloc(sizeof(double) * f.n);
    for (size_t i = 0; i < f.n; i++)
        moved[i] = f.tm->coords[i] + disp[i];
    assert_true(boundary_rms_exact(f.tm, moved) < 1e-12);
    assert_int_equal(run_from(&f, disp, warm, &rw, &err), SM_OK);
    if (getenv("SM_DEBUG"))
        print_message("cold %d it, J %.6g -> %.6g, l2 %.3g; warm %d it, J %.6g -> %.6g, l2 %.3g\n",
                      rc.iterations, rc.J_initial, rc.J, rc.boundary_l2, rw.iterations,
                      rw.J_initial, rw.J, rw.boundary_l2);
    assert_int_equal(rc.stop, SM_STOP_BOUNDARY);
    assert_int_equal(rw.stop, SM_STOP_BOUNDARY);
    /* it started at the start: J there is near the final J, far below
     * the template's */
    assert_true(rw.J_initial < rc.J_initial);
    assert_true(fabs(rw.J_initial - rc.J) < 0.1 * fabs(rc.J_initial - rc.J));
    assert_true(rw.iterations < rc.iterations);
    assert_true(rw.boundary_l2 <= 2e-4);
    /* both final boundaries on the exact ellipse, the warm one as well
     * as the cold one (within 10%, or both below a tenth of the
     * background's cell) */
    double ec = boundary_rms_exact(f.tm, cold), ew = boundary_rms_exact(f.tm, warm);
    assert_true(ew <= 1.1 * ec || ew < 6e-4);
    /* the clamp held: vertices in the ball did not move */
    for (int32_t v = 0; v < f.tm->nverts; v++) {
        double dx = f.tm->coords[2 * v] - 0.5, dy = f.tm->coords[2 * v + 1] - 0.5;
        if (sqrt(dx * dx + dy * dy) < CLAMP_R * 0.99)
            assert_true(warm[2 * v] == f.tm->coords[2 * v] &&
                        warm[2 * v + 1] == f.tm->coords[2 * v + 1]);
    }
    free(moved);
    free(cold);
    free(warm);
    free(disp);
    free_fixture(&f);
}

/* An interior vertex (not in the clamp ball) moved across the disk. */
static int32_t interior_vertex(const fixture *f)
{
    for (int32_t v = 0; v < f->tm->nverts; v++) {
        double dx = f->tm->coords[2 * v] - 0.5, dy = f->tm->coords[2 * v + 1] - 0.5;
        double r = sqrt(dx * dx + dy * dy);
        if (r > 0.1 && r < 0.15)
            return v;
    }
    fail_msg("no interior vertex");
    return -1;
}

static void test_invalid_starts_refused(void **state)
{
    (void)state;
    fixture f;
    setup_fixture(&f);
    f.p.max_iter = 15;
    f.p.tol_boundary = 0;
    double *disp = calloc(f.n, sizeof(double));
    double *a = malloc(sizeof(double) * f.n), *b = malloc(sizeof(double) * f.n);
    sm_result ra, rb;
    sm_error err;
    assert_int_equal(run_from(&f, NULL, a, &ra, &err), SM_OK);

    sm_match_opts o = {.template_mesh = f.tm, .params = &f.p};
    sm_match *m = NULL;
    assert_int_equal(sm_match_new(&o, &m, &err), SM_OK);
    /* inverted: one vertex thrown across the disk */
    int32_t v = interior_vertex(&f);
    disp[2 * v] = 0.5 - 2 * (f.tm->coords[2 * v] - 0.5) - f.tm->coords[2 * v];
    disp[2 * v + 1] = 0.5 - 2 * (f.tm->coords[2 * v + 1] - 0.5) - f.tm->coords[2 * v + 1];
    assert_int_equal(sm_match_set_start(m, disp, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "inverted"));
    disp[2 * v] = disp[2 * v + 1] = 0;
    /* a clamped vertex (the centre) that moves */
    int32_t centre = -1;
    for (int32_t w = 0; w < f.tm->nverts && centre < 0; w++)
        if (f.tm->coords[2 * w] == 0.5 && f.tm->coords[2 * w + 1] == 0.5)
            centre = w;
    assert_true(centre >= 0);
    disp[2 * centre] = 1e-3;
    assert_int_equal(sm_match_set_start(m, disp, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "clamp set"));
    disp[2 * centre] = 0;
    /* not finite */
    disp[2 * v + 1] = NAN;
    assert_int_equal(sm_match_set_start(m, disp, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "non-finite"));
    disp[2 * v + 1] = 0;
    assert_int_equal(sm_match_set_start(m, NULL, &err), SM_ERR_INVALID);
    /* refused starts changed nothing: the cold run, bit for bit */
    assert_int_equal(sm_match_execute(m, f.field, NULL, b, &rb, &err), SM_OK);
    assert_memory_equal(a, b, sizeof(double) * f.n);
    assert_true(ra.J == rb.J && ra.iterations == rb.iterations);
    /* after the run: too late */
    assert_int_equal(sm_match_set_start(m, disp, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "already executed"));
    sm_match_free(m);

    /* through sm_match_run's opts.start: the same refusal */
    disp[2 * v] = 0.5 - 2 * (f.tm->coords[2 * v] - 0.5) - f.tm->coords[2 * v];
    disp[2 * v + 1] = 0.5 - 2 * (f.tm->coords[2 * v + 1] - 0.5) - f.tm->coords[2 * v + 1];
    assert_int_equal(run_from(&f, disp, b, &rb, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "inverted"));

    /* below the quality floor, nothing inverted: no clamp, the disk
     * squashed to a tenth of its height */
    f.p.clamp = SM_CLAMP_NONE;
    for (int32_t w = 0; w < f.tm->nverts; w++) {
        disp[2 * w] = 0;
        disp[2 * w + 1] = -0.9 * (f.tm->coords[2 * w + 1] - 0.5);
    }
    f.p.min_quality = 0.3;
    assert_int_equal(run_from(&f, disp, b, &rb, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "quality floor"));
    free(disp);
    free(a);
    free(b);
    free_fixture(&f);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_warm_start_from_the_analytic_map),
        cmocka_unit_test(test_invalid_starts_refused),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
