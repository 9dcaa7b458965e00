/* Writing surfaces (see sm_surface.h, sm_surface_write): one format per
 * output name, so that whatever sm_surface_read took in (STL, OBJ, PLY,
 * OFF, VTK, Medit) can go back out in kind after its vertices moved
 * (`shapematch warp --mesh`, POST /v1/jobs/{id}/warp).  The text formats
 * write %.17g-exact numbers (sm__writer_real) and carry the facets'
 * references where the format has a place for them (Medit, VTK's "ref"
 * cell array). */
#include "shapematch/sm_surface.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "io/sm_writer.h"

typedef enum surface_format {
    FMT_UNKNOWN,
    FMT_MEDIT,
    FMT_STL,
    FMT_OBJ,
    FMT_PLY,
    FMT_OFF,
    FMT_VTK,
    FMT_VTU
} surface_format;

static int has_suffix(const char *path, const char *suffix)
{
    size_t n = strlen(path), k = strlen(suffix);
    return n >= k && strcasecmp(path + n - k, suffix) == 0;
}

static surface_format format_of(const char *path)
{
    static const struct {
        const char *suffix;
        surface_format f;
    } table[] = {{".mesh", FMT_MEDIT}, {".meshb", FMT_MEDIT}, {".mesh.gz", FMT_MEDIT},
                 {".meshb.gz", FMT_MEDIT}, {".stl", FMT_STL}, {".obj", FMT_OBJ},
                 {".ply", FMT_PLY}, {".off", FMT_OFF}, {".vtk", FMT_VTK}, {".vtu", FMT_VTU}};
    for (size_t i = 0; i < sizeof table / sizeof table[0]; i++)
        if (has_suffix(path, table[i].suffix))
            return table[i].f;
    return FMT_UNKNOWN;
}

/* A surface as a Medit mesh of facets only (no elements). */
static sm_status write_medit(const char *path, const sm_surface *s, const double *xyz,
                             sm_error *err)
{
    sm_mesh m;
    memset(&m, 0, sizeof m);
    m.dim = s->dim;
    m.nverts = s->nverts;
    m.coords = (double *)xyz;
    int32_t *refs = calloc((size_t)s->nverts + 1, sizeof *refs);
    int32_t *frefs = s->facet_refs ? NULL : calloc((size_t)s->nfacets + 1, sizeof *frefs);
    if (!refs || (!s->facet_refs && !frefs)) {
        free(refs);
        free(frefs);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    }
    m.vert_refs = refs;
    m.nfacets = s->nfacets;
    m.facets = s->facets;
    m.facet_refs = s->facet_refs ? s->facet_refs : frefs;
    sm_status st = sm_mesh_write_coords(path, &m, xyz, err);
    free(refs);
    free(frefs);
    return st;
}

static void put_f32(unsigned char *p, double v)
{
    float f = (float)v;
    uint32_t u;
    memcpy(&u, &f, 4);
    for (int i = 0; i < 4; i++)
        p[i] = (unsigned char)(u >> (8 * i));
}

/* Binary STL (little endian, single precision as the format is), normals
 * from the triangles as written. */
static void write_stl(sm_writer *w, const sm_surface *s, const double *xyz)
{
    unsigned char head[84] = "binary STL written by shapematch";
    uint32_t n = (uint32_t)s->nfacets;
    for (int i = 0; i < 4; i++)
        head[80 + i] = (unsigned char)(n >> (8 * i));
    sm__writer_bytes(w, head, sizeof head);
    for (int32_t t = 0; t < s->nfacets; t++) {
        const double *p[3];
        for (int k = 0; k < 3; k++)
            p[k] = xyz + (size_t)s->facets[(size_t)t * 3 + k] * 3;
        double u[3], v[3], nrm[3], len = 0;
        for (int i = 0; i < 3; i++) {
            u[i] = p[1][i] - p[0][i];
            v[i] = p[2][i] - p[0][i];
        }
        for (int i = 0; i < 3; i++) {
            nrm[i] = u[(i + 1) % 3] * v[(i + 2) % 3] - u[(i + 2) % 3] * v[(i + 1) % 3];
            len += nrm[i] * nrm[i];
        }
        len = sqrt(len);
        unsigned char rec[50] = {0};
        for (int i = 0; i < 3; i++)
            put_f32(rec + 4 * i, len > 0 ? nrm[i] / len : 0.0);
        for (int k = 0; k < 3; k++)
            for (int i = 0; i < 3; i++)
                put_f32(rec + 12 + 12 * k + 4 * i, p[k][i]);
        sm__writer_bytes(w, rec, sizeof rec);
    }
}

