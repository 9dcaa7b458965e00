/* The correspondence (core/sm_warp.c): template vertices onto the
 * deformed vertices bitwise; random barycentric points inside random
 * elements onto the same barycentric combination of the deformed
 * vertices; points on facets onto the facet's own combination (the map
 * is continuous whichever element is found); inverse(forward(x)) = x;
 * outside points flagged, extrapolated exactly under an affine map and
 * refused when strict; vectors and tensors under an affine map equal to
 * A v and A T A^T (and A^-1 v back).  2D and 3D, on meshes whose elements
 * have both orientations.  The expected values are computed here from
 * the vertices, not by the module. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "shapematch/sm_mesh.h"
#include "shapematch/sm_warp.h"
#include "util_mesh.h"

static double urand(uint64_t *s)
{
    *s ^= *s << 13;
    *s ^= *s >> 7;
    *s ^= *s << 17;
    return (double)(*s >> 11) * (1.0 / 9007199254740992.0);
}

/* A smooth bijection of the unit box (Jacobian I + at most 0.32 off the
 * diagonal): the template is deformed by it at its vertices. */
static void bend(int D, const double *x, double *y)
{
    const double tau = 6.283185307179586;
    y[0] = x[0] + 0.05 * sin(tau * x[1]);
    y[1] = x[1] + 0.05 * sin(tau * x[0]);
    if (D == 3) {
        y[0] += 0.03 * x[2] * x[2];
        y[2] = x[2] + 0.04 * sin(tau * (x[0] + x[1]) / 2);
    }
}

static const double A3[3][3] = {{1.2, 0.3, -0.1}, {-0.2, 0.9, 0.25}, {0.05, -0.15, 1.1}};
static const double B3[3] = {0.5, -1.0, 2.0};

static void affine(int D, const double *x, double *y)
{
    for (int i = 0; i < D; i++) {
        y[i] = B3[i];
        for (int k = 0; k < D; k++)
            y[i] += A3[i][k] * x[k];
    }
}

typedef struct fixture {
    sm_mesh *m;
    double *Y;
    sm_warp *w;
} fixture;

static void fixture_make(fixture *f, int D, int n, void (*map)(int, const double *, double *))
{
    static const double lo[3] = {0, 0, 0}, hi[3] = {1, 1, 1};
    f->m = util_box_mesh(D, n, lo, hi, 1); /* shuffled: both orientations */
    assert_non_null(f->m);
    f->Y = malloc((size_t)f->m->nverts * D * sizeof *f->Y);
    for (int32_t v = 0; v < f->m->nverts; v++)
        map(D, f->m->coords + (size_t)v * D, f->Y + (size_t)v * D);
    sm_error err;
    assert_int_equal(sm_warp_new(f->m, f->Y, SM_WARP_LOCATE_FORWARD | SM_WARP_LOCATE_INVERSE,
                                 &f->w, &err),
                     SM_OK);
    assert_int_equal(sm_warp_dim(f->w), D);
}

static void fixture_free(fixture *f)
{
    sm_warp_free(f->w);
    free(f->Y);
    sm_mesh_free(f->m);
}

/* the barycentric combination of the vertices ev (cnt of them) */
static void combine(const double *coords, const int32_t *ev, int cnt, const double *lam, int D,
                    double *out)
{
    for (int i = 0; i < D; i++) {
        out[i] = 0.0;
        for (int k = 0; k < cnt; k++)
            out[i] += lam[k] * coords[(size_t)ev[k] * D + i];
    }
}

static void check_close(const double *a, const double *b, int D, double tol)
{
    for (int i = 0; i < D; i++)
        if (!(fabs(a[i] - b[i]) <= tol))
            fail_msg("coordinate %d: %.17g vs %.17g (tolerance %g)", i, a[i], b[i], tol);
}

static void vertices_exact(int D)
{
    fixture f;
    fixture_make(&f, D, D == 2 ? 12 : 6, bend);
    int32_t nv = f.m->nverts;
    double *out = malloc((size_t)nv * D * sizeof *out);
    uint8_t *in = malloc((size_t)nv);
    int64_t nout = -1;
    sm_error err;
    assert_int_equal(sm_warp_points(f.w, SM_WARP_FORWARD, 1, nv, f.m->coords, out, in, &nout, &err),
                     SM_OK);
    assert_int_equal(nout, 0);
    assert_memory_equal(out, f.Y, (size_t)nv * D * sizeof *out); /* bitwise */
    assert_int_equal(sm_warp_points(f.w, SM_WARP_INVERSE, 1, nv, f.Y, out, in, &nout, &err), SM_OK);
    assert_memory_equal(out, f.m->coords, (size_t)nv * D * sizeof *out);
    for (int32_t v = 0; v < nv; v++)
        assert_int_equal(in[v], 1);
    free(out);
    free(in);
    fixture_free(&f);
}

static void test_vertices_2d(void **s)
{
    (void)s;
    vertices_exact(2);
}

static void test_vertices_3d(void **s)
{
    (void)s;
    vertices_exact(3);
}

/* Random points in random elements (kind 0), on a random facet of a
 * random element (kind 1: most facets are shared by two elements), and
 * forward then back. */
