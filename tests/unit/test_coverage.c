/* The two-sided measure (sm_coverage) against exact answers: a cube of
 * half-side 0.5 (the template's boundary) inside the exact surface of a
 * cube of half-side 1 (the target).
 *   - result -> target: every point of the inner cube's faces is 0.5 from
 *     the outer cube (the nearest face plane): rms, mean and max 0.5;
 *   - target -> result: a point (1, y, z) of an outer face is
 *     sqrt(0.25 + a^2 + b^2) from the inner cube, a = max(0, |y| - 0.5),
 *     b = max(0, |z| - 0.5): mean square 1/3 over a face (rms 0.5774),
 *     max sqrt(0.75) at the corners (the target's vertices count);
 *   - the target's measure (its samples' weights) is the area, 24;
 *   - the missed part beyond 0.6 is the share of a face where
 *     a^2 + b^2 > 0.11, integrated here on a fine grid;
 *   - before a measure the missed part is all zero (the target's samples
 *     are made by the measure), and a second measure gives the same
 *     figures bit for bit (they are made again, the same points). */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>

#include <cmocka.h>

#include "shapematch/sm_coverage.h"
#include "shapematch/sm_field.h"
#include "shapematch/sm_mesh.h"
#include "util_mesh.h"

typedef struct cubes {
    sm_mesh *inner, *outer, *bg;
    double *d;
    sm_field *field;
    sm_surface target;
} cubes;

static void make_cubes(cubes *c)
{
    sm_error err;
    const double ilo[3] = {-0.5, -0.5, -0.5}, ihi[3] = {0.5, 0.5, 0.5};
    const double olo[3] = {-1, -1, -1}, ohi[3] = {1, 1, 1};
    const double blo[3] = {-1.5, -1.5, -1.5}, bhi[3] = {1.5, 1.5, 1.5};
    c->inner = util_box_mesh(3, 4, ilo, ihi, 0);
    c->outer = util_box_mesh(3, 6, olo, ohi, 0);
    c->bg = util_box_mesh(3, 6, blo, bhi, 0);
    assert_non_null(c->inner);
    assert_non_null(c->outer);
    assert_non_null(c->bg);
    assert_int_equal(sm_mesh_build_boundary(c->inner, &err), SM_OK);
    assert_int_equal(sm_mesh_build_boundary(c->outer, &err), SM_OK);
    /* the field is required; with the exact surface given it is not
     * what the distances are measured to */
    c->d = malloc(sizeof *c->d * (size_t)c->bg->nverts);
    assert_non_null(c->d);
    for (int32_t v = 0; v < c->bg->nverts; v++) {
        const double *x = c->bg->coords + 3 * (size_t)v;
        c->d[v] = fmax(fabs(x[0]), fmax(fabs(x[1]), fabs(x[2]))) - 1;
    }
    assert_int_equal(sm_field_new(c->bg, c->d, &c->field, &err), SM_OK);
    c->target = (sm_surface){.dim = 3, .nverts = c->outer->nverts, .coords = c->outer->coords,
                             .nfacets = c->outer->nbfacets, .facets = c->outer->bfacets};
}

static void free_cubes(cubes *c)
{
    sm_field_free(c->field);
    sm_mesh_free(c->inner);
    sm_mesh_free(c->outer);
    sm_mesh_free(c->bg);
    free(c->d);
}

/* The share of a face [-1, 1]^2 where a^2 + b^2 > t (a, b as above),
 * by the midpoint rule on a 2000^2 grid. */
static double face_share_beyond(double t)
{
    const int n = 2000;
    int64_t beyond = 0;
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) {
            double y = -1 + (i + 0.5) * 2.0 / n, z = -1 + (j + 0.5) * 2.0 / n;
            double a = fmax(0, fabs(y) - 0.5), b = fmax(0, fabs(z) - 0.5);
            beyond += a * a + b * b > t;
        }
    return (double)beyond / ((double)n * n);
}

static void test_cubes_exact(void **state)
{
    (void)state;
    cubes c;
    make_cubes(&c);
    sm_error err;
    sm_coverage *cov = NULL;
    assert_int_equal(sm_coverage_new(c.field, &c.target, c.inner, NULL, 0, &cov, &err), SM_OK);

    double measure = 0;
    assert_true(sm_coverage_target_samples(cov, &measure) > 0);
    assert_true(fabs(measure - 24) < 1e-9);

    sm_coverage_missed missed;
    sm_coverage_missed_part(cov, 0, 0.0, &missed);
    assert_int_equal(missed.samples, 0);
    assert_true(missed.fraction == 0 && missed.measure == 0 && missed.max == 0);

    sm_distance a, b;
    assert_int_equal(sm_coverage_measure(cov, c.inner->coords, &a, &err), SM_OK);
    const sm_distance_side *r = &a.result_to_target, *t = &a.target_to_result;
    assert_true(fabs(r->rms - 0.5) < 1e-12);
    assert_true(fabs(r->mean - 0.5) < 1e-12);
    assert_true(fabs(r->max - 0.5) < 1e-12);
    /* the target's samples are centroids of its facets' parts: the mean
     * square, quadratic per piece, is exact to O(spacing^2) */
    assert_true(fabs(t->rms - sqrt(1.0 / 3)) < 0.01 * sqrt(1.0 / 3));
    assert_true(fabs(t->max - sqrt(0.75)) < 1e-12);
    assert_true(t->mean > 0.5 && t->mean < t->rms);

    double share = face_share_beyond(0.6 * 0.6 - 0.25);
    sm_coverage_missed_part(cov, 0, 0.6, &missed);
    assert_true(missed.samples > 0);
    assert_true(fabs(missed.fraction - share) < 0.03 * share + 0.002);
    /* (the samples' farthest: the vertices count toward t->max only) */
    assert_true(missed.max > 0.6 && missed.max <= sqrt(0.75));
    /* the result's side: nothing of the inner cube is beyond 0.6 */
    sm_coverage_missed_part(cov, 1, 0.6, &missed);
    assert_int_equal(missed.samples, 0);

    assert_int_equal(sm_coverage_measure(cov, c.inner->coords, &b, &err), SM_OK);
    assert_memory_equal(&a, &b, sizeof a);

    sm_coverage_free(cov);
    free_cubes(&c);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_cubes_exact),
    };
    return cmocka_run_group_tests_name("coverage", tests, NULL, NULL);
}
