/* Pre-alignment (core/sm_align*.c): the small linear algebra against its
 * defining identities, Kabsch/Umeyama exact on noiseless pairs, the
 * landmark reader's rows and refusals, and known transforms recovered
 * from a target's distance field alone on Gmsh-made asymmetric shapes
 * (rotations to 180 degrees about random axes, translations of 100
 * diameters, scales 1e-3 and 1e3, an anisotropic stretch); on an exact
 * surface target, known maps recovered to rounding; and the two-sided
 * misfit's point: a smaller template no longer wins (a capsule's affine
 * map onto a bent capsule spans both arms, a ball's similarity scale
 * follows the volume ratio).  The truth is the transform the test
 * applies to make the target, or a volume computed another way, never
 * the code's own output. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "shapematch/sm_align.h"
#include "shapematch/sm_clock.h"
#include "shapematch/sm_field.h"
#include "shapematch/sm_sdf.h"
#include "shapematch/sm_surface.h"
#include "sm_align_internal.h"
#include "util_gmsh.h"

static unsigned long long rng_state = 0x9e3779b97f4a7c15ull;
static double uniform(void)
{
    rng_state = rng_state * 6364136223846793005ull + 1442695040888963407ull;
    return (double)(rng_state >> 11) / 9007199254740992.0;
}

/* Rotation about axis (unit) by angle, written out from Rodrigues'
 * formula here, independently of the library's increments. */
static void rotation(int dim, const double axis[3], double angle, double r[3][3])
{
    memset(r, 0, 9 * sizeof(double));
    if (dim == 2) {
        r[0][0] = cos(angle), r[0][1] = -sin(angle), r[1][0] = sin(angle), r[1][1] = cos(angle);
        r[2][2] = 1;
        return;
    }
    double n = sqrt(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]);
    double x = axis[0] / n, y = axis[1] / n, z = axis[2] / n, c = cos(angle), s = sin(angle),
           t = 1 - c;
    double m[3][3] = {{t * x * x + c, t * x * y - s * z, t * x * z + s * y},
                      {t * x * y + s * z, t * y * y + c, t * y * z - s * x},
                      {t * x * z - s * y, t * y * z + s * x, t * z * z + c}};
    memcpy(r, m, sizeof m);
}

static void make_transform(int dim, double r[3][3], double scale, const double b[3],
                           sm_transform *t)
{
    sm_transform_identity(t, dim);
    for (int i = 0; i < dim; i++) {
        t->b[i] = b[i];
        for (int j = 0; j < dim; j++)
            t->a[i][j] = scale * r[i][j];
    }
}

/* ------------------------------------------------------ linear algebra */

static void test_eigen_svd(void **state)
{
    (void)state;
    for (int trial = 0; trial < 50; trial++) {
        int n = 2 + trial % 2;
        double a[3][3] = {{0}}, val[3], vec[3][3];
        for (int i = 0; i < n; i++)
            for (int j = 0; j <= i; j++)
                a[i][j] = a[j][i] = uniform() * 2 - 1;
        if (trial == 0) /* a repeated eigenvalue */
            memcpy(a, (double[3][3]){{2, 0, 0}, {0, 2, 0}, {0, 0, 1}}, sizeof a);
        sm__sym_eigen(n, (const double(*)[3])a, val, vec);
        for (int i = 0; i + 1 < n; i++)
            assert_true(val[i] >= val[i + 1]);
        assert_true(fabs(sm__det(n, (const double(*)[3])vec) - 1) < 1e-12);
        for (int i = 0; i < n; i++) /* a = V diag V^T */
            for (int j = 0; j < n; j++) {
                double x = 0;
                for (int k = 0; k < n; k++)
                    x += vec[i][k] * val[k] * vec[j][k];
                assert_true(fabs(x - a[i][j]) < 1e-12);
            }
        double b[3][3] = {{0}}, u[3][3], s[3], v[3][3];
        for (int i = 0; i < n; i++)
            for (int j = 0; j < n; j++)
                b[i][j] = uniform() * 2 - 1;
        if (trial == 1) /* rank one */
            for (int i = 0; i < n; i++)
                for (int j = 0; j < n; j++)
                    b[i][j] = (i + 1.0) * (j - 0.5);
        sm__svd(n, (const double(*)[3])b, u, s, v);
        for (int i = 0; i < n; i++)
            for (int j = 0; j < n; j++) {
                double x = 0, uu = 0;
                for (int k = 0; k < n; k++) {
                    x += u[i][k] * s[k] * v[j][k];
                    uu += u[k][i] * u[k][j];
                }
                assert_true(fabs(x - b[i][j]) < 1e-9);
                assert_true(fabs(uu - (i == j)) < 1e-9);
            }
    }
}

