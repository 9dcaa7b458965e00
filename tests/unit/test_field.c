/* The target field: point location against brute force (random points,
 * points exactly on vertices and facets, points outside), exact P1
 * reproduction of affine fields, the outside extension against an
 * analytic value (box backgrounds) and a brute-force nearest point
 * (non-convex and non-conforming backgrounds), hint independence, and
 * hostile inputs. */
#include <float.h>
#include <math.h>
#include <pthread.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>
#include <omp.h>

#include "shapematch/sm_field.h"
#include "shapematch/sm_mesh.h"
#include "util_gmsh.h"
#include "util_mesh.h"

/* ------------------------------------------------------------------ */
/* Reference computations, written independently of core/sm_field*.c   */

static double urand(uint64_t *s)
{
    *s ^= *s << 13;
    *s ^= *s >> 7;
    *s ^= *s << 17;
    return (double)(*s >> 11) * (1.0 / 9007199254740992.0);
}

static const double *vx(const sm_mesh *m, int32_t v)
{
    return m->coords + (size_t)v * m->dim;
}

static void cross3(const double *a, const double *b, double *c)
{
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}

static double dot(const double *a, const double *b, int d)
{
    double s = 0.0;
    for (int i = 0; i < d; i++)
        s += a[i] * b[i];
    return s;
}

/* Barycentric coordinates by Cramer's rule; 0 for a flat element. */
static int ref_bary(const sm_mesh *m, int32_t e, const double *x, double *lam)
{
    const int d = m->dim;
    const int32_t *ev = m->elems + (size_t)e * (d + 1);
    const double *p0 = vx(m, ev[0]);
    double a[3], b[3], c[3], y[3];
    for (int i = 0; i < d; i++) {
        a[i] = vx(m, ev[1])[i] - p0[i];
        b[i] = vx(m, ev[2])[i] - p0[i];
        y[i] = x[i] - p0[i];
        c[i] = d == 3 ? vx(m, ev[3])[i] - p0[i] : 0.0;
    }
    if (d == 2) {
        double det = a[0] * b[1] - a[1] * b[0];
        if (det == 0.0)
            return 0;
        lam[1] = (y[0] * b[1] - y[1] * b[0]) / det;
        lam[2] = (a[0] * y[1] - a[1] * y[0]) / det;
        lam[0] = 1.0 - lam[1] - lam[2];
    } else {
        double bc[3], yc[3], by[3];
        cross3(b, c, bc);
        double det = dot(a, bc, 3);
        if (det == 0.0)
            return 0;
        cross3(y, c, yc);
        cross3(b, y, by);
        lam[1] = dot(y, bc, 3) / det;
        lam[2] = dot(a, yc, 3) / det;
        lam[3] = dot(a, by, 3) / det;
        lam[0] = 1.0 - lam[1] - lam[2] - lam[3];
    }
    return 1;
}

static double min_of(const double *lam, int n)
{
    double m = lam[0];
    for (int i = 1; i < n; i++)
        m = lam[i] < m ? lam[i] : m;
    return m;
}

/* Exhaustive scans are the reference.  To keep them fast enough for 10^4
 * points, elements are sorted by the low x of their (inflated) bounding
 * box, so a scan only visits the slab of elements whose box can matter. */
typedef struct ref_mesh {
    const sm_mesh *m;
    int32_t n;      /* non-flat elements */
    int32_t *elem;  /* non-flat elements by increasing box lo[0] */
    double *box;    /* per entry of elem: lo then hi (dim each), inflated */
    double maxw;    /* widest box along x */
    uint8_t *used;  /* vertex of a non-flat element */
} ref_mesh;

static const sm_mesh *sort_mesh;
static double sort_key(int32_t e)
{
    const int d = sort_mesh->dim;
    double lo = INFINITY;
    for (int k = 0; k <= d; k++)
        lo = fmin(lo, vx(sort_mesh, sort_mesh->elems[(size_t)e * (d + 1) + k])[0]);
    return lo;
}
static int cmp_lo(const void *a, const void *b)
{
    double x = sort_key(*(const int32_t *)a), y = sort_key(*(const int32_t *)b);
    return (x > y) - (x < y);
}

static void ref_init(ref_mesh *r, const sm_mesh *m)
{
    const int d = m->dim;
    r->m = m;
    r->elem = malloc(sizeof(int32_t) * (size_t)m->nelems + 1);
    r->box = malloc(sizeof(double) * (size_t)m->nelems * 2 * d + 1);
    assert_true(r->box && r->elem);
    const double zero[3] = {0, 0, 0};
    r->n = 0;
    for (int32_t e = 0; e < m->nelems; e++) {
        double lam[4];
        if (ref_bary(m, e, zero, lam))
            r->elem[r->n++] = e;
    }
    sort_mesh = m;
    qsort(r->elem, (size_t)r->n, sizeof(int32_t), cmp_lo);
    r->maxw = 0.0;
    r->used = calloc((size_t)m->nverts + 1, 1);
    assert_non_null(r->used);
    for (int32_t j = 0; j < r->n; j++) {
        int32_t e = r->elem[j];
        for (int k = 0; k <= d; k++)
            r->used[m->elems[(size_t)e * (d + 1) + k]] = 1;
        double *lo = r->box + (size_t)j * 2 * d, *hi = lo + d;
        for (int i = 0; i < d; i++) {
            lo[i] = INFINITY;
            hi[i] = -INFINITY;
        }
        for (int k = 0; k <= d; k++)
            for (int i = 0; i < d; i++) {
                double c = vx(m, m->elems[(size_t)e * (d + 1) + k])[i];
                lo[i] = fmin(lo[i], c);
                hi[i] = fmax(hi[i], c);
            }
        for (int i = 0; i < d; i++) {
            double pad = 1e-6 * (hi[i] - lo[i]);
            lo[i] -= pad;
            hi[i] += pad;
        }
        r->maxw = fmax(r->maxw, hi[0] - lo[0]);
    }
}

static void ref_free(ref_mesh *r)
{
    free(r->box);
    free(r->elem);
    free(r->used);
}

/* First entry whose box lo[0] >= t. */
static int32_t ref_lower(const ref_mesh *r, double t)
{
    int32_t a = 0, b = r->n;
    while (a < b) {
        int32_t mid = a + (b - a) / 2;
        if (r->box[(size_t)mid * 2 * r->m->dim] < t)
            a = mid + 1;
        else
            b = mid;
    }
    return a;
}

/* Squared distance from x to the box of entry j. */
static double box_dist2(const ref_mesh *r, int32_t j, const double *x)
{
    const int d = r->m->dim;
    const double *lo = r->box + (size_t)j * 2 * d, *hi = lo + d;
    double s = 0.0;
    for (int i = 0; i < d; i++) {
        double t = x[i] < lo[i] ? lo[i] - x[i] : x[i] > hi[i] ? x[i] - hi[i] : 0.0;
        s += t * t;
    }
    return s;
}

/* Largest min-barycentric over the elements whose box holds x: >= 0 iff x
 * is in the mesh; -INFINITY when no box holds it (clearly outside). */
static double brute_depth(const ref_mesh *r, const double *x)
{
    double best = -INFINITY, lam[4];
    int32_t j1 = ref_lower(r, nextafter(x[0], INFINITY));
    for (int32_t j = ref_lower(r, x[0] - r->maxw); j < j1; j++)
        if (box_dist2(r, j, x) == 0.0 && ref_bary(r->m, r->elem[j], x, lam)) {
            double t = min_of(lam, r->m->dim + 1);
            if (t > best)
                best = t;
        }
    return best;
}

