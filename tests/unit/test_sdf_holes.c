/* The sign of surfaces with holes (issue 21): after sm_surface_repair,
 * sm_sdf_signed's sign against the exact answer, at points farther than
 * twice the largest gap from the surface:
 *  - 2D: closed polylines written here — a star (r = 0.3 (1 + 0.25 cos 5t))
 *    and a non-convex horseshoe (an annular sector whose centroid lies
 *    outside it), centred away from the origin — with 1-5% of their edges
 *    removed at random, with every facet reversed at random (so the pieces
 *    between the gaps come out either way), and with overlaps (pieces
 *    extended over a neighbour's first edges); exact answer: even-odd
 *    point-in-polygon of the undamaged polygon, distances by brute force;
 *  - 3D: a Gmsh-made sphere stretched into an ellipsoid away from the
 *    origin, with bands of triangles removed that split it into four
 *    pieces, facets reversed at random; exact answer: the analytic
 *    ellipsoid, distances to the undamaged triangulation by brute force;
 *  - the health report: pieces turned over and facets flipped within a
 *    piece, against what the test did to the input. */
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

#include "shapematch/sm_sdf.h"
#include "shapematch/sm_surface.h"
#include "util_gmsh.h"

static uint64_t rng = 0x9e3779b97f4a7c15ull;
static double urand(void)
{
    rng ^= rng << 13;
    rng ^= rng >> 7;
    rng ^= rng << 17;
    return (double)(rng >> 11) / 9007199254740992.0;
}

/* ---- 2D ---- */

enum curve { STAR, HORSESHOE };

/* n points of the closed counter-clockwise polygon, centred at (cx, cy) */
static double *polygon(enum curve k, int n, double cx, double cy)
{
    double *p = malloc((size_t)n * 2 * sizeof *p);
    assert_non_null(p);
    if (k == STAR) {
        for (int i = 0; i < n; i++) {
            double t = 2 * M_PI * i / n, r = 0.3 * (1 + 0.25 * cos(5 * t));
            p[2 * i] = cx + r * cos(t);
            p[2 * i + 1] = cy + r * sin(t);
        }
        return p;
    }
    /* annular sector 30..330 degrees, radii 0.2 and 0.35: outer arc
     * counter-clockwise, a radial side, inner arc back, the other side;
     * points in proportion to the lengths */
    double a0 = M_PI / 6, a1 = 11 * M_PI / 6, ro = 0.35, ri = 0.2, w = ro - ri;
    double len[4] = {ro * (a1 - a0), w, ri * (a1 - a0), w}, total = 0;
    for (int s = 0; s < 4; s++)
        total += len[s];
    int m = 0;
    for (int s = 0; s < 4; s++) {
        int ns = s == 3 ? n - m : (int)lround(n * len[s] / total);
        for (int i = 0; i < ns; i++, m++) {
            double u = (double)i / ns, x, y;
            if (s == 0 || s == 2) {
                double a = s == 0 ? a0 + u * (a1 - a0) : a1 - u * (a1 - a0);
                double r = s == 0 ? ro : ri;
                x = r * cos(a);
                y = r * sin(a);
            } else {
                double a = s == 1 ? a1 : a0, r = s == 1 ? ro - u * w : ri + u * w;
                x = r * cos(a);
                y = r * sin(a);
            }
            p[2 * m] = cx + x;
            p[2 * m + 1] = cy + y;
        }
    }
    return p;
}

static int in_polygon(const double *p, int n, const double *q)
{
    int in = 0;
    for (int i = 0, j = n - 1; i < n; j = i++) {
        const double *a = p + 2 * i, *b = p + 2 * j;
        if ((a[1] > q[1]) != (b[1] > q[1]) &&
            q[0] < (b[0] - a[0]) * (q[1] - a[1]) / (b[1] - a[1]) + a[0])
            in = !in;
    }
    return in;
}

static double seg_dist(const double *p, const double *a, const double *b, int dim)
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
    return sqrt(d2);
}

static double polygon_dist(const double *p, int n, const double *q)
{
    double best = INFINITY;
    for (int i = 0; i < n; i++)
        best = fmin(best, seg_dist(q, p + 2 * i, p + 2 * ((i + 1) % n), 2));
    return best;
}