/* ----------------------------------------------------------- landmarks */

static void test_landmarks_exact(void **state)
{
    (void)state;
    for (int trial = 0; trial < 40; trial++) {
        int dim = 2 + trial % 2;
        sm_align_mode mode = trial % 4 < 2 ? SM_ALIGN_RIGID : SM_ALIGN_SIMILARITY;
        double axis[3] = {uniform() - 0.5, uniform() - 0.5, uniform() - 0.5}, r[3][3];
        rotation(dim, axis, M_PI * (2 * uniform() - 1), r);
        double scale = mode == SM_ALIGN_RIGID ? 1 : pow(10, 6 * uniform() - 3);
        double b[3] = {200 * uniform() - 100, 200 * uniform() - 100, 200 * uniform() - 100};
        sm_transform truth, got;
        make_transform(dim, r, scale, b, &truth);
        int32_t n = dim + trial % 5;
        double src[3 * 8], dst[3 * 8];
        for (int i = 0; i < n * dim; i++)
            src[i] = uniform() * 2 - 1;
        sm_transform_apply(&truth, n, src, dst);
        sm_error err;
        assert_int_equal(sm_align_landmarks(dim, n, src, dst, mode, &got, &err), SM_OK);
        for (int i = 0; i < dim; i++) {
            for (int j = 0; j < dim; j++)
                if (!(fabs(got.a[i][j] - truth.a[i][j]) < 1e-9 * scale))
                    fail_msg("trial %d (%dD, n %d, mode %d): a[%d][%d] %.17g, truth %.17g", trial, dim, (int)n, (int)mode, i, j, got.a[i][j], truth.a[i][j]);
            assert_true(fabs(got.b[i] - truth.b[i]) < 1e-9 * (100 + scale));
        }
    }
}

/* Extreme magnitudes: a set onto itself is the identity whatever its
 * size (fuzz_landmarks found two 2D points 1e59 apart, whose covariance
 * overflowed the SVD's column products; tests/fuzz/seeds/landmarks/
 * far-apart-1e59), and so is a tiny one. */
static void test_landmarks_extreme(void **state)
{
    (void)state;
    const double sets[3][4] = {{8.88888888888889e50, 5, 5, 2.88888888888889e59},
                               {1e-80, 0, 0, 3e-80},
                               {1e150, -1e150, -2e150, 1e150}};
    for (int k = 0; k < 3; k++) {
        sm_transform t;
        sm_error err;
        assert_int_equal(sm_align_landmarks(2, 2, sets[k], sets[k], SM_ALIGN_SIMILARITY, &t, &err),
                         SM_OK);
        for (int i = 0; i < 2; i++)
            for (int j = 0; j < 2; j++)
                if (!(fabs(t.a[i][j] - (i == j)) < 1e-9))
                    fail_msg("set %d: a[%d][%d] = %.17g", k, i, j, t.a[i][j]);
    }
}

static void test_landmarks_refused(void **state)
{
    (void)state;
    sm_transform t;
    sm_error err;
    double line[9] = {0, 0, 0, 1, 1, 1, 2, 2, 2}, good[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    assert_int_equal(sm_align_landmarks(3, 3, line, good, SM_ALIGN_RIGID, &t, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "collinear"));
    assert_int_equal(sm_align_landmarks(3, 2, good, good, SM_ALIGN_RIGID, &t, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "at least 3"));
    double nan_pts[9] = {0, 0, 0, 1, 0, 0, 0, NAN, 0};
    assert_int_equal(sm_align_landmarks(3, 3, good, nan_pts, SM_ALIGN_RIGID, &t, &err),
                     SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "non-finite"));
    assert_int_equal(sm_align_landmarks(3, 3, good, good, SM_ALIGN_NONE, &t, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "--align"));
    double same2[4] = {1, 1, 1, 1}, ok2[4] = {0, 0, 1, 0};
    assert_int_equal(sm_align_landmarks(2, 2, same2, ok2, SM_ALIGN_RIGID, &t, &err), SM_ERR_INVALID);
    assert_int_equal(sm_align_landmarks(2, 2, ok2, ok2, SM_ALIGN_SIMILARITY, &t, &err), SM_OK);
}

