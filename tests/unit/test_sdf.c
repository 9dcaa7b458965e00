/* run.sh: seconds 15 */
/* Distance and sign to target surfaces (sm_sdf.h, sm_surface_repair):
 *  - the hierarchy's distance equals brute force (all points x all facets,
 *    with this file's own point-facet formula) to 1e-12, at random points
 *    inside and outside and at points on the surface (vertices, edge
 *    midpoints, centroids), on Gmsh-made sphere, torus and box (sharp
 *    edges), and on 2D polylines;
 *  - the sign: 0 errors on closed surfaces in random orientation mixes
 *    (after repair) against the analytic inside test away from the
 *    surface; with holes, duplicated patches and flipped facets, 0 errors
 *    farther than twice the defect size from the defect;
 *  - the graded background: covers its box exactly (volumes), cells of
 *    at most h near the surface, far fewer vertices than the uniform grid
 *    of size h, and a P1 interpolation error of the distance near the
 *    surface no worse than that uniform grid's. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "shapematch/sm_field.h"
#include "shapematch/sm_sdf.h"
#include "shapematch/sm_surface.h"
#include "util_gmsh.h"

#define TORUS_GEO "SetFactory(\"OpenCASCADE\");\nTorus(1) = {0, 0, 0, 1, 0.4};\n" \
                  "Mesh.MeshSizeFromPoints = 0;\n"
#define BOX_GEO "SetFactory(\"OpenCASCADE\");\nBox(1) = {-1, -0.7, -0.5, 2, 1.4, 1};\n" \
                "Mesh.MeshSizeFromPoints = 0;\n"
/* a curve only: gmsh -2 meshes it into a polyline (Medit Edges, z = 0) */
#define CIRCLE_GEO "SetFactory(\"OpenCASCADE\");\nCircle(1) = {0, 0, 0, 1};\n" \
                   "Mesh.MeshSizeFromPoints = 0;\n"

enum shape { SPHERE, TORUS, BOX, CIRCLE };

static uint64_t rng = 88172645463325252ull;
static double urand(void)
{
    rng ^= rng << 13;
    rng ^= rng >> 7;
    rng ^= rng << 17;
    return (double)(rng >> 11) / 9007199254740992.0;
}

/* Analytic signed distance-like function: < 0 inside. */
static double analytic(enum shape k, const double *p)
{
    switch (k) {
    case SPHERE: return sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]) - 1;
    case TORUS: return hypot(hypot(p[0], p[1]) - 1, p[2]) - 0.4;
    case BOX: {
        double q[3] = {fabs(p[0]) - 1, fabs(p[1]) - 0.7, fabs(p[2]) - 0.5};
        double m = fmax(q[0], fmax(q[1], q[2]));
        return m;
    }
    default: return hypot(p[0], p[1]) - 1;
    }
}

static sm_surface *make_surface(enum shape k, double h)
{
    const char *geo = k == SPHERE ? UTIL_GMSH_UNIT_BALL : k == TORUS ? TORUS_GEO : k == BOX ? BOX_GEO : CIRCLE_GEO;
    char dir[] = "/tmp/sm_sdf_XXXXXX";
    assert_non_null(mkdtemp(dir));
    char path[64], msg[1024];
    snprintf(path, sizeof path, "%s/s.mesh", dir);
    if (util_gmsh_write_format(geo, 2, h, "mesh", 0, path, msg, sizeof msg) != SM_OK)
        fail_msg("gmsh: %s", msg);
    sm_surface *s = NULL;
    sm_error err;
    sm_error_clear(&err);
    if (sm_surface_read(path, &s, &err) != SM_OK)
        fail_msg("%s", err.msg);
    assert_int_equal(s->dim, k == CIRCLE ? 2 : 3);
    unlink(path);
    rmdir(dir);
    return s;
}

/* ---- independent brute force ---- */

static double seg2(const double *p, const double *a, const double *b, int dim)
{
    double ab2 = 0, t = 0;
    for (int k = 0; k < dim; k++) {
        ab2 += (b[k] - a[k]) * (b[k] - a[k]);
        t += (p[k] - a[k]) * (b[k] - a[k]);
    }
    t = ab2 > 0 ? fmin(1, fmax(0, t / ab2)) : 0;
    double d2 = 0;
    for (int k = 0; k < dim; k++) {
        double e = p[k] - (a[k] + t * (b[k] - a[k]));
        d2 += e * e;
    }
    return d2;
}