static void seg_closest(const double *x, const double *a, const double *b, int d, double *p)
{
    double ab[3] = {0, 0, 0}, ax[3] = {0, 0, 0};
    for (int i = 0; i < d; i++) {
        ab[i] = b[i] - a[i];
        ax[i] = x[i] - a[i];
    }
    double t = dot(ax, ab, d) / dot(ab, ab, d);
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    for (int i = 0; i < d; i++)
        p[i] = a[i] + t * ab[i];
}

static double dist(const double *a, const double *b, int d)
{
    double s = 0.0;
    for (int i = 0; i < d; i++)
        s += (a[i] - b[i]) * (a[i] - b[i]);
    return sqrt(s);
}

/* Closest point on a 3D triangle: projection on the plane when it falls
 * inside (signed sub-areas), else the best of the three edges. */
static void tri_closest(const double *x, const double *a, const double *b, const double *c,
                        double *p)
{
    double ab[3], ac[3], n[3], ax[3];
    for (int i = 0; i < 3; i++) {
        ab[i] = b[i] - a[i];
        ac[i] = c[i] - a[i];
        ax[i] = x[i] - a[i];
    }
    cross3(ab, ac, n);
    double nn = dot(n, n, 3), h = dot(ax, n, 3) / nn, q[3];
    for (int i = 0; i < 3; i++)
        q[i] = x[i] - h * n[i];
    const double *v[3] = {a, b, c};
    int inside = 1;
    for (int k = 0; k < 3; k++) {
        double e1[3], e2[3], cr[3];
        for (int i = 0; i < 3; i++) {
            e1[i] = v[(k + 1) % 3][i] - q[i];
            e2[i] = v[(k + 2) % 3][i] - q[i];
        }
        cross3(e1, e2, cr);
        if (dot(cr, n, 3) < 0)
            inside = 0;
    }
    if (inside) {
        memcpy(p, q, sizeof q);
        return;
    }
    double best = INFINITY, t[3];
    for (int k = 0; k < 3; k++) {
        seg_closest(x, v[k], v[(k + 1) % 3], 3, t);
        double dd = dist(x, t, 3);
        if (dd < best) {
            best = dd;
            memcpy(p, t, sizeof t);
        }
    }
}

/* Nearest point over every facet of every non-flat element (valid for x
 * outside all elements) and the P1 value there.  The nearest vertex
 * bounds the distance, which bounds the slab of elements to look at. */
static double brute_extension(const ref_mesh *r, const double *vals, const double *x,
                              double *nearest_dist)
{
    const sm_mesh *m = r->m;
    const int d = m->dim;
    double bound = INFINITY, lam[4];
    for (int32_t v = 0; v < m->nverts; v++)
        if (r->used[v])
            bound = fmin(bound, dist(x, vx(m, v), d));
    double best = INFINITY, best_val = NAN;
    int32_t j1 = ref_lower(r, nextafter(x[0] + bound, INFINITY));
    for (int32_t j = ref_lower(r, x[0] - bound - r->maxw); j < j1; j++) {
        if (box_dist2(r, j, x) > fmin(best, bound) * fmin(best, bound) * (1 + 1e-9))
            continue;
        int32_t e = r->elem[j];
        const int32_t *ev = m->elems + (size_t)e * (d + 1);
        for (int k = 0; k <= d; k++) {
            const double *fv[3];
            int n = 0;
            for (int i = 0; i <= d; i++)
                if (i != k)
                    fv[n++] = vx(m, ev[i]);
            double p[3];
            if (d == 2)
                seg_closest(x, fv[0], fv[1], 2, p);
            else
                tri_closest(x, fv[0], fv[1], fv[2], p);
            double dd = dist(x, p, d);
            if (dd < best) {
                best = dd;
                ref_bary(m, e, p, lam);
                best_val = 0.0;
                for (int i = 0; i <= d; i++)
                    best_val += lam[i] * vals[ev[i]];
            }
        }
    }
    *nearest_dist = best;
    return best_val;
}

/* ------------------------------------------------------------------ */
/* Point sets and fields                                               */

static double affine(const double *x, int d)
{
    return 0.7 - 1.3 * x[0] + 0.45 * x[1] + (d == 3 ? 2.1 * x[2] : 0.0);
}
static const double affine_grad[3] = {-1.3, 0.45, 2.1};

static double *affine_values(const sm_mesh *m)
{
    double *v = malloc(sizeof(double) * (size_t)m->nverts);
    assert_non_null(v);
    for (int32_t i = 0; i < m->nverts; i++)
        v[i] = affine(vx(m, i), m->dim);
    return v;
}

static void mesh_bbox(const sm_mesh *m, double *lo, double *hi)
{
    for (int i = 0; i < m->dim; i++) {
        lo[i] = INFINITY;
        hi[i] = -INFINITY;
    }
    for (int32_t v = 0; v < m->nverts; v++)
        for (int i = 0; i < m->dim; i++) {
            lo[i] = fmin(lo[i], vx(m, v)[i]);
            hi[i] = fmax(hi[i], vx(m, v)[i]);
        }
}

/* n points: 70% uniform in the bounding box grown by 15% per side, 10%
 * exact vertices, 10% exact edge midpoints, 10% random points of random
 * element facets (on the facet up to rounding). */
static double *test_points(const sm_mesh *m, int n, uint64_t seed)
{
    const int d = m->dim;
    double lo[3], hi[3];
    mesh_bbox(m, lo, hi);
    double *pts = malloc(sizeof(double) * (size_t)n * d);
    assert_non_null(pts);
    uint64_t s = seed | 1;
    for (int j = 0; j < n; j++) {
        double *x = pts + (size_t)j * d;
        int kind = j % 10;
        int32_t e = (int32_t)(urand(&s) * m->nelems);
        const int32_t *ev = m->elems + (size_t)e * (d + 1);
        if (kind < 7) {
            for (int i = 0; i < d; i++) {
                double w = hi[i] - lo[i];
                x[i] = lo[i] - 0.15 * w + 1.3 * w * urand(&s);
            }
        } else if (kind == 7) {
            memcpy(x, vx(m, ev[j % (d + 1)]), sizeof(double) * d);
        } else if (kind == 8) {
            const double *a = vx(m, ev[0]), *b = vx(m, ev[1 + j % d]);
            for (int i = 0; i < d; i++)
                x[i] = 0.5 * (a[i] + b[i]);
        } else {
            int skip = j % (d + 1);
            double w[4], ws = 0.0;
            for (int k = 0; k <= d; k++) {
                w[k] = k == skip ? 0.0 : urand(&s);
                ws += w[k];
            }
            for (int i = 0; i < d; i++) {
                x[i] = 0.0;
                for (int k = 0; k <= d; k++)
                    x[i] += w[k] / ws * vx(m, ev[k])[i];
            }
        }
    }
    return pts;
}

typedef struct check_counts {
    int inside, outside;
} check_counts;

/* Location of one point against brute force, bary coordinates reproducing
 * x, the value against P1 with the reference barycentrics of the element
 * found; outside: the extension against the brute-force nearest point
 * and, when box_lo != NULL, against the analytic value for a box. */