/* ------------------------------------------------------------- shapes */

/* Asymmetric shapes (no rotation maps them onto themselves, so the truth
 * is the only answer): a box or rectangle with a ball or disk bulging
 * off-centre on every axis. */
#define SHAPE_3D                                                                     \
    "SetFactory(\"OpenCASCADE\");\nBox(1) = {0, 0, 0, 1, 0.6, 0.4};\n"               \
    "Sphere(2) = {0.85, 0.5, 0.3, 0.25};\nBooleanUnion{ Volume{1}; Delete; }{ "      \
    "Volume{2}; Delete; }\nMesh.MeshSizeFromPoints = 0;\n"
#define SHAPE_2D                                                                     \
    "SetFactory(\"OpenCASCADE\");\nRectangle(1) = {0, 0, 0, 1, 0.5};\n"              \
    "Disk(2) = {0.85, 0.45, 0, 0.22};\nBooleanUnion{ Surface{1}; Delete; }{ "        \
    "Surface{2}; Delete; }\nMesh.MeshSizeFromPoints = 0;\n"

typedef struct target {
    sm_mesh *bg;
    double *values;
    sm_field *field;
} target;

/* The template's boundary moved by truth, as a surface, its exact signed
 * distance on a graded background around it (cells ~2% of its size). */
static void make_target(const sm_mesh *m, const sm_transform *truth, target *t)
{
    const int dim = m->dim;
    sm_surface *s;
    sm_error err;
    assert_int_equal(sm_surface_alloc(&s, dim, m->nverts, m->nbfacets, &err), SM_OK);
    sm_transform_apply(truth, m->nverts, m->coords, s->coords);
    memcpy(s->facets, m->bfacets, (size_t)m->nbfacets * dim * sizeof *s->facets);
    sm_sdf *d;
    assert_int_equal(sm_sdf_new(s, &d, &err), SM_OK);
    double lo[3], hi[3], diag = 0;
    for (int c = 0; c < dim; c++) {
        lo[c] = INFINITY, hi[c] = -INFINITY;
        for (int32_t v = 0; v < s->nverts; v++) {
            lo[c] = fmin(lo[c], s->coords[(size_t)v * dim + c]);
            hi[c] = fmax(hi[c], s->coords[(size_t)v * dim + c]);
        }
        diag += (hi[c] - lo[c]) * (hi[c] - lo[c]);
    }
    diag = sqrt(diag);
    for (int c = 0; c < dim; c++)
        lo[c] -= 0.2 * diag, hi[c] += 0.2 * diag;
    if (sm_background_graded_new(dim, lo, hi, 0.02 * diag, d, &t->bg, &err) != SM_OK)
        fail_msg("background: %s", err.msg);
    t->values = malloc((size_t)t->bg->nverts * sizeof *t->values);
    assert_int_equal(sm_sdf_signed(d, t->bg->nverts, t->bg->coords, t->values, &err), SM_OK);
    assert_int_equal(sm_field_new(t->bg, t->values, &t->field, &err), SM_OK);
    sm_sdf_free(d);
    sm_surface_free(s);
}

static void target_free(target *t)
{
    sm_field_free(t->field);
    free(t->values);
    sm_mesh_free(t->bg);
}

/* Gmsh runs once per dimension (a process start costs more than an
 * alignment); the cases clone it. */
static sm_mesh *shapes[4];

static int free_shapes(void **state)
{
    (void)state;
    for (int d = 0; d < 4; d++)
        sm_mesh_free(shapes[d]);
    return 0;
}

static sm_mesh *shape(int dim)
{
    sm_mesh *m;
    sm_error err;
    if (shapes[dim]) {
        assert_int_equal(sm_mesh_clone(shapes[dim], &m, &err), SM_OK);
        return m;
    }
    char msg[512];
    if (util_gmsh_mesh(dim == 3 ? SHAPE_3D : SHAPE_2D, dim, dim == 3 ? 0.1 : 0.05, &m, msg,
                       sizeof msg) != SM_OK)
        fail_msg("gmsh: %s", msg);
    assert_int_equal(sm_mesh_build_boundary(m, &err), SM_OK);
    shapes[dim] = m;
    return shape(dim);
}

