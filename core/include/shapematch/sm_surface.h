/* Target surfaces: what users have instead of a sampled distance — a
 * triangle surface in 3D (STL from a scanner or a segmentation, OBJ, a
 * Medit or Gmsh surface) or a polyline in 2D (Medit edges, Gmsh lines).
 * The surface need not be closed, manifold or consistently oriented: the
 * distance (sm_sdf.h) copes with that.
 *
 * Indices are 0-based.  Readers treat their input as hostile, like the
 * mesh readers (sm_io.h): counts checked against the file size before
 * allocation, indices checked, reals finite, errors with file:line or
 * byte offset; on error *out is NULL and nothing leaks. */
#ifndef SM_SURFACE_H
#define SM_SURFACE_H

#include <stdint.h>

#include "sm_error.h"
#include "sm_io.h"

typedef struct sm_surface {
    int dim;             /* 3: triangles, 2: segments */
    int32_t nverts;
    double *coords;      /* nverts * dim */
    int32_t nfacets;
    int32_t *facets;     /* nfacets * dim */
    int32_t *facet_refs; /* nfacets (0 when the format has none) */
} sm_surface;

/* Zero-filled surface of the given sizes; free with sm_surface_free. */
sm_status sm_surface_alloc(sm_surface **out, int dim, int32_t nverts, int32_t nfacets,
                           sm_error *err);
void sm_surface_free(sm_surface *s);

/* Reads a surface, the format decided by the content, gzip or not:
 *   - Gmsh .msh ("$MeshFormat", the versions sm_mesh_read reads):
 *     triangles (3D), or lines when there are no triangles and all z = 0;
 *   - Medit .mesh/.meshb: Triangles in 3D (a volume file's Triangles),
 *     Edges of a Dimension 2 file (or Dimension 3 with all z = 0);
 *   - STL binary (84 + 50 n bytes; the 80-byte header may start with
 *     "solid") or ASCII ("solid" ... "facet" ... "endsolid"); coincident
 *     STL vertices are merged (exactly equal coordinates);
 *   - OBJ (v, f; negative indices count back from the last vertex;
 *     polygons are fan-triangulated; vt, vn, groups, materials and other
 *     statements are skipped); coincident vertices are merged as for STL;
 *     without faces, its "l" polylines with all z = 0 are a 2D curve;
 *   - PLY ASCII or binary in either byte order (the vertex element's x,
 *     y, z, the face element's vertex_indices; polygons fan-triangulated;
 *     without faces, the edge element's vertex1-vertex2 segments with
 *     all z = 0 are a 2D curve), OFF and its variants (COFF, NOFF...),
 *     Gmsh's PLY2; merged as STL;
 *   - VTK legacy .vtk (ASCII or binary, versions before 5 and 5.x) and
 *     XML .vtu/.vtp (ASCII, base64, appended raw or base64, optionally
 *     zlib-compressed): triangles, quads, polygons and strips (3D), or
 *     lines when there are none and all z = 0 (2D); references from a cell
 *     array "ref", "CellEntityIds", "gmsh:physical" or "medit:ref".
 * An unknown format is an error naming the formats read. */
sm_status sm_surface_read(const char *path, sm_surface **out, sm_error *err);
/* The same within limits (sm_io.h): decompressed bytes, and vertices and
 * facets (declared counts, or counted as an STL or OBJ file grows);
 * beyond one, SM_ERR_NOMEM with limits->hit set.  limits NULL: none. */
sm_status sm_surface_read_limited(const char *path, sm_read_limits *limits, sm_surface **out,
                                  sm_error *err);

/* Writes s with coordinates coords (nverts*dim; NULL: s->coords), the
 * format chosen by the name's extension: .mesh/.meshb (optionally .gz:
 * Medit, facets only, with their references), .stl (binary, single
 * precision), .obj (v and f, or l in 2D), .ply (ASCII), .off, .vtk
 * (legacy ASCII POLYDATA) and .vtu (ASCII unstructured grid of triangles
 * or lines) — the last two with a cell array "ref" of the references.
 * STL, PLY and OFF hold triangles: a 2D polyline is SM_ERR_INVALID
 * there.  The text formats write numbers with 17 significant digits (an
 * exact round trip).  SM_ERR_INVALID for another extension, a
 * non-finite coordinate or an index out of range; SM_ERR_IO. */
#define SM_SURFACE_WRITE_FORMATS ".mesh, .meshb (optionally .gz), .stl, .obj, .ply, .off, .vtk, .vtu"
sm_status sm_surface_write(const char *path, const sm_surface *s, const double *coords,
                           sm_error *err);

/* What sm_surface_repair found (and did): the surface health report.
 * Edges are the facets' sides in 3D and their end points in 2D. */
typedef struct sm_surface_health {
    int64_t open_edges;        /* on one facet only: holes, borders */
    int64_t nonmanifold_edges; /* on three facets or more */
    int64_t reoriented;        /* facets whose orientation was flipped: */
    int64_t reoriented_within; /*   against the majority of their piece */
    int64_t pieces_turned;     /* pieces whose majority was turned over */
    int64_t duplicates;        /* facets on the same vertices as another */
    int64_t degenerate;        /* zero area (length in 2D) */
    int64_t components;        /* connected over shared edges: pieces */
    int64_t open_components;   /* pieces with a boundary (between holes) */
    int64_t open_by_volume;    /* open pieces oriented by their own volume
                                * alone (too many to couple) */
    double lo[3], hi[3];       /* bounding box (z = 0 in 2D) */
} sm_surface_health;

/* Orients the facets consistently and outward.  A facet on the same
 * vertices as an earlier one (a duplicate) takes that one's orientation
 * and is otherwise left out.  Within each piece (connected over edges
 * shared by exactly two facets) the first facet's orientation is
 * propagated to its neighbours.  Then whole pieces are turned over: a
 * closed piece when the volume (area in 2D) it encloses is negative; the
 * open pieces (with holes between them) consistently with each other, by
 * how their boundaries face each other across the holes, and all together
 * so that their volume about their centroid is positive — not each by its
 * own volume, which depends on the point it is measured from
 * (sm_surface_orient.c).  Fills h (may be NULL): reoriented counts every
 * facet flipped; reoriented_within those that disagreed with the
 * majority of their piece, pieces_turned the pieces whose majority was
 * turned over.  Nothing is removed. */
sm_status sm_surface_repair(sm_surface *s, sm_surface_health *h, sm_error *err);

/* Mean length of the facets' edges (0 for no facets): the resolution of
 * the surface, which sizes a generated background (sm_sdf.h). */
double sm_surface_mean_edge(const sm_surface *s);

/* The formats sm_surface_read reads, for messages. */
#define SM_SURFACE_FORMATS                                                      \
    "STL (ASCII or binary), OBJ, PLY (ASCII or binary), OFF, PLY2, VTK .vtk, " \
    ".vtu or .vtp, Medit .mesh/.meshb or Gmsh .msh surfaces, optionally "      \
    "gzip-compressed"

#endif
