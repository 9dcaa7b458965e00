/* The descent end to end on meshes built in code: it converges onto an
 * analytic target, J never increases, the elastic direction is a descent
 * direction (J'(u) < 0, checked against an independent volume
 * quadrature), the result is the template plus the cumulative
 * displacement, and cancellation and bad clamps are reported. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "sm_elasticity.h"
#include "shapematch/sm_field.h"
#include "shapematch/sm_match.h"
#include "sm_shape.h"
#include "util_mesh.h"

/* target: ellipse (x-0.5)^2/a^2 + (y-0.5)^2/b^2 = 1 given by an
 * approximate signed distance (exact for a circle, a=b) */
static double ellipse_d(const double *x, double a, double b)
{
    double dx = x[0] - 0.5, dy = x[1] - 0.5;
    double r = sqrt(dx * dx + dy * dy);
    if (r == 0)
        return -(a < b ? a : b);
    double c = dx / r, s = dy / r;
    double rb = 1.0 / sqrt(c * c / (a * a) + s * s / (b * b));
    return r - rb;
}

typedef struct target {
    sm_mesh *bg;
    double *d;
    sm_field *field; /* built once, shared by every run on this target */
} target;

static void make_target(target *t, int cells, double a, double b)
{
    const double lo[2] = {0, 0}, hi[2] = {1, 1};
    t->bg = util_box_mesh(2, cells, lo, hi, 11);
    t->d = malloc(sizeof(double) * t->bg->nverts);
    for (int32_t v = 0; v < t->bg->nverts; v++)
        t->d[v] = ellipse_d(t->bg->coords + 2 * v, a, b);
    sm_error err;
    assert_int_equal(sm_field_new(t->bg, t->d, &t->field, &err), SM_OK);
}

static void free_target(target *t)
{
    sm_field_free(t->field);
    sm_mesh_free(t->bg);
    free(t->d);
}

/* sm_match_run on the target's prebuilt field. */
static sm_status run_match(const sm_mesh *tm, const target *t, const sm_params *p,
                           sm_progress_fn progress, void *user, const volatile int *cancel,
                           double *out, sm_result *res, sm_error *err)
{
    sm_match_opts opts = {.template_mesh = tm, .target = t->field, .params = p};
    sm_match_callbacks cb = {.progress = progress, .user = user, .cancel = cancel};
    return sm_match_run(&opts, &cb, out, res, err);
}

typedef struct history {
    int n;
    double J[4096];
    double l2[4096];
    double qmin[4096];
    int cancel_at;
} history;

static int record(const sm_progress *p, const double *coords, void *user)
{
    (void)coords;
    history *h = user;
    if (h->n < 4096) {
        h->J[h->n] = p->J;
        h->l2[h->n] = p->boundary_l2;
        h->qmin[h->n] = p->min_quality;
        h->n++;
    }
    return h->cancel_at > 0 && p->iteration >= h->cancel_at;
}

/* The 2D case of several tests: a disk of radius 0.25 clamped at its
 * centre, matched onto the ellipse of semi-axes 0.32 x 0.22. */
static sm_mesh *ellipse_case(target *t, sm_params *p, int max_iter)
{
    make_target(t, 160, 0.32, 0.22);
    const double c[2] = {0.5, 0.5};
    sm_params_default(p);
    p->clamp = SM_CLAMP_BALL;
    p->clamp_center[0] = p->clamp_center[1] = 0.5;
    p->clamp_radius = 0.05;
    p->max_iter = max_iter;
    return util_disk_mesh(c, 0.25, 12);
}