/* The largest entry error of a over the truth's scale, and of b over the
 * target's size. */
static void compare(const sm_transform *got, const sm_transform *truth, double size,
                    double *err_a, double *err_b)
{
    double s = sm_transform_scale(truth);
    *err_a = *err_b = 0;
    for (int i = 0; i < truth->dim; i++) {
        for (int j = 0; j < truth->dim; j++)
            *err_a = fmax(*err_a, fabs(got->a[i][j] - truth->a[i][j]) / s);
        *err_b = fmax(*err_b, fabs(got->b[i] - truth->b[i]) / (s * size));
    }
}

typedef struct known {
    int dim;
    sm_align_mode mode;
    double angle;       /* about a random axis */
    double scale;
    double shift;       /* in template diameters, random direction */
    double stretch[3];  /* affine: diagonal stretch before the rotation */
} known;

static void check_known(const known *k)
{
    sm_mesh *m = shape(k->dim);
    double diam = sm_mesh_diameter(m, m->coords);
    double axis[3] = {uniform() - 0.5, uniform() - 0.5, uniform() - 0.5}, r[3][3];
    rotation(k->dim, axis, k->angle, r);
    double dir[3] = {uniform() - 0.5, uniform() - 0.5, k->dim == 3 ? uniform() - 0.5 : 0}, nd = 0;
    for (int c = 0; c < 3; c++)
        nd += dir[c] * dir[c];
    double b[3];
    for (int c = 0; c < 3; c++)
        b[c] = k->shift * diam * k->scale * dir[c] / sqrt(nd);
    sm_transform truth;
    make_transform(k->dim, r, k->scale, b, &truth);
    if (k->mode == SM_ALIGN_AFFINE)
        for (int i = 0; i < k->dim; i++)
            for (int j = 0; j < k->dim; j++)
                truth.a[i][j] *= k->stretch[j];
    target t;
    make_target(m, &truth, &t);
    sm_align_opts o = {.mode = k->mode, .template_mesh = m, .target = t.field,
                       .background = t.bg, .distance = t.values};
    sm_align_result res;
    sm_error err;
    if (sm_align_run(&o, &res, &err) != SM_OK)
        fail_msg("align: %s", err.msg);
    double ea, eb;
    compare(&res.transform, &truth, diam, &ea, &eb);
    print_message("# %dD %s angle %.0f deg scale %g shift %g: matrix error %.2e, translation "
                  "%.2e, rms %.3e -> %.3e (relative %.2e), %d iterations, %d candidates, %.3f s\n",
                  k->dim, sm_align_mode_name(k->mode), k->angle * 180 / M_PI, k->scale, k->shift,
                  ea, eb, res.rms_before, res.rms_after, res.rms_after / (k->scale * diam),
                  res.iterations, res.candidates, res.seconds);
    /* the bound for rigid and similarity; an affine fit of a
     * faceted shape is less determined (a stretch along a flat face
     * barely changes d), so its bound is the misfit, below the
     * background's cells (2% of the size) by far */
    if (k->mode != SM_ALIGN_AFFINE) {
        assert_true(ea < 1e-3);
        assert_true(eb < 1e-3);
    } else {
        assert_true(ea < 2e-2);
    }
    assert_true(res.rms_after < 2e-3 * k->scale * diam);
    assert_true(fabs(res.scale - sm_transform_scale(&truth)) < 1e-2 * res.scale);
    target_free(&t);
    sm_mesh_free(m);
}

static void test_known_3d(void **state)
{
    (void)state;
    const known cases[] = {
        {3, SM_ALIGN_RIGID, M_PI, 1, 100, {1, 1, 1}},
        {3, SM_ALIGN_SIMILARITY, 2.8, 1e-3, 5, {1, 1, 1}},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++)
        check_known(&cases[i]);
}