/* The vertices as "x y z" lines (z = 0 in 2D), each ending with end. */
static void write_points(sm_writer *w, const sm_surface *s, const double *xyz, const char *prefix)
{
    const int D = s->dim;
    for (int32_t v = 0; v < s->nverts; v++) {
        const double *x = xyz + (size_t)v * (size_t)D;
        sm__writer_printf(w, "%s", prefix);
        sm__writer_real(w, x[0], ' ');
        sm__writer_real(w, x[1], ' ');
        sm__writer_real(w, D == 3 ? x[2] : 0.0, '\n');
    }
}

/* The facets' vertex indices (plus base) after a prefix, one per line. */
static void write_facets(sm_writer *w, const sm_surface *s, const char *prefix, int base)
{
    const int D = s->dim;
    for (int32_t t = 0; t < s->nfacets; t++) {
        const int32_t *f = s->facets + (size_t)t * (size_t)D;
        sm__writer_printf(w, "%s", prefix);
        for (int k = 0; k < D; k++)
            sm__writer_int(w, (int64_t)f[k] + base, k + 1 < D ? ' ' : '\n');
    }
}

/* The facets' references as a VTK cell array of ints, "ref" (the name
 * sm_vtu_write gives them and the VTK readers take back). */
static void write_vtk_refs(sm_writer *w, const sm_surface *s)
{
    for (int32_t t = 0; t < s->nfacets; t++)
        sm__writer_int(w, s->facet_refs ? s->facet_refs[t] : 0, '\n');
}

static void write_text(sm_writer *w, surface_format f, const sm_surface *s, const double *xyz)
{
    const int D = s->dim;
    const char *cell = D == 3 ? "3 " : "2 ";
    switch (f) {
    case FMT_OBJ:
        sm__writer_printf(w, "# written by shapematch\n");
        write_points(w, s, xyz, "v ");
        write_facets(w, s, D == 3 ? "f " : "l ", 1);
        break;
    case FMT_PLY: /* triangles only (3D) */
        sm__writer_printf(w,
                          "ply\nformat ascii 1.0\ncomment written by shapematch\n"
                          "element vertex %ld\nproperty double x\nproperty double y\n"
                          "property double z\n",
                          (long)s->nverts);
        sm__writer_printf(w, "element face %ld\nproperty list uchar int vertex_indices\n"
                             "end_header\n",
                          (long)s->nfacets);
        write_points(w, s, xyz, "");
        write_facets(w, s, "3 ", 0);
        break;
    case FMT_OFF:
        sm__writer_printf(w, "OFF\n%ld %ld 0\n", (long)s->nverts, (long)s->nfacets);
        write_points(w, s, xyz, "");
        write_facets(w, s, cell, 0);
        break;
    case FMT_VTK:
        sm__writer_printf(w, "# vtk DataFile Version 4.2\nwritten by shapematch\nASCII\n"
                             "DATASET POLYDATA\nPOINTS %ld double\n",
                          (long)s->nverts);
        write_points(w, s, xyz, "");
        sm__writer_printf(w, "%s %ld %ld\n", D == 3 ? "POLYGONS" : "LINES", (long)s->nfacets,
                          (long)s->nfacets * (D + 1));
        write_facets(w, s, cell, 0);
        sm__writer_printf(w, "CELL_DATA %ld\nSCALARS ref int 1\nLOOKUP_TABLE default\n",
                          (long)s->nfacets);
        write_vtk_refs(w, s);
        break;
    default: /* FMT_VTU: an unstructured grid of triangles (5) or lines (3) */
        sm__writer_printf(w,
                          "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" "
                          "version=\"1.0\" byte_order=\"LittleEndian\">\n<UnstructuredGrid>\n"
                          "<Piece NumberOfPoints=\"%ld\" NumberOfCells=\"%ld\">\n<Points>\n"
                          "<DataArray type=\"Float64\" NumberOfComponents=\"3\" "
                          "format=\"ascii\">\n",
                          (long)s->nverts, (long)s->nfacets);
        write_points(w, s, xyz, "");
        sm__writer_printf(w, "</DataArray>\n</Points>\n<Cells>\n<DataArray type=\"Int32\" "
                             "Name=\"connectivity\" format=\"ascii\">\n");
        write_facets(w, s, "", 0);
        sm__writer_printf(w, "</DataArray>\n<DataArray type=\"Int64\" Name=\"offsets\" "
                             "format=\"ascii\">\n");
        for (int32_t t = 0; t < s->nfacets; t++)
            sm__writer_int(w, (int64_t)(t + 1) * D, '\n');
        sm__writer_printf(w, "</DataArray>\n<DataArray type=\"UInt8\" Name=\"types\" "
                             "format=\"ascii\">\n");
        for (int32_t t = 0; t < s->nfacets; t++)
            sm__writer_int(w, D == 3 ? 5 : 3, '\n');
        sm__writer_printf(w, "</DataArray>\n</Cells>\n<CellData>\n<DataArray type=\"Int32\" "
                             "Name=\"ref\" format=\"ascii\">\n");
        write_vtk_refs(w, s);
        sm__writer_printf(w, "</DataArray>\n</CellData>\n</Piece>\n</UnstructuredGrid>\n"
                             "</VTKFile>\n");
        break;
    }
}