static void check_point(const ref_mesh *r, const double *vals, const sm_field *f,
                        const double *x, int32_t hint, const double *box_lo,
                        const double *box_hi, check_counts *cnt)
{
    const sm_mesh *m = r->m;
    const int d = m->dim;
    double bary[4] = {NAN, NAN, NAN, NAN}, lam[4];
    double scale = 0.0;
    for (int i = 0; i < d; i++)
        scale += fabs(x[i]);
    scale = 1.0 + scale;
    int32_t e = sm_field_locate(f, x, hint, bary);
    double depth = brute_depth(r, x);
    if (e >= 0) {
        assert_true(e < m->nelems);
        assert_true(ref_bary(m, e, x, lam));
        if (min_of(lam, d + 1) < -1e-9) {
            print_error("element %d does not contain (%g %g): min bary %g\n", e, x[0], x[1],
                        min_of(lam, d + 1));
            fail();
        }
        double sum = 0.0, y[3] = {0, 0, 0};
        const int32_t *ev = m->elems + (size_t)e * (d + 1);
        for (int k = 0; k <= d; k++) {
            sum += bary[k];
            for (int i = 0; i < d; i++)
                y[i] += bary[k] * vx(m, ev[k])[i];
        }
        assert_true(fabs(sum - 1.0) < 1e-12);
        for (int i = 0; i < d; i++)
            assert_true(fabs(y[i] - x[i]) < 1e-12 * scale);
        double ref = 0.0;
        for (int k = 0; k <= d; k++)
            ref += lam[k] * vals[ev[k]];
        double got = sm_field_eval(f, x, NULL);
        if (fabs(got - ref) > 1e-12 * (1.0 + fabs(ref))) {
            print_error("P1 value %.17g, expected %.17g\n", got, ref);
            fail();
        }
        cnt->inside++;
    } else {
        if (depth >= -1e-11) {
            print_error("(%.17g %.17g %.17g) not located, brute-force depth %g\n", x[0], x[1],
                        d == 3 ? x[2] : 0.0, depth);
            fail();
        }
        double bd, bval = brute_extension(r, vals, x, &bd);
        double got = sm_field_eval(f, x, NULL);
        double expected = bval + bd;
        assert_true(bd > 0.0);
        assert_true(got > bval);
        if (fabs(got - expected) > 1e-10 * (1.0 + fabs(expected))) {
            print_error("extension %.17g, expected %.17g (nearest at %g)\n", got, expected, bd);
            fail();
        }
        double p[3], fd;
        assert_true(sm_field_nearest(f, x, p, &fd) >= 0);
        assert_true(fabs(fd - bd) < 1e-12 * scale);
        assert_true(fabs(dist(x, p, d) - bd) < 1e-12 * scale);
        if (box_lo) {
            double c[3] = {0, 0, 0};
            for (int i = 0; i < d; i++)
                c[i] = x[i] < box_lo[i] ? box_lo[i] : x[i] > box_hi[i] ? box_hi[i] : x[i];
            double exact = affine(c, d) + dist(x, c, d);
            if (fabs(got - exact) > 1e-12 * (1.0 + fabs(exact))) {
                print_error("box extension %.17g, analytic %.17g\n", got, exact);
                fail();
            }
        }
        cnt->outside++;
    }
}

static void check_points(const sm_mesh *m, const double *vals, int n, uint64_t seed,
                         const double *box_lo, const double *box_hi)
{
    sm_error err;
    sm_field *f = NULL;
    assert_int_equal(sm_field_new(m, vals, &f, &err), SM_OK);
    assert_int_equal(sm_field_dim(f), m->dim);
    double *pts = test_points(m, n, seed);
    check_counts cnt = {0, 0};
    ref_mesh r;
    ref_init(&r, m);
    uint64_t s = seed * 7 + 1;
    for (int j = 0; j < n; j++) {
        /* no hint, a random hint, or an invalid one */
        int32_t hint = j % 3 == 0 ? -1 : j % 3 == 1 ? (int32_t)(urand(&s) * m->nelems) : m->nelems + 5;
        check_point(&r, vals, f, pts + (size_t)j * m->dim, hint, box_lo, box_hi, &cnt);
    }
    ref_free(&r);
    /* the sample is meaningful: both kinds well represented */
    assert_true(cnt.inside > n / 4);
    assert_true(cnt.outside > n / 50);
    free(pts);
    sm_field_free(f);
}

/* ------------------------------------------------------------------ */
/* Structured boxes with offset, non-unit bounding boxes                */

static void test_box2d_offset(void **state)
{
    (void)state;
    const double lo[2] = {-3, 2}, hi[2] = {5, 2.5};
    sm_mesh *m = util_box_mesh(2, 40, lo, hi, 11); /* mixed orientations */
    assert_non_null(m);
    double *v = affine_values(m);
    check_points(m, v, 10000, 0x1234, lo, hi);

    sm_field *f = NULL;
    sm_error err;
    assert_int_equal(sm_field_new(m, v, &f, &err), SM_OK);
    sm_field_stats st;
    sm_field_get_stats(f, &st);
    /* the grid covers the real box, not [0,1]^2, with cells of about the
     * right count and shape (the box is 16:1) */
    assert_true(fabs(st.lo[0] + 3) < 1e-6 && fabs(st.hi[0] - 5) < 1e-6);
    assert_true(fabs(st.lo[1] - 2) < 1e-6 && fabs(st.hi[1] - 2.5) < 1e-6);
    assert_true(st.ncells >= m->nelems / 2 && st.ncells <= 4 * m->nelems);
    assert_true(st.grid[0] > 8 * st.grid[1]);
    assert_int_equal(st.nboundary_facets, 4 * 40);
    assert_int_equal(st.ndegenerate, 0);
    /* gradient: inside the P1 gradient; outside across the face x = 5 the
     * unit normal plus the tangential part */
    double x[2] = {1.0, 2.2}, g[2];
    int32_t hint = -1;
    double val = sm_field_eval_grad(f, x, &hint, g);
    assert_true(fabs(val - affine(x, 2)) < 1e-12);
    assert_true(fabs(g[0] - affine_grad[0]) < 1e-12 && fabs(g[1] - affine_grad[1]) < 1e-12);
    x[0] = 5.5;
    val = sm_field_eval_grad(f, x, &hint, g);
    double c[2] = {5.0, 2.2};
    assert_true(fabs(val - (affine(c, 2) + 0.5)) < 1e-12);
    assert_true(fabs(g[0] - 1.0) < 1e-12 && fabs(g[1] - affine_grad[1]) < 1e-12);
    assert_true(hint >= 0 && hint < m->nelems);
    /* nearest point: x itself inside, the clamped point outside */
    double p[2], nd;
    const double in[2] = {-2.5, 2.49};
    assert_true(sm_field_nearest(f, in, p, &nd) >= 0);
    assert_true(nd == 0.0 && p[0] == in[0] && p[1] == in[1]);
    const double out[2] = {-4.0, 1.0};
    assert_true(sm_field_nearest(f, out, p, &nd) >= 0);
    assert_true(fabs(p[0] + 3) < 1e-14 && fabs(p[1] - 2) < 1e-14 && fabs(nd - sqrt(2)) < 1e-14);
    sm_field_free(f);
    free(v);
    sm_mesh_free(m);
}

static void test_box3d_offset(void **state)
{
    (void)state;
    const double lo[3] = {-1, 0.5, 10}, hi[3] = {2, 1, 11};
    sm_mesh *m = util_box_mesh(3, 10, lo, hi, 5);
    assert_non_null(m);
    double *v = affine_values(m);
    check_points(m, v, 10000, 0x5678, lo, hi);
    free(v);
    sm_mesh_free(m);
}

/* Random vertex values (not affine): location and P1 value against the
 * reference barycentrics on an unshuffled box. */
static void test_box_random_values(void **state)
{
    (void)state;
    for (int d = 2; d <= 3; d++) {
        const double lo[3] = {0.25, -7, 3}, hi[3] = {0.5, -6, 3.5};
        sm_mesh *m = util_box_mesh(d, d == 2 ? 30 : 8, lo, hi, 0);
        double *v = malloc(sizeof(double) * m->nverts);
        uint64_t s = 99;
        for (int32_t i = 0; i < m->nverts; i++)
            v[i] = urand(&s) - 0.5;
        check_points(m, v, 4000, 0x9abc + d, NULL, NULL);
        free(v);
        sm_mesh_free(m);
    }
}