static void test_known_2d(void **state)
{
    (void)state;
    const known cases[] = {
        {2, SM_ALIGN_RIGID, M_PI, 1, 100, {1, 1, 1}},
        {2, SM_ALIGN_SIMILARITY, 2.5, 1e3, 100, {1, 1, 1}},
        {2, SM_ALIGN_AFFINE, 0.3, 1, 1, {1.5, 0.7, 1}},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++)
        check_known(&cases[i]);
}

/* ------------------------------------------- exact surface targets */

/* The boundary of m moved by truth, as a surface (m's outward facets). */
static sm_surface *moved_surface(const sm_mesh *m, const sm_transform *truth)
{
    sm_surface *s;
    sm_error err;
    assert_int_equal(sm_surface_alloc(&s, m->dim, m->nverts, m->nbfacets, &err), SM_OK);
    sm_transform_apply(truth, m->nverts, m->coords, s->coords);
    memcpy(s->facets, m->bfacets, (size_t)m->nbfacets * m->dim * sizeof *s->facets);
    return s;
}

/* The largest displacement error of got against truth over m's vertices,
 * over the target's size (its box diagonal): the measure. */
static double map_error(const sm_mesh *m, const sm_transform *got, const sm_transform *truth)
{
    double *a = malloc((size_t)m->nverts * m->dim * sizeof *a);
    double *b = malloc((size_t)m->nverts * m->dim * sizeof *b);
    assert_non_null(a);
    assert_non_null(b);
    sm_transform_apply(got, m->nverts, m->coords, a);
    sm_transform_apply(truth, m->nverts, m->coords, b);
    double worst = 0, lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int32_t v = 0; v < m->nverts; v++) {
        double e2 = 0;
        for (int c = 0; c < m->dim; c++) {
            double d = a[(size_t)v * m->dim + c] - b[(size_t)v * m->dim + c];
            e2 += d * d;
            lo[c] = fmin(lo[c], b[(size_t)v * m->dim + c]);
            hi[c] = fmax(hi[c], b[(size_t)v * m->dim + c]);
        }
        worst = fmax(worst, sqrt(e2));
    }
    double diag = 0;
    for (int c = 0; c < m->dim; c++)
        diag += (hi[c] - lo[c]) * (hi[c] - lo[c]);
    free(a);
    free(b);
    return worst / sqrt(diag);
}

/* Known rigid and similarity maps onto the template's own boundary as an
 * exact surface: angles to 180 degrees about random axes, scales 0.5 to
 * 2, shifts of 10 diameters.  Every residual is then an exact
 * point-to-surface distance, zero at the truth, so the map is recovered
 * to far better than Open3D's FPFH + RANSAC + ICP on the same task
 * (6.8e-6 rigid, 1.9e-5 similarity, of the target's size: issue 33). */
static void test_known_exact(void **state)
{
    (void)state;
    static const struct {
        int dim;
        sm_align_mode mode;
        double angle, scale;
    } cases[] = {
        {3, SM_ALIGN_RIGID, M_PI, 1},        {3, SM_ALIGN_RIGID, 2.5, 1},
        {3, SM_ALIGN_RIGID, 0.6, 1},         {3, SM_ALIGN_SIMILARITY, M_PI, 0.5},
        {3, SM_ALIGN_SIMILARITY, 1.8, 2},    {3, SM_ALIGN_SIMILARITY, 0.4, 1.3},
        {2, SM_ALIGN_RIGID, M_PI, 1},        {2, SM_ALIGN_SIMILARITY, 2.2, 0.5},
    };
    double worst[2] = {0, 0};
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        const int dim = cases[i].dim;
        sm_mesh *m = shape(dim);
        double diam = sm_mesh_diameter(m, m->coords);
        double axis[3] = {uniform() - 0.5, uniform() - 0.5, uniform() - 0.5}, r[3][3];
        rotation(dim, axis, cases[i].angle, r);
        double b[3] = {10 * diam * (uniform() - 0.5), 10 * diam * (uniform() - 0.5),
                       dim == 3 ? 10 * diam * (uniform() - 0.5) : 0};
        sm_transform truth;
        make_transform(dim, r, cases[i].scale, b, &truth);
        sm_surface *s = moved_surface(m, &truth);
        sm_sdf *d;
        sm_error err;
        assert_int_equal(sm_sdf_new(s, &d, &err), SM_OK);
        sm_align_opts o = {.mode = cases[i].mode, .template_mesh = m, .surface = d};
        sm_align_result res;
        if (sm_align_run(&o, &res, &err) != SM_OK)
            fail_msg("align: %s", err.msg);
        double e = map_error(m, &res.transform, &truth);
        int sim = cases[i].mode == SM_ALIGN_SIMILARITY;
        worst[sim] = fmax(worst[sim], e);
        print_message("# exact %dD %s angle %.0f deg scale %g: map error %.2e of the target's "
                      "size, rms %.2e / %.2e, %d iterations, %.3f s\n",
                      dim, sm_align_mode_name(cases[i].mode), cases[i].angle * 180 / M_PI,
                      cases[i].scale, e, res.rms_after, res.target_rms_after, res.iterations,
                      res.seconds);
        assert_true(e < (sim ? 1.9e-5 : 6.8e-6));
        sm_sdf_free(d);
        sm_surface_free(s);
        sm_mesh_free(m);
    }
    print_message("# exact: worst rigid %.2e (Open3D 6.8e-6), similarity %.2e (1.9e-5)\n",
                  worst[0], worst[1]);
}

