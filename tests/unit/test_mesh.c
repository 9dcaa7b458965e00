/* Mesh model: orientation, boundary extraction, outward normals, volumes,
 * quality, reference transfer and rejection of broken topologies. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "shapematch/sm_mesh.h"
#include "sm_facets.h"
#include "util_mesh.h"

static sm_mesh *structured(int dim, int n, unsigned seed)
{
    const double lo[3] = {0, 0, 0}, hi[3] = {2, 1, 1};
    sm_mesh *m = util_box_mesh(dim, n, lo, hi, seed);
    assert_non_null(m);
    return m;
}

static void check_closed_boundary(sm_mesh *m, double expected_volume, int32_t expected_bfacets)
{
    sm_error err;
    assert_int_equal(sm_mesh_build_boundary(m, &err), SM_OK);
    double vol = 0.0;
    for (int32_t e = 0; e < m->nelems; e++) {
        double v = sm_elem_volume(m, m->coords, e);
        assert_true(v > 0.0);
        vol += v;
    }
    assert_true(fabs(vol - expected_volume) < 1e-12);
    assert_int_equal(m->nbfacets, expected_bfacets);
    /* closed surface: sum of area vectors is 0; divergence theorem for x:
     * sum over facets of (centroid . n) |f| = dim * |Omega| */
    double sum_n[3] = {0, 0, 0}, flux = 0.0;
    double center[3] = {1.0, 0.5, 0.5};
    for (int32_t f = 0; f < m->nbfacets; f++) {
        double n[3];
        double area = sm_bfacet_normal(m, m->coords, f, n);
        double mid[3] = {0, 0, 0};
        for (int i = 0; i < m->dim; i++)
            for (int c = 0; c < m->dim; c++)
                mid[c] += m->coords[m->bfacets[f * m->dim + i] * m->dim + c] / m->dim;
        double out = 0.0;
        for (int c = 0; c < m->dim; c++) {
            sum_n[c] += area * n[c];
            flux += area * n[c] * mid[c];
            out += n[c] * (mid[c] - center[c]);
        }
        assert_true(out > 0.0); /* convex box: outward means away from its center */
    }
    for (int c = 0; c < m->dim; c++)
        assert_true(fabs(sum_n[c]) < 1e-12);
    assert_true(fabs(flux - m->dim * expected_volume) < 1e-12);
}

static void test_orientation_and_normals_2d(void **state)
{
    (void)state;
    sm_mesh *m = structured(2, 8, 1);
    check_closed_boundary(m, 2.0, 4 * 8);
    for (int32_t v = 0; v < m->nverts; v++) {
        double x = m->coords[2 * v], y = m->coords[2 * v + 1];
        int expect = x == 0.0 || x == 2.0 || y == 0.0 || y == 1.0;
        assert_int_equal(m->on_boundary[v], expect);
    }
    sm_mesh_free(m);
}

static void test_orientation_and_normals_3d(void **state)
{
    (void)state;
    sm_mesh *m = structured(3, 5, 2);
    check_closed_boundary(m, 2.0, 6 * 5 * 5 * 2);
    sm_mesh_free(m);
}

static void test_quality(void **state)
{
    (void)state;
    sm_mesh *m = NULL;
    sm_error err;
    assert_int_equal(sm_mesh_alloc(&m, 2, 4, 2, 0, &err), SM_OK);
    double c[] = {0, 0, 1, 0, 0.5, sqrt(3.0) / 2, 2, 0};
    for (int i = 0; i < 8; i++)
        m->coords[i] = c[i];
    int32_t el[] = {0, 1, 2, 0, 2, 1};
    for (int i = 0; i < 6; i++)
        m->elems[i] = el[i];
    assert_true(fabs(sm_elem_quality(m, m->coords, 0) - 1.0) < 1e-14);
    assert_true(fabs(sm_elem_quality(m, m->coords, 1) + 1.0) < 1e-14); /* inverted */
    m->coords[5] = 0.0; /* flatten */
    assert_true(fabs(sm_elem_quality(m, m->coords, 0)) < 1e-14);
    sm_mesh_free(m);

    assert_int_equal(sm_mesh_alloc(&m, 3, 4, 1, 0, &err), SM_OK);
    double t[] = {1, 1, 1, 1, -1, -1, -1, 1, -1, -1, -1, 1}; /* regular tetrahedron */
    for (int i = 0; i < 12; i++)
        m->coords[i] = t[i];
    for (int i = 0; i < 4; i++)
        m->elems[i] = i;
    assert_true(fabs(fabs(sm_elem_quality(m, m->coords, 0)) - 1.0) < 1e-12);
    sm_quality_stats qs;
    sm_mesh_quality(m, m->coords, &qs);
    assert_true(fabs(fabs(qs.min) - 1.0) < 1e-12);
    assert_true(fabs(sm_mesh_diameter(m, m->coords) - sqrt(12.0)) < 1e-14);
    sm_mesh_free(m);
}

/* sm_mesh_min_quality against the minimum of sm_elem_quality, element by
 * element, on boxes with shuffled vertex orders (half the elements
 * inverted) and after turning one element inside out. */
