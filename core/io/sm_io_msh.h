/* Gmsh .msh reader (internal, not part of the public API; sm_mesh_read
 * dispatches here when a file starts with "$MeshFormat").
 *
 * Read: format 4.1 ASCII and binary (the binary data size must be 8, as
 * Gmsh writes it on every platform it supports; either byte order), and
 * 2.2 ASCII.  Sections used: $MeshFormat (first), $PhysicalNames,
 * $Entities (4.1: the physical tags of each entity), $Nodes, $Elements;
 * any other section ($NodeData, $Periodic, ...) is skipped up to its
 * $End line.  Element types: 1 (2-node line), 2 (3-node triangle),
 * 4 (4-node tetrahedron), 15 (point, ignored); any other type (quads,
 * hexahedra, prisms, pyramids, second-order elements) is an error naming
 * it.  A reference is the first physical tag of the element's entity
 * (4.1) or the element's first tag (2.2), 0 when there is none.
 *
 * $PhysicalNames are kept (sm_mesh.names): a dimension in [0, 3], a
 * tag, a quoted name of at most SM_MESH_NAME_MAX bytes on one line.
 * Hostile input: counts are checked against SM_MAX_ENTITIES and against
 * the bytes left in the file before allocation (sm__medit_check_count),
 * node tags are looked up (a tag not in $Nodes is an error), reals must
 * be finite.  Errors name "file:line" (ASCII) or "file: byte N" (binary
 * sections). */
#ifndef SM_IO_MSH_H
#define SM_IO_MSH_H

#include <stdint.h>

#include "shapematch/sm_error.h"
#include "shapematch/sm_mesh.h"
#include "io/sm_reader.h"

/* Simplices of one kind as read: 0-based indices into the nodes. */
typedef struct sm_msh_block {
    int64_t count, cap;
    int nidx;           /* 2 lines, 3 triangles, 4 tetrahedra */
    int32_t *idx;       /* count * nidx */
    int32_t *refs;      /* count */
} sm_msh_block;

/* What a .msh file holds, before deciding what kind of mesh it is. */
typedef struct sm_msh_data {
    int64_t nnodes;
    double *coords;     /* nnodes * 3 */
    sm_msh_block lines, triangles, tetrahedra;
    int32_t nnames;     /* $PhysicalNames entries, in file order */
    sm_mesh_name *names;
} sm_msh_data;

/* True when the first bytes of r are "$MeshFormat". */
int sm__msh_detect(sm_reader *r);

/* Parses an opened reader into d (zeroed by the call; free it with
 * sm__msh_data_free, also after an error). */
sm_status sm__msh_parse(sm_reader *r, sm_msh_data *d, sm_error *err);
void sm__msh_data_free(sm_msh_data *d);

/* A volume mesh from d: tetrahedra (facets: triangles) or, with no
 * tetrahedra, triangles whose z are all 0 (a 2D mesh; facets: lines).
 * The mesh takes over d's physical names (sm_mesh.names). */
sm_status sm__msh_to_mesh(const char *path, sm_msh_data *d, sm_mesh **out,
                          sm_error *err);

#endif