static void test_converges_on_ellipse(void **state)
{
    (void)state;
    target t;
    sm_params p;
    sm_mesh *tm = ellipse_case(&t, &p, 400);
    p.tol_boundary = 2e-4;
    double *out = malloc(sizeof(double) * tm->nverts * 2);
    sm_result res;
    sm_error err;
    history *h = calloc(1, sizeof *h);
    assert_int_equal(run_match(tm, &t, &p, record, h, NULL, out, &res, &err), SM_OK);
    if (getenv("SM_DEBUG"))
        print_message("stop %s it %d l2 %.3g -> %.3g J %.6g -> %.6g acc %d rej %d q %.3f\n",
                      sm_stop_reason_name(res.stop), res.iterations, h->l2[0], res.boundary_l2,
                      res.J_initial, res.J, res.accepted, res.rejected, res.min_quality);
    assert_int_equal(res.stop, SM_STOP_BOUNDARY);
    assert_true(res.boundary_l2 <= 2e-4);
    assert_int_equal(h->n, res.iterations + 1);
    for (int i = 1; i < h->n; i++) {
        assert_true(h->J[i] < h->J[i - 1]); /* Armijo: strictly decreasing */
        assert_true(h->qmin[i] > 0.0);
    }
    /* the final mesh is valid, and the clamped vertex did not move */
    sm_mesh *res_mesh;
    assert_int_equal(sm_mesh_clone(tm, &res_mesh, &err), SM_OK);
    memcpy(res_mesh->coords, out, sizeof(double) * tm->nverts * 2);
    sm_quality_stats qs;
    assert_int_equal(sm_mesh_build_boundary(res_mesh, &err), SM_OK);
    sm_mesh_quality(res_mesh, out, &qs);
    assert_int_equal(qs.ninverted, 0);
    assert_true(out[0] == 0.5 && out[1] == 0.5);
    /* J accumulated from swept regions agrees with a volume quadrature */
    sm_field *f;
    assert_int_equal(sm_field_new(t.bg, t.d, &f, &err), SM_OK);
    sm_shape *sh;
    assert_int_equal(sm__shape_new(res_mesh, f, NULL, 0, &sh, &err), SM_OK);
    double jv = sm__shape_volume_j(sh, out);
    assert_true(fabs(jv - res.J) < 1e-3 * fabs(res.J_initial - res.J));
    sm__shape_free(sh);
    sm_field_free(f);
    sm_mesh_free(res_mesh);
    free(h);
    free(out);
    sm_mesh_free(tm);
    free_target(&t);
}

/* J'(Omega)(u) = int d u.n < 0 for the elastic direction u, computed
 * independently: finite differences of the volume quadrature of J. */
static void test_elastic_direction_descends(void **state)
{
    (void)state;
    target t;
    make_target(&t, 120, 0.3, 0.3);
    const double c[2] = {0.5, 0.5};
    sm_mesh *tm = util_disk_mesh(c, 0.2, 10);
    sm_error err;
    assert_int_equal(sm_mesh_build_boundary(tm, &err), SM_OK);
    sm_field *f;
    assert_int_equal(sm_field_new(t.bg, t.d, &f, &err), SM_OK);
    sm_shape *sh;
    assert_int_equal(sm__shape_new(tm, f, NULL, 0, &sh, &err), SM_OK);
    uint8_t *clamped = calloc(tm->nverts, 1);
    for (int32_t v = 0; v < tm->nverts; v++) /* a small disk: no rigid motion left */
        clamped[v] = hypot(tm->coords[2 * v] - 0.5, tm->coords[2 * v + 1] - 0.5) <= 0.05;
    sm_elasticity *el;
    sm_elasticity_opts eopts = {.young = 1.0, .poisson = 0.3, .alpha = 0.0};
    assert_int_equal(sm__elasticity_new(tm, clamped, &eopts, &el, &err), SM_OK);
    assert_int_equal(sm__elasticity_factorize(el, tm->coords, &err), SM_OK);
    size_t ndof = (size_t)tm->nverts * 2;
    double *load = malloc(sizeof(double) * ndof), *u = malloc(sizeof(double) * ndof);
    double *x = malloc(sizeof(double) * ndof);
    sm_boundary_error be;
    sm__shape_load(sh, tm->coords, load, &be);
    assert_int_equal(sm__elasticity_solve(el, load, NULL, u, &err), SM_OK);
    double dj = 0.0;
    for (size_t i = 0; i < ndof; i++)
        dj -= load[i] * u[i];
    assert_true(dj < 0.0);
    double umax = 0;
    for (size_t i = 0; i < ndof; i++)
        umax = fmax(umax, fabs(u[i]));
    double eps = 1e-5 / umax;
    for (size_t i = 0; i < ndof; i++)
        x[i] = tm->coords[i] + eps * u[i];
    double jp = sm__shape_volume_j(sh, x);
    for (size_t i = 0; i < ndof; i++)
        x[i] = tm->coords[i] - eps * u[i];
    double jm = sm__shape_volume_j(sh, x);
    double fd = (jp - jm) / (2 * eps);
    assert_true(fd < 0.0);
    assert_true(fabs(fd - dj) < 0.05 * fabs(dj));
    free(load);
    free(u);
    free(x);
    free(clamped);
    sm__elasticity_free(el);
    sm__shape_free(sh);
    sm_field_free(f);
    sm_mesh_free(tm);
    free_target(&t);
}