/* projection onto the plane if inside the triangle, else the edges */
static double tri2(const double *p, const double *a, const double *b, const double *c)
{
    double u[3], v[3], w[3], n[3];
    for (int k = 0; k < 3; k++) {
        u[k] = b[k] - a[k];
        v[k] = c[k] - a[k];
        w[k] = p[k] - a[k];
    }
    n[0] = u[1] * v[2] - u[2] * v[1];
    n[1] = u[2] * v[0] - u[0] * v[2];
    n[2] = u[0] * v[1] - u[1] * v[0];
    double nn = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
    double edges = fmin(seg2(p, a, b, 3), fmin(seg2(p, b, c, 3), seg2(p, c, a, 3)));
    if (nn == 0)
        return edges;
    double s = (w[0] * n[0] + w[1] * n[1] + w[2] * n[2]) / nn;
    double q[3] = {p[0] - s * n[0], p[1] - s * n[1], p[2] - s * n[2]};
    /* barycentric signs via sub-triangle normals */
    const double *P[3] = {a, b, c};
    int inside = 1;
    for (int e = 0; e < 3; e++) {
        const double *x = P[e], *y = P[(e + 1) % 3];
        double xy[3] = {y[0] - x[0], y[1] - x[1], y[2] - x[2]};
        double xq[3] = {q[0] - x[0], q[1] - x[1], q[2] - x[2]};
        double m[3] = {xy[1] * xq[2] - xy[2] * xq[1], xy[2] * xq[0] - xy[0] * xq[2],
                       xy[0] * xq[1] - xy[1] * xq[0]};
        if (m[0] * n[0] + m[1] * n[1] + m[2] * n[2] < 0)
            inside = 0;
    }
    return inside ? fmin(s * s * nn, edges) : edges;
}

static double brute(const sm_surface *s, const double *p)
{
    double best = INFINITY;
    for (int32_t f = 0; f < s->nfacets; f++) {
        const int32_t *v = s->facets + (size_t)f * s->dim;
        double d2 = s->dim == 3 ? tri2(p, s->coords + 3 * v[0], s->coords + 3 * v[1], s->coords + 3 * v[2])
                                : seg2(p, s->coords + 2 * v[0], s->coords + 2 * v[1], 2);
        best = fmin(best, d2);
    }
    return sqrt(best);
}

/* random points in the padded box, plus points on the surface */
static double *query_points(const sm_surface *s, int64_t nrand, int64_t *n)
{
    int dim = s->dim;
    int64_t total = nrand + s->nverts + 2 * (int64_t)s->nfacets;
    double *p = malloc((size_t)total * dim * sizeof *p);
    int64_t m = 0;
    for (int64_t i = 0; i < nrand; i++, m++)
        for (int k = 0; k < dim; k++)
            p[m * dim + k] = -1.6 + 3.2 * urand();
    for (int32_t i = 0; i < s->nverts; i++, m++)
        memcpy(p + m * dim, s->coords + (size_t)i * dim, dim * sizeof *p);
    for (int32_t f = 0; f < s->nfacets; f++) {
        const int32_t *v = s->facets + (size_t)f * dim;
        for (int k = 0; k < dim; k++) {
            double c = 0;
            for (int j = 0; j < dim; j++)
                c += s->coords[(size_t)v[j] * dim + k] / dim;
            p[m * dim + k] = c;
            p[(m + 1) * dim + k] = (s->coords[(size_t)v[0] * dim + k] + s->coords[(size_t)v[1] * dim + k]) / 2;
        }
        m += 2;
    }
    *n = m;
    return p;
}

