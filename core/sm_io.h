/* File formats: Medit .mesh/.meshb and .sol/.solb (any of them .gz), and
 * the VTK XML .vtu writer.  Readers treat their input as hostile. */
#ifndef SM_IO_H
#define SM_IO_H

#include "sm_error.h"
#include "sm_mesh.h"

/* A solution file: one field (SolAtVertices), scalar or vector. */
typedef struct sm_sol {
    int dim;            /* 2 or 3 (the file's Dimension) */
    int32_t nverts;
    int ncomp;          /* 1 (scalar) or dim (vector) */
    double *values;     /* nverts * ncomp */
} sm_sol;

sm_status sm_sol_alloc(sm_sol **out, int dim, int32_t nverts, int ncomp,
                       sm_error *err);
void sm_sol_free(sm_sol *s);

/* Reads .mesh, .meshb, .mesh.gz, .meshb.gz.  The format is decided by the
 * content (binary files start with the 32-bit code 1 in either byte
 * order), compression is detected transparently.  A "Dimension 3" file
 * with Triangles but no Tetrahedra whose z coordinates are all 0 (as Gmsh
 * writes planar meshes) is read as a 2D mesh.  Does not build the
 * boundary (see sm_mesh_build_boundary). */
sm_status sm_mesh_read(const char *path, sm_mesh **out, sm_error *err);

/* Writes by extension: .mesh (ASCII), .meshb (binary, version 2), with an
 * optional trailing .gz (zlib).  Writes Vertices, Edges/Triangles
 * (the file facets), Triangles/Tetrahedra. */
sm_status sm_mesh_write(const char *path, const sm_mesh *m, sm_error *err);

/* Same, with coordinates taken from coords instead of m->coords. */
sm_status sm_mesh_write_coords(const char *path, const sm_mesh *m,
                               const double *coords, sm_error *err);

/* .sol, .solb, optionally .gz; SolAtVertices with exactly one field of
 * type 1 (scalar) or 2 (vector). */
sm_status sm_sol_read(const char *path, sm_sol **out, sm_error *err);
sm_status sm_sol_write(const char *path, const sm_sol *s, sm_error *err);

/* VTK XML UnstructuredGrid (ascii-free: appended raw base64 not needed;
 * written as inline ascii for portability).  Point fields are optional
 * (NULL to skip): displacement (nverts*dim), distance (nverts). */
sm_status sm_vtu_write(const char *path, const sm_mesh *m,
                       const double *coords, const double *displacement,
                       const double *distance, sm_error *err);

#endif