static void test_cancel_and_no_clamp(void **state)
{
    (void)state;
    target t;
    make_target(&t, 60, 0.3, 0.25);
    const double c[2] = {0.52, 0.47};
    sm_mesh *tm = util_disk_mesh(c, 0.2, 6);
    sm_params p;
    sm_params_default(&p);
    p.clamp = SM_CLAMP_NONE;
    p.alpha = 0.1;
    double *out = malloc(sizeof(double) * tm->nverts * 2);
    sm_result res;
    sm_error err;
    history *h = calloc(1, sizeof *h);
    h->cancel_at = 3;
    assert_int_equal(run_match(tm, &t, &p, record, h, NULL, out, &res, &err), SM_OK);
    assert_int_equal(res.stop, SM_STOP_CANCELLED);
    assert_int_equal(res.iterations, 3);
    assert_true(res.J < res.J_initial);
    /* cancellation through the flag */
    volatile int flag = 1;
    assert_int_equal(run_match(tm, &t, &p, NULL, NULL, &flag, out, &res, &err), SM_OK);
    assert_int_equal(res.stop, SM_STOP_CANCELLED);
    assert_int_equal(res.iterations, 0);
    assert_memory_equal(out, tm->coords, sizeof(double) * tm->nverts * 2);
    free(h);
    free(out);
    sm_mesh_free(tm);
    free_target(&t);
}

/* A prepared template (boundary built by the caller, as the job runner's
 * input check does) gives the same descent, bit for bit, as the run's own
 * copy; and a field of the wrong dimension is refused. */
static void test_prepared_template_same_descent(void **state)
{
    (void)state;
    target t;
    make_target(&t, 60, 0.3, 0.25);
    const double c[2] = {0.5, 0.5};
    sm_mesh *tm = util_disk_mesh(c, 0.2, 6);
    sm_params p;
    sm_params_default(&p);
    p.clamp = SM_CLAMP_BALL;
    p.clamp_center[0] = p.clamp_center[1] = 0.5;
    p.clamp_radius = 0.05;
    p.max_iter = 12;
    size_t n = (size_t)tm->nverts * 2;
    double *a = malloc(sizeof(double) * n), *b = malloc(sizeof(double) * n);
    sm_result ra, rb;
    sm_error err;
    assert_int_equal(run_match(tm, &t, &p, NULL, NULL, NULL, a, &ra, &err), SM_OK);
    sm_mesh *prepared;
    assert_int_equal(sm_mesh_clone(tm, &prepared, &err), SM_OK);
    assert_int_equal(sm_mesh_build_boundary(prepared, &err), SM_OK);
    sm_match_opts opts = {.template_mesh = tm, .prepared = prepared, .target = t.field, .params = &p};
    assert_int_equal(sm_match_run(&opts, NULL, b, &rb, &err), SM_OK);
    assert_int_equal(ra.iterations, 12);
    assert_int_equal(rb.iterations, ra.iterations);
    assert_int_equal(rb.accepted, ra.accepted);
    assert_int_equal(rb.rejected, ra.rejected);
    assert_true(rb.J == ra.J && rb.boundary_l2 == ra.boundary_l2);
    assert_memory_equal(a, b, sizeof(double) * n);
    /* a 3D field under a 2D template */
    const double lo[3] = {0, 0, 0}, hi[3] = {1, 1, 1};
    sm_mesh *bg3 = util_box_mesh(3, 2, lo, hi, 1);
    double *d3 = calloc((size_t)bg3->nverts, sizeof(double));
    sm_field *f3;
    assert_int_equal(sm_field_new(bg3, d3, &f3, &err), SM_OK);
    opts.prepared = NULL;
    opts.target = f3;
    assert_int_equal(sm_match_run(&opts, NULL, b, &rb, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "the template is 2D but the target background mesh is 3D"));
    sm_field_free(f3);
    free(d3);
    sm_mesh_free(bg3);
    sm_mesh_free(prepared);
    free(a);
    free(b);
    sm_mesh_free(tm);
    free_target(&t);
}