static void check_against_brute(enum shape k, double h, const char *name)
{
    sm_surface *s = make_surface(k, h);
    sm_sdf *d;
    sm_error err;
    sm_error_clear(&err);
    assert_int_equal(sm_sdf_new(s, &d, &err), SM_OK);
    int64_t n;
    double *p = query_points(s, 3000, &n);
    double *dist = malloc((size_t)n * sizeof *dist);
    sm_sdf_distance(d, n, p, dist, NULL);
    double worst = 0;
    for (int64_t i = 0; i < n; i++)
        worst = fmax(worst, fabs(dist[i] - brute(s, p + i * s->dim)));
    print_message("# %s: %d facets, %lld points, max |bvh - brute| = %.3g\n", name, s->nfacets,
                  (long long)n, worst);
    assert_true(worst <= 1e-12);
    free(p);
    free(dist);
    sm_sdf_free(d);
    sm_surface_free(s);
}

static void test_distance_sphere(void **state) { (void)state; check_against_brute(SPHERE, 0.15, "sphere"); }
static void test_distance_torus(void **state) { (void)state; check_against_brute(TORUS, 0.15, "torus"); }
static void test_distance_box(void **state) { (void)state; check_against_brute(BOX, 0.2, "box"); }
static void test_distance_circle(void **state) { (void)state; check_against_brute(CIRCLE, 0.05, "circle"); }

/* ---- sign ---- */

/* Counts sign errors at random points whose analytic distance exceeds
 * margin and (when center is given) that are farther than keep from it. */
static int64_t sign_errors(sm_surface *s, enum shape k, double margin, const double *center,
                           double keep, int64_t *checked)
{
    sm_error err;
    sm_error_clear(&err);
    sm_surface_health h;
    assert_int_equal(sm_surface_repair(s, &h, &err), SM_OK);
    sm_sdf *d;
    assert_int_equal(sm_sdf_new(s, &d, &err), SM_OK);
    int dim = s->dim;
    int64_t n = 4000;
    double *p = malloc((size_t)n * dim * sizeof *p), *sd = malloc((size_t)n * sizeof *sd);
    for (int64_t i = 0; i < n * dim; i++)
        p[i] = -1.6 + 3.2 * urand();
    int64_t wound = 0;
    if (sm_sdf_signed_stats(d, n, p, sd, &wound, &err) != SM_OK)
        fail_msg("%s", err.msg);
    /* the sign carried between points (closed surfaces) is the sign of
     * the winding number evaluated at every point */
    double *ud = malloc((size_t)n * sizeof *ud), *w = malloc((size_t)n * sizeof *w);
    sm_sdf_distance(d, n, p, ud, NULL);
    sm_sdf_winding(d, n, p, w);
    int64_t differ = 0;
    for (int64_t i = 0; i < n; i++)
        differ += sd[i] != (w[i] > 0.5 ? -ud[i] : ud[i]);
    print_message("# %lld of %lld points needed their winding number, %lld differ from it "
                  "everywhere\n", (long long)wound, (long long)n, (long long)differ);
    assert_int_equal(differ, 0);
    free(ud);
    free(w);
    int64_t bad = 0;
    *checked = 0;
    for (int64_t i = 0; i < n; i++) {
        double a = analytic(k, p + i * dim);
        if (fabs(a) < margin)
            continue;
        if (center) {
            double r2 = 0;
            for (int j = 0; j < dim; j++)
                r2 += (p[i * dim + j] - center[j]) * (p[i * dim + j] - center[j]);
            if (sqrt(r2) < keep)
                continue;
        }
        (*checked)++;
        bad += (a < 0) != (sd[i] < 0);
    }
    free(p);
    free(sd);
    sm_sdf_free(d);
    return bad;
}

static void flip(sm_surface *s, int32_t f)
{
    int32_t t = s->facets[(size_t)f * s->dim];
    s->facets[(size_t)f * s->dim] = s->facets[(size_t)f * s->dim + 1];
    s->facets[(size_t)f * s->dim + 1] = t;
}