typedef struct damage2 {
    double drop;    /* fraction of edges removed */
    int reverse;    /* reverse each facet with probability 1/2 */
    int overlaps;   /* extend pieces over their neighbour's first edges */
} damage2;

/* The polygon as a surface with the damage done; *gap: the longest run
 * of removed edges (its length). */
static sm_surface *damaged_curve(const double *p, int n, damage2 dm, double *gap)
{
    uint8_t *gone = calloc((size_t)n, 1);
    assert_non_null(gone);
    int k = (int)lround(dm.drop * n);
    for (int r = 0; r < k;) {
        int i = (int)(urand() * n) % n;
        if (!gone[i]) {
            gone[i] = 1;
            r++;
        }
    }
    *gap = 0;
    for (int i = 0; i < n; i++) {
        double run = 0;
        for (int j = i; gone[j % n] && j < i + n; j++)
            run += seg_dist(p + 2 * (j % n), p + 2 * ((j + 1) % n), p + 2 * ((j + 1) % n), 2);
        *gap = fmax(*gap, run);
    }
    /* overlaps: after each gap, a copy of the next piece's first two edges
     * (own vertices, 1e-4 off the curve) starts one edge before the gap */
    int extra_v = 0, extra_f = 0;
    for (int i = 0; i < n && dm.overlaps; i++)
        if (gone[i] && !gone[(i + 1) % n] && !gone[(i + 2) % n] && i > 0 && !gone[i - 1]) {
            extra_v += 4;
            extra_f += 3;
        }
    sm_surface *s;
    sm_error err;
    sm_error_clear(&err);
    assert_int_equal(sm_surface_alloc(&s, 2, n + extra_v, n - k + extra_f, &err), SM_OK);
    memcpy(s->coords, p, (size_t)n * 2 * sizeof *p);
    int32_t f = 0, v = n;
    for (int i = 0; i < n; i++) {
        if (gone[i])
            continue;
        s->facets[2 * f] = i;
        s->facets[2 * f + 1] = (i + 1) % n;
        f++;
    }
    for (int i = 0; i < n && dm.overlaps; i++) {
        if (!(gone[i] && !gone[(i + 1) % n] && !gone[(i + 2) % n] && i > 0 && !gone[i - 1]))
            continue;
        /* vertices i-1 .. i+2, moved 1e-4 toward the inside (left) */
        for (int j = 0; j < 4; j++) {
            int a = (i - 1 + j) % n;
            const double *x = p + 2 * a, *y = p + 2 * ((a + 1) % n);
            double tx = y[0] - x[0], ty = y[1] - x[1], l = hypot(tx, ty);
            s->coords[2 * (v + j)] = x[0] - 1e-4 * ty / l;
            s->coords[2 * (v + j) + 1] = x[1] + 1e-4 * tx / l;
        }
        for (int j = 0; j < 3; j++) {
            s->facets[2 * f] = v + j;
            s->facets[2 * f + 1] = v + j + 1;
            f++;
        }
        v += 4;
    }
    assert_int_equal(f, s->nfacets);
    for (int32_t g = 0; g < s->nfacets && dm.reverse; g++)
        if (urand() < 0.5) {
            int32_t t = s->facets[2 * g];
            s->facets[2 * g] = s->facets[2 * g + 1];
            s->facets[2 * g + 1] = t;
        }
    free(gone);
    return s;
}

/* The exact answer on a grid over the polygon's padded box: the points,
 * their distance to the polygon and whether they are inside it. */
typedef struct grid2 {
    int64_t m;
    double *q, *dist;
    uint8_t *in;
} grid2;

static grid2 exact_grid(const double *p, int n)
{
    double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
    for (int i = 0; i < n; i++)
        for (int k = 0; k < 2; k++) {
            lo[k] = fmin(lo[k], p[2 * i + k]);
            hi[k] = fmax(hi[k], p[2 * i + k]);
        }
    int g = 90;
    grid2 x = {(int64_t)g * g, NULL, NULL, NULL};
    x.q = malloc((size_t)x.m * 2 * sizeof *x.q);
    x.dist = malloc((size_t)x.m * sizeof *x.dist);
    x.in = malloc((size_t)x.m);
    assert_true(x.q && x.dist && x.in);
    for (int i = 0; i < g; i++)
        for (int j = 0; j < g; j++) {
            double *q = x.q + 2 * (i * g + j);
            q[0] = lo[0] - 0.1 + (hi[0] - lo[0] + 0.2) * (i + 0.37) / g;
            q[1] = lo[1] - 0.1 + (hi[1] - lo[1] + 0.2) * (j + 0.61) / g;
            x.dist[i * g + j] = polygon_dist(p, n, q);
            x.in[i * g + j] = (uint8_t)in_polygon(p, n, q);
        }
    return x;
}

