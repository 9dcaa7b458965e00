/* File formats: Medit .mesh/.meshb and .sol/.solb, Gmsh .msh meshes (any
 * of them .gz), and
 * the VTK XML .vtu writer.
 *
 * Readers treat their input as hostile: every count is checked against
 * SM_MAX_ENTITIES and against what the rest of the file could possibly
 * hold before anything is allocated, every index against [1, nverts],
 * every real for NaN/Inf.  Errors are SM_ERR_FORMAT (SM_ERR_IO when the
 * file cannot be opened or read) with a message naming the place:
 *   "dir/x.mesh:12: expected 3 vertex indices and a reference in
 *    Triangles record 4 of 10, found 'End'"
 *   "x.meshb: byte 1234: Triangles record 2 of 2: vertex index 0 out of
 *    range [1, 4]"
 * On error *out is NULL and nothing leaks.
 *
 * Writers pick the format from the file name (.mesh/.meshb, .sol/.solb,
 * optionally followed by .gz), write to a temporary file in the same
 * directory and rename it into place, so a failed write (SM_ERR_IO,
 * including ENOSPC) never leaves a truncated file under the final name
 * (devices and pipes such as /dev/stdout are written in place).  Numbers
 * are written with "%.17g": an ASCII round trip is bitwise exact.  Both
 * directions use the C numeric locale whatever the application's is. */
#ifndef SM_IO_H
#define SM_IO_H

#include "sm_error.h"
#include "sm_mesh.h"

/* A solution file: one field (SolAtVertices), scalar, vector or
 * symmetric tensor (Medit type 3, components xx, xy, yy[, xz, yz, zz]). */
typedef struct sm_sol {
    int dim;            /* 2 or 3 (the file's Dimension) */
    int32_t nverts;
    int ncomp;          /* 1 (scalar), dim (vector), dim*(dim+1)/2 (tensor) */
    double *values;     /* nverts * ncomp */
} sm_sol;

/* Zero-filled solution; ncomp must be 1, dim or dim*(dim+1)/2.  Free
 * with sm_sol_free. */
sm_status sm_sol_alloc(sm_sol **out, int dim, int32_t nverts, int ncomp,
                       sm_error *err);
void sm_sol_free(sm_sol *s);

/* Bounds on the work one file may cause, for readers of untrusted files
 * (a daemon's uploads): a gzip file that decompresses beyond max_inflated
 * bytes, or a declared record count beyond max_vertices (Vertices,
 * SolAtVertices) or max_elements (every other section), is refused as
 * SM_ERR_NOMEM ("size limit exceeded") before the records are allocated,
 * and `hit` says which bound (SM_LIMIT_*).  A zero bound is no bound
 * beyond the readers' own (SM_MAX_ENTITIES, the file's size). */
enum { SM_LIMIT_NONE = 0, SM_LIMIT_INFLATED, SM_LIMIT_VERTICES, SM_LIMIT_ELEMENTS };
typedef struct sm_read_limits {
    uint64_t max_inflated;
    int64_t max_vertices;
    int64_t max_elements;
    int hit; /* out: the bound that refused the file, SM_LIMIT_NONE if none */
} sm_read_limits;

/* Reads .mesh, .meshb, .mesh.gz, .meshb.gz into a new mesh (free with
 * sm_mesh_free).  The format is decided by the content (binary files
 * start with the 32-bit code 1 in either byte order; libMeshb versions
 * 1 to 4 are read), compression is detected transparently.
 *
 * ASCII: keywords are case-insensitive, '#' starts a comment; sections
 * shapematch does not use (Corners, Ridges, Required*, Normals,
 * NormalAtVertices, Tangents, TangentAtVertices, Identifier, Geometry...)
 * are read and discarded; an unknown keyword is an error.  Binary:
 * unknown keywords are skipped through their next-keyword position.
 * Quadrilaterals, Prisms, Hexahedra and Pyramids are rejected (shapematch
 * needs simplices).
 *
 * Dimension 2: Triangles are the elements and Edges the facets.
 * Dimension 3 with Tetrahedra: Tetrahedra are the elements, Triangles the
 * facets (Edges are ignored).  A "Dimension 3" file with Triangles but no
 * Tetrahedra whose z coordinates are all 0 (as Gmsh writes planar meshes)
 * is read as a 2D mesh; any other surface mesh is an error.  Elements of
 * either orientation are accepted.  Does not build the boundary (see
 * sm_mesh_build_boundary). */
sm_status sm_mesh_read(const char *path, sm_mesh **out, sm_error *err);
/* A file that starts with "$MeshFormat" is read as a Gmsh .msh mesh
 * instead: format 4.1 ASCII or binary, or 2.2 ASCII, gzip or not;
 * elements are tetrahedra (facets: triangles) or, without tetrahedra,
 * planar triangles (a 2D mesh; facets: lines); references are physical
 * tags (0 when an entity has none); other element types are errors.
 * A VTK legacy (.vtk) or XML (.vtu) file is read the same way: its
 * tetrahedra (facets: its triangles) or its planar triangles (facets:
 * lines), references from a cell array "ref" (what sm_vtu_write writes),
 * "CellEntityIds" (Gmsh), "gmsh:physical" or "medit:ref" (meshio). */