/* ------------------------------------------------------------------ */
/* Non-convex, non-conforming, degenerate                               */

/* Copy of m without the elements whose centroid is within r of c: a box
 * with a hole (2D) or a cavity (3D), and many non-convex boundary parts. */
static sm_mesh *drill(const sm_mesh *m, const double *c, double r)
{
    const int d = m->dim;
    sm_mesh *out = NULL;
    assert_int_equal(sm_mesh_alloc(&out, d, m->nverts, m->nelems, 0, NULL), SM_OK);
    memcpy(out->coords, m->coords, sizeof(double) * m->nverts * d);
    int32_t ne = 0;
    for (int32_t e = 0; e < m->nelems; e++) {
        double g[3] = {0, 0, 0};
        for (int k = 0; k <= d; k++)
            for (int i = 0; i < d; i++)
                g[i] += vx(m, m->elems[e * (d + 1) + k])[i] / (d + 1);
        if (dist(g, c, d) < r)
            continue;
        memcpy(out->elems + (size_t)ne * (d + 1), m->elems + (size_t)e * (d + 1),
               sizeof(int32_t) * (d + 1));
        ne++;
    }
    out->nelems = ne;
    return out;
}

static void test_hole(void **state)
{
    (void)state;
    for (int d = 2; d <= 3; d++) {
        const double lo[3] = {0, 0, 0}, hi[3] = {2, 1, 1};
        sm_mesh *box = util_box_mesh(d, d == 2 ? 30 : 10, lo, hi, 3);
        const double c[3] = {1.0, 0.5, 0.5};
        sm_mesh *m = drill(box, c, 0.3);
        assert_true(m->nelems < box->nelems * 95 / 100);
        double *v = malloc(sizeof(double) * m->nverts);
        for (int32_t i = 0; i < m->nverts; i++)
            v[i] = dist(vx(m, i), c, d) - 0.3; /* signed distance, roughly */
        check_points(m, v, d == 2 ? 10000 : 6000, 0xdef0 + d, NULL, NULL);
        /* the center of the hole is outside, its value grows with depth */
        sm_field *f = NULL;
        sm_error err;
        assert_int_equal(sm_field_new(m, v, &f, &err), SM_OK);
        assert_int_equal(sm_field_locate(f, c, -1, NULL), -1);
        double p[3], nd;
        assert_true(sm_field_nearest(f, c, p, &nd) >= 0);
        assert_true(nd > 0.1 && nd < 0.4);
        assert_true(fabs(sm_field_eval(f, c, NULL) - (sm_field_eval(f, p, NULL) + nd)) < 1e-12);
        sm_field_free(f);
        free(v);
        sm_mesh_free(m);
        sm_mesh_free(box);
    }
}

/* Concatenation of two overlapping box meshes with unrelated vertices, plus
 * flat elements (repeated vertex, collinear/coplanar vertices). */
static sm_mesh *overlap_mesh(int d)
{
    const double lo1[3] = {0, 0, 0}, hi1[3] = {1, 1, 1};
    const double lo2[3] = {0.55, 0.3, 0.2}, hi2[3] = {1.45, 1.3, 0.9};
    sm_mesh *a = util_box_mesh(d, d == 2 ? 20 : 6, lo1, hi1, 1);
    sm_mesh *b = util_box_mesh(d, d == 2 ? 17 : 5, lo2, hi2, 2);
    int nflat = 3;
    sm_mesh *m = NULL;
    assert_int_equal(sm_mesh_alloc(&m, d, a->nverts + b->nverts,
                                   a->nelems + b->nelems + nflat, 0, NULL),
                     SM_OK);
    memcpy(m->coords, a->coords, sizeof(double) * a->nverts * d);
    memcpy(m->coords + (size_t)a->nverts * d, b->coords, sizeof(double) * b->nverts * d);
    size_t na = (size_t)a->nelems * (d + 1);
    memcpy(m->elems, a->elems, sizeof(int32_t) * na);
    for (size_t i = 0; i < (size_t)b->nelems * (d + 1); i++)
        m->elems[na + i] = b->elems[i] + a->nverts;
    int32_t *fl = m->elems + (size_t)(a->nelems + b->nelems) * (d + 1);
    /* repeated vertex */
    for (int k = 0; k <= d; k++)
        fl[k] = k == d ? 0 : k;
    /* vertices 0, 1, 2 of the first box lie on the line y = 0 (and z = 0) */
    for (int k = 0; k <= d; k++)
        fl[d + 1 + k] = k < 3 ? k : 3;
    /* a flat element spanning both meshes: three collinear vertices */
    for (int k = 0; k <= d; k++)
        fl[2 * (d + 1) + k] = k < 3 ? 5 + k : 5;
    sm_mesh_free(a);
    sm_mesh_free(b);
    return m;
}

static void test_nonconforming(void **state)
{
    (void)state;
    for (int d = 2; d <= 3; d++) {
        sm_mesh *m = overlap_mesh(d);
        double *v = affine_values(m);
        check_points(m, v, d == 2 ? 10000 : 5000, 0x4242 + d, NULL, NULL);
        sm_field *f = NULL;
        sm_error err;
        assert_int_equal(sm_field_new(m, v, &f, &err), SM_OK);
        sm_field_stats st;
        sm_field_get_stats(f, &st);
        assert_int_equal(st.ndegenerate, 3);
        /* a hint on a flat element is ignored, not divided by */
        double x[3] = {0.3, 0.4, 0.5};
        int32_t hint = m->nelems - 1;
        double val = sm_field_eval(f, x, &hint);
        assert_true(fabs(val - affine(x, d)) < 1e-12);
        assert_true(hint >= 0 && hint < m->nelems - 3);
        sm_field_free(f);
        free(v);
        sm_mesh_free(m);
    }
}

/* Folded pairs: elements sharing a facet from the same side (an inverted
 * element in a deformed background).  The shared facet is on the
 * boundary of the union, so the outside search must keep it. */
static void test_folded(void **state)
{
    (void)state;
    for (int d = 2; d <= 3; d++) {
        sm_mesh *m = NULL;
        assert_int_equal(sm_mesh_alloc(&m, d, d + 2, 2, 0, NULL), SM_OK);
        /* unit simplex, and a smaller one on the same facet x_last = 0 */
        for (int k = 0; k <= d; k++)
            for (int i = 0; i < d; i++)
                m->coords[k * d + i] = (k == i + 1) ? 1.0 : 0.0;
        for (int i = 0; i < d; i++)
            m->coords[(d + 1) * d + i] = 0.2;
        /* facet opposite vertex d (the last axis) is shared */
        for (int k = 0; k <= d; k++) {
            m->elems[k] = k;
            m->elems[d + 1 + k] = k == d ? d + 1 : k;
        }
        double *v = affine_values(m);
        check_points(m, v, 3000, 0x777 + d, NULL, NULL);
        /* just beyond the shared facet: its nearest point is on it */
        sm_field *f = NULL;
        sm_error err;
        assert_int_equal(sm_field_new(m, v, &f, &err), SM_OK);
        double x[3] = {0.3, 0.2, 0.2}, p[3], nd;
        x[d - 1] = -0.25;
        assert_true(sm_field_nearest(f, x, p, &nd) >= 0);
        assert_true(fabs(nd - 0.25) < 1e-14);
        sm_field_free(f);
        free(v);
        sm_mesh_free(m);
    }
}

/* ------------------------------------------------------------------ */
/* Unstructured meshes from Gmsh                                       */