/* sm_match_new then sm_match_execute: the same descent, bit for bit, as
 * sm_match_run (the template side set up before the target is known);
 * one execute per run; a target of the wrong dimension and a bad clamp
 * are refused by the step that can see them. */
static void test_two_step_run(void **state)
{
    (void)state;
    target t;
    sm_params p;
    sm_mesh *tm = ellipse_case(&t, &p, 15);
    size_t n = (size_t)tm->nverts * 2;
    double *a = malloc(sizeof(double) * n), *b = malloc(sizeof(double) * n);
    history ha = {0}, hb = {0};
    sm_result ra, rb;
    sm_error err;
    assert_int_equal(run_match(tm, &t, &p, record, &ha, NULL, a, &ra, &err), SM_OK);
    sm_match_opts opts = {.template_mesh = tm, .params = &p};
    sm_match *m = NULL;
    assert_int_equal(sm_match_new(&opts, &m, &err), SM_OK);
    sm_match_callbacks cb = {.progress = record, .user = &hb};
    assert_int_equal(sm_match_execute(m, t.field, &cb, b, &rb, &err), SM_OK);
    assert_int_equal(rb.iterations, 15);
    assert_int_equal(rb.iterations, ra.iterations);
    assert_int_equal(rb.accepted, ra.accepted);
    assert_int_equal(rb.rejected, ra.rejected);
    assert_true(rb.J == ra.J && rb.J_initial == ra.J_initial && rb.boundary_l2 == ra.boundary_l2);
    assert_int_equal(hb.n, ha.n);
    assert_memory_equal(hb.l2, ha.l2, sizeof(double) * (size_t)ha.n);
    assert_memory_equal(a, b, sizeof(double) * n);
    assert_true(rb.time.setup > 0 && rb.time.total >= rb.time.setup);
    assert_int_equal(sm_match_execute(m, t.field, NULL, b, &rb, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "already executed"));
    sm_match_free(m);

    /* a 3D field under a 2D template: refused by execute */
    const double lo[3] = {0, 0, 0}, hi[3] = {1, 1, 1};
    sm_mesh *bg3 = util_box_mesh(3, 2, lo, hi, 1);
    double *d3 = calloc((size_t)bg3->nverts, sizeof(double));
    sm_field *f3;
    assert_int_equal(sm_field_new(bg3, d3, &f3, &err), SM_OK);
    assert_int_equal(sm_match_new(&opts, &m, &err), SM_OK);
    assert_int_equal(sm_match_execute(m, f3, NULL, b, &rb, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "the template is 2D but the target background mesh is 3D"));
    sm_match_free(m);
    /* a clamp set that holds nothing: refused by new, *out NULL */
    p.clamp_center[0] = 5.0;
    m = (sm_match *)&opts; /* not a run: new must reset it */
    assert_int_equal(sm_match_new(&opts, &m, &err), SM_ERR_INVALID);
    assert_null(m);
    assert_non_null(strstr(err.msg, "clamp set is empty"));
    sm_match_free(NULL);
    sm_field_free(f3);
    free(d3);
    sm_mesh_free(bg3);
    free(a);
    free(b);
    sm_mesh_free(tm);
    free_target(&t);
}

