/* Target surfaces (sm_surface_read): one Gmsh-made sphere written by the
 * real gmsh at test time as Medit, .msh 4.1 ASCII/binary, STL ASCII and
 * STL binary (and gzip) must read as the same surface; OBJ's statements
 * (negative indices, polygons, vt/vn/g skipped); 2D polylines from Medit
 * edges and .msh lines.  Hostile cases: tests/data/malformed/surface-*. */
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
#include <zlib.h>

#include "shapematch/sm_surface.h"
#include "util_gmsh.h"

typedef struct fixture {
    char dir[512];
} fixture;

static const char *const names[] = {"s.mesh", "s41.msh", "sb41.msh", "s.stl", "sb.stl",
                                    "sb.stl.gz", "s.obj", "c.mesh", "c.msh"};
#define NNAMES (sizeof names / sizeof names[0])

static int setup(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    const char *tmp = getenv("TMPDIR");
    snprintf(f->dir, sizeof f->dir, "%s/sm_surf_XXXXXX", tmp && *tmp ? tmp : "/tmp");
    if (!mkdtemp(f->dir))
        return -1;
    *state = f;
    return 0;
}

static int teardown(void **state)
{
    fixture *f = *state;
    char path[700];
    for (size_t k = 0; k < NNAMES; k++) {
        snprintf(path, sizeof path, "%s/%s", f->dir, names[k]);
        unlink(path);
    }
    rmdir(f->dir);
    free(f);
    return 0;
}

static void path_of(const fixture *f, const char *name, char *out, size_t cap)
{
    snprintf(out, cap, "%s/%s", f->dir, name);
}

static void gmsh_write(const char *geo, int dim, const char *fmt, int binary, const char *path)
{
    char msg[1024];
    if (util_gmsh_write_format(geo, dim, 0.3, fmt, binary, path, msg, sizeof msg) != SM_OK)
        fail_msg("gmsh %s: %s", fmt, msg);
}

static sm_surface *read_ok(const char *path)
{
    sm_surface *s = NULL;
    sm_error err;
    sm_error_clear(&err);
    if (sm_surface_read(path, &s, &err) != SM_OK)
        fail_msg("reading %s: %s", path, err.msg);
    return s;
}

/* Signed volume enclosed by a triangle surface and its area. */
static void volume_area(const sm_surface *s, double *vol, double *area)
{
    *vol = *area = 0;
    for (int32_t f = 0; f < s->nfacets; f++) {
        const double *a = s->coords + 3 * s->facets[3 * f], *b = s->coords + 3 * s->facets[3 * f + 1],
                     *c = s->coords + 3 * s->facets[3 * f + 2];
        double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
        double v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        double n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
        *vol += (a[0] * n[0] + a[1] * n[1] + a[2] * n[2]) / 6;
        *area += sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]) / 2;
    }
}

static void gzip_copy(const char *src, const char *dst)
{
    FILE *in = fopen(src, "rb");
    gzFile out = gzopen(dst, "wb");
    assert_non_null(in);
    assert_non_null(out);
    char buf[4096];
    size_t n;
    while ((n = fread(buf, 1, sizeof buf, in)) > 0)
        assert_int_equal(gzwrite(out, buf, (unsigned)n), (int)n);
    fclose(in);
    assert_int_equal(gzclose(out), Z_OK);
}

/* Writes s as OBJ with relative (negative) indices and OBJ noise. */
static void write_obj(const sm_surface *s, const char *path)
{
    FILE *o = fopen(path, "w");
    assert_non_null(o);
    fprintf(o, "# made by test_surface\nmtllib none.mtl\no sphere\ng part\ns 1\n");
    for (int32_t f = 0; f < s->nfacets; f++) {
        for (int k = 0; k < 3; k++) {
            const double *p = s->coords + 3 * s->facets[3 * f + k];
            fprintf(o, "v %.17g %.17g %.17g\nvt 0.5 0.5\nvn 0 0 1\n", p[0], p[1], p[2]);
        }
        fprintf(o, f % 2 ? "f -3/-3/-3 -2/-2/-2 -1/-1/-1\n" : "f -3//-1 -2//-1 -1//-1 # c\n");
    }
    fclose(o);
}

static void test_sphere_formats_agree(void **state)
{
    fixture *f = *state;
    char p[NNAMES][700];
    for (size_t k = 0; k < NNAMES; k++)
        path_of(f, names[k], p[k], sizeof p[k]);
    gmsh_write(UTIL_GMSH_UNIT_BALL, 2, "mesh", 0, p[0]);
    gmsh_write(UTIL_GMSH_UNIT_BALL, 2, "msh41", 0, p[1]);
    gmsh_write(UTIL_GMSH_UNIT_BALL, 2, "msh41", 1, p[2]);
    gmsh_write(UTIL_GMSH_UNIT_BALL, 2, "stl", 0, p[3]);
    gmsh_write(UTIL_GMSH_UNIT_BALL, 2, "stl", 1, p[4]);
    gzip_copy(p[4], p[5]);
    sm_surface *ref = read_ok(p[0]);
    assert_int_equal(ref->dim, 3);
    write_obj(ref, p[6]);
    double v0, a0;
    volume_area(ref, &v0, &a0);
    print_message("# sphere: %d vertices, %d triangles, volume %.9g, area %.9g\n", ref->nverts,
                  ref->nfacets, v0, a0);
    assert_true(fabs(fabs(v0) - 4 * M_PI / 3) < 0.2 && fabs(a0 - 4 * M_PI) < 0.4);
    for (int k = 1; k <= 6; k++) {
        sm_surface *s = read_ok(p[k]);
        double v, a;
        volume_area(s, &v, &a);
        print_message("# %s: %d vertices, %d triangles, volume %.9g\n", names[k], s->nverts,
                      s->nfacets, v);
        assert_int_equal(s->dim, 3);
        assert_int_equal(s->nfacets, ref->nfacets);
        assert_int_equal(s->nverts, ref->nverts); /* STL and OBJ vertices welded */
        int single = k == 4 || k == 5;            /* float32 binary STL */
        assert_true(fabs(v - v0) <= (single ? 1e-6 : 1e-13));
        assert_true(fabs(a - a0) <= (single ? 1e-6 : 1e-13));
        sm_surface_free(s);
    }
    sm_surface_free(ref);
}

