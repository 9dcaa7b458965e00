// The Netgen shim: nglib's C++ API behind the two extern "C" entries of
// sm_nglib.h.  Runs in a child process of sm_template_mesh.c only (one
// call per process: nglib keeps global state), which is why nothing here
// frees nglib's objects on the error paths: the process ends right after.
#include "sm_nglib.h"

#include <cstdio>
#include <cstdlib>
#include <cstring>

namespace nglib {
#include <netgen/nglib.h>
}
// nglib's messages go to stdout unless their importance is lowered
// (a global of Netgen's libmesh, not in nglib.h).
namespace netgen {
extern int printmessage_importance;
}

using namespace nglib;

namespace {

int fail(sm_nglib_out *out, const char *step, int code)
{
    std::snprintf(out->msg, sizeof out->msg, "nglib: %s failed (Ng_Result %d)", step, code);
    return 1;
}

int nomem(sm_nglib_out *out)
{
    std::snprintf(out->msg, sizeof out->msg, "out of memory copying nglib's mesh");
    return 1;
}

void setup(Ng_Meshing_Parameters *mp, double h, int optsteps)
{
    netgen::printmessage_importance = 0;
    mp->maxh = h;
    mp->minh = 0;
    mp->optsteps_3d = optsteps;
    mp->optsteps_2d = optsteps;
    mp->optsurfmeshenable = 1;
    mp->optvolmeshenable = 1;
    mp->second_order = 0;
    mp->quad_dominated = 0;
}

} // namespace

extern "C" int sm_nglib_volume(const double *coords, int32_t nverts, const int32_t *tris,
                               int32_t ntris, double h, int optsteps, sm_nglib_out *out)
{
    std::memset(out, 0, sizeof *out);
    Ng_Init();
    Ng_Meshing_Parameters mp;
    setup(&mp, h, optsteps);
    Ng_STL_Geometry *geom = Ng_STL_NewGeometry();
    for (int32_t t = 0; t < ntris; t++) {
        double p[3][3];
        for (int k = 0; k < 3; k++) {
            int32_t v = tris[3 * t + k];
            if (v < 0 || v >= nverts)
                return fail(out, "a triangle's vertex index", -1);
            std::memcpy(p[k], coords + 3 * (size_t)v, sizeof p[k]);
        }
        Ng_STL_AddTriangle(geom, p[0], p[1], p[2]);
    }
    Ng_Result r = Ng_STL_InitSTLGeometry(geom);
    if (r != NG_OK)
        return fail(out, "reading the surface as an STL geometry (Ng_STL_InitSTLGeometry)", r);
    Ng_Mesh *mesh = Ng_NewMesh();
    if ((r = Ng_STL_MakeEdges(geom, mesh, &mp)) != NG_OK)
        return fail(out, "finding the surface's edges (Ng_STL_MakeEdges)", r);
    if ((r = Ng_STL_GenerateSurfaceMesh(geom, mesh, &mp)) != NG_OK)
        return fail(out, "remeshing the surface (Ng_STL_GenerateSurfaceMesh)", r);
    if ((r = Ng_GenerateVolumeMesh(mesh, &mp)) != NG_OK)
        return fail(out, "meshing the volume (Ng_GenerateVolumeMesh)", r);
    int np = Ng_GetNP(mesh), ne = Ng_GetNE(mesh);
    if (np <= 0 || ne <= 0)
        return fail(out, "meshing the volume (no tetrahedra)", 0);
    out->coords = static_cast<double *>(std::malloc(sizeof(double) * 3 * (size_t)np));
    out->elems = static_cast<int32_t *>(std::malloc(sizeof(int32_t) * 4 * (size_t)ne));
    if (!out->coords || !out->elems)
        return nomem(out);
    for (int i = 0; i < np; i++)
        Ng_GetPoint(mesh, i + 1, out->coords + 3 * (size_t)i);
    for (int e = 0; e < ne; e++) {
        int pi[10];
        if (Ng_GetVolumeElement(mesh, e + 1, pi) != NG_TET)
            return fail(out, "meshing the volume (an element that is not a tetrahedron)", 0);
        for (int k = 0; k < 4; k++)
            out->elems[4 * (size_t)e + k] = pi[k] - 1;
    }
    out->nverts = np;
    out->nelems = ne;
    return 0;
}

extern "C" int sm_nglib_planar(const double *coords, int32_t nverts, const int32_t *segs,
                               int32_t nsegs, double h, int optsteps, const char *scratch,
                               sm_nglib_out *out)
{
    std::memset(out, 0, sizeof *out);
    // nglib's 2D geometry is read from a file only (splinecurves2dv2:
    // points, then straight segments "left right 2 p q" with the domain
    // 1 on their left: the curve is outward, counter-clockwise)
    FILE *f = std::fopen(scratch, "w");
    if (!f)
        return fail(out, "writing the polygon for Ng_LoadGeometry_2D", -1);
    std::fprintf(f, "splinecurves2dv2\n5\npoints\n");
    for (int32_t i = 0; i < nverts; i++)
        std::fprintf(f, "%d %.17g %.17g\n", (int)i + 1, coords[2 * (size_t)i],
                     coords[2 * (size_t)i + 1]);
    std::fprintf(f, "segments\n");
    for (int32_t s = 0; s < nsegs; s++)
        std::fprintf(f, "1 0 2 %d %d -bc=1\n", (int)segs[2 * (size_t)s] + 1,
                     (int)segs[2 * (size_t)s + 1] + 1);
    std::fprintf(f, "materials\n1 domain1 -maxh=%.17g\n", h);
    if (std::fclose(f) != 0) {
        std::remove(scratch);
        return fail(out, "writing the polygon for Ng_LoadGeometry_2D", -1);
    }
    Ng_Init();
    Ng_Meshing_Parameters mp;
    setup(&mp, h, optsteps);
    Ng_Geometry_2D *geom = Ng_LoadGeometry_2D(scratch);
    std::remove(scratch);
    if (!geom)
        return fail(out, "reading the polygon (Ng_LoadGeometry_2D)", -1);
    Ng_Mesh *mesh = nullptr;
    Ng_Result r = Ng_GenerateMesh_2D(geom, &mesh, &mp);
    if (r != NG_OK || !mesh)
        return fail(out, "meshing the polygon (Ng_GenerateMesh_2D)", r);
    int np = Ng_GetNP_2D(mesh), ne = Ng_GetNE_2D(mesh);
    if (np <= 0 || ne <= 0)
        return fail(out, "meshing the polygon (no triangles)", 0);
    out->coords = static_cast<double *>(std::malloc(sizeof(double) * 2 * (size_t)np));
    out->elems = static_cast<int32_t *>(std::malloc(sizeof(int32_t) * 3 * (size_t)ne));
    if (!out->coords || !out->elems)
        return nomem(out);
    for (int i = 0; i < np; i++)
        Ng_GetPoint_2D(mesh, i + 1, out->coords + 2 * (size_t)i);
    for (int e = 0; e < ne; e++) {
        int pi[8];
        if (Ng_GetElement_2D(mesh, e + 1, pi) != NG_TRIG)
            return fail(out, "meshing the polygon (an element that is not a triangle)", 0);
        for (int k = 0; k < 3; k++)
            out->elems[3 * (size_t)e + k] = pi[k] - 1;
    }
    out->nverts = np;
    out->nelems = ne;
    return 0;
}
