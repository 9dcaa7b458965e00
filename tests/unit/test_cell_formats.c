/* PLY, OFF/PLY2 and VTK (legacy .vtk, XML .vtu/.vtp) reading
 * (core/io/sm_io_ply.c, sm_io_off.c, sm_io_vtk.c, sm_io_vtkxml.c):
 *   - the samples of tests/data/formats/cells/ (written by its generate.py
 *     in every encoding: PLY ASCII and both byte orders, OFF with colours,
 *     VTK legacy 4.2 and 5.1 ASCII and binary, XML ASCII, base64 inline,
 *     appended raw and base64, zlib-compressed, UInt64 headers, big endian)
 *     equal, exactly, the Medit file of the same content written beside
 *     them by the script (read by the independent Medit reader);
 *   - files written by the real gmsh at test time (VTK ASCII and binary,
 *     PLY2) equal gmsh's .msh 4.1 of the same mesh;
 *   - the .vtu shapematch writes reads back as the mesh written;
 *   - a format that is not read is named as unknown.
 * The hostile cases are tests/data/malformed/surface-{ply,off,vtk}* and
 * mesh-vtk* (test_malformed); the fuzz targets fuzz_ply and fuzz_vtk. */
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

#include "shapematch/sm_io.h"
#include "shapematch/sm_surface.h"
#include "util_gmsh.h"

#define BALL_GEO                                                                     \
    UTIL_GMSH_UNIT_BALL                                                              \
    "Physical Surface(\"skin\", 7) = {1};\nPhysical Volume(\"core\", 9) = {1};\n"

static const char *data_path(const char *rel, char *out, size_t cap)
{
    const char *root = getenv("SM_ROOT");
    snprintf(out, cap, "%s/tests/data/formats/cells/%s", root && *root ? root : ".", rel);
    return out;
}

static sm_mesh *mesh_ok(const char *path)
{
    sm_mesh *m = NULL;
    sm_error err;
    sm_error_clear(&err);
    if (sm_mesh_read(path, &m, &err) != SM_OK)
        fail_msg("reading %s: %s", path, err.msg);
    return m;
}

static sm_surface *surface_ok(const char *path)
{
    sm_surface *s = NULL;
    sm_error err;
    sm_error_clear(&err);
    if (sm_surface_read(path, &s, &err) != SM_OK)
        fail_msg("reading %s: %s", path, err.msg);
    return s;
}

/* tol: 0 for bit for bit, else the largest coordinate difference (gmsh
 * prints its .msh and .vtk coordinates to 16 digits, not 17). */
static void assert_same_mesh(const sm_mesh *a, const sm_mesh *b, double tol, const char *what)
{
    print_message("# %s: dim %d, %d vertices, %d elements, %d facets\n", what, b->dim,
                  b->nverts, b->nelems, b->nfacets);
    assert_int_equal(a->dim, b->dim);
    assert_int_equal(a->nverts, b->nverts);
    assert_int_equal(a->nelems, b->nelems);
    assert_int_equal(a->nfacets, b->nfacets);
    for (int64_t i = 0; i < (int64_t)a->nverts * a->dim; i++)
        if (tol == 0 ? memcmp(&a->coords[i], &b->coords[i], 8) != 0
                     : !(fabs(a->coords[i] - b->coords[i]) <= tol))
            fail_msg("%s: coordinate %lld differs: %.17g vs %.17g", what, (long long)i,
                     a->coords[i], b->coords[i]);
    assert_memory_equal(a->elems, b->elems, (size_t)a->nelems * (size_t)(a->dim + 1) * 4);
    assert_memory_equal(a->elem_refs, b->elem_refs, (size_t)a->nelems * 4);
    assert_memory_equal(a->facets, b->facets, (size_t)a->nfacets * (size_t)a->dim * 4);
    assert_memory_equal(a->facet_refs, b->facet_refs, (size_t)a->nfacets * 4);
}