/* Sign errors at the grid points farther than margin from the polygon;
 * *checked: how many such points. */
static int64_t curve_sign_errors(sm_surface *s, const grid2 *x, double margin, int64_t *checked,
                                 sm_surface_health *h)
{
    sm_error err;
    sm_error_clear(&err);
    assert_int_equal(sm_surface_repair(s, h, &err), SM_OK);
    sm_sdf *d;
    assert_int_equal(sm_sdf_new(s, &d, &err), SM_OK);
    double *sd = malloc((size_t)x->m * sizeof *sd);
    assert_non_null(sd);
    if (sm_sdf_signed(d, x->m, x->q, sd, &err) != SM_OK)
        fail_msg("%s", err.msg);
    int64_t bad = 0;
    *checked = 0;
    for (int64_t i = 0; i < x->m; i++) {
        if (x->dist[i] <= margin)
            continue;
        (*checked)++;
        bad += x->in[i] != (sd[i] < 0);
    }
    free(sd);
    sm_sdf_free(d);
    return bad;
}

static void test_curves_with_gaps(void **state)
{
    (void)state;
    const int n = 2000;
    const double centers[2][2] = {{0.5, 0.5}, {-3.0, 7.0}};
    const damage2 kinds[] = {{0.01, 0, 0}, {0.03, 1, 0}, {0.05, 1, 0}, {0.02, 0, 1}, {0.04, 1, 1}};
    for (int k = STAR; k <= HORSESHOE; k++)
        for (int c = 0; c < 2; c++) {
            double *p = polygon((enum curve)k, n, centers[c][0], centers[c][1]);
            grid2 x = exact_grid(p, n);
            for (size_t i = 0; i < sizeof kinds / sizeof kinds[0]; i++)
                for (int trial = 0; trial < 2; trial++) {
                    double gap;
                    sm_surface *s = damaged_curve(p, n, kinds[i], &gap);
                    sm_surface_health h;
                    int64_t checked, bad = curve_sign_errors(s, &x, 2 * gap, &checked, &h);
                    print_message("# %s at (%g, %g), %.0f%% removed%s%s: gap %.2e, %lld pieces "
                                  "(%lld open), %lld turned, %lld flipped within; %lld sign "
                                  "errors in %lld points\n",
                                  k == STAR ? "star" : "horseshoe", centers[c][0], centers[c][1],
                                  100 * kinds[i].drop, kinds[i].reverse ? ", reversed" : "",
                                  kinds[i].overlaps ? ", overlaps" : "", gap,
                                  (long long)h.components, (long long)h.open_components,
                                  (long long)h.pieces_turned, (long long)h.reoriented_within,
                                  (long long)bad, (long long)checked);
                    assert_true(h.open_components > 1);
                    assert_true(checked > 3000);
                    assert_int_equal(bad, 0);
                    sm_surface_free(s);
                }
            free(x.q);
            free(x.dist);
            free(x.in);
            free(p);
        }
}

/* ---- 3D ---- */

static const double ell_axes[3] = {1.5, 1.0, 0.7}, ell_center[3] = {6.0, -4.0, 3.0};

/* unit-sphere coordinates of a point of the ellipsoid's frame */
static void to_unit(const double *x, double *u)
{
    for (int k = 0; k < 3; k++)
        u[k] = (x[k] - ell_center[k]) / ell_axes[k];
}