sm_status sm_surface_write(const char *path, const sm_surface *s, const double *coords,
                           sm_error *err)
{
    if (!path)
        return sm_error_set(err, SM_ERR_INVALID, "no surface file name");
    if (!s || (s->dim != 2 && s->dim != 3) || s->nverts < 0 || s->nfacets < 0 ||
        (s->nfacets > 0 && !s->facets))
        return sm_error_set(err, SM_ERR_INVALID, "sm_surface_write: invalid surface");
    const double *xyz = coords ? coords : s->coords;
    surface_format f = format_of(path);
    if (f == FMT_UNKNOWN)
        return sm_error_set(err, SM_ERR_INVALID,
                            "%s: the surface format is chosen by the name's extension: %s", path,
                            SM_SURFACE_WRITE_FORMATS);
    if ((f == FMT_STL || f == FMT_PLY || f == FMT_OFF) && s->dim != 3)
        return sm_error_set(err, SM_ERR_INVALID,
                            "%s: a 2D polyline is written as .mesh, .meshb, .obj, .vtk or .vtu "
                            "(STL, PLY and OFF hold triangles)",
                            path);
    for (size_t i = 0; i < (size_t)s->nverts * (size_t)s->dim; i++)
        if (!isfinite(xyz[i]))
            return sm_error_set(err, SM_ERR_INVALID, "%s: vertex %zu has a non-finite coordinate",
                                path, i / (size_t)s->dim + 1);
    for (size_t i = 0; i < (size_t)s->nfacets * (size_t)s->dim; i++)
        if (s->facets[i] < 0 || s->facets[i] >= s->nverts)
            return sm_error_set(err, SM_ERR_INVALID, "%s: facet %zu has a vertex out of range",
                                path, i / (size_t)s->dim + 1);
    if (f == FMT_MEDIT)
        return write_medit(path, s, xyz, err);
    sm_writer *w;
    sm_status st = sm__writer_open(&w, path, err);
    if (st != SM_OK)
        return st;
    if (f == FMT_STL)
        write_stl(w, s, xyz);
    else
        write_text(w, f, s, xyz);
    return sm__writer_close(w, err);
}
