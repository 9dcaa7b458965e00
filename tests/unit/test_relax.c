/* The interior relaxation (core/sm_relax.h) on meshes built in code: on
 * a box whose interior vertices were pushed into a corner of their
 * cells (degenerate elements), the worst quality rises several times,
 * no element inverts, and the boundary and the fixed vertices keep their
 * coordinates bit for bit (which is what leaves J and T unchanged); an
 * undistorted mesh above the threshold is not touched. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "sm_relax.h"
#include "util_mesh.h"

/* Moves every interior vertex of the box [0,1]^dim (n cells a side) by
 * shift * the cell size along x: the layer of elements next to the face
 * x = 1 is squeezed to 1 - shift of its width, none inverted for
 * shift < 1. */
static void squeeze(sm_mesh *m, int n, double shift)
{
    for (int32_t v = 0; v < m->nverts; v++)
        if (!m->on_boundary[v])
            m->coords[(size_t)v * (size_t)m->dim] += shift / n;
}

static void check_relax(int dim, int n)
{
    const double lo[3] = {0, 0, 0}, hi[3] = {1, 1, 1};
    sm_mesh *m = util_box_mesh(dim, n, lo, hi, 0);
    assert_non_null(m);
    assert_int_equal(sm_mesh_build_boundary(m, NULL), SM_OK);
    squeeze(m, n, 0.9);
    /* one interior vertex fixed, as a clamp's would be */
    uint8_t *fixed = calloc((size_t)m->nverts + 1, 1);
    int32_t pinned = -1;
    for (int32_t v = 0; v < m->nverts && pinned < 0; v++)
        if (!m->on_boundary[v])
            pinned = v;
    assert_true(pinned >= 0);
    fixed[pinned] = 1;
    const size_t ndof = (size_t)m->nverts * (size_t)dim;
    double *before = malloc((ndof + 1) * sizeof *before);
    memcpy(before, m->coords, ndof * sizeof *before);
    double q0 = sm_mesh_min_quality(m, m->coords, NULL);
    assert_true(q0 > 0 && q0 < 0.2);

    sm_relax *r = NULL;
    assert_int_equal(sm__relax_new(m, fixed, &r, NULL), SM_OK);
    int moves = sm__relax_run(r, m->coords, 0.5, 5);
    double q1 = sm_mesh_min_quality(m, m->coords, NULL);
    print_message("%dD: worst quality %.3g -> %.3g, %d moves\n", dim, q0, q1, moves);
    assert_true(moves > 0);
    assert_true(q1 > 2.5 * q0); /* 2D: 0.091 -> 0.45, 3D: 0.153 -> 0.433 */
    for (int32_t e = 0; e < m->nelems; e++)
        assert_true(sm_elem_quality(m, m->coords, e) > 0);
    for (int32_t v = 0; v < m->nverts; v++)
        if (m->on_boundary[v] || v == pinned)
            assert_memory_equal(m->coords + (size_t)v * (size_t)dim,
                                before + (size_t)v * (size_t)dim, (size_t)dim * sizeof(double));

    /* above the threshold nothing moves */
    memcpy(before, m->coords, ndof * sizeof *before);
    assert_int_equal(sm__relax_run(r, m->coords, 0.5 * q1, 5), 0);
    assert_memory_equal(m->coords, before, ndof * sizeof *before);

    sm__relax_free(r);
    free(before);
    free(fixed);
    sm_mesh_free(m);
}

static void test_relax_2d(void **s) { (void)s; check_relax(2, 6); }
static void test_relax_3d(void **s) { (void)s; check_relax(3, 4); }

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_relax_2d),
        cmocka_unit_test(test_relax_3d),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