static void barycentric(int D)
{
    fixture f;
    fixture_make(&f, D, D == 2 ? 10 : 5, bend);
    enum { N = 4000 };
    double *x = malloc(N * D * sizeof *x), *want = malloc(N * D * sizeof *want);
    double *y = malloc(N * D * sizeof *y), *back = malloc(N * D * sizeof *back);
    uint8_t in[N];
    uint64_t seed = 0x9e3779b97f4a7c15ull + (uint64_t)D;
    for (int p = 0; p < N; p++) {
        int32_t e = (int32_t)(urand(&seed) * f.m->nelems);
        const int32_t *ev = f.m->elems + (size_t)e * (D + 1);
        int32_t fv[4];
        double lam[4], sum = 0.0;
        int cnt = 0, skip = p % 2 ? (int)(urand(&seed) * (D + 1)) : -1;
        for (int k = 0; k <= D; k++)
            if (k != skip)
                fv[cnt++] = ev[k];
        for (int k = 0; k < cnt; k++)
            sum += lam[k] = 0.05 + urand(&seed);
        for (int k = 0; k < cnt; k++)
            lam[k] /= sum;
        combine(f.m->coords, fv, cnt, lam, D, x + (size_t)p * D);
        combine(f.Y, fv, cnt, lam, D, want + (size_t)p * D);
    }
    sm_error err;
    int64_t nout;
    assert_int_equal(sm_warp_points(f.w, SM_WARP_FORWARD, 1, N, x, y, in, &nout, &err), SM_OK);
    assert_int_equal(nout, 0);
    double diam = sm_mesh_diameter(f.m, f.m->coords);
    for (int p = 0; p < N; p++)
        check_close(y + (size_t)p * D, want + (size_t)p * D, D, 1e-13 * diam);
    assert_int_equal(sm_warp_points(f.w, SM_WARP_INVERSE, 1, N, y, back, in, &nout, &err), SM_OK);
    for (int p = 0; p < N; p++)
        check_close(back + (size_t)p * D, x + (size_t)p * D, D, 1e-9 * diam);
    free(x);
    free(want);
    free(y);
    free(back);
    fixture_free(&f);
}

static void test_barycentric_2d(void **s)
{
    (void)s;
    barycentric(2);
}

static void test_barycentric_3d(void **s)
{
    (void)s;
    barycentric(3);
}

/* Outside the box: flagged, and under an affine map the extrapolation by
 * the nearest element is the affine map itself; strict refuses, naming
 * the first outside point. */
static void outside(int D)
{
    fixture f;
    fixture_make(&f, D, 4, affine);
    double x[4][3] = {{0.5, 0.5, 0.5}, {1.7, 0.2, 0.4}, {-0.3, -0.6, 0.5}, {0.25, 1.0, 1.0}};
    double pts[12], y[12], back[12], want[3];
    for (int p = 0; p < 4; p++)
        memcpy(pts + p * D, x[p], (size_t)D * sizeof *pts);
    uint8_t in[4];
    int64_t nout;
    sm_error err;
    assert_int_equal(sm_warp_points(f.w, SM_WARP_FORWARD, 0, 4, pts, y, in, &nout, &err), SM_OK);
    assert_int_equal(nout, 2);
    uint8_t expect[4] = {1, 0, 0, 1}; /* the last one is on the boundary: inside */
    assert_memory_equal(in, expect, 4);
    for (int p = 0; p < 4; p++) {
        affine(D, pts + p * D, want);
        check_close(y + p * D, want, D, 1e-12);
    }
    assert_int_equal(sm_warp_points(f.w, SM_WARP_INVERSE, 0, 4, y, back, in, &nout, &err), SM_OK);
    assert_memory_equal(in, expect, 4);
    for (int p = 0; p < 4; p++)
        check_close(back + p * D, pts + p * D, D, 1e-12);
    assert_int_equal(sm_warp_points(f.w, SM_WARP_FORWARD, 1, 4, pts, y, NULL, NULL, &err),
                     SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "point 2 is outside the template"));
    pts[D] = NAN;
    assert_int_equal(sm_warp_points(f.w, SM_WARP_FORWARD, 0, 4, pts, y, NULL, NULL, &err),
                     SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "point 2 has a non-finite"));
    fixture_free(&f);
}

static void test_outside_2d(void **s)
{
    (void)s;
    outside(2);
}

static void test_outside_3d(void **s)
{
    (void)s;
    outside(3);
}

/* Vectors to A v (unit when normalized), back to A^-1 v; tensors to
 * A T A^T; scalars unchanged. */