static double tri_dist(const double *p, const double *a, const double *b, const double *c)
{
    double u[3], v[3], w[3], nrm[3];
    for (int k = 0; k < 3; k++) {
        u[k] = b[k] - a[k];
        v[k] = c[k] - a[k];
        w[k] = p[k] - a[k];
    }
    nrm[0] = u[1] * v[2] - u[2] * v[1];
    nrm[1] = u[2] * v[0] - u[0] * v[2];
    nrm[2] = u[0] * v[1] - u[1] * v[0];
    double nn = nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2];
    double edges = fmin(seg_dist(p, a, b, 3), fmin(seg_dist(p, b, c, 3), seg_dist(p, c, a, 3)));
    if (nn == 0)
        return edges;
    double t = (w[0] * nrm[0] + w[1] * nrm[1] + w[2] * nrm[2]) / nn;
    double q[3] = {p[0] - t * nrm[0], p[1] - t * nrm[1], p[2] - t * nrm[2]};
    const double *P[3] = {a, b, c};
    for (int e = 0; e < 3; e++) {
        const double *x = P[e], *y = P[(e + 1) % 3];
        double xy[3] = {y[0] - x[0], y[1] - x[1], y[2] - x[2]};
        double xq[3] = {q[0] - x[0], q[1] - x[1], q[2] - x[2]};
        double m[3] = {xy[1] * xq[2] - xy[2] * xq[1], xy[2] * xq[0] - xy[0] * xq[2],
                       xy[0] * xq[1] - xy[1] * xq[0]};
        if (m[0] * nrm[0] + m[1] * nrm[1] + m[2] * nrm[2] < 0)
            return edges;
    }
    return fmin(fabs(t) * sqrt(nn), edges);
}

/* which band a triangle's centroid (unit-sphere frame) falls in, 0 none:
 * two latitude bands cut off two caps, two meridian cuts (x ~ 0) split
 * the belt between them in two */
static int in_band(const double *u, double w)
{
    if (fabs(u[2] - 0.35) < w / 2 || fabs(u[2] + 0.3) < w / 2)
        return 1;
    return fabs(u[0]) < w / 2 && u[2] > -0.3 && u[2] < 0.35;
}

static void test_ellipsoid_with_bands(void **state)
{
    (void)state;
    char dir[] = "/tmp/sm_holes_XXXXXX", path[64], msg[1024];
    assert_non_null(mkdtemp(dir));
    snprintf(path, sizeof path, "%s/s.mesh", dir);
    if (util_gmsh_write_format(UTIL_GMSH_UNIT_BALL, 2, 0.1, "mesh", 0, path, msg, sizeof msg) !=
        SM_OK)
        fail_msg("gmsh: %s", msg);
    sm_surface *full = NULL;
    sm_error err;
    sm_error_clear(&err);
    if (sm_surface_read(path, &full, &err) != SM_OK)
        fail_msg("%s", err.msg);
    unlink(path);
    rmdir(dir);
    for (int32_t i = 0; i < full->nverts; i++)
        for (int k = 0; k < 3; k++)
            full->coords[3 * i + k] = ell_center[k] + ell_axes[k] * full->coords[3 * i + k];
    const double w = 0.15; /* band width, unit-sphere frame */
    /* random points; far: farther than twice the widest band (in the
     * ellipsoid's frame) from the undamaged triangulation; in: inside the
     * analytic ellipsoid (the triangulation's chords are well within) */
    const double margin = 2 * w * ell_axes[0] + 0.05;
    const int64_t n = 3000;
    double *q = malloc((size_t)n * 3 * sizeof *q), *sd = malloc((size_t)n * sizeof *sd);
    uint8_t *far = malloc((size_t)n), *in = malloc((size_t)n);
    assert_true(q && sd && far && in);
    for (int64_t i = 0; i < n; i++) {
        for (int k = 0; k < 3; k++)
            q[3 * i + k] = ell_center[k] + (2 * urand() - 1) * (ell_axes[k] + 0.8);
        double best = INFINITY, u[3];
        for (int32_t f = 0; f < full->nfacets; f++) {
            const int32_t *v = full->facets + 3 * (size_t)f;
            best = fmin(best, tri_dist(q + 3 * i, full->coords + 3 * (size_t)v[0],
                                       full->coords + 3 * (size_t)v[1],
                                       full->coords + 3 * (size_t)v[2]));
        }
        to_unit(q + 3 * i, u);
        far[i] = best > margin;
        in[i] = u[0] * u[0] + u[1] * u[1] + u[2] * u[2] < 1;
    }
    for (int trial = 0; trial < 3; trial++) {
        sm_surface *s;
        assert_int_equal(sm_surface_alloc(&s, 3, full->nverts, full->nfacets, &err), SM_OK);
        memcpy(s->coords, full->coords, (size_t)full->nverts * 3 * sizeof *s->coords);
        int32_t m = 0;
        for (int32_t f = 0; f < full->nfacets; f++) {
            double c[3] = {0, 0, 0}, u[3];
            for (int j = 0; j < 3; j++)
                for (int k = 0; k < 3; k++)
                    c[k] += full->coords[3 * (size_t)full->facets[3 * f + j] + k] / 3;
            to_unit(c, u);
            if (in_band(u, w))
                continue;
            memcpy(s->facets + 3 * (size_t)m, full->facets + 3 * (size_t)f, 3 * sizeof(int32_t));
            if (trial > 0 && urand() < 0.5) {
                int32_t t = s->facets[3 * m];
                s->facets[3 * m] = s->facets[3 * m + 1];
                s->facets[3 * m + 1] = t;
            }
            m++;
        }
        s->nfacets = m;
        sm_surface_health h;
        assert_int_equal(sm_surface_repair(s, &h, &err), SM_OK);
        sm_sdf *d;
        assert_int_equal(sm_sdf_new(s, &d, &err), SM_OK);
        int64_t checked = 0, bad = 0;
        if (sm_sdf_signed(d, n, q, sd, &err) != SM_OK)
            fail_msg("%s", err.msg);
        for (int64_t i = 0; i < n; i++) {
            checked += far[i];
            bad += far[i] && in[i] != (sd[i] < 0);
        }
        print_message("# ellipsoid trial %d: %d of %d triangles, %lld pieces (%lld open), %lld "
                      "turned, %lld flipped within, %lld open edges: %lld sign errors in %lld "
                      "points\n", trial, s->nfacets, full->nfacets, (long long)h.components,
                      (long long)h.open_components, (long long)h.pieces_turned,
                      (long long)h.reoriented_within, (long long)h.open_edges, (long long)bad,
                      (long long)checked);
        assert_int_equal(h.components, 4);
        assert_int_equal(h.open_components, 4);
        assert_true(checked > 500);
        assert_int_equal(bad, 0);
        sm_sdf_free(d);
        sm_surface_free(s);
    }
    free(q);
    free(sd);
    free(far);
    free(in);
    sm_surface_free(full);
}