static void write_text(const char *path, const char *text)
{
    FILE *o = fopen(path, "w");
    assert_non_null(o);
    fputs(text, o);
    fclose(o);
}

/* Polygons are fan-triangulated; positive and negative indices mix. */
static void test_obj_polygons(void **state)
{
    fixture *f = *state;
    char path[700];
    path_of(f, "s.obj", path, sizeof path);
    write_text(path, "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.5 0.5 1\n"
                     "f 1 4 3 2\nf 1/1 2/2 -1/3\nf -4 3 5\n");
    sm_surface *s = read_ok(path);
    assert_int_equal(s->nverts, 5);
    assert_int_equal(s->nfacets, 4);
    const int32_t want[12] = {0, 3, 2, 0, 2, 1, 0, 1, 4, 1, 2, 4};
    assert_memory_equal(s->facets, want, sizeof want);
    sm_surface_free(s);
}

/* Binary STL whose header starts with "solid" is still binary. */
static void test_stl_binary_solid_header(void **state)
{
    fixture *f = *state;
    char path[700];
    path_of(f, "sb.stl", path, sizeof path);
    FILE *o = fopen(path, "wb");
    assert_non_null(o);
    char head[80];
    memset(head, ' ', sizeof head);
    memcpy(head, "solid facet endsolid", 20);
    fwrite(head, 1, 80, o);
    uint32_t n = 1;
    fwrite(&n, 4, 1, o);
    float rec[12] = {0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0};
    fwrite(rec, 4, 12, o);
    fwrite("\0", 1, 2, o);
    fclose(o);
    sm_surface *s = read_ok(path);
    assert_int_equal(s->nfacets, 1);
    assert_int_equal(s->nverts, 3);
    double sx = 0, sy = 0, sz = 0;
    for (int i = 0; i < 3; i++) {
        sx += s->coords[3 * i];
        sy += s->coords[3 * i + 1];
        sz += s->coords[3 * i + 2];
    }
    assert_true(sx == 1.0 && sy == 1.0 && sz == 0.0);
    sm_surface_free(s);
}

#define CIRCLE_GEO                                                              \
    "SetFactory(\"OpenCASCADE\");\nCircle(1) = {0, 0, 0, 1};\n"                \
    "Physical Curve(\"rim\", 6) = {1};\nMesh.SaveElementTagType = 2;\n"

/* 2D polylines: Medit edges (Dimension 3, z = 0) and .msh lines. */
static void test_polylines(void **state)
{
    fixture *f = *state;
    char pm[700], pg[700];
    path_of(f, "c.mesh", pm, sizeof pm);
    path_of(f, "c.msh", pg, sizeof pg);
    gmsh_write(CIRCLE_GEO, 2, "mesh", 0, pm);
    gmsh_write(CIRCLE_GEO, 2, "msh41", 0, pg);
    /* gmsh -2 of a curve only meshes the curve */
    sm_surface *a = read_ok(pm), *b = read_ok(pg);
    assert_int_equal(a->dim, 2);
    assert_int_equal(b->dim, 2);
    assert_int_equal(a->nfacets, b->nfacets);
    double la = 0, lb = 0;
    for (int32_t i = 0; i < a->nfacets; i++) {
        const double *p = a->coords + 2 * a->facets[2 * i], *q = a->coords + 2 * a->facets[2 * i + 1];
        la += hypot(q[0] - p[0], q[1] - p[1]);
        p = b->coords + 2 * b->facets[2 * i];
        q = b->coords + 2 * b->facets[2 * i + 1];
        lb += hypot(q[0] - p[0], q[1] - p[1]);
        assert_int_equal(b->facet_refs[i], 6);
    }
    print_message("# circle: %d segments, length %.12g\n", a->nfacets, la);
    assert_true(fabs(la - lb) < 1e-13 && fabs(la - 2 * M_PI) < 0.05);
    sm_surface_free(a);
    sm_surface_free(b);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_sphere_formats_agree, setup, teardown),
        cmocka_unit_test_setup_teardown(test_obj_polygons, setup, teardown),
        cmocka_unit_test_setup_teardown(test_stl_binary_solid_header, setup, teardown),
        cmocka_unit_test_setup_teardown(test_polylines, setup, teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
