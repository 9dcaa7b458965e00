/* The mesh and surface readers (internal, not part of the public API),
 * each a row of the format table in sm_io.c, which detects the format
 * by content, opens the reader (sm_reader.h: bounded reads, gzip,
 * positions in messages; only peeked at so far) and closes it; a reader
 * fills a new mesh, a new surface, or the simplices of an sm_msh_data.
 * What several surface readers share is sm_surface_build.c's; Gmsh has
 * its own header (sm_io_msh.h), the image readers sm_image_formats.h. */
#ifndef SM_IO_FORMATS_H
#define SM_IO_FORMATS_H

#include "io/sm_io_msh.h"
#include "io/sm_reader.h"
#include "shapematch/sm_mesh.h"
#include "shapematch/sm_surface.h"

/* Medit (sm_io_medit.c): ASCII .mesh or binary .meshb, told apart by the
 * first bytes (sm__medit_detect). */
sm_status sm__medit_mesh_read(sm_reader *r, sm_mesh **out, sm_error *err);
sm_status sm__medit_surface_read(sm_reader *r, sm_surface **out, sm_error *err);

/* STL: binary when the file size is 84 + 50 n with n the count at byte
 * 80, or when it does not start like an ASCII STL ("solid" then
 * "facet"/"endsolid" in printable text); ASCII otherwise. */
int sm__stl_detect(sm_reader *r);
sm_status sm__stl_read(sm_reader *r, sm_surface **out, sm_error *err);

/* OBJ: the first word is an OBJ statement (v, vt, vn, f, o, g, s, l,
 * mtllib, usemtl) or a '#' comment. */
int sm__obj_detect(sm_reader *r);
sm_status sm__obj_read(sm_reader *r, sm_surface **out, sm_error *err);

/* PLY ("ply" on the first line; sm_io_ply.c), OFF and Gmsh's PLY2
 * (sm_io_off.c: *ply2 set for the latter): triangle surfaces. */
int sm__ply_detect(sm_reader *r);
sm_status sm__ply_read(sm_reader *r, sm_surface **out, sm_error *err);
int sm__off_detect(sm_reader *r, int *ply2);
sm_status sm__off_read(sm_reader *r, sm_surface **out, sm_error *err);

/* VTK legacy ("# vtk DataFile Version"; sm_io_vtk.c) and XML ("<VTKFile"
 * in the first 512 bytes; sm_io_vtkxml.c): their simplices into d
 * (sm_io_cells.h), which becomes a mesh or a surface like a .msh file's;
 * free d with sm__msh_data_free, also after an error. */
int sm__vtk_detect(sm_reader *r);
sm_status sm__vtk_parse(sm_reader *r, sm_msh_data *d, sm_error *err);
int sm__vtkxml_detect(sm_reader *r);
sm_status sm__vtkxml_parse(sm_reader *r, sm_msh_data *d, sm_error *err);

/* The surface of a .msh (or VTK, PLY) file's simplices: triangles in 3D,
 * or lines when all z = 0 (sm_surface_build.c); otherwise an error naming
 * what the file holds. */
sm_status sm__msh_surface(const char *path, const sm_msh_data *d, sm_surface **out,
                          sm_error *err);

/* Merges vertices with exactly equal coordinates (STL repeats them per
 * facet; sm_surface_build.c); the merged vertices keep the order of their
 * first appearance and facets are renumbered. */
sm_status sm__surface_weld(sm_surface *s, sm_error *err);

#endif
