/* Cells of the formats that describe a mesh as points and polygons or
 * VTK cells (PLY, OFF, VTK legacy and XML; internal, not part of the
 * public API), gathered into the Gmsh reader's sm_msh_data (sm_io_msh.h)
 * so that the one conversion to a volume mesh (sm__msh_to_mesh) or to a
 * surface (sm__msh_surface) serves them all.
 *
 * While a file is read, a simplex's ref holds the number of the file cell
 * it came from; sm__cells_finish then replaces it by that cell's reference
 * (a cell array such as "ref", "CellEntityIds" or "gmsh:physical") or 0.
 * Functions return SM_OK or an error code with the reason in r->why; the
 * format reader adds the position (line or byte). */
#ifndef SM_IO_CELLS_H
#define SM_IO_CELLS_H

#include <stdint.h>

#include "io/sm_io_msh.h"
#include "io/sm_reader.h"

/* VTK cell types read (others are named in the error). */
enum {
    SM_VTK_VERTEX = 1, SM_VTK_POLY_VERTEX = 2, SM_VTK_LINE = 3, SM_VTK_POLY_LINE = 4,
    SM_VTK_TRIANGLE = 5, SM_VTK_TRIANGLE_STRIP = 6, SM_VTK_POLYGON = 7, SM_VTK_PIXEL = 8,
    SM_VTK_QUAD = 9, SM_VTK_TETRA = 10
};

/* The most vertices of one polygon or cell. */
#define SM_CELL_MAX_NODES 65536

/* Zeroes d and sets its blocks' widths. */
void sm__cells_init(sm_msh_data *d);

/* Allocates d->coords for n points (n checked against SM_MAX_ENTITIES
 * and r->limits; the caller checked n against the bytes left). */
sm_status sm__cells_points(sm_reader *r, sm_msh_data *d, int64_t n, sm_error *err);

/* Adds VTK cell number cell of type type on nv point indices v (checked
 * against d->nnodes): vertices are dropped, lines and poly-lines become
 * segments, triangles, strips, polygons, pixels and quads triangles (fan
 * or strip order), tetrahedra stay; any other type is an error. */
sm_status sm__cells_add_vtk(sm_reader *r, sm_msh_data *d, int type, int64_t nv,
                            const int64_t *v, int64_t cell);

/* A polygon (PLY, OFF face) of nv >= 3 vertices: fan-triangulated. */
sm_status sm__cells_add_polygon(sm_reader *r, sm_msh_data *d, int64_t nv, const int64_t *v,
                                int64_t cell);

/* Turns the cell numbers held in the refs into refs[cell] (ncells of
 * them), or 0 for every simplex when refs is NULL. */
void sm__cells_finish(sm_msh_data *d, const int32_t *refs, int64_t ncells);

/* Reads the rest of the current line (without its newline, which is
 * consumed) into buf; a longer line is cut to cap - 1 bytes. */
sm_status sm__reader_line(sm_reader *r, char *buf, size_t cap);

/* True for the names of the cell arrays read as references: "ref" (what
 * shapematch writes), "CellEntityIds" (Gmsh's VTK), "gmsh:physical"
 * and "medit:ref" (meshio). */
int sm__cells_ref_name(const char *name);

#endif
