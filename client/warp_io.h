/* The files of `shapematch warp` (cmd_warp.c): a whole input file read
 * within a bound, and a mesh or surface warped vertex by vertex and
 * written in the format its output name asks for: Medit .mesh/.meshb
 * (optionally .gz) and .vtu for both, and for surfaces the formats of
 * sm_surface_write (STL, OBJ, PLY, OFF, VTK legacy).  Volume meshes are
 * read first (sm_mesh_read: Medit, Gmsh, VTK), surfaces when that fails
 * (sm_surface_read: STL, OBJ, PLY, OFF, VTK, Medit or Gmsh surfaces); the
 * topology and the references are kept. */
#ifndef CLI_WARP_IO_H
#define CLI_WARP_IO_H

#include <stddef.h>

#include "shapematch/sm_error.h"
#include "shapematch/sm_warp.h"

/* The whole of path into a new malloc'd buffer (*len bytes, plus a NUL
 * not counted).  More than max bytes is SM_ERR_NOMEM; SM_ERR_IO naming
 * the path. */
sm_status warp_read_file(const char *path, size_t max, char **out, size_t *len, sm_error *err);

/* Warps the mesh or surface in_path into out_path (messages on stderr);
 * returns a cli.h exit code. */
int warp_mesh_file(const char *in_path, const char *out_path, const sm_warp *w,
                   sm_warp_direction dir, int strict, int quiet);

#endif
