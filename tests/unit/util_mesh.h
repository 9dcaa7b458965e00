/* Meshes built in code for tests (no file, no Gmsh): structured boxes and
 * a ring-structured disk. */
#ifndef UTIL_MESH_H
#define UTIL_MESH_H

#include "shapematch/sm_mesh.h"

/* Box [lo,hi] split in n^dim cells (2 triangles / 6 Kuhn tetrahedra each).
 * With shuffle != 0 the vertex order inside each element is randomized
 * (seeded), so about half of the elements are negatively oriented. */
sm_mesh *util_box_mesh(int dim, int n, const double *lo, const double *hi,
                       unsigned shuffle);

/* Disk of given center and radius: a center vertex and `rings` rings, ring
 * k holding 6k vertices; boundary edges listed as facets with ref 1. */
sm_mesh *util_disk_mesh(const double *center, double radius, int rings);

#endif
