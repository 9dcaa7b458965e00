/* Gmsh .msh reading (core/io/sm_io_msh.c): meshes written by the real gmsh
 * at test time from one geometry in Medit, .msh 4.1 ASCII, 4.1 binary
 * (also gzip-compressed) and 2.2 ASCII must read as the same mesh:
 * vertices, elements, facets and references (physical tags).  The
 * hostile cases are in tests/data/malformed/msh-* (test_malformed). */
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

#include "shapematch/sm_io.h"
#include "util_gmsh.h"

/* a unit cube made of several entities, with physical groups */
#define CUBE_GEO                                                                   \
    UTIL_GMSH_UNIT_CUBE                                                            \
    "Physical Volume(\"solid\", 7) = {1};\n"                                       \
    "Physical Surface(\"bottom\", 3) = {1};\n"                                     \
    "Physical Surface(\"sides\", 4) = {13, 17, 21, 25, 26};\n"                     \
    "Mesh.SaveElementTagType = 2;\n"
#define SQUARE_GEO                                                                 \
    UTIL_GMSH_UNIT_SQUARE                                                          \
    "Physical Surface(\"plate\", 5) = {1};\n"                                      \
    "Physical Curve(\"left\", 2) = {4};\n"                                         \
    "Physical Curve(\"others\", 9) = {1, 2, 3};\n"                                 \
    "Mesh.SaveElementTagType = 2;\n"

typedef struct fixture {
    char dir[512];
} fixture;

static int setup(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    const char *tmp = getenv("TMPDIR");
    snprintf(f->dir, sizeof f->dir, "%s/sm_msh_XXXXXX", tmp && *tmp ? tmp : "/tmp");
    if (!mkdtemp(f->dir))
        return -1;
    *state = f;
    return 0;
}

static int teardown(void **state)
{
    fixture *f = *state;
    static const char *const names[] = {"a.mesh", "a41.msh", "b41.msh", "a22.msh", "b41.msh.gz"};
    char path[700];
    for (size_t k = 0; k < sizeof names / sizeof names[0]; k++) {
        snprintf(path, sizeof path, "%s/%s", f->dir, names[k]);
        unlink(path);
    }
    rmdir(f->dir);
    free(f);
    return 0;
}

static void gmsh_write(const char *geo, int dim, const char *fmt, int binary, const char *path)
{
    char msg[1024];
    sm_status st = util_gmsh_write_format(geo, dim, 0.4, fmt, binary, path, msg, sizeof msg);
    if (st != SM_OK)
        fail_msg("gmsh %s: %s", fmt, msg);
}

static sm_mesh *read_ok(const char *path)
{
    sm_mesh *m = NULL;
    sm_error err;
    sm_error_clear(&err);
    if (sm_mesh_read(path, &m, &err) != SM_OK)
        fail_msg("reading %s: %s", path, err.msg);
    return m;
}