/* Meshes geo_text with gmsh (shared helper) and reads the result. */
static sm_mesh *gmsh_mesh(const char *geo_text, int dim, double clmax)
{
    sm_mesh *m = NULL;
    char msg[512];
    sm_status st = util_gmsh_mesh(geo_text, dim, clmax, &m, msg, sizeof msg);
    if (st != SM_OK)
        print_error("gmsh: %s\n", msg);
    assert_int_equal(st, SM_OK);
    assert_int_equal(m->dim, dim);
    return m;
}

/* Plate [-1,2]x[0.5,2.5] with a circular hole: non-convex, offset box. */
static void test_gmsh_plate_with_hole(void **state)
{
    (void)state;
    sm_mesh *m = gmsh_mesh("SetFactory(\"OpenCASCADE\");\n"
                           "Rectangle(1) = {-1, 0.5, 0, 3, 2};\n"
                           "Disk(2) = {0.5, 1.5, 0, 0.5, 0.5};\n"
                           "BooleanDifference{ Surface{1}; Delete; }{ Surface{2}; Delete; }\n",
                           2, 0.08);
    assert_true(m->nelems > 1000);
    double *v = affine_values(m);
    check_points(m, v, 10000, 0x2d2d, NULL, NULL);
    /* signed distance to the hole's circle: P1 against the reference */
    const double c[2] = {0.5, 1.5};
    for (int32_t i = 0; i < m->nverts; i++)
        v[i] = 0.5 - dist(vx(m, i), c, 2);
    check_points(m, v, 3000, 0x2d2e, NULL, NULL);
    free(v);
    sm_mesh_free(m);
}

/* Unit cube with a spherical cavity: non-convex, unstructured tetrahedra. */
static void test_gmsh_cube_with_cavity(void **state)
{
    (void)state;
    sm_mesh *m = gmsh_mesh("SetFactory(\"OpenCASCADE\");\n"
                           "Box(1) = {0, 0, 0, 1, 1, 1};\n"
                           "Sphere(2) = {0.5, 0.5, 0.5, 0.25};\n"
                           "BooleanDifference{ Volume{1}; Delete; }{ Volume{2}; Delete; }\n",
                           3, 0.12);
    assert_true(m->nelems > 1000);
    double *v = affine_values(m);
    check_points(m, v, 10000, 0x3d3d, NULL, NULL);
    sm_field *f = NULL;
    sm_error err;
    assert_int_equal(sm_field_new(m, v, &f, &err), SM_OK);
    sm_field_stats st;
    sm_field_get_stats(f, &st);
    /* boundary facets found by the adjacency = the file's boundary */
    assert_int_equal(st.nboundary_facets, m->nfacets);
    sm_field_free(f);
    free(v);
    sm_mesh_free(m);
}

/* Points far from a round background (disk, ball), where the nearest
 * point search has to leave the grid rings for the facet tree (the
 * extension through the coarse rings first, the warp's sm_field_nearest
 * directly), and points close to it: both against brute force. */
static void check_far(const sm_mesh *m, double half_width, int n, uint64_t seed)
{
    double *v = affine_values(m);
    sm_field *f = NULL;
    sm_error err;
    assert_int_equal(sm_field_new(m, v, &f, &err), SM_OK);
    ref_mesh r;
    ref_init(&r, m);
    check_counts cnt = {0, 0};
    uint64_t s = seed;
    for (int j = 0; j < n; j++) {
        double x[3] = {0, 0, 0};
        double w = j % 2 ? half_width : 1.2;
        for (int i = 0; i < m->dim; i++)
            x[i] = w * (2 * urand(&s) - 1);
        check_point(&r, v, f, x, j % 3 ? -1 : 0, NULL, NULL, &cnt);
    }
    assert_true(cnt.outside > n / 2);
    ref_free(&r);
    sm_field_free(f);
    free(v);
}

static void test_far_points(void **state)
{
    (void)state;
    const double c[2] = {0, 0};
    sm_mesh *disk = util_disk_mesh(c, 1.0, 20);
    check_far(disk, 5.0, 3000, 31);
    check_far(disk, 100.0, 1000, 43);
    sm_mesh_free(disk);
    sm_mesh *ball = gmsh_mesh(UTIL_GMSH_UNIT_BALL, 3, 0.25);
    check_far(ball, 5.0, 1500, 37);
    check_far(ball, 100.0, 600, 41); /* every point far: the tree */
    sm_mesh_free(ball);
}

/* ------------------------------------------------------------------ */
/* Hints                                                               */

static void test_hint_path(void **state)
{
    (void)state;
    for (int d = 2; d <= 3; d++) {
        const double lo[3] = {-1, -1, -1}, hi[3] = {1, 1, 1};
        sm_mesh *m = util_box_mesh(d, d == 2 ? 50 : 12, lo, hi, 9);
        double *v = malloc(sizeof(double) * m->nverts);
        for (int32_t i = 0; i < m->nverts; i++)
            v[i] = dist(vx(m, i), lo + 0, 0) + sin(3 * vx(m, i)[0]) * vx(m, i)[1];
        sm_field *f = NULL;
        sm_error err;
        assert_int_equal(sm_field_new(m, v, &f, &err), SM_OK);
        double x[3] = {0, 0, 0};
        int32_t hint = -1, walked = 0, outside = 0;
        for (int step = 0; step < 20000; step++) {
            /* a Lissajous curve with small steps that leaves the box and
             * comes back */
            double t = 0.004 * step;
            for (int i = 0; i < d; i++)
                x[i] = 1.05 * sin((1.0 + 0.37 * i) * t + 0.5 * i);
            int32_t before = hint;
            double with_hint = sm_field_eval(f, x, &hint);
            double without = sm_field_eval(f, x, NULL);
            assert_true(isfinite(with_hint));
            if (fabs(with_hint - without) > 1e-13 * (1 + fabs(without))) {
                print_error("step %d: %.17g with hint, %.17g without\n", step, with_hint, without);
                fail();
            }
            int32_t e = sm_field_locate(f, x, before, NULL);
            if (e >= 0) {
                assert_int_equal(e, hint);
                walked += before != e;
            } else {
                outside++;
            }
        }
        assert_true(walked > 500);
        assert_true(outside > 100);
        sm_field_free(f);
        free(v);
        sm_mesh_free(m);
    }
}

/* Concurrent evaluation: the field is read-only, so threads evaluating the
 * same path (each with its own hints) get exactly the serial values. */
typedef struct eval_job {
    const sm_field *f;
    const double *pts;
    int n, dim;
    double *out;
} eval_job;

static void *eval_path(void *arg)
{
    eval_job *job = arg;
    int32_t hint = -1;
    for (int j = 0; j < job->n; j++)
        job->out[j] = sm_field_eval(job->f, job->pts + (size_t)j * job->dim, &hint);
    return NULL;
}