static void test_sign_orientation_mixes(void **state)
{
    (void)state;
    enum shape shapes[] = {SPHERE, TORUS, BOX, CIRCLE};
    for (int i = 0; i < 4; i++) {
        sm_surface *s = make_surface(shapes[i], shapes[i] == CIRCLE ? 0.05 : 0.15);
        /* all one way, all the other way, random mixes */
        for (int mix = 0; mix < 4; mix++) {
            for (int32_t f = 0; f < s->nfacets; f++)
                if (mix == 1 || (mix >= 2 && urand() < 0.5))
                    flip(s, f);
            int64_t checked, bad = sign_errors(s, shapes[i], 0.02, NULL, 0, &checked);
            print_message("# shape %d mix %d: %lld sign errors in %lld points\n", i, mix,
                          (long long)bad, (long long)checked);
            assert_int_equal(bad, 0);
            assert_true(checked > 1000);
        }
        sm_surface_free(s);
    }
}

/* removes (hole), duplicates (patch) or flips the facets near center */
static void damage(sm_surface *s, const double *center, double radius, int kind)
{
    int dim = s->dim;
    int32_t m = 0, n = s->nfacets;
    int32_t *keep = malloc(((size_t)n * 2 + 1) * dim * sizeof *keep);
    for (int32_t f = 0; f < n; f++) {
        const int32_t *v = s->facets + (size_t)f * dim;
        double r2 = 0;
        for (int j = 0; j < dim; j++) {
            double e = s->coords[(size_t)v[0] * dim + j] - center[j];
            r2 += e * e;
        }
        int near = sqrt(r2) < radius;
        if (near && kind == 0)
            continue;
        memcpy(keep + (size_t)m * dim, v, dim * sizeof *keep);
        m++;
        if (near && kind == 1) { /* a reversed duplicate */
            memcpy(keep + (size_t)m * dim, v, dim * sizeof *keep);
            int32_t t = keep[(size_t)m * dim];
            keep[(size_t)m * dim] = keep[(size_t)m * dim + 1];
            keep[(size_t)m * dim + 1] = t;
            m++;
        }
    }
    free(s->facets);
    free(s->facet_refs);
    s->facets = keep;
    s->facet_refs = calloc((size_t)m + 1, sizeof(int32_t));
    s->nfacets = m;
    if (kind == 2)
        for (int32_t f = 0; f < m; f++)
            if (urand() < 0.3)
                flip(s, f);
}

static void test_sign_defects(void **state)
{
    (void)state;
    enum shape shapes[] = {SPHERE, TORUS, BOX, CIRCLE};
    for (int i = 0; i < 4; i++) {
        for (int kind = 0; kind < 3; kind++) {
            sm_surface *s = make_surface(shapes[i], shapes[i] == CIRCLE ? 0.05 : 0.15);
            double c[3] = {1, 0, 0};
            if (shapes[i] == TORUS)
                c[0] = 1.4;
            double radius = 0.3;
            damage(s, c, radius, kind);
            sm_surface_health h;
            sm_error err;
            sm_error_clear(&err);
            sm_surface *t = s;
            int64_t checked, bad = sign_errors(t, shapes[i], 0.02, c, 2 * radius, &checked);
            assert_int_equal(sm_surface_repair(s, &h, &err), SM_OK);
            print_message("# shape %d defect %d: %lld facets, %lld open edges, %lld non-manifold, "
                          "%lld duplicates, %lld components: %lld sign errors in %lld points\n",
                          i, kind, (long long)s->nfacets, (long long)h.open_edges,
                          (long long)h.nonmanifold_edges, (long long)h.duplicates,
                          (long long)h.components, (long long)bad, (long long)checked);
            if (kind == 0)
                assert_true(h.open_edges > 0);
            if (kind == 1)
                assert_true(h.duplicates > 0);
            assert_int_equal(bad, 0);
            assert_true(checked > 500);
            sm_surface_free(s);
        }
    }
}

