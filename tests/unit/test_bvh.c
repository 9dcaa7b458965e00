/* run.sh: seconds 3 */
/* The facet hierarchy's nearest-facet search (sm_bvh.h) against an
 * exhaustive pass over every facet with the same point-facet distance:
 *  - the same bits (the search is exact, not within a tolerance: the
 *    two-sided measure's figures rest on it) and a facet at that
 *    distance, for random points near the surface (the measure's case:
 *    a facet's point moved off by 1e-6 to 1e-2), inside and around its
 *    box, far away, and exactly on vertices;
 *  - for the tree with the winding number's moments (sm__bvh_build) and
 *    the one without (sm__bvh_build_boxes): the same answer and the
 *    same facet (the same boxes, visited in the same order);
 *  - seeded with a random facet (the descent's hints): the same distance;
 *  - after the vertices moved and the tree was refitted (sm__bvh_refit):
 *    the exhaustive pass's answer at the new positions;
 *  - on a bumpy closed sphere, a random triangle soup with degenerate
 *    triangles (a repeated vertex, collinear corners), and a 2D closed
 *    polyline. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sm_bvh.h"

#define QUERIES 3000

static uint64_t rng_state = 0x9e3779b97f4a7c15ull;

/* Uniform in [0, 1) (xorshift64*: reproducible on every platform). */
static double uniform(void)
{
    rng_state ^= rng_state >> 12;
    rng_state ^= rng_state << 25;
    rng_state ^= rng_state >> 27;
    return (double)((rng_state * 0x2545f4914f6cdd1dull) >> 11) / 9007199254740992.0;
}

typedef struct owned_surface {
    sm_surface s;
    double *coords;
    int32_t *facets;
} owned_surface;

static void own(owned_surface *o, int dim, int32_t nverts, int32_t nfacets)
{
    o->coords = calloc((size_t)nverts * dim, sizeof *o->coords);
    o->facets = calloc((size_t)nfacets * dim, sizeof *o->facets);
    assert_non_null(o->coords);
    assert_non_null(o->facets);
    o->s = (sm_surface){.dim = dim, .nverts = nverts, .coords = o->coords, .nfacets = nfacets,
                        .facets = o->facets, .facet_refs = NULL};
}

static void disown(owned_surface *o)
{
    free(o->coords);
    free(o->facets);
}

/* A UV sphere of radius 0.4 about (0.5, 0.5, 0.5), its radius varied by
 * bumps of 5% (nonconvex, facets of many shapes). */
static void bumpy_sphere(owned_surface *o)
{
    const int nt = 30, np = 60;
    own(o, 3, 2 + (nt - 1) * np, 2 * np * (nt - 1));
    double *x = o->coords;
    int32_t nv = 0;
    x[3 * nv + 0] = 0.5, x[3 * nv + 1] = 0.5, x[3 * nv + 2] = 0.9, nv++;
    for (int i = 1; i < nt; i++)
        for (int j = 0; j < np; j++) {
            double th = M_PI * i / nt, ph = 2 * M_PI * j / np;
            double r = 0.4 * (1 + 0.05 * sin(5 * th) * cos(3 * ph));
            x[3 * nv + 0] = 0.5 + r * sin(th) * cos(ph);
            x[3 * nv + 1] = 0.5 + r * sin(th) * sin(ph);
            x[3 * nv + 2] = 0.5 + r * cos(th);
            nv++;
        }
    x[3 * nv + 0] = 0.5, x[3 * nv + 1] = 0.5, x[3 * nv + 2] = 0.1, nv++;
    int32_t *f = o->facets, nf = 0;
#define RING(i, j) (1 + ((i) - 1) * np + ((j) % np))
    for (int j = 0; j < np; j++) {
        f[3 * nf] = 0, f[3 * nf + 1] = RING(1, j), f[3 * nf + 2] = RING(1, j + 1), nf++;
        f[3 * nf] = nv - 1, f[3 * nf + 1] = RING(nt - 1, j + 1), f[3 * nf + 2] = RING(nt - 1, j),
        nf++;
    }
    for (int i = 1; i < nt - 1; i++)
        for (int j = 0; j < np; j++) {
            f[3 * nf] = RING(i, j), f[3 * nf + 1] = RING(i + 1, j), f[3 * nf + 2] = RING(i + 1, j + 1);
            nf++;
            f[3 * nf] = RING(i, j), f[3 * nf + 1] = RING(i + 1, j + 1), f[3 * nf + 2] = RING(i, j + 1);
            nf++;
        }
#undef RING
    assert_int_equal(nv, o->s.nverts);
    assert_int_equal(nf, o->s.nfacets);
}

/* Random small triangles in the unit cube, one in ten degenerate (a
 * repeated vertex or three collinear corners). */
static void soup(owned_surface *o)
{
    const int32_t n = 600;
    own(o, 3, 3 * n, n);
    for (int32_t f = 0; f < n; f++) {
        double *a = o->coords + 9 * (size_t)f;
        for (int k = 0; k < 3; k++)
            a[k] = uniform();
        for (int v = 1; v < 3; v++)
            for (int k = 0; k < 3; k++)
                a[3 * v + k] = a[k] + 0.1 * (uniform() - 0.5);
        if (f % 20 == 0)
            memcpy(a + 6, a + 3, 3 * sizeof *a);
        else if (f % 20 == 10)
            for (int k = 0; k < 3; k++)
                a[6 + k] = a[k] + 2.5 * (a[3 + k] - a[k]);
        for (int v = 0; v < 3; v++)
            o->facets[3 * (size_t)f + v] = 3 * f + v;
    }
}

