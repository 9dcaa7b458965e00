/* The matching functional J(Omega) = int_Omega d and its shape derivative
 * J'(Omega)(theta) = int_{dOmega} d theta.n, evaluated consistently on a
 * deforming mesh.
 *
 * Why the functional is evaluated this way: the exact derivative of
 * int_Omega d under a piecewise-affine mesh motion only involves the
 * boundary (interior motions change nothing), so
 *   - the load uses a facet quadrature of d sampled on the background field
 *     (not d at the vertices interpolated), and
 *   - the change of J between two meshes is the integral of d over the
 *     region swept by the active boundary facets, computed with a tensor
 *     quadrature (facet rule x Simpson's rule along the motion) that is
 *     exact when d is affine.  At zero step its derivative is exactly
 *     -load.u (same facet rule).  Simpson's end points are the facet
 *     points of the two meshes: a step reuses the current mesh's samples,
 *     and the load of the mesh a step leads to reuses the step's.
 * A volume quadrature of J whose error changes whenever interior vertices
 * move would instead make the line search stall once the true decrease
 * falls below that noise (the authors' code stalls near 1e-3 / 3e-4). */
#ifndef SM_SHAPE_H
#define SM_SHAPE_H

#include <stdint.h>

#include "shapematch/sm_error.h"
#include "shapematch/sm_field.h"
#include "shapematch/sm_mesh.h"

typedef struct sm_shape sm_shape;

/* m must have its boundary built (sm_mesh_build_boundary).  Boundary
 * facets whose reference is in free_refs (nfree entries) are excluded
 * from the load, from the change of J and from the boundary error
 * ("free boundary").  m and field are borrowed. */
sm_status sm__shape_new(const sm_mesh *m, const sm_field *field,
                       const int32_t *free_refs, int nfree, sm_shape **out,
                       sm_error *err);
void sm__shape_free(sm_shape *s);

/* Number of boundary facets that carry the load. */
int32_t sm__shape_active_facets(const sm_shape *s);

typedef struct sm_boundary_error {
    double l2;   /* ||d||_L2(active boundary), facet quadrature */
    double max;  /* max |d| over boundary vertices and quadrature points */
    double measure; /* |active boundary| (length 2D, area 3D) */
} sm_boundary_error;

/* load (nverts*dim) = nodal forces of F(v) = -int_{dOmega} d v.n ds on the
 * mesh with vertex positions coords; also measures the boundary error. */
void sm__shape_load(sm_shape *s, const double *coords, double *load,
                   sm_boundary_error *be);

/* J(coords + disp) - J(coords): integral of d over the region swept by
 * the active boundary facets.  The samples at coords + disp are kept:
 * the next sm__shape_load takes them if it is given exactly that mesh. */
double sm__shape_delta_j(sm_shape *s, const double *coords,
                        const double *disp);

/* J by a degree-2 volume quadrature on every element (the initial value,
 * and an independent check of the accumulated changes). */
double sm__shape_volume_j(sm_shape *s, const double *coords);

#endif