/* A surface that encloses nothing is an error, not a silent zero. */
static void test_encloses_nothing(void **state)
{
    (void)state;
    sm_surface *s;
    sm_error err;
    sm_error_clear(&err);
    assert_int_equal(sm_surface_alloc(&s, 3, 3, 1, &err), SM_OK);
    double x[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    memcpy(s->coords, x, sizeof x);
    for (int k = 0; k < 3; k++)
        s->facets[k] = k;
    sm_sdf *d;
    assert_int_equal(sm_sdf_new(s, &d, &err), SM_OK);
    double p[3] = {0.2, 0.2, 0.5}, out;
    assert_int_equal(sm_sdf_signed(d, 1, p, &out, &err), SM_ERR_INVALID);
    print_message("# %s\n", err.msg);
    assert_non_null(strstr(err.msg, "encloses nothing"));
    sm_sdf_free(d);
    sm_surface_free(s);
}

/* Sum of |element volume| (the Kuhn cells tile the box: no overlap, no
 * gap) and the longest edge of the elements whose centroid is within h/2
 * of the surface. */
static void graded_geometry(const sm_mesh *m, const sm_sdf *d, double *vol, double *near_edge,
                            double h)
{
    int dim = m->dim, n = dim + 1;
    double *c = calloc((size_t)m->nelems * dim, sizeof *c), *dc = malloc((size_t)m->nelems * sizeof *dc);
    double *longest = calloc((size_t)m->nelems, sizeof *longest);
    assert_true(c && dc && longest);
    *vol = 0;
    *near_edge = 0;
    for (int32_t e = 0; e < m->nelems; e++) {
        const double *x[4];
        double a[3][3];
        for (int j = 0; j < n; j++) {
            x[j] = m->coords + (size_t)m->elems[(size_t)e * n + j] * dim;
            for (int k = 0; k < dim; k++)
                c[(size_t)e * dim + k] += x[j][k] / n;
        }
        for (int j = 0; j < dim; j++)
            for (int k = 0; k < dim; k++)
                a[j][k] = x[j + 1][k] - x[0][k];
        double det = dim == 2 ? a[0][0] * a[1][1] - a[0][1] * a[1][0]
                              : a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) -
                                    a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0]) +
                                    a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
        *vol += fabs(det) / (dim == 2 ? 2 : 6);
        for (int i = 0; i < n; i++)
            for (int j = i + 1; j < n; j++)
                longest[e] = fmax(longest[e], sqrt(seg2(x[i], x[j], x[j], dim)));
    }
    sm_sdf_distance(d, m->nelems, c, dc, NULL);
    for (int32_t e = 0; e < m->nelems; e++)
        if (dc[e] < h / 2)
            *near_edge = fmax(*near_edge, longest[e]);
    free(c);
    free(dc);
    free(longest);
}

/* Max P1 error of the exact distance sampled at bg's vertices, at the
 * points pts (n) whose exact signed distance is exact. */
static double p1_error(const sm_sdf *d, sm_mesh *bg, int64_t n, const double *pts,
                       const double *exact)
{
    sm_error err;
    sm_error_clear(&err);
    double *val = malloc((size_t)bg->nverts * sizeof *val), *got = malloc((size_t)n * sizeof *got);
    sm_field *f = NULL;
    assert_non_null(val);
    assert_non_null(got);
    if (sm_sdf_signed(d, bg->nverts, bg->coords, val, &err) != SM_OK ||
        sm_mesh_build_boundary(bg, &err) != SM_OK || sm_field_new(bg, val, &f, &err) != SM_OK)
        fail_msg("%s", err.msg);
    sm_field_eval_many(f, n, pts, NULL, got);
    double worst = 0;
    for (int64_t i = 0; i < n; i++)
        worst = fmax(worst, fabs(got[i] - exact[i]));
    sm_field_free(f);
    free(val);
    free(got);
    return worst;
}