static void test_concurrent(void **state)
{
    (void)state;
    const double c[3] = {0.5, 0.5, 0.5}, lo[3] = {0, 0, 0}, hi[3] = {1, 1, 1};
    sm_mesh *box = util_box_mesh(3, 8, lo, hi, 4);
    sm_mesh *m = drill(box, c, 0.3);
    double *v = affine_values(m);
    sm_field *f = NULL;
    sm_error err;
    assert_int_equal(sm_field_new(m, v, &f, &err), SM_OK);
    enum { NPTS = 4000, NTHREADS = 4 };
    double *pts = malloc(sizeof(double) * NPTS * 3);
    for (int j = 0; j < NPTS; j++)
        for (int i = 0; i < 3; i++)
            pts[3 * j + i] = 0.5 + 0.6 * sin(0.01 * j * (1 + 0.3 * i) + i);
    double *serial = malloc(sizeof(double) * NPTS);
    eval_job ref = {f, pts, NPTS, 3, serial};
    eval_path(&ref);
    pthread_t th[NTHREADS];
    eval_job jobs[NTHREADS];
    double *outs[NTHREADS];
    for (int t = 0; t < NTHREADS; t++) {
        outs[t] = malloc(sizeof(double) * NPTS);
        jobs[t] = (eval_job){f, pts, NPTS, 3, outs[t]};
        assert_int_equal(pthread_create(&th[t], NULL, eval_path, &jobs[t]), 0);
    }
    for (int t = 0; t < NTHREADS; t++) {
        assert_int_equal(pthread_join(th[t], NULL), 0);
        assert_memory_equal(outs[t], serial, sizeof(double) * NPTS);
        free(outs[t]);
    }
    free(serial);
    free(pts);
    sm_field_free(f);
    free(v);
    sm_mesh_free(m);
    sm_mesh_free(box);
}

/* ------------------------------------------------------------------ */
/* Hostile inputs                                                      */

static void test_hostile(void **state)
{
    (void)state;
    sm_error err;
    sm_field *f = (sm_field *)&err; /* must be reset to NULL on error */
    const double lo[2] = {0, 0}, hi[2] = {1, 1};

    sm_mesh *empty = NULL;
    assert_int_equal(sm_mesh_alloc(&empty, 2, 0, 0, 0, NULL), SM_OK);
    double none = 0;
    assert_int_equal(sm_field_new(empty, &none, &f, &err), SM_ERR_INVALID);
    assert_null(f);
    assert_non_null(strstr(err.msg, "empty"));
    sm_mesh_free(empty);

    sm_mesh *m = util_box_mesh(2, 4, lo, hi, 0);
    double *v = affine_values(m);
    assert_int_equal(sm_field_new(NULL, v, &f, &err), SM_ERR_INVALID);
    assert_int_equal(sm_field_new(m, NULL, &f, &err), SM_ERR_INVALID);

    v[7] = NAN;
    assert_int_equal(sm_field_new(m, v, &f, &err), SM_ERR_INVALID);
    assert_null(f);
    assert_non_null(strstr(err.msg, "vertex 8"));
    assert_non_null(strstr(err.msg, "not finite"));
    v[7] = INFINITY;
    assert_int_equal(sm_field_new(m, v, &f, &err), SM_ERR_INVALID);
    v[7] = 0.0;

    m->coords[3] = NAN;
    assert_int_equal(sm_field_new(m, v, &f, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "coordinate"));
    m->coords[3] = 0.25;

    int32_t saved = m->elems[5];
    m->elems[5] = m->nverts;
    assert_int_equal(sm_field_new(m, v, &f, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "element 2"));
    m->elems[5] = -1;
    assert_int_equal(sm_field_new(m, v, &f, &err), SM_ERR_INVALID);
    m->elems[5] = saved;

    m->dim = 4;
    assert_int_equal(sm_field_new(m, v, &f, &err), SM_ERR_INVALID);
    m->dim = 2;

    /* all elements flat */
    sm_mesh *flat = NULL;
    assert_int_equal(sm_mesh_alloc(&flat, 3, 4, 2, 0, NULL), SM_OK);
    for (int i = 0; i < 4; i++) {
        flat->coords[3 * i] = i;
        flat->coords[3 * i + 1] = 2 * i;
    }
    for (int i = 0; i < 8; i++)
        flat->elems[i] = i % 4;
    double fv[4] = {0, 0, 0, 0};
    assert_int_equal(sm_field_new(flat, fv, &f, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "degenerate"));
    sm_mesh_free(flat);

    /* a good field, hostile queries: never NaN, never a crash */
    assert_int_equal(sm_field_new(m, v, &f, &err), SM_OK);
    const double bad[][2] = {{NAN, 0.5}, {0.5, INFINITY}, {-INFINITY, NAN}, {1e300, -1e300},
                             {1e160, 0.5}, {-1e-300, 0.5}, {DBL_MAX, 0}, {0.5, -DBL_MAX}};
    for (size_t j = 0; j < sizeof bad / sizeof bad[0]; j++) {
        const int32_t hints[] = {-1, 0, 3, m->nelems - 1, m->nelems, -7, INT32_MAX};
        for (size_t h = 0; h < sizeof hints / sizeof hints[0]; h++) {
            int32_t hint = hints[h];
            double g[2];
            double val = sm_field_eval(f, bad[j], &hint);
            assert_false(isnan(val));
            assert_true(val > 0.0);
            assert_true(hint == hints[h] || (hint >= 0 && hint < m->nelems));
            val = sm_field_eval_grad(f, bad[j], NULL, g);
            assert_false(isnan(val) || isnan(g[0]) || isnan(g[1]));
            int32_t e = sm_field_locate(f, bad[j], hints[h], NULL);
            assert_true(e == -1 || (bad[j][0] == -1e-300 && e >= 0));
        }
    }
    /* huge but finite: the exact extension where it is representable */
    const double far[2] = {1e9, 0.5}, edge[2] = {1.0, 0.5};
    double val = sm_field_eval(f, far, NULL);
    assert_true(fabs(val - (affine(edge, 2) + (1e9 - 1.0))) < 1e-6);
    sm_field_free(f);
    free(v);
    sm_mesh_free(m);
}

/* One huge element over many tiny ones (overlapping): the grid must stay
 * bounded and location exact. */
static void test_hostile_sizes(void **state)
{
    (void)state;
    const double lo[2] = {0, 0}, hi[2] = {1, 1};
    sm_mesh *small = util_box_mesh(2, 60, lo, hi, 0);
    sm_mesh *m = NULL;
    assert_int_equal(sm_mesh_alloc(&m, 2, small->nverts + 3, small->nelems + 1, 0, NULL), SM_OK);
    memcpy(m->coords, small->coords, sizeof(double) * small->nverts * 2);
    memcpy(m->elems, small->elems, sizeof(int32_t) * small->nelems * 3);
    double *c = m->coords + (size_t)small->nverts * 2;
    c[0] = -1e4; c[1] = -1e4; c[2] = 3e4; c[3] = -1e4; c[4] = -1e4; c[5] = 3e4;
    int32_t *t = m->elems + (size_t)small->nelems * 3;
    t[0] = small->nverts; t[1] = small->nverts + 1; t[2] = small->nverts + 2;
    double *v = affine_values(m);
    sm_field *f = NULL;
    sm_error err;
    assert_int_equal(sm_field_new(m, v, &f, &err), SM_OK);
    sm_field_stats st;
    sm_field_get_stats(f, &st);
    assert_true(st.ncells <= 4 * (int64_t)m->nelems);
    assert_true(st.elem_entries <= 40 * (int64_t)m->nelems);
    ref_mesh r;
    ref_init(&r, m);
    uint64_t s = 5;
    for (int j = 0; j < 3000; j++) {
        double x[2];
        /* mostly in the small mesh's box, some anywhere in the big one */
        double w = j % 4 ? 1.2 : 4e4;
        x[0] = (j % 4 ? -0.1 : -1e4) + w * urand(&s);
        x[1] = (j % 4 ? -0.1 : -1e4) + w * urand(&s);
        double bary[3];
        int32_t e = sm_field_locate(f, x, -1, bary);
        double depth = brute_depth(&r, x);
        if (depth >= -1e-11)
            assert_true(e >= 0);
        if (e >= 0) {
            double lam[3];
            assert_true(ref_bary(m, e, x, lam));
            assert_true(min_of(lam, 3) >= -1e-9);
            assert_true(fabs(sm_field_eval(f, x, NULL) - affine(x, 2)) < 1e-9 * (1 + fabs(affine(x, 2))));
        }
    }
    ref_free(&r);
    sm_field_free(f);
    free(v);
    sm_mesh_free(m);
    sm_mesh_free(small);
}