static void test_min_quality(void **state)
{
    (void)state;
    const double lo[3] = {0, 0, 0}, hi[3] = {1, 2, 0.5};
    for (int dim = 2; dim <= 3; dim++) {
        sm_mesh *m = util_box_mesh(dim, 5, lo, hi, 7);
        sm_error err;
        for (int pass = 0; pass < 2; pass++) {
            double best = INFINITY;
            int32_t first = -1;
            for (int32_t e = 0; e < m->nelems; e++) {
                double q = sm_elem_quality(m, m->coords, e);
                if (q < best) {
                    best = q;
                    first = e;
                }
            }
            int32_t worst = -2;
            double q = sm_mesh_min_quality(m, m->coords, &worst);
            assert_true(q == best);
            assert_int_equal(worst, first);
            /* then with every element positive but one crushed flat-ish */
            assert_int_equal(sm_mesh_build_boundary(m, &err), SM_OK);
            m->coords[(size_t)m->elems[5 * (dim + 1)] * dim] += 0.19;
        }
        sm_mesh_free(m);
    }
}

/* sm__facet_match against a quadratic search: every facet's neighbour,
 * the boundary in lexicographic order, and a facet held by three
 * elements reported with its holders. */
static void test_facet_match(void **state)
{
    (void)state;
    const double lo[3] = {0, 0, 0}, hi[3] = {1, 1, 1};
    for (int dim = 2; dim <= 3; dim++) {
        sm_mesh *m = util_box_mesh(dim, dim == 2 ? 7 : 3, lo, hi, 3);
        const int nv = dim + 1;
        size_t nf = (size_t)m->nelems * (size_t)nv;
        int32_t *nbr = malloc(nf * sizeof *nbr), *order = malloc(nf * sizeof *order);
        sm_facet_match fm;
        sm_error err;
        assert_int_equal(sm__facet_match(dim, m->nverts, m->nelems, m->elems, nbr, order, &fm, &err),
                         SM_OK);
        assert_int_equal(fm.crowded, -1);
        int64_t nb = 0;
        for (size_t f = 0; f < nf; f++) {
            int32_t key[3], other[3], expect = -1;
            sm__facet_sorted_vertices(dim, m->elems + f / nv * nv, (int)(f % nv), key);
            for (size_t g = 0; g < nf; g++) {
                if (g / nv == f / nv)
                    continue;
                sm__facet_sorted_vertices(dim, m->elems + g / nv * nv, (int)(g % nv), other);
                if (memcmp(key, other, (size_t)dim * sizeof *key) == 0)
                    expect = (int32_t)(g / nv);
            }
            assert_int_equal(nbr[f], expect);
            nb += expect < 0;
        }
        assert_int_equal(fm.nboundary, nb);
        for (int64_t b = 1; b < fm.nboundary; b++) {
            int32_t k0[3], k1[3];
            sm__facet_sorted_vertices(dim, m->elems + order[b - 1] / nv * nv, order[b - 1] % nv, k0);
            sm__facet_sorted_vertices(dim, m->elems + order[b] / nv * nv, order[b] % nv, k1);
            int cmp = 0;
            for (int i = 0; i < dim && !cmp; i++)
                cmp = (k0[i] > k1[i]) - (k0[i] < k1[i]);
            assert_true(cmp < 0);
        }
        /* a third element on facet 0 of element 0 */
        int32_t *elems = malloc((nf + (size_t)nv) * sizeof *elems);
        memcpy(elems, m->elems, nf * sizeof *elems);
        for (int i = 0; i < nv; i++)
            elems[nf + (size_t)i] = m->elems[i];
        elems[nf] = m->nverts - 1; /* replaces the vertex opposite facet 0 */
        int32_t *nbr2 = malloc((nf + (size_t)nv) * sizeof *nbr2);
        assert_int_equal(sm__facet_match(dim, m->nverts, m->nelems + 1, elems, nbr2, NULL, &fm, &err),
                         SM_OK);
        if (nbr[0] >= 0) { /* an interior facet: now held by three */
            assert_int_equal(fm.crowded_holders, 3);
            assert_int_equal(nbr2[0], -2);
            assert_int_equal(nbr2[nf], -2);
        } else {
            assert_int_equal(nbr2[0], m->nelems);
        }
        free(nbr2);
        free(elems);
        free(nbr);
        free(order);
        sm_mesh_free(m);
    }
}

/* Two triangles sharing an edge; the file lists the shared (interior)
 * edge with reference 10 and two boundary edges with references 1 and 2. */