static void check_graded(enum shape k, double hs, double h)
{
    sm_surface *s = make_surface(k, hs);
    sm_error err;
    sm_error_clear(&err);
    assert_int_equal(sm_surface_repair(s, NULL, &err), SM_OK);
    sm_sdf *d;
    assert_int_equal(sm_sdf_new(s, &d, &err), SM_OK);
    int dim = s->dim;
    double lo[3] = {-1.5, -1.4, -1.3}, hi[3] = {1.5, 1.6, 1.4}, box = 1;
    for (int a = 0; a < dim; a++)
        box *= hi[a] - lo[a];
    sm_mesh *g = NULL, *u = NULL;
    if (sm_background_graded_new(dim, lo, hi, h, d, &g, &err) != SM_OK ||
        sm_background_new(dim, lo, hi, h, &u, &err) != SM_OK)
        fail_msg("%s", err.msg);
    double vol, near_edge;
    graded_geometry(g, d, &vol, &near_edge, h);
    printf("# graded %dD, size %g: %d vertices (uniform %d), near-surface edge %.3g\n", dim, h,
           g->nverts, u->nverts, near_edge);
    assert_true(fabs(vol - box) < 1e-9 * box);
    assert_true(near_edge > 0 && near_edge <= sqrt(dim) * h * (1 + 1e-9));
    assert_true(g->nverts * (dim == 2 ? 4 : 2) < u->nverts);
    /* points with |d| < h, exact signed distance there */
    int64_t n = 0, want = 4000;
    double *pts = malloc((size_t)want * dim * sizeof *pts), *ex = malloc((size_t)want * sizeof *ex);
    assert_non_null(pts);
    assert_non_null(ex);
    double *cand = malloc(4096 * 3 * sizeof *cand), cd[4096], cw[4096];
    assert_non_null(cand);
    while (n < want) {
        int nc = 0;
        while (nc < 4096) { /* candidates near the analytic surface */
            double *p = cand + nc * dim;
            for (int a = 0; a < dim; a++)
                p[a] = lo[a] + (hi[a] - lo[a]) * urand();
            nc += fabs(analytic(k, p)) <= h * 1.5;
        }
        sm_sdf_distance(d, nc, cand, cd, NULL);
        sm_sdf_winding(d, nc, cand, cw);
        for (int i = 0; i < nc && n < want; i++) {
            double dv = cw[i] > 0.5 ? -cd[i] : cd[i];
            if (fabs(dv) < h) {
                memcpy(pts + n * dim, cand + i * dim, dim * sizeof *pts);
                ex[n++] = dv;
            }
        }
    }
    free(cand);
    double eg = p1_error(d, g, n, pts, ex), eu = p1_error(d, u, n, pts, ex);
    printf("# P1 error of d at |d| < h: graded %.3g, uniform %.3g\n", eg, eu);
    assert_true(eg > 0 && eg <= 1.05 * eu);
    free(pts);
    free(ex);
    sm_mesh_free(g);
    sm_mesh_free(u);
    sm_sdf_free(d);
    sm_surface_free(s);
}

static void test_graded_background(void **state)
{
    (void)state;
    check_graded(CIRCLE, 0.02, 0.02);
    check_graded(SPHERE, 0.15, 0.06);
}

/* A size too fine for the box is refused before any count becomes an
 * integer (issue 28: 1e-300 shifted an int64_t out of range, undefined
 * behaviour the sanitizer build died of), in 2D and 3D, graded and not. */
static void test_background_tiny_size(void **state)
{
    (void)state;
    sm_surface *s = make_surface(SPHERE, 0.3);
    sm_error err;
    sm_sdf *d;
    assert_int_equal(sm_surface_repair(s, NULL, &err), SM_OK);
    assert_int_equal(sm_sdf_new(s, &d, &err), SM_OK);
    const double lo[3] = {-1, -1, -1}, hi[3] = {1, 1, 1};
    const double sizes[] = {1e-300, 1e-30, 1e-9, 5e-324};
    for (int dim = 2; dim <= 3; dim++)
        for (size_t i = 0; i < sizeof sizes / sizeof sizes[0]; i++) {
            sm_mesh *m = NULL;
            sm_error_clear(&err);
            assert_int_equal(sm_background_graded_new(dim, lo, hi, sizes[i], d, &m, &err),
                             SM_ERR_INVALID);
            assert_null(m);
            assert_non_null(strstr(err.msg, "--background-size"));
            sm_error_clear(&err);
            assert_int_equal(sm_background_new(dim, lo, hi, sizes[i], &m, &err), SM_ERR_INVALID);
            assert_null(m);
        }
    sm_sdf_free(d);
    sm_surface_free(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_distance_sphere),
        cmocka_unit_test(test_distance_torus),
        cmocka_unit_test(test_distance_box),
        cmocka_unit_test(test_distance_circle),
        cmocka_unit_test(test_sign_orientation_mixes),
        cmocka_unit_test(test_sign_defects),
        cmocka_unit_test(test_encloses_nothing),
        cmocka_unit_test(test_graded_background),
        cmocka_unit_test(test_background_tiny_size),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