/* ------------------------------------------------------------------ */
/* Numbering, shared facets, threads                                   */

/* Copy of m with its vertices and elements in a random order (as mesh
 * generators write them); each element keeps its local vertex order.
 * new_elem[e] is the index of element e of m in the copy. */
static sm_mesh *renumbered(const sm_mesh *m, uint64_t seed, int32_t *new_elem)
{
    const int d = m->dim;
    sm_mesh *r = NULL;
    assert_int_equal(sm_mesh_alloc(&r, d, m->nverts, m->nelems, 0, NULL), SM_OK);
    int32_t *new_vert = malloc(sizeof(int32_t) * (size_t)m->nverts);
    assert_non_null(new_vert);
    uint64_t s = seed | 1;
    for (int32_t v = 0; v < m->nverts; v++)
        new_vert[v] = v;
    for (int32_t v = m->nverts - 1; v > 0; v--) {
        int32_t w = (int32_t)(urand(&s) * (v + 1)), t = new_vert[v];
        new_vert[v] = new_vert[w];
        new_vert[w] = t;
    }
    for (int32_t e = 0; e < m->nelems; e++)
        new_elem[e] = e;
    for (int32_t e = m->nelems - 1; e > 0; e--) {
        int32_t w = (int32_t)(urand(&s) * (e + 1)), t = new_elem[e];
        new_elem[e] = new_elem[w];
        new_elem[w] = t;
    }
    for (int32_t v = 0; v < m->nverts; v++)
        memcpy(r->coords + (size_t)new_vert[v] * d, vx(m, v), sizeof(double) * d);
    for (int32_t e = 0; e < m->nelems; e++)
        for (int k = 0; k <= d; k++)
            r->elems[(size_t)new_elem[e] * (d + 1) + k] = new_vert[m->elems[(size_t)e * (d + 1) + k]];
    free(new_vert);
    return r;
}

static double wavy(const double *x, int d)
{
    return sin(3.0 * x[0]) * cos(2.0 * x[1]) + (d == 3 ? 0.5 * x[2] * x[2] : 0.0);
}

/* A box mesh and the same mesh in random order, large enough for the
 * facet matching to split its buckets twice: both find every interior
 * facet (the boundary is the box's), locate the same elements and give
 * bitwise the same values inside (same element records), and the
 * renumbered one agrees with brute force. */
static void test_renumbered(void **state)
{
    (void)state;
    for (int d = 2; d <= 3; d++) {
        const double lo[3] = {-2, 1, 5}, hi[3] = {1, 2.5, 6};
        const int n = d == 2 ? 66 : 16;
        sm_mesh *m = util_box_mesh(d, n, lo, hi, 7);
        assert_true(m->nverts > 4096);
        int32_t *new_elem = malloc(sizeof(int32_t) * (size_t)m->nelems);
        assert_non_null(new_elem);
        sm_mesh *r = renumbered(m, 0xabcdef + d, new_elem);
        double *vm = malloc(sizeof(double) * m->nverts), *vr = malloc(sizeof(double) * r->nverts);
        assert_true(vm && vr);
        for (int32_t v = 0; v < m->nverts; v++)
            vm[v] = wavy(vx(m, v), d);
        for (int32_t v = 0; v < r->nverts; v++)
            vr[v] = wavy(vx(r, v), d);
        sm_field *fm = NULL, *fr = NULL;
        sm_error err;
        assert_int_equal(sm_field_new(m, vm, &fm, &err), SM_OK);
        assert_int_equal(sm_field_new(r, vr, &fr, &err), SM_OK);
        sm_field_stats sm, sr;
        sm_field_get_stats(fm, &sm);
        sm_field_get_stats(fr, &sr);
        int32_t expected = d == 2 ? 4 * n : 12 * n * n;
        assert_int_equal(sm.nboundary_facets, expected);
        assert_int_equal(sr.nboundary_facets, expected);
        assert_int_equal(sr.ndegenerate, 0);
        uint64_t s = 77 + d;
        int32_t hm = -1, hr = -1;
        for (int j = 0; j < 20000; j++) {
            double x[3] = {0, 0, 0};
            for (int i = 0; i < d; i++)
                x[i] = lo[i] + (hi[i] - lo[i]) * (1.2 * urand(&s) - 0.1);
            int32_t em = sm_field_locate(fm, x, -1, NULL), er = sm_field_locate(fr, x, -1, NULL);
            assert_true((em < 0) == (er < 0));
            if (em >= 0)
                assert_int_equal(new_elem[em], er);
            /* outside, the nearest point may be shared by facets whose
             * order differs: the same value up to rounding */
            double a = sm_field_eval(fm, x, &hm), b = sm_field_eval(fr, x, &hr);
            if (em >= 0 ? a != b : fabs(a - b) > 1e-14 * (1 + fabs(a))) {
                print_error("(%g %g %g): %.17g ordered, %.17g renumbered\n", x[0], x[1], x[2], a, b);
                fail();
            }
        }
        check_points(r, vr, 2000, 0x5151 + d, NULL, NULL);
        sm_field_free(fm);
        sm_field_free(fr);
        free(vm);
        free(vr);
        free(new_elem);
        sm_mesh_free(m);
        sm_mesh_free(r);
    }
}

/* Three elements on one facet (two on the same side): a non-manifold
 * facet links none of them, so it stays a boundary facet of each, and
 * location still agrees with brute force. */
static void test_nonmanifold_facet(void **state)
{
    (void)state;
    for (int d = 2; d <= 3; d++) {
        sm_mesh *m = NULL;
        assert_int_equal(sm_mesh_alloc(&m, d, d + 3, 3, 0, NULL), SM_OK);
        /* the facet: the unit simplex of the plane x_last = 0 */
        for (int k = 0; k < d; k++)
            for (int i = 0; i < d; i++)
                m->coords[k * d + i] = (i == k - 1) ? 1.0 : 0.0;
        const double apex_z[3] = {0.8, 0.4, -0.6};
        for (int a = 0; a < 3; a++) {
            double *p = m->coords + (size_t)(d + a) * d;
            for (int i = 0; i < d - 1; i++)
                p[i] = 0.2 + 0.1 * a;
            p[d - 1] = apex_z[a];
            for (int k = 0; k < d; k++)
                m->elems[a * (d + 1) + k] = k;
            m->elems[a * (d + 1) + d] = d + a;
        }
        double *v = affine_values(m);
        sm_field *f = NULL;
        sm_error err;
        assert_int_equal(sm_field_new(m, v, &f, &err), SM_OK);
        sm_field_stats st;
        sm_field_get_stats(f, &st);
        assert_int_equal(st.nboundary_facets, 3 * (d + 1));
        sm_field_free(f);
        check_points(m, v, 3000, 0x3e3e + d, NULL, NULL);
        free(v);
        sm_mesh_free(m);
    }
}

/* The construction runs on the OpenMP threads; the structure, hence every
 * answer, must not depend on their number. */