/* Same points and facets (and references when with_refs). */
static void assert_same_surface(const sm_surface *a, const sm_surface *b, int with_refs,
                                const char *what)
{
    print_message("# %s: %d vertices, %d facets\n", what, b->nverts, b->nfacets);
    assert_int_equal(a->dim, b->dim);
    assert_int_equal(a->nverts, b->nverts);
    assert_int_equal(a->nfacets, b->nfacets);
    assert_memory_equal(a->coords, b->coords, (size_t)a->nverts * (size_t)a->dim * 8);
    assert_memory_equal(a->facets, b->facets, (size_t)a->nfacets * (size_t)a->dim * 4);
    for (int32_t f = 0; f < b->nfacets; f++)
        assert_int_equal(b->facet_refs[f], with_refs ? a->facet_refs[f] : 0);
}

static void test_samples_volume(void **state)
{
    (void)state;
    static const char *const files[] = {
        "volume-42-ascii.vtk", "volume-42-binary.vtk", "volume-51-ascii.vtk",
        "volume-51-binary.vtk", "volume-ascii.vtu", "volume-binary.vtu",
        "volume-binary-zlib.vtu", "volume-binary-zlib-uint64-be.vtu",
        "volume-appended-raw.vtu", "volume-appended-raw-zlib.vtu",
        "volume-appended-base64.vtu", "volume-appended-base64-zlib-uint64.vtu"};
    char p[600];
    sm_mesh *ref = mesh_ok(data_path("ref-volume.mesh", p, sizeof p));
    for (size_t k = 0; k < sizeof files / sizeof files[0]; k++) {
        sm_mesh *m = mesh_ok(data_path(files[k], p, sizeof p));
        assert_same_mesh(ref, m, 0, files[k]);
        sm_mesh_free(m);
        /* as a target surface: the same file's triangles */
        sm_surface *s = surface_ok(p);
        assert_int_equal(s->nfacets, ref->nfacets);
        assert_memory_equal(s->facets, ref->facets, (size_t)ref->nfacets * 12);
        assert_memory_equal(s->facet_refs, ref->facet_refs, (size_t)ref->nfacets * 4);
        sm_surface_free(s);
    }
    sm_mesh_free(ref);
}

static void test_samples_surface(void **state)
{
    (void)state;
    static const struct {
        const char *file;
        int refs;
    } files[] = {{"surface-ascii.ply", 0},     {"surface-le.ply", 0},
                 {"surface-be.ply", 0},        {"surface.off", 0},
                 {"surface-colours.off", 0},   {"surface-42-ascii.vtk", 1},
                 {"surface-42-binary.vtk", 1}, {"surface-51-ascii.vtk", 1},
                 {"surface-51-binary.vtk", 1}, {"surface-ascii.vtp", 1},
                 {"surface-binary-zlib.vtp", 1}, {"surface-appended-raw-zlib.vtp", 1}};
    char p[600];
    sm_surface *ref = surface_ok(data_path("ref-surface.mesh", p, sizeof p));
    for (size_t k = 0; k < sizeof files / sizeof files[0]; k++) {
        sm_surface *s = surface_ok(data_path(files[k].file, p, sizeof p));
        assert_same_surface(ref, s, files[k].refs, files[k].file);
        sm_surface_free(s);
    }
    sm_surface_free(ref);
}

typedef struct fixture {
    char dir[512];
} fixture;

static int setup(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    const char *tmp = getenv("TMPDIR");
    snprintf(f->dir, sizeof f->dir, "%s/sm_cells_XXXXXX", tmp && *tmp ? tmp : "/tmp");
    if (!mkdtemp(f->dir))
        return -1;
    *state = f;
    return 0;
}

static const char *const tmp_names[] = {"a.msh", "a.vtk", "b.vtk", "s.msh", "s.ply2", "r.vtu"};

static int teardown(void **state)
{
    fixture *f = *state;
    char path[700];
    for (size_t k = 0; k < sizeof tmp_names / sizeof tmp_names[0]; k++) {
        snprintf(path, sizeof path, "%s/%s", f->dir, tmp_names[k]);
        unlink(path);
    }
    rmdir(f->dir);
    free(f);
    return 0;
}