static void test_reference_transfer(void **state)
{
    (void)state;
    sm_mesh *m = NULL;
    sm_error err;
    assert_int_equal(sm_mesh_alloc(&m, 2, 4, 2, 3, &err), SM_OK);
    double c[] = {0, 0, 1, 0, 1, 1, 0, 1};
    for (int i = 0; i < 8; i++)
        m->coords[i] = c[i];
    int32_t el[] = {0, 2, 1, 0, 2, 3}; /* first one clockwise, second counter */
    for (int i = 0; i < 6; i++)
        m->elems[i] = el[i];
    int32_t fa[] = {2, 0, 1, 0, 3, 2};
    int32_t fr[] = {10, 1, 2};
    for (int i = 0; i < 6; i++)
        m->facets[i] = fa[i];
    for (int i = 0; i < 3; i++)
        m->facet_refs[i] = fr[i];
    assert_int_equal(sm_mesh_build_boundary(m, &err), SM_OK);
    assert_int_equal(m->nbfacets, 4);
    int seen1 = 0, seen2 = 0, seen0 = 0;
    for (int32_t f = 0; f < 4; f++) {
        int32_t a = m->bfacets[2 * f], b = m->bfacets[2 * f + 1];
        assert_false((a == 0 && b == 2) || (a == 2 && b == 0)); /* interior edge excluded */
        if (m->bfacet_refs[f] == 1) {
            seen1++;
            assert_true((a == 0 && b == 1) || (a == 1 && b == 0));
        } else if (m->bfacet_refs[f] == 2) {
            seen2++;
        } else {
            assert_int_equal(m->bfacet_refs[f], 0);
            seen0++;
        }
    }
    assert_int_equal(seen1, 1);
    assert_int_equal(seen2, 1);
    assert_int_equal(seen0, 2);
    /* the file's facet list is left as it was */
    assert_int_equal(m->nfacets, 3);
    assert_int_equal(m->facet_refs[0], 10);
    sm_mesh_free(m);
}

static void test_rejections(void **state)
{
    (void)state;
    sm_error err;
    sm_mesh *m = structured(2, 2, 3);
    m->elems[4] = 99;
    assert_int_equal(sm_mesh_build_boundary(m, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "vertex 100"));
    sm_mesh_free(m);

    m = structured(2, 2, 3);
    m->elems[1] = m->elems[0]; /* repeated vertex: degenerate */
    assert_int_equal(sm_mesh_build_boundary(m, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "degenerate"));
    sm_mesh_free(m);

    m = structured(2, 2, 3);
    m->coords[3] = NAN;
    assert_int_equal(sm_mesh_build_boundary(m, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "non-finite"));
    sm_mesh_free(m);

    /* three triangles on one edge: not a manifold */
    assert_int_equal(sm_mesh_alloc(&m, 2, 5, 3, 0, &err), SM_OK);
    double c[] = {0, 0, 1, 0, 0.5, 1, 0.5, -1, 2, 2};
    for (int i = 0; i < 10; i++)
        m->coords[i] = c[i];
    int32_t el[] = {0, 1, 2, 0, 1, 3, 0, 1, 4};
    for (int i = 0; i < 9; i++)
        m->elems[i] = el[i];
    assert_int_equal(sm_mesh_build_boundary(m, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "not manifold"));
    sm_mesh_free(m);

    assert_int_equal(sm_mesh_alloc(&m, 4, 1, 1, 0, &err), SM_ERR_INVALID);
    assert_int_equal(sm_mesh_alloc(&m, 2, -1, 1, 0, &err), SM_ERR_NOMEM);
    assert_null(m);
}

static void test_disk_helper(void **state)
{
    (void)state;
    sm_error err;
    const double c[2] = {0.5, 0.5};
    sm_mesh *m = util_disk_mesh(c, 0.25, 6);
    assert_non_null(m);
    assert_int_equal(m->nelems, 6 * 36);
    assert_int_equal(sm_mesh_build_boundary(m, &err), SM_OK);
    assert_int_equal(m->nbfacets, 36);
    for (int32_t f = 0; f < m->nbfacets; f++)
        assert_int_equal(m->bfacet_refs[f], 1);
    double area = 0.0;
    for (int32_t e = 0; e < m->nelems; e++)
        area += sm_elem_volume(m, m->coords, e);
    /* inscribed 36-gon */
    assert_true(fabs(area - 0.5 * 36 * 0.0625 * sin(2 * M_PI / 36)) < 1e-12);
    sm_mesh_free(m);
}

static void test_clone(void **state)
{
    (void)state;
    sm_error err;
    sm_mesh *m = structured(3, 2, 4), *c = NULL;
    assert_int_equal(sm_mesh_build_boundary(m, &err), SM_OK);
    assert_int_equal(sm_mesh_clone(m, &c, &err), SM_OK);
    assert_int_equal(c->nbfacets, m->nbfacets);
    assert_memory_equal(c->bfacets, m->bfacets, sizeof(int32_t) * 3 * m->nbfacets);
    assert_memory_equal(c->coords, m->coords, sizeof(double) * 3 * m->nverts);
    sm_mesh_free(c);
    sm_mesh_free(m);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_orientation_and_normals_2d),
        cmocka_unit_test(test_orientation_and_normals_3d),
        cmocka_unit_test(test_quality),
        cmocka_unit_test(test_min_quality),
        cmocka_unit_test(test_facet_match),
        cmocka_unit_test(test_reference_transfer),
        cmocka_unit_test(test_rejections),
        cmocka_unit_test(test_clone),
        cmocka_unit_test(test_disk_helper),
    };
    return cmocka_run_group_tests_name("mesh", tests, NULL, NULL);
}