/* A closed star-shaped polyline about (0.5, 0.5) in 2D. */
static void polyline(owned_surface *o)
{
    const int32_t n = 400;
    own(o, 2, n, n);
    for (int32_t i = 0; i < n; i++) {
        double t = 2 * M_PI * i / n, r = 0.3 + 0.1 * sin(7 * t);
        o->coords[2 * i] = 0.5 + r * cos(t);
        o->coords[2 * i + 1] = 0.5 + r * sin(t);
        o->facets[2 * i] = i;
        o->facets[2 * i + 1] = (i + 1) % n;
    }
}

/* A query point: near a random facet (its point moved off by 1e-6 to
 * 1e-2 in each coordinate), anywhere around the surface, far away, or
 * on a vertex. */
static void query(const sm_surface *s, int i, double *p)
{
    const int dim = s->dim;
    p[0] = p[1] = p[2] = 0;
    int kind = i % 4;
    if (kind == 0 || kind == 3) {
        int32_t f = (int32_t)(uniform() * s->nfacets);
        const int32_t *v = s->facets + (size_t)f * dim;
        double w[3] = {uniform(), uniform(), dim == 3 ? uniform() : 0}, sw = w[0] + w[1] + w[2];
        for (int k = 0; k < dim; k++) {
            for (int j = 0; j < dim; j++)
                p[k] += w[j] / sw * s->coords[(size_t)v[j] * dim + k];
            if (kind == 0)
                p[k] += pow(10, -6 + 4 * uniform()) * (uniform() - 0.5);
        }
        if (kind == 3) /* exactly on a corner */
            memcpy(p, s->coords + (size_t)v[i % dim] * dim, (size_t)dim * sizeof *p);
    } else if (kind == 1) {
        for (int k = 0; k < dim; k++)
            p[k] = 1.6 * uniform() - 0.3;
    } else {
        for (int k = 0; k < dim; k++)
            p[k] = 1e3 * (uniform() - 0.5);
    }
}

/* Every query answered by each tree as by the exhaustive pass. */
static void check_against_all(const sm_bvh *a, const sm_bvh *b)
{
    const sm_surface *s = a->s;
    int depth = a->depth > b->depth ? a->depth : b->depth;
    sm_bvh_entry *stack = malloc((2 * (size_t)depth + 2) * sizeof *stack);
    assert_non_null(stack);
    for (int i = 0; i < QUERIES; i++) {
        double p[3];
        query(s, i, p);
        double all = INFINITY;
        for (int32_t f = 0; f < s->nfacets; f++) {
            double d2 = sm__bvh_facet_dist2(a, f, p);
            all = d2 < all ? d2 : all;
        }
        int32_t ha = -1, hb = -1, hs = (int32_t)(uniform() * s->nfacets);
        double da = sm__bvh_nearest(a, p, &ha, stack);
        double db = sm__bvh_nearest(b, p, &hb, stack);
        double ds = sm__bvh_nearest(a, p, &hs, stack);
        assert_true(da == sqrt(all));
        assert_true(db == da);
        assert_true(ds == da);
        assert_int_equal(ha, hb);
        assert_true(sm__bvh_facet_dist2(a, ha, p) == all);
        assert_true(sm__bvh_facet_dist2(a, hs, p) == all);
    }
    free(stack);
}

static void check_surface(owned_surface *o)
{
    sm_error err;
    sm_bvh with_moments, boxes;
    assert_int_equal(sm__bvh_build(&o->s, &with_moments, &err), SM_OK);
    assert_int_equal(sm__bvh_build_boxes(&o->s, &boxes, &err), SM_OK);
    assert_int_equal(with_moments.nnodes, boxes.nnodes);
    for (int32_t n = 0; n < boxes.nnodes; n++) {
        assert_memory_equal(with_moments.nodes[n].lo, boxes.nodes[n].lo, sizeof boxes.nodes[n].lo);
        assert_memory_equal(with_moments.nodes[n].hi, boxes.nodes[n].hi, sizeof boxes.nodes[n].hi);
    }
    check_against_all(&with_moments, &boxes);
    /* the vertices move (as the descent's boundary does) and both trees
     * are refitted to them */
    for (int64_t i = 0; i < (int64_t)o->s.nverts * o->s.dim; i++)
        o->coords[i] += 0.02 * (uniform() - 0.5);
    sm__bvh_refit(&with_moments);
    sm__bvh_refit(&boxes);
    check_against_all(&with_moments, &boxes);
    sm__bvh_free(&with_moments);
    sm__bvh_free(&boxes);
}

static void test_sphere(void **state)
{
    (void)state;
    owned_surface o;
    bumpy_sphere(&o);
    check_surface(&o);
    disown(&o);
}

static void test_soup(void **state)
{
    (void)state;
    owned_surface o;
    soup(&o);
    check_surface(&o);
    disown(&o);
}

static void test_polyline(void **state)
{
    (void)state;
    owned_surface o;
    polyline(&o);
    check_surface(&o);
    disown(&o);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_sphere),
        cmocka_unit_test(test_soup),
        cmocka_unit_test(test_polyline),
    };
    return cmocka_run_group_tests_name("bvh", tests, NULL, NULL);
}