static void gmsh(const fixture *f, int dim, const char *fmt, int binary, const char *name,
                 char *path, size_t cap)
{
    char msg[1024];
    snprintf(path, cap, "%s/%s", f->dir, name);
    if (util_gmsh_write_format(BALL_GEO, dim, 0.5, fmt, binary, path, msg, sizeof msg) != SM_OK)
        fail_msg("gmsh %s: %s", fmt, msg);
}

/* gmsh's VTK (ASCII, binary) of a ball equals its .msh: points, tetrahedra,
 * triangles, physical tags (CellEntityIds). */
static void test_gmsh_vtk(void **state)
{
    const fixture *f = *state;
    char pm[700], pa[700], pb[700];
    gmsh(f, 3, "msh41", 0, "a.msh", pm, sizeof pm);
    gmsh(f, 3, "vtk", 0, "a.vtk", pa, sizeof pa);
    gmsh(f, 3, "vtk", 1, "b.vtk", pb, sizeof pb);
    sm_mesh *ref = mesh_ok(pm), *a = mesh_ok(pa), *b = mesh_ok(pb);
    assert_true(ref->nelems > 100);
    assert_int_equal(ref->elem_refs[0], 9);
    assert_int_equal(ref->facet_refs[0], 7);
    assert_same_mesh(ref, a, 1e-14, "gmsh vtk ASCII");
    assert_same_mesh(ref, b, 1e-14, "gmsh vtk binary");
    sm_mesh_free(ref);
    sm_mesh_free(a);
    sm_mesh_free(b);
}

/* gmsh's PLY2 surface equals the triangles of its .msh (references
 * aside: PLY2 has none). */
static void test_gmsh_ply2(void **state)
{
    const fixture *f = *state;
    char pm[700], pp[700];
    gmsh(f, 2, "msh41", 0, "s.msh", pm, sizeof pm);
    gmsh(f, 2, "ply2", 0, "s.ply2", pp, sizeof pp);
    sm_surface *ref = surface_ok(pm), *s = surface_ok(pp);
    assert_true(ref->nfacets > 50);
    assert_same_surface(ref, s, 0, "gmsh ply2");
    sm_surface_free(ref);
    sm_surface_free(s);
}

/* The .vtu shapematch writes (sm_vtu_write) reads back as its mesh. */
static void test_own_vtu(void **state)
{
    const fixture *f = *state;
    char pm[700], pv[700];
    gmsh(f, 3, "msh41", 0, "a.msh", pm, sizeof pm);
    snprintf(pv, sizeof pv, "%s/r.vtu", f->dir);
    sm_mesh *ref = mesh_ok(pm);
    sm_error err;
    sm_error_clear(&err);
    if (sm_vtu_write(pv, ref, NULL, NULL, NULL, &err) != SM_OK)
        fail_msg("%s", err.msg);
    sm_mesh *m = mesh_ok(pv);
    assert_same_mesh(ref, m, 0, "shapematch .vtu");
    sm_mesh_free(m);
    sm_mesh_free(ref);
}

/* Text of no format read: named as unknown, with the formats read. */
static void test_unknown(void **state)
{
    const fixture *f = *state;
    char p[700];
    snprintf(p, sizeof p, "%s/r.vtu", f->dir);
    FILE *fp = fopen(p, "w");
    assert_non_null(fp);
    for (int k = 0; k < 20; k++)
        fputs("This is a text file that is not a surface at all.\n", fp);
    fclose(fp);
    sm_surface *s = NULL;
    sm_error err;
    sm_error_clear(&err);
    assert_int_equal(sm_surface_read(p, &s, &err), SM_ERR_FORMAT);
    print_message("# %s\n", err.msg);
    assert_non_null(strstr(err.msg, "unknown surface format"));
    assert_non_null(strstr(err.msg, "PLY"));
    assert_null(strstr(err.msg, "STL facet count"));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_samples_volume),
        cmocka_unit_test(test_samples_surface),
        cmocka_unit_test_setup_teardown(test_gmsh_vtk, setup, teardown),
        cmocka_unit_test_setup_teardown(test_gmsh_ply2, setup, teardown),
        cmocka_unit_test_setup_teardown(test_own_vtu, setup, teardown),
        cmocka_unit_test_setup_teardown(test_unknown, setup, teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