/* A capsule (length 5, radius 0.5 along x), a bent one of the same
 * length (two arms of 2 at a right angle, radius 0.5) and the unit ball. */
#define CAPSULE                                                                      \
    "SetFactory(\"OpenCASCADE\");\nCylinder(1) = {0, 0, 0, 4, 0, 0, 0.5};\n"        \
    "Sphere(2) = {0, 0, 0, 0.5};\nSphere(3) = {4, 0, 0, 0.5};\n"                      \
    "BooleanUnion{ Volume{1}; Delete; }{ Volume{2}; Volume{3}; Delete; }\n"          \
    "Mesh.MeshSizeFromPoints = 0;\n"
#define BENT_CAPSULE                                                                 \
    "SetFactory(\"OpenCASCADE\");\nCylinder(1) = {0, 0, 0, 2, 0, 0, 0.5};\n"        \
    "Cylinder(2) = {2, 0, 0, 0, 2, 0, 0.5};\nSphere(3) = {0, 0, 0, 0.5};\n"           \
    "Sphere(4) = {2, 0, 0, 0.5};\nSphere(5) = {2, 2, 0, 0.5};\n"                      \
    "BooleanUnion{ Volume{1}; Delete; }{ Volume{2}; Volume{3}; Volume{4}; Volume{5}; "  \
    "Delete; }\nMesh.MeshSizeFromPoints = 0;\n"

static sm_mesh *gmsh_shape(const char *geo, double h)
{
    sm_mesh *m;
    sm_error err;
    char msg[512];
    if (util_gmsh_mesh(geo, 3, h, &m, msg, sizeof msg) != SM_OK)
        fail_msg("gmsh: %s", msg);
    assert_int_equal(sm_mesh_build_boundary(m, &err), SM_OK);
    return m;
}

/* Volume of a tetrahedral mesh. */
static double mesh_volume(const sm_mesh *m)
{
    double v = 0;
    for (int32_t e = 0; e < m->nelems; e++)
        v += fabs(sm_elem_volume(m, m->coords, e));
    return v;
}

/* The alignments that used to shrink: scored from the template's side
 * only, a smaller template always wins.  Two-sided, the capsule's affine
 * map onto the bent capsule spans both arms (one-sided it was squeezed to
 * 0.49 of its length into one arm), and the ball's similarity scale
 * follows the volume ratio (one-sided: 0.58 where the ratio gives 0.80). */
