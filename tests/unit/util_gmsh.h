/* Gmsh meshes at test time: run the real gmsh (Debian 4.8) on a .geo
 * text in a fresh temporary directory, read the result back with
 * sm_mesh_read, clean up.  Generic: any test may use it. */
#ifndef UTIL_GMSH_H
#define UTIL_GMSH_H

#include <stddef.h>

#include "shapematch/sm_error.h"
#include "shapematch/sm_mesh.h"

/* Ready-made geometries (the mesh size comes from the clmax argument). */
#define UTIL_GMSH_UNIT_SQUARE                                                  \
    "Point(1) = {0, 0, 0, 1}; Point(2) = {1, 0, 0, 1};\n"                          \
    "Point(3) = {1, 1, 0, 1}; Point(4) = {0, 1, 0, 1};\n"                          \
    "Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};\n" \
    "Curve Loop(1) = {1, 2, 3, 4};\nPlane Surface(1) = {1};\n"
#define UTIL_GMSH_UNIT_CUBE                                                    \
    "Point(1) = {0, 0, 0, 1}; Point(2) = {1, 0, 0, 1};\n"                          \
    "Point(3) = {1, 1, 0, 1}; Point(4) = {0, 1, 0, 1};\n"                          \
    "Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};\n" \
    "Curve Loop(1) = {1, 2, 3, 4};\nPlane Surface(1) = {1};\n"                 \
    "Extrude {0, 0, 1} { Surface{1}; }\n"
/* unit disk / ball centred at the origin (OpenCASCADE kernel) */
#define UTIL_GMSH_UNIT_DISK \
    "SetFactory(\"OpenCASCADE\");\nDisk(1) = {0, 0, 0, 1};\nMesh.MeshSizeFromPoints = 0;\n"
#define UTIL_GMSH_UNIT_BALL \
    "SetFactory(\"OpenCASCADE\");\nSphere(1) = {0, 0, 0, 1};\nMesh.MeshSizeFromPoints = 0;\n"

/* Runs `gmsh -<dim> -format <fmt> -clmax <clmax> -nt 1` on geo and writes
 * out_path; fmt from the extension: .mesh (Medit ASCII) or .msh (Gmsh 4.1
 * ASCII).  On failure returns SM_ERR_IO with the end of gmsh's log in msg. */
sm_status util_gmsh_write(const char *geo, int dim, double clmax, const char *out_path,
                          char *msg, size_t msglen);

/* Same with an explicit Gmsh format name ("msh41", "msh22", "mesh",
 * "stl", ...) and, when binary is set, Gmsh's -bin option. */
sm_status util_gmsh_write_format(const char *geo, int dim, double clmax, const char *format,
                                 int binary, const char *out_path, char *msg, size_t msglen);

/* Same into a temporary .mesh, read with sm_mesh_read (boundary not
 * built), temporary directory removed.  *out is owned by the caller. */
sm_status util_gmsh_mesh(const char *geo, int dim, double clmax, sm_mesh **out, char *msg,
                         size_t msglen);

#endif