/* The formats sm_mesh_read reads, for messages. */
#define SM_MESH_FORMATS                                                          \
    "Medit .mesh/.meshb, Gmsh .msh (4.1 ASCII/binary, 2.2 ASCII) or VTK .vtk/.vtu " \
    "with tetrahedra, optionally gzip-compressed"

/* The same within limits (NULL: none). */
sm_status sm_mesh_read_limited(const char *path, sm_read_limits *limits, sm_mesh **out,
                               sm_error *err);

/* Writes by extension: .mesh (ASCII, Dimension = m->dim) or .meshb
 * (binary, version 2; version 3 if the file would exceed 2 GiB), with an
 * optional trailing .gz.  Writes Vertices, the file facets (Edges in 2D,
 * Triangles in 3D) and the elements (Triangles/Tetrahedra), all with
 * their references.  A mesh with out-of-range indices or non-finite
 * coordinates is refused (SM_ERR_INVALID) before anything is written. */
sm_status sm_mesh_write(const char *path, const sm_mesh *m, sm_error *err);

/* Same, with coordinates taken from coords (nverts*dim) instead of
 * m->coords (NULL means m->coords). */
sm_status sm_mesh_write_coords(const char *path, const sm_mesh *m,
                               const double *coords, sm_error *err);

/* .sol, .solb, optionally .gz; SolAtVertices with exactly one field of
 * type 1 (scalar), 2 (vector) or 3 (symmetric tensor, xx xy yy[ xz yz zz]); Time and Iterations are ignored.  The
 * writer uses ASCII for .sol and binary version 2 for .solb. */
sm_status sm_sol_read(const char *path, sm_sol **out, sm_error *err);
sm_status sm_sol_read_limited(const char *path, sm_read_limits *limits, sm_sol **out,
                              sm_error *err);
sm_status sm_sol_write(const char *path, const sm_sol *s, sm_error *err);

/* VTK XML UnstructuredGrid (ParaView, VTK, meshio): points padded to 3D,
 * cells VTK_TRIANGLE (5) / VTK_TETRA (10) then the facets (VTK_LINE 3 /
 * VTK_TRIANGLE), cell data "ref" (references) and "cell_dim".  coords
 * NULL means m->coords.  Point fields are optional (NULL to skip):
 * "displacement" (nverts*dim, written with 3 components) and "distance"
 * (nverts).  Non-finite values are written as 0 (VTK's ASCII parser
 * cannot read them).  sm_vtu_write writes SM_VTU_ZLIB: binary, compressed
 * by blocks as VTK's vtkZLibDataCompressor (inline base64, UInt64
 * headers); SM_VTU_ASCII: inline ASCII (%.17g), several times larger.
 * Never gzip the result: ParaView does not open a .vtu.gz. */
typedef enum sm_vtu_encoding { SM_VTU_ZLIB = 0, SM_VTU_ASCII = 1 } sm_vtu_encoding;
sm_status sm_vtu_write(const char *path, const sm_mesh *m, const double *coords,
                       const double *displacement, const double *distance, sm_error *err);
sm_status sm_vtu_write_as(const char *path, const sm_mesh *m, const double *coords,
                          const double *displacement, const double *distance,
                          sm_vtu_encoding encoding, sm_error *err);
/* The binary (SM_VTU_ZLIB) file of m at coords with any number of named
 * vector point fields (nverts*dim values each, written with 3
 * components; the first is the file's Vectors), e.g. a shape model's
 * modes (sm_shape_model.h).  Names are written as given (plain
 * identifiers: no XML escaping). */
typedef struct sm_vtu_field {
    const char *name;
    const double *values;
} sm_vtu_field;
sm_status sm_vtu_write_fields(const char *path, const sm_mesh *m, const double *coords,
                              const sm_vtu_field *fields, int nfields, sm_error *err);

/* NumPy .npy arrays of points (numpy.save / numpy.load): version 1.0 to
 * 3.0, a 2-D C-order array of shape (N, 2) or (N, 3), float64 ('<f8') or
 * float32 ('<f4') little-endian.  sm_npy_parse reads len bytes (a whole
 * file, in memory): the N * cols values as doubles in *values (malloc'd,
 * row after row), every one finite; another type, byte order, Fortran
 * order or shape, a header that is not numpy's dict, data that are not
 * exactly N rows, is SM_ERR_FORMAT with a message naming name and what to
 * do; more than max_rows rows (0: no bound) SM_ERR_NOMEM.  On error
 * *values is NULL.  sm_npy_encode writes rows x cols doubles as a version
 * 1.0 '<f8' C-order file (numpy's own layout, its header padded to 64
 * bytes) into *out (malloc'd, *len bytes); NaN values are written as
 * they are. */
sm_status sm_npy_parse(const void *bytes, size_t len, int64_t max_rows, const char *name,
                       double **values, int64_t *rows, int *cols, sm_error *err);
sm_status sm_npy_encode(const double *values, int64_t rows, int cols, char **out, size_t *len,
                        sm_error *err);

#endif