static void test_no_shrink(void **state)
{
    (void)state;
    sm_mesh *capsule = gmsh_shape(CAPSULE, 0.15), *bent = gmsh_shape(BENT_CAPSULE, 0.15);
    sm_mesh *ball = gmsh_shape(UTIL_GMSH_UNIT_BALL, 0.2);
    sm_transform id;
    sm_transform_identity(&id, 3);
    sm_surface *s = moved_surface(bent, &id);
    sm_sdf *d;
    sm_error err;
    assert_int_equal(sm_sdf_new(s, &d, &err), SM_OK);
    /* the capsule: the image of its axis (0,0,0)-(4,0,0) against the
     * chord between the arms' end centres (0,0,0)-(2,2,0), 2.83 long */
    sm_align_opts o = {.mode = SM_ALIGN_AFFINE, .template_mesh = capsule, .surface = d};
    sm_align_result res;
    assert_int_equal(sm_align_run(&o, &res, &err), SM_OK);
    double axis[3] = {4 * res.transform.a[0][0], 4 * res.transform.a[1][0],
                      4 * res.transform.a[2][0]};
    double len = sqrt(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]);
    print_message("# capsule -> bent capsule, affine: axis %.3f long (chord 2.83, one arm 2; "
                  "was 0.49 x 4 = 1.96), rms %.3f / target side %.3f, %.3f s\n",
                  len, res.rms_after, res.target_rms_after, res.seconds);
    assert_true(len > 0.85 * 2 * sqrt(2.0));
    assert_true(res.target_rms_after < 0.25);
    /* the ball: the similarity scale against the volume ratio's */
    double ratio = cbrt(mesh_volume(bent) / mesh_volume(ball));
    o = (sm_align_opts){.mode = SM_ALIGN_SIMILARITY, .template_mesh = ball, .surface = d};
    assert_int_equal(sm_align_run(&o, &res, &err), SM_OK);
    print_message("# ball -> bent capsule, similarity: scale %.3f, the volume ratio's %.3f "
                  "(was 0.58 against 0.80)\n", res.scale, ratio);
    assert_true(fabs(res.scale - ratio) < 0.12 * ratio);
    sm_sdf_free(d);
    sm_surface_free(s);
    sm_mesh_free(capsule);
    sm_mesh_free(bent);
    sm_mesh_free(ball);
}

/* A landmark start (noisy, rotation off by the noise) refined onto the
 * exact answer, in 3D: the start is used, and improved; with an
 * anisotropic stretch (affine: the 3D one, from moments). */
static void test_landmark_start(void **state)
{
    (void)state;
    const known stretched = {3, SM_ALIGN_AFFINE, 0.7, 1, 1, {1.4, 0.8, 1.1}};
    check_known(&stretched);
    sm_mesh *m = shape(3);
    double axis[3] = {1, 2, 3}, r[3][3], b[3] = {5, -3, 2};
    rotation(3, axis, 2.5, r);
    sm_transform truth, start;
    make_transform(3, r, 1, b, &truth);
    target t;
    make_target(m, &truth, &t);
    double src[12] = {0, 0, 0, 1, 0, 0, 0, 0.6, 0, 0.85, 0.5, 0.55}, dst[12];
    sm_transform_apply(&truth, 4, src, dst);
    for (int i = 0; i < 12; i++)
        dst[i] += 0.02 * (uniform() - 0.5);
    sm_error err;
    assert_int_equal(sm_align_landmarks(3, 4, src, dst, SM_ALIGN_RIGID, &start, &err), SM_OK);
    sm_align_opts o = {.mode = SM_ALIGN_RIGID, .template_mesh = m, .target = t.field,
                       .background = t.bg, .distance = t.values, .start = &start};
    sm_align_result res;
    assert_int_equal(sm_align_run(&o, &res, &err), SM_OK);
    double ea0, eb0, ea, eb;
    compare(&start, &truth, 1, &ea0, &eb0);
    compare(&res.transform, &truth, 1, &ea, &eb);
    print_message("# landmark start: matrix error %.2e -> %.2e\n", ea0, ea);
    assert_int_equal(res.candidates, 1);
    assert_true(ea < 1e-3 && eb < 1e-3 && ea < ea0);
    target_free(&t);
    sm_mesh_free(m);
}

static void test_refusals(void **state)
{
    (void)state;
    sm_mesh *m = shape(2);
    sm_transform id;
    sm_transform_identity(&id, 2);
    target t;
    make_target(m, &id, &t);
    sm_align_result res;
    sm_error err;
    sm_align_opts o = {.mode = SM_ALIGN_NONE, .template_mesh = m, .target = t.field,
                       .background = t.bg, .distance = t.values};
    assert_int_equal(sm_align_run(&o, &res, &err), SM_ERR_INVALID);
    o.mode = SM_ALIGN_RIGID;
    for (int32_t v = 0; v < t.bg->nverts; v++) /* a target with no inside */
        t.values[v] = fabs(t.values[v]) + 1;
    assert_int_equal(sm_align_run(&o, &res, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "no inside"));
    sm_align_mode mode;
    assert_int_equal(sm_align_mode_from_name("similarity", &mode), 0);
    assert_int_equal(mode, SM_ALIGN_SIMILARITY);
    assert_int_equal(sm_align_mode_from_name("Rigid", &mode), -1);
    assert_null(sm_align_mode_name((sm_align_mode)4));
    double h[9];
    sm_transform_homogeneous(&id, h);
    assert_true(h[0] == 1 && h[1] == 0 && h[2] == 0 && h[8] == 1);
    target_free(&t);
    sm_mesh_free(m);
}