static void test_bad_inputs(void **state)
{
    (void)state;
    target t;
    make_target(&t, 20, 0.3, 0.3);
    const double c[2] = {0.5, 0.5};
    sm_mesh *tm = util_disk_mesh(c, 0.2, 4);
    double *out = malloc(sizeof(double) * tm->nverts * 2);
    sm_result res;
    sm_error err;
    sm_params p;
    sm_params_default(&p);
    p.clamp = SM_CLAMP_BALL;
    p.clamp_center[0] = 5.0;
    p.clamp_center[1] = 5.0;
    p.clamp_radius = 0.1;
    assert_int_equal(run_match(tm, &t, &p, NULL, NULL, NULL, out, &res, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "clamp set is empty"));
    p.clamp_center[0] = p.clamp_center[1] = 0.5; /* only the center vertex */
    p.clamp_radius = 1e-3;
    assert_int_equal(run_match(tm, &t, &p, NULL, NULL, NULL, out, &res, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "rigid rotations stay free"));
    p.clamp_radius = 10.0; /* every vertex */
    assert_int_equal(run_match(tm, &t, &p, NULL, NULL, NULL, out, &res, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "nothing could move"));
    p.clamp = SM_CLAMP_ELEMENTS;
    p.n_clamp_refs = 1;
    p.clamp_refs[0] = 42;
    assert_int_equal(run_match(tm, &t, &p, NULL, NULL, NULL, out, &res, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "clamp set is empty"));
    p.clamp = SM_CLAMP_NONE;
    p.alpha = -1;
    assert_int_equal(run_match(tm, &t, &p, NULL, NULL, NULL, out, &res, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "alpha"));
    sm_params_default(&p);
    p.poisson = 0.5;
    assert_int_equal(sm_params_validate(&p, 2, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "poisson"));
    sm_params_default(&p);
    p.free_refs[0] = 1;
    p.n_free_refs = 1;
    assert_int_equal(run_match(tm, &t, &p, NULL, NULL, NULL, out, &res, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "free boundary"));
    free(out);
    sm_mesh_free(tm);
    free_target(&t);
}


/* First iteration whose error is within 10% of the best of the run. */
static int first_within_10pct(const history *h)
{
    double best = INFINITY;
    for (int i = 0; i < h->n; i++)
        if (h->l2[i] < best)
            best = h->l2[i];
    for (int i = 0; i < h->n; i++)
        if (h->l2[i] <= 1.1 * best)
            return i;
    return h->n;
}

/* The stall rule (on by default) ends a converged run no earlier than
 * the iteration that comes within 10% of the best error of the long run
 * and within twice that; it only stops, the descent is the same bit for
 * bit as with the rule off (tol_stall 0). */
static void test_stall_rule_bounds(void **state)
{
    (void)state;
    target t;
    sm_params p;
    sm_mesh *tm = ellipse_case(&t, &p, 300);
    double *out = malloc(sizeof(double) * tm->nverts * 2);
    sm_result off, on;
    sm_error err;
    history *h_off = calloc(1, sizeof *h_off), *h_on = calloc(1, sizeof *h_on);
    p.tol_stall = 0.0;
    assert_int_equal(run_match(tm, &t, &p, record, h_off, NULL, out, &off, &err), SM_OK);
    assert_int_not_equal(off.stop, SM_STOP_STALLED);
    sm_params_default(&p);
    p.clamp = SM_CLAMP_BALL;
    p.clamp_center[0] = p.clamp_center[1] = 0.5;
    p.clamp_radius = 0.05;
    p.max_iter = 300;
    assert_true(p.tol_stall > 0 && p.stall_window > 1); /* on by default */
    assert_int_equal(run_match(tm, &t, &p, record, h_on, NULL, out, &on, &err), SM_OK);
    int needed = first_within_10pct(h_off);
    if (getenv("SM_DEBUG"))
        print_message("off: %s after %d; needed %d; on: %s after %d\n",
                      sm_stop_reason_name(off.stop), off.iterations, needed,
                      sm_stop_reason_name(on.stop), on.iterations);
    assert_int_equal(on.stop, SM_STOP_STALLED);
    assert_string_equal(sm_stop_reason_name(on.stop), "stalled");
    assert_true(on.iterations >= needed);
    assert_true(on.iterations <= 2 * needed);
    assert_true(on.iterations < off.iterations);
    for (int i = 0; i < h_on->n; i++)
        assert_true(h_on->J[i] == h_off->J[i] && h_on->l2[i] == h_off->l2[i]);
    free(h_off);
    free(h_on);
    free(out);
    sm_mesh_free(tm);
    free_target(&t);
}

