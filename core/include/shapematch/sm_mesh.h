/* The simplicial mesh model: triangles in 2D, tetrahedra in 3D, with
 * Medit-style integer references on vertices, elements and facets.
 *
 * Indices are 0-based in memory (Medit files are 1-based; the readers
 * convert).  Element connectivity has dim+1 entries per element, facet
 * connectivity dim entries per facet (edges in 2D, triangles in 3D). */
#ifndef SM_MESH_H
#define SM_MESH_H

#include <stdint.h>

#include "sm_error.h"

/* Hard limits that keep hostile inputs from asking for absurd memory. */
#define SM_MAX_ENTITIES 200000000 /* per entity kind */

/* One Gmsh physical name: physical tag `tag` of dimension `dim` (0 to
 * 3) is called `name` (UTF-8 as in the file, at most SM_MESH_NAME_MAX
 * bytes). */
#define SM_MESH_NAME_MAX 255
typedef struct sm_mesh_name {
    int32_t dim, tag;
    char *name;
} sm_mesh_name;

typedef struct sm_mesh {
    int dim;              /* 2 or 3 */

    int32_t nverts;
    double *coords;       /* nverts * dim */
    int32_t *vert_refs;   /* nverts */

    int32_t nelems;
    int32_t *elems;       /* nelems * (dim+1) */
    int32_t *elem_refs;   /* nelems */

    /* Facets as listed in the file (Edges in 2D, Triangles in 3D).  They
     * may be boundary facets or interior ones (e.g. the surface of a clamp
     * ball); written back unchanged. */
    int32_t nfacets;
    int32_t *facets;      /* nfacets * dim */
    int32_t *facet_refs;  /* nfacets */

    /* Derived by sm_mesh_build_boundary(): facets owned by exactly one
     * element, oriented so that their normal points out of the mesh;
     * references taken from the matching file facet (0 if none). */
    int32_t nbfacets;
    int32_t *bfacets;     /* nbfacets * dim */
    int32_t *bfacet_refs; /* nbfacets */
    int32_t *bfacet_elem; /* owning element of each boundary facet */
    uint8_t *on_boundary; /* nverts flags: vertex lies on a boundary facet */

    /* The $PhysicalNames of a Gmsh .msh file, in file order, so that a
     * reference can be reported by its name; 0 and NULL for other
     * formats.  Owned by the mesh (sm_mesh_free, kept by sm_mesh_clone);
     * the writers ignore them. */
    int32_t nnames;
    sm_mesh_name *names;
} sm_mesh;

/* Allocates an empty mesh of the given sizes (arrays zeroed).  Any count
 * may be 0.  Returns SM_ERR_NOMEM / SM_ERR_INVALID on absurd sizes. */
sm_status sm_mesh_alloc(sm_mesh **out, int dim, int32_t nverts,
                        int32_t nelems, int32_t nfacets, sm_error *err);
void sm_mesh_free(sm_mesh *m);
/* Frees a name table of n entries (names and array; NULL allowed). */
void sm_mesh_names_free(sm_mesh_name *names, int32_t n);
/* Deep copy (including derived boundary data when present). */
sm_status sm_mesh_clone(const sm_mesh *m, sm_mesh **out, sm_error *err);

/* Checks indices, finite coordinates, non-degenerate elements; reorients
 * negatively oriented elements (so every element has positive signed
 * volume) and extracts the boundary facets (in the lexicographic order
 * of their sorted vertices); a facet held by three or more elements is
 * SM_ERR_INVALID.  O(elements + vertices).  Must be called before any
 * geometric use; the readers do not call it. */
sm_status sm_mesh_build_boundary(sm_mesh *m, sm_error *err);

/* Checks that the elements around each vertex are joined through facets
 * holding it (no bowtie: two triangles, or tetrahedra, touching at one
 * vertex only), which the boundary and the solver assume.  Call after
 * sm_mesh_build_boundary (indices checked).  SM_ERR_INVALID naming the
 * vertex and two of its elements; O(elements + vertices). */
sm_status sm_mesh_check_manifold(const sm_mesh *m, sm_error *err);

/* Signed volume (area in 2D) of element e with vertex coordinates taken
 * from coords (nverts*dim, e.g. a deformed copy of m->coords). */
double sm_elem_volume(const sm_mesh *m, const double *coords, int32_t e);

/* Normalized quality in [0,1]: 1 for the equilateral simplex, 0 when
 * flat; negative when inverted.  2D: 4*sqrt(3)*A / sum(l^2);
 * 3D: 12*(3V)^(2/3) / sum(l^2). */
double sm_elem_quality(const sm_mesh *m, const double *coords, int32_t e);

/* The smallest sm_elem_quality over the elements (negative when one is
 * inverted; 0 for an empty mesh) and, when worst is not NULL, the first
 * element reaching it: exactly the minimum of sm_elem_quality, at a
 * fraction of its cost (the elements are compared by a monotone function
 * of their quality that needs no cube root, and only those within
 * rounding of the smallest get sm_elem_quality); parallel over the
 * OpenMP threads, with a result that does not depend on their number. */
double sm_mesh_min_quality(const sm_mesh *m, const double *coords, int32_t *worst);

typedef struct sm_quality_stats {
    double min, mean;
    int32_t worst_elem;
    int32_t ninverted;    /* elements with volume <= 0 */
} sm_quality_stats;
void sm_mesh_quality(const sm_mesh *m, const double *coords,
                     sm_quality_stats *st);

/* Axis-aligned bounding box; lo/hi have dim entries. */
void sm_mesh_bbox(const sm_mesh *m, const double *coords, double *lo,
                  double *hi);
/* Length of the bounding-box diagonal. */
double sm_mesh_diameter(const sm_mesh *m, const double *coords);

/* Outward unit normal and measure (length/area) of boundary facet f. */
double sm_bfacet_normal(const sm_mesh *m, const double *coords, int32_t f,
                        double *normal);

#endif