/* A cancel during the alignment: the flag is polled before every pass
 * over the boundary points, so the run returns within about a pass of the
 * flag being set, cancelled, however far it had to go.  The flag is set
 * by another thread a third of the way through a full alignment (the
 * job runner's cancel from a signal or a daemon's DELETE arrives so). */
typedef struct canceller {
    volatile int flag;
    double delay, set_at;
} canceller;

static void *cancel_later(void *arg)
{
    canceller *c = arg;
    struct timespec ts = {(time_t)c->delay, (long)((c->delay - (time_t)c->delay) * 1e9)};
    nanosleep(&ts, NULL);
    c->set_at = sm_clock_seconds();
    c->flag = 1;
    return NULL;
}

static void test_cancel(void **state)
{
    (void)state;
    sm_mesh *m = shape(3);
    double axis[3] = {1, -2, 0.5}, r[3][3], b[3] = {30, -10, 4};
    rotation(3, axis, 2.9, r);
    sm_transform truth;
    make_transform(3, r, 2.5, b, &truth);
    target t;
    make_target(m, &truth, &t);
    sm_align_opts o = {.mode = SM_ALIGN_AFFINE, .template_mesh = m, .target = t.field,
                       .background = t.bg, .distance = t.values};
    sm_align_result full, res;
    sm_error err;
    assert_int_equal(sm_align_run(&o, &full, &err), SM_OK);
    assert_int_equal(full.cancelled, 0);
    /* set before the start: only the passes before the first poll (the
     * points, rms_before, the moments) */
    canceller c = {.flag = 1};
    o.cancel = &c.flag;
    assert_int_equal(sm_align_run(&o, &res, &err), SM_OK);
    assert_int_equal(res.cancelled, 1);
    assert_int_equal(res.iterations, 0);
    double before_poll = res.seconds;
    /* set by another thread mid-way */
    c.flag = 0;
    c.delay = full.seconds / 3;
    pthread_t th;
    assert_int_equal(pthread_create(&th, NULL, cancel_later, &c), 0);
    assert_int_equal(sm_align_run(&o, &res, &err), SM_OK);
    double returned = sm_clock_seconds();
    pthread_join(th, NULL);
    double latency = returned - c.set_at;
    print_message("# cancel: full alignment %.3f s (%d iterations); preset flag %.4f s; set at "
                  "%.3f s: returned %.4f s later, cancelled %d, %d iterations\n",
                  full.seconds, full.iterations, before_poll, c.delay, latency, res.cancelled,
                  res.iterations);
    if (res.cancelled) {
        assert_true(res.iterations < full.iterations);
        assert_true(isnan(res.rms_after));
        /* a pass costs less than the preset run's few passes; the
         * slack, a quarter of the full run (the same machine's speed), is
         * for a descheduled thread on a loaded machine: without the polls
         * the run would go on for two thirds of it */
        assert_true(latency < before_poll + 0.25 * full.seconds);
    } else { /* the thread was late (a loaded machine): it ended first */
        assert_true(latency <= 0);
    }
    target_free(&t);
    sm_mesh_free(m);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_eigen_svd),       cmocka_unit_test(test_landmarks_exact), cmocka_unit_test(test_landmarks_extreme),
        cmocka_unit_test(test_landmarks_refused),
        cmocka_unit_test(test_known_3d),        cmocka_unit_test(test_known_2d),
        cmocka_unit_test(test_landmark_start),  cmocka_unit_test(test_known_exact),
        cmocka_unit_test(test_no_shrink),       cmocka_unit_test(test_refusals),
        cmocka_unit_test(test_cancel),
    };
    return cmocka_run_group_tests(tests, NULL, free_shapes);
}