/* ---- the health report says what was done ---- */

/* A star cut into pieces, every facet outward, then whole pieces reversed
 * and a few single facets reversed inside other pieces: the report counts
 * exactly those pieces as turned and those facets as flipped within. */
static void test_report_counts(void **state)
{
    (void)state;
    const int n = 400;
    double *p = polygon(STAR, n, 0.5, 0.5);
    sm_surface *s;
    sm_error err;
    sm_error_clear(&err);
    /* edges 0..399 except 0, 100, 200, 300: four pieces of 99 edges */
    assert_int_equal(sm_surface_alloc(&s, 2, n, n - 4, &err), SM_OK);
    memcpy(s->coords, p, (size_t)n * 2 * sizeof *p);
    int32_t f = 0;
    for (int i = 0; i < n; i++)
        if (i % 100 != 0) {
            int rev = (i > 100 && i < 200) || (i > 300) || i == 50 || i == 251 || i == 252;
            s->facets[2 * f] = rev ? (i + 1) % n : i;
            s->facets[2 * f + 1] = rev ? i : (i + 1) % n;
            f++;
        }
    sm_surface_health h;
    assert_int_equal(sm_surface_repair(s, &h, &err), SM_OK);
    print_message("# report: %lld pieces, %lld open, %lld turned, %lld within, %lld reoriented\n",
                  (long long)h.components, (long long)h.open_components,
                  (long long)h.pieces_turned, (long long)h.reoriented_within,
                  (long long)h.reoriented);
    assert_int_equal(h.components, 4);
    assert_int_equal(h.open_components, 4);
    assert_int_equal(h.pieces_turned, 2);
    assert_int_equal(h.reoriented_within, 3);
    assert_int_equal(h.reoriented, 2 * 99 + 3);
    /* every facet now runs counter-clockwise (outward) */
    for (int32_t g = 0; g < s->nfacets; g++)
        assert_int_equal((s->facets[2 * g] + 1) % n, s->facets[2 * g + 1]);
    sm_surface_free(s);
    free(p);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_curves_with_gaps),
        cmocka_unit_test(test_ellipsoid_with_bands),
        cmocka_unit_test(test_report_counts),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