static void fields(int D)
{
    fixture f;
    fixture_make(&f, D, 3, affine);
    int32_t nv = f.m->nverts;
    int nt = D * (D + 1) / 2;
    double *v = malloc((size_t)nv * D * sizeof *v), *u = malloc((size_t)nv * D * sizeof *u);
    double *t = malloc((size_t)nv * nt * sizeof *t), *sc = malloc((size_t)nv * sizeof *sc);
    uint64_t seed = 77;
    for (size_t i = 0; i < (size_t)nv * D; i++)
        v[i] = u[i] = urand(&seed) - 0.5;
    for (size_t i = 0; i < (size_t)nv * nt; i++)
        t[i] = urand(&seed) - 0.5;
    for (int32_t i = 0; i < nv; i++)
        sc[i] = urand(&seed);
    double *t0 = malloc((size_t)nv * nt * sizeof *t0), *sc0 = malloc((size_t)nv * sizeof *sc0);
    memcpy(t0, t, (size_t)nv * nt * sizeof *t0);
    memcpy(sc0, sc, (size_t)nv * sizeof *sc0);
    sm_error err;
    assert_int_equal(sm_warp_field(f.w, SM_WARP_FORWARD, D, 0, v, &err), SM_OK);
    assert_int_equal(sm_warp_field(f.w, SM_WARP_FORWARD, D, 1, u, &err), SM_OK);
    assert_int_equal(sm_warp_field(f.w, SM_WARP_FORWARD, nt, 0, t, &err), SM_OK);
    assert_int_equal(sm_warp_field(f.w, SM_WARP_FORWARD, 1, 0, sc, &err), SM_OK);
    assert_memory_equal(sc, sc0, (size_t)nv * sizeof *sc);
    static const int i2[2][2] = {{0, 1}, {1, 2}}, i3[3][3] = {{0, 1, 3}, {1, 2, 4}, {3, 4, 5}};
    seed = 77;
    for (int32_t p = 0; p < nv; p++) {
        double v0[3], want[3], len = 0;
        for (int i = 0; i < D; i++)
            v0[i] = urand(&seed) - 0.5;
        for (int i = 0; i < D; i++) {
            want[i] = 0;
            for (int k = 0; k < D; k++)
                want[i] += A3[i][k] * v0[k];
            len += want[i] * want[i];
        }
        check_close(v + (size_t)p * D, want, D, 1e-13);
        for (int i = 0; i < D; i++)
            want[i] /= sqrt(len);
        check_close(u + (size_t)p * D, want, D, 1e-13);
        const double *T = t0 + (size_t)p * nt;
        for (int i = 0; i < D; i++)
            for (int j = 0; j < D; j++) {
                double s = 0;
                for (int a = 0; a < D; a++)
                    for (int b = 0; b < D; b++)
                        s += A3[i][a] * T[D == 2 ? i2[a][b] : i3[a][b]] * A3[j][b];
                double got = t[(size_t)p * nt + (D == 2 ? i2[i][j] : i3[i][j])];
                if (!(fabs(got - s) <= 1e-13))
                    fail_msg("tensor at vertex %d (%d,%d): %.17g vs %.17g", p, i, j, got, s);
            }
    }
    /* back: A^-1 (A v) = v */
    assert_int_equal(sm_warp_field(f.w, SM_WARP_INVERSE, D, 0, v, &err), SM_OK);
    seed = 77;
    for (int32_t p = 0; p < nv; p++) {
        double v0[3];
        for (int i = 0; i < D; i++)
            v0[i] = urand(&seed) - 0.5;
        check_close(v + (size_t)p * D, v0, D, 1e-13);
    }
    assert_int_equal(sm_warp_field(f.w, SM_WARP_FORWARD, 7, 0, v, &err), SM_ERR_INVALID);
    free(v);
    free(u);
    free(t);
    free(t0);
    free(sc);
    free(sc0);
    fixture_free(&f);
}

static void test_fields_2d(void **s)
{
    (void)s;
    fields(2);
}

static void test_fields_3d(void **s)
{
    (void)s;
    fields(3);
}

/* A warp that was not asked for a direction says so. */
static void test_not_prepared(void **s)
{
    (void)s;
    static const double lo[2] = {0, 0}, hi[2] = {1, 1};
    sm_mesh *m = util_box_mesh(2, 2, lo, hi, 0);
    sm_warp *w;
    sm_error err;
    assert_int_equal(sm_warp_new(m, m->coords, SM_WARP_LOCATE_FORWARD, &w, &err), SM_OK);
    double x[2] = {0.5, 0.5}, y[2];
    assert_int_equal(sm_warp_points(w, SM_WARP_INVERSE, 0, 1, x, y, NULL, NULL, &err),
                     SM_ERR_INVALID);
    assert_int_equal(sm_warp_points(w, SM_WARP_FORWARD, 0, 1, x, y, NULL, NULL, &err), SM_OK);
    check_close(y, x, 2, 1e-15);
    sm_warp_free(w);
    double bad[18];
    memcpy(bad, m->coords, (size_t)m->nverts * 2 * sizeof *bad);
    bad[3] = INFINITY;
    assert_int_equal(sm_warp_new(m, bad, 0, &w, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "deformed vertex 2"));
    sm_mesh_free(m);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_vertices_2d),    cmocka_unit_test(test_vertices_3d),
        cmocka_unit_test(test_barycentric_2d), cmocka_unit_test(test_barycentric_3d),
        cmocka_unit_test(test_outside_2d),     cmocka_unit_test(test_outside_3d),
        cmocka_unit_test(test_fields_2d),      cmocka_unit_test(test_fields_3d),
        cmocka_unit_test(test_not_prepared),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
