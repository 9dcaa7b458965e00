/* A template meshed from what users have: the inside of a closed surface
 * (triangles in 3D, a closed polyline in 2D; sm_surface.h) filled with
 * tetrahedra (triangles in 2D) by Netgen's nglib (LGPL-2.1, dynamically
 * loaded: docs/your-data.md says why nglib).
 *
 * sm_template_surface_check is the part that decides whether a surface
 * can be meshed at all, cheap and hostile-input safe (the fuzz target's);
 * sm_template_mesh_surface runs it, then nglib in a child process with a
 * time bound, and checks what comes back.  Both take the surface as the
 * readers give it: repair it first (sm_surface_repair orients it
 * outward; the check refuses an inconsistent orientation). */
#ifndef SM_TEMPLATE_MESH_H
#define SM_TEMPLATE_MESH_H

#include <stdint.h>

#include "sm_error.h"
#include "sm_mesh.h"
#include "sm_surface.h"

/* Elements a meshing may make when the caller states no bound. */
#define SM_TEMPLATE_MAX_ELEMENTS_DEFAULT 4000000
/* Wall seconds a meshing may take when the caller states no bound. */
#define SM_TEMPLATE_MAX_SECONDS_DEFAULT 600.0
/* Facets a template surface may have (the self-intersection test and
 * nglib's surface remeshing grow with them). */
#define SM_TEMPLATE_MAX_FACETS 2000000

typedef struct sm_template_mesh_opts {
    double size;          /* element size H, a length in the surface's
                           * unit; 0: the surface's mean edge */
    int64_t max_elements; /* refused before meshing when the volume over
                           * H's regular simplex exceeds it; 0: default */
    double max_seconds;   /* the child is killed after it; 0: default */
    double min_quality;   /* quality floor (sm_elem_quality): below it
                           * nglib optimises again, then the meshing is
                           * refused; 0: the descent's default floor */
} sm_template_mesh_opts;

typedef struct sm_template_mesh_info {
    double size;           /* H used */
    double surface_volume; /* enclosed by the surface (area in 2D),
                            * divergence theorem */
    double mesh_volume;    /* sum of the elements' */
    double min_quality, mean_quality;
    int32_t nverts, nelems;
    int passes;            /* nglib runs (2: optimised again) */
    double seconds;        /* wall time of the meshing */
    int64_t estimated_elements; /* the bound's estimate */
} sm_template_mesh_info;

/* Refuses, SM_ERR_INVALID with a message naming the defect: an empty
 * surface, more than SM_TEMPLATE_MAX_FACETS facets, a non-finite
 * coordinate, a degenerate facet (zero area, zero length in 2D), an open
 * one (an edge on one facet: "open: N edges on one triangle only, e.g.
 * between (x,y,z) and (x,y,z)"), a non-manifold one (an edge on three
 * facets or more; in 2D a vertex on three segments), inconsistent
 * orientation (an edge used twice in the same direction), a
 * self-intersecting one (two facets not sharing a vertex that cross,
 * found through a uniform grid of their boxes), or a non-positive
 * enclosed volume (inside-out).  SM_ERR_NOMEM.  volume (may be NULL):
 * the enclosed volume (area in 2D). */
sm_status sm_template_surface_check(const sm_surface *s, double *volume, sm_error *err);

/* Meshes the inside of s (checked as above) at size o->size (o may be
 * NULL: every default): an element bound from the volume and H first
 * (SM_ERR_INVALID naming --template-size when exceeded), then nglib in
 * a child process (SM_ERR_INVALID with nglib's failing step, or its
 * time bound, or how the child ended); elements oriented positively;
 * quality below the floor: nglib again with more optimisation steps,
 * then SM_ERR_INVALID naming the worst quality.  The mesh's elements
 * and facets (its boundary) have reference 1.  *out is the caller's
 * (sm_mesh_free); info (may be NULL) says what was made.  SM_ERR_IO
 * when the shim (libshapematch_nglib.so.0, found next to the program or
 * library holding this function, or by the loader's path) cannot be
 * loaded: the message says so. */
sm_status sm_template_mesh_surface(const sm_surface *s, const sm_template_mesh_opts *o,
                                   sm_mesh **out, sm_template_mesh_info *info, sm_error *err);

#endif