static void test_threads(void **state)
{
    (void)state;
    const double c[3] = {0.5, 0.5, 0.5}, lo[3] = {0, 0, 0}, hi[3] = {1, 1, 1};
    sm_mesh *box = util_box_mesh(3, 12, lo, hi, 3);
    sm_mesh *meshes[2] = {drill(box, c, 0.3), overlap_mesh(3)};
    int saved = omp_get_max_threads();
    for (int mi = 0; mi < 2; mi++) {
        const sm_mesh *m = meshes[mi];
        double *v = malloc(sizeof(double) * m->nverts);
        assert_non_null(v);
        for (int32_t i = 0; i < m->nverts; i++)
            v[i] = wavy(vx(m, i), 3);
        enum { NPTS = 5000 };
        double *pts = test_points(m, NPTS, 0x7e7e + mi);
        double ref_val[NPTS];
        int32_t ref_elem[NPTS];
        sm_field_stats ref_st;
        for (int threads = 1; threads <= 3; threads++) {
            omp_set_num_threads(threads);
            sm_field *f = NULL;
            sm_error err;
            assert_int_equal(sm_field_new(m, v, &f, &err), SM_OK);
            sm_field_stats st;
            sm_field_get_stats(f, &st);
            int32_t hint = -1;
            for (int j = 0; j < NPTS; j++) {
                const double *x = pts + (size_t)j * 3;
                int32_t e = sm_field_locate(f, x, -1, NULL);
                double val = sm_field_eval(f, x, &hint);
                if (threads == 1) {
                    ref_elem[j] = e;
                    ref_val[j] = val;
                } else {
                    assert_int_equal(e, ref_elem[j]);
                    assert_memory_equal(&val, &ref_val[j], sizeof val);
                }
            }
            if (threads == 1)
                ref_st = st;
            else
                assert_memory_equal(&st, &ref_st, sizeof st);
            sm_field_free(f);
        }
        free(pts);
        free(v);
    }
    omp_set_num_threads(saved);
    sm_mesh_free(meshes[0]);
    sm_mesh_free(meshes[1]);
    sm_mesh_free(box);
}

/* sm_field_eval_many against sm_field_eval one point at a time: the same
 * values and the same hints, bitwise, over inside, outside and on-facet
 * points, good, stale, invalid and far hints, non-finite points, and no
 * hints at all; several successive passes, as in a descent. */
static void test_eval_many(void **state)
{
    (void)state;
    for (int d = 2; d <= 3; d++) {
        const double lo[3] = {0, 0, 0}, hi[3] = {1, 1, 1}, c[3] = {0.5, 0.5, 0.5};
        sm_mesh *box = util_box_mesh(d, d == 2 ? 40 : 10, lo, hi, 5);
        sm_mesh *m = drill(box, c, 0.25);
        double *v = malloc(sizeof(double) * m->nverts);
        assert_non_null(v);
        for (int32_t i = 0; i < m->nverts; i++)
            v[i] = wavy(vx(m, i), d);
        sm_field *f = NULL;
        sm_error err;
        assert_int_equal(sm_field_new(m, v, &f, &err), SM_OK);
        enum { NPTS = 3001 };
        double *pts = test_points(m, NPTS, 0x6e6e + d);
        int32_t h1[NPTS], h2[NPTS];
        double v1[NPTS], v2[NPTS];
        uint64_t s = 99 + d;
        for (int j = 0; j < NPTS; j++) {
            int kind = j % 5;
            h1[j] = kind == 0 ? -1 : kind == 1 ? m->nelems + 3 : (int32_t)(urand(&s) * m->nelems);
            h2[j] = h1[j];
        }
        pts[7 * d] = NAN;
        pts[11 * d + d - 1] = INFINITY;
        for (int pass = 0; pass < 3; pass++) {
            for (int j = 0; j < NPTS; j++)
                v1[j] = sm_field_eval(f, pts + (size_t)j * d, &h1[j]);
            sm_field_eval_many(f, NPTS, pts, h2, v2);
            assert_memory_equal(h1, h2, sizeof h1);
            assert_memory_equal(v1, v2, sizeof v1);
            /* the next pass starts from moved points */
            for (int j = 0; j < NPTS * d; j++)
                if (isfinite(pts[j]))
                    pts[j] += 0.02 * (urand(&s) - 0.5);
        }
        sm_field_eval_many(f, NPTS, pts, NULL, v2);
        for (int j = 0; j < NPTS; j++) {
            double ref = sm_field_eval(f, pts + (size_t)j * d, NULL);
            assert_memory_equal(&ref, &v2[j], sizeof ref);
        }
        sm_field_eval_many(f, 0, pts, h2, v2);
        free(pts);
        sm_field_free(f);
        free(v);
        sm_mesh_free(m);
        sm_mesh_free(box);
    }
}

/* sm_field_eval_points (Morton order, each walk from its predecessor's
 * element) against sm_field_eval one point at a time without a hint, on
 * a drilled box (a hole: points outside the mesh too) with a NaN point;
 * the hints it returns locate their points, and a second call with 1 and
 * 2 threads gives the same values. */
static void test_eval_points(void **state)
{
    (void)state;
    for (int d = 2; d <= 3; d++) {
        const double lo[3] = {0, 0, 0}, hi[3] = {1, 1, 1}, c[3] = {0.5, 0.5, 0.5};
        sm_mesh *box = util_box_mesh(d, d == 2 ? 40 : 10, lo, hi, 5);
        sm_mesh *m = drill(box, c, 0.25);
        double *v = malloc(sizeof(double) * m->nverts);
        for (int32_t i = 0; i < m->nverts; i++)
            v[i] = wavy(vx(m, i), d);
        sm_field *f = NULL;
        sm_error err;
        assert_int_equal(sm_field_new(m, v, &f, &err), SM_OK);
        enum { NPTS = 9001 };
        double *pts = test_points(m, NPTS, 0x7e7e + d);
        pts[5 * d] = NAN;
        int32_t *hints = malloc(NPTS * sizeof *hints);
        double *got = malloc(NPTS * sizeof *got), *again = malloc(NPTS * sizeof *again);
        sm_field_eval_points(f, NPTS, pts, hints, got);
        for (int j = 0; j < NPTS; j++) {
            double ref = sm_field_eval(f, pts + (size_t)j * d, NULL);
            if (isinf(ref)) {
                assert_true(isinf(got[j]));
                continue;
            }
            assert_true(fabs(got[j] - ref) <= 1e-12 * (1 + fabs(ref)));
            double bary[4];
            if (sm_field_locate(f, pts + (size_t)j * d, -1, bary) >= 0) /* inside */
                assert_int_equal(sm_field_locate(f, pts + (size_t)j * d, hints[j], NULL), hints[j]);
        }
        int threads = omp_get_max_threads();
        omp_set_num_threads(threads > 1 ? 1 : 2);
        sm_field_eval_points(f, NPTS, pts, NULL, again);
        omp_set_num_threads(threads);
        assert_memory_equal(got, again, NPTS * sizeof *got);
        free(hints);
        free(got);
        free(again);
        free(pts);
        sm_field_free(f);
        free(v);
        sm_mesh_free(m);
        sm_mesh_free(box);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_box2d_offset),
        cmocka_unit_test(test_box3d_offset),
        cmocka_unit_test(test_box_random_values),
        cmocka_unit_test(test_hole),
        cmocka_unit_test(test_nonconforming),
        cmocka_unit_test(test_folded),
        cmocka_unit_test(test_gmsh_plate_with_hole),
        cmocka_unit_test(test_gmsh_cube_with_cavity),
        cmocka_unit_test(test_far_points),
        cmocka_unit_test(test_hint_path),
        cmocka_unit_test(test_concurrent),
        cmocka_unit_test(test_hostile),
        cmocka_unit_test(test_hostile_sizes),
        cmocka_unit_test(test_renumbered),
        cmocka_unit_test(test_nonmanifold_facet),
        cmocka_unit_test(test_threads),
        cmocka_unit_test(test_eval_many),
        cmocka_unit_test(test_eval_points),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