/* Runs the ellipse case with everything scaled by s (a change of unit). */
static void run_scaled(double s, double tol_rel, double tol_abs, sm_result *res)
{
    target t;
    make_target(&t, 100, 0.32, 0.22);
    for (int32_t v = 0; v < t.bg->nverts; v++) {
        t.bg->coords[2 * v] *= s;
        t.bg->coords[2 * v + 1] *= s;
        t.d[v] *= s;
    }
    sm_field_free(t.field);
    sm_error err;
    assert_int_equal(sm_field_new(t.bg, t.d, &t.field, &err), SM_OK);
    const double c[2] = {0.5, 0.5};
    sm_mesh *tm = util_disk_mesh(c, 0.25, 10);
    for (int32_t i = 0; i < 2 * tm->nverts; i++)
        tm->coords[i] *= s;
    sm_params p;
    sm_params_default(&p);
    p.clamp = SM_CLAMP_BALL;
    p.clamp_center[0] = p.clamp_center[1] = 0.5 * s;
    p.clamp_radius = 0.05 * s;
    p.max_iter = 300;
    p.tol_stall = 0.0;
    p.tol_boundary_rel = tol_rel;
    p.tol_boundary = tol_abs;
    double *out = malloc(sizeof(double) * tm->nverts * 2);
    assert_int_equal(run_match(tm, &t, &p, NULL, NULL, NULL, out, res, &err), SM_OK);
    free(out);
    sm_mesh_free(tm);
    free_target(&t);
}

/* tol_boundary_rel is unit-free: the case in metres and in millimetres
 * stops after the same iterations with the same relative error, while
 * the absolute tol_boundary does not. */
static void test_relative_tolerance_is_unit_free(void **state)
{
    (void)state;
    sm_result m, mm;
    run_scaled(1.0, 5e-4, 0.0, &m);
    run_scaled(1000.0, 5e-4, 0.0, &mm);
    if (getenv("SM_DEBUG"))
        print_message("m: %s %d rms %g d %g; mm: %s %d rms %g d %g\n",
                      sm_stop_reason_name(m.stop), m.iterations, m.boundary_rms, m.diameter,
                      sm_stop_reason_name(mm.stop), mm.iterations, mm.boundary_rms, mm.diameter);
    assert_int_equal(m.stop, SM_STOP_BOUNDARY);
    assert_int_equal(mm.stop, SM_STOP_BOUNDARY);
    assert_true(m.iterations > 3);
    assert_int_equal(mm.iterations, m.iterations);
    assert_true(m.boundary_rms <= 5e-4 * m.diameter);
    assert_true(fabs(mm.boundary_rms / mm.diameter - m.boundary_rms / m.diameter) <=
                1e-6 * m.boundary_rms / m.diameter);
    /* rms = l2 / sqrt(|boundary|), the boundary a curve of length ~ 1.7 */
    double len = (m.boundary_l2 / m.boundary_rms) * (m.boundary_l2 / m.boundary_rms);
    assert_true(len > 1.4 && len < 2.0);
    /* the absolute tolerance that stops the metre run never stops the
     * millimetre one (its error is 1000^1.5 times larger) */
    sm_result am, amm;
    run_scaled(1.0, 0.0, m.boundary_l2 * 1.0001, &am);
    run_scaled(1000.0, 0.0, m.boundary_l2 * 1.0001, &amm);
    assert_int_equal(am.stop, SM_STOP_BOUNDARY);
    assert_int_not_equal(amm.stop, SM_STOP_BOUNDARY);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_converges_on_ellipse),
        cmocka_unit_test(test_elastic_direction_descends),
        cmocka_unit_test(test_cancel_and_no_clamp),
        cmocka_unit_test(test_prepared_template_same_descent),
        cmocka_unit_test(test_two_step_run),
        cmocka_unit_test(test_bad_inputs),
        cmocka_unit_test(test_stall_rule_bounds),
        cmocka_unit_test(test_relative_tolerance_is_unit_free),
    };
    return cmocka_run_group_tests_name("match", tests, NULL, NULL);
}