static void assert_same_mesh(const sm_mesh *a, const sm_mesh *b, const char *what)
{
    print_message("# %s: dim %d, %d vertices, %d elements, %d facets\n", what, b->dim, b->nverts,
                  b->nelems, b->nfacets);
    assert_int_equal(a->dim, b->dim);
    assert_int_equal(a->nverts, b->nverts);
    assert_int_equal(a->nelems, b->nelems);
    assert_int_equal(a->nfacets, b->nfacets);
    for (int64_t i = 0; i < (int64_t)a->nverts * a->dim; i++)
        if (fabs(a->coords[i] - b->coords[i]) > 1e-14)
            fail_msg("%s: coordinate %lld differs: %.17g vs %.17g", what, (long long)i,
                     a->coords[i], b->coords[i]);
    assert_memory_equal(a->elems, b->elems, (size_t)a->nelems * (size_t)(a->dim + 1) * 4);
    assert_memory_equal(a->elem_refs, b->elem_refs, (size_t)a->nelems * 4);
    assert_memory_equal(a->facets, b->facets, (size_t)a->nfacets * (size_t)a->dim * 4);
    assert_memory_equal(a->facet_refs, b->facet_refs, (size_t)a->nfacets * 4);
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

/* The same physical names, in the same order. */
static void assert_same_names(const sm_mesh *a, const sm_mesh *b, const char *what)
{
    assert_int_equal(a->nnames, b->nnames);
    for (int32_t i = 0; i < a->nnames; i++) {
        if (a->names[i].dim != b->names[i].dim || a->names[i].tag != b->names[i].tag ||
            strcmp(a->names[i].name, b->names[i].name) != 0)
            fail_msg("%s: physical name %d differs", what, (int)i);
    }
}

/* m names (dim, tag) name, exactly once. */
static void assert_has_name(const sm_mesh *m, int dim, int tag, const char *name)
{
    int found = 0;
    for (int32_t i = 0; i < m->nnames; i++)
        found += m->names[i].dim == dim && m->names[i].tag == tag &&
                 strcmp(m->names[i].name, name) == 0;
    if (found != 1)
        fail_msg("physical name (%d, %d) \"%s\" found %d times", dim, tag, name, found);
}

/* Every .msh variant of geo equals gmsh's Medit export of it. */
static void check_formats_agree(fixture *f, const char *geo, int dim)
{
    char p[5][700];
    const char *names[] = {"a.mesh", "a41.msh", "b41.msh", "a22.msh", "b41.msh.gz"};
    for (int k = 0; k < 5; k++)
        snprintf(p[k], sizeof p[k], "%s/%s", f->dir, names[k]);
    gmsh_write(geo, dim, "mesh", 0, p[0]);
    gmsh_write(geo, dim, "msh41", 0, p[1]);
    gmsh_write(geo, dim, "msh41", 1, p[2]);
    gmsh_write(geo, dim, "msh22", 0, p[3]);
    gzip_copy(p[2], p[4]);
    sm_mesh *ref = read_ok(p[0]);
    assert_int_equal(ref->dim, dim);
    assert_int_equal(ref->nnames, 0); /* Medit has no names */
    sm_mesh *first = read_ok(p[1]);
    for (int k = 1; k < 5; k++) {
        sm_mesh *m = read_ok(p[k]);
        assert_same_mesh(ref, m, names[k]);
        assert_same_names(first, m, names[k]);
        sm_mesh_free(m);
    }
    sm_mesh_free(first);
    sm_mesh_free(ref);
}

static void test_cube_formats_agree(void **state)
{
    fixture *f = *state;
    check_formats_agree(f, CUBE_GEO, 3);
    /* the physical tags became the references */
    char path[700];
    snprintf(path, sizeof path, "%s/b41.msh", f->dir);
    sm_mesh *m = read_ok(path);
    for (int32_t e = 0; e < m->nelems; e++)
        assert_int_equal(m->elem_refs[e], 7);
    int32_t n3 = 0, n4 = 0;
    for (int32_t i = 0; i < m->nfacets; i++) {
        assert_true(m->facet_refs[i] == 3 || m->facet_refs[i] == 4);
        n3 += m->facet_refs[i] == 3;
        n4 += m->facet_refs[i] == 4;
    }
    assert_true(n3 > 0 && n4 > 4 * n3);
    /* ... and their $PhysicalNames travel with the mesh, also in a copy */
    assert_int_equal(m->nnames, 3);
    assert_has_name(m, 3, 7, "solid");
    assert_has_name(m, 2, 3, "bottom");
    assert_has_name(m, 2, 4, "sides");
    sm_mesh *c = NULL;
    sm_error err;
    sm_error_clear(&err);
    assert_int_equal(sm_mesh_clone(m, &c, &err), SM_OK);
    assert_same_names(m, c, "clone");
    assert_true(c->names != m->names && c->names[0].name != m->names[0].name);
    sm_mesh_free(c);
    sm_mesh_free(m);
}

static void test_square_formats_agree(void **state)
{
    fixture *f = *state;
    check_formats_agree(f, SQUARE_GEO, 2);
    char path[700];
    snprintf(path, sizeof path, "%s/a22.msh", f->dir);
    sm_mesh *m = read_ok(path);
    assert_int_equal(m->dim, 2);
    for (int32_t e = 0; e < m->nelems; e++)
        assert_int_equal(m->elem_refs[e], 5);
    for (int32_t i = 0; i < m->nfacets; i++) {
        int32_t a = m->facets[2 * i], b = m->facets[2 * i + 1];
        int left = m->coords[2 * a] == 0.0 && m->coords[2 * b] == 0.0;
        assert_int_equal(m->facet_refs[i], left ? 2 : 9);
    }
    assert_int_equal(m->nnames, 3); /* 2.2 has $PhysicalNames too */
    assert_has_name(m, 2, 5, "plate");
    assert_has_name(m, 1, 2, "left");
    assert_has_name(m, 1, 9, "others");
    sm_mesh_free(m);
}

/* A surface (triangles in 3D, no tetrahedra) is not a volume mesh. */
static void test_surface_is_not_a_volume(void **state)
{
    fixture *f = *state;
    char path[700];
    snprintf(path, sizeof path, "%s/a41.msh", f->dir);
    gmsh_write(UTIL_GMSH_UNIT_BALL, 2, "msh41", 0, path);
    sm_mesh *m = (sm_mesh *)(uintptr_t)1;
    sm_error err;
    sm_error_clear(&err);
    assert_int_equal(sm_mesh_read(path, &m, &err), SM_ERR_FORMAT);
    assert_null(m);
    assert_non_null(strstr(err.msg, "surface mesh is not a volume mesh"));
}

/* An unknown format says which formats are read. */
static void test_unknown_format(void **state)
{
    fixture *f = *state;
    char path[700];
    snprintf(path, sizeof path, "%s/a.mesh", f->dir);
    FILE *o = fopen(path, "w");
    assert_non_null(o);
    fputs("solid cube\nfacet normal 0 0 1\n", o);
    fclose(o);
    sm_mesh *m = NULL;
    sm_error err;
    sm_error_clear(&err);
    assert_int_equal(sm_mesh_read(path, &m, &err), SM_ERR_FORMAT);
    print_message("# %s\n", err.msg);
    /* an ASCII STL: named for what it is, and where a surface goes */
    assert_non_null(strstr(err.msg, "a surface (STL), not a volume mesh"));
    assert_non_null(strstr(err.msg, "--target-surface"));
    assert_non_null(strstr(err.msg, "Gmsh .msh"));
    assert_non_null(strstr(err.msg, "Medit .mesh"));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_cube_formats_agree, setup, teardown),
        cmocka_unit_test_setup_teardown(test_square_formats_agree, setup, teardown),
        cmocka_unit_test_setup_teardown(test_surface_is_not_a_volume, setup, teardown),
        cmocka_unit_test_setup_teardown(test_unknown_format, setup, teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
