/* The correspondence a match computes, used: points, vertices and fields
 * carried through the piecewise-linear map from the template to the
 * target (forward) or back (inverse).
 *
 * The map is given by the template mesh (its topology and coordinates X)
 * and the deformed coordinates Y of the same vertices (a result's
 * result.mesh; X = Y - displacement).  In each element it is the affine
 * map sending the template element onto the deformed one:
 *   forward  x in template element e, barycentric coordinates l:
 *            y = sum_k l_k Y[e_k]        (continuous across facets)
 *   inverse  y located in the deformed mesh, x = sum_k l_k X[e_k]
 * A point given exactly at a vertex of the element found maps exactly
 * onto that vertex's image (no rounding).  Location is the target
 * field's (sm_field.h: bucket grid and walk), over the template for the
 * forward map and over the deformed mesh for the inverse.
 *
 * Inside: within the source mesh up to the location's relative tolerance
 * (1e-10 of the element size: points on the boundary are inside).  A
 * point outside is mapped by the affine map of the element holding its
 * nearest point of the source mesh (an extrapolation, continuous for
 * points near the boundary) and flagged inside = 0, or refused when
 * strict.
 *
 * Fields on the vertices: scalars are carried as they are (the vertex is
 * the same material point on both sides); vectors are pushed forward by
 * the deformation gradient F = dY/dX (constant per element; at a vertex
 * the average over its elements weighted by their template volumes), and
 * symmetric tensors T become F T F^T.  The inverse uses F^-1 averaged by
 * the deformed volumes.
 *
 * Every function is safe to call concurrently on one sm_warp, which is
 * read-only once built; point batches are shared by the OpenMP threads
 * with results that do not depend on their number. */
#ifndef SM_WARP_H
#define SM_WARP_H

#include <stdint.h>

#include "sm_error.h"
#include "sm_mesh.h"

typedef struct sm_warp sm_warp;

typedef enum sm_warp_direction {
    SM_WARP_FORWARD = 0, /* template -> target (the deformed mesh) */
    SM_WARP_INVERSE = 1  /* target -> template */
} sm_warp_direction;

/* Bits of sm_warp_new's `directions`: which location structures to
 * build (each costs about a field construction, sm_field_new). */
#define SM_WARP_LOCATE_FORWARD (1u << SM_WARP_FORWARD)
#define SM_WARP_LOCATE_INVERSE (1u << SM_WARP_INVERSE)

/* Builds the map, with the location structures of `directions` (the
 * template's for the forward map, the deformed mesh's for the inverse;
 * 0 for fields only).  tmpl (dim 2 or 3, valid indices, finite
 * coordinates) and deformed (tmpl->nverts * dim finite coordinates) are
 * borrowed: they must outlive the warp.  SM_ERR_INVALID naming the fault
 * (a non-finite deformed coordinate, an empty mesh), SM_ERR_NOMEM. */
sm_status sm_warp_new(const sm_mesh *tmpl, const double *deformed, unsigned directions,
                      sm_warp **out, sm_error *err);
void sm_warp_free(sm_warp *w);

/* The dimension (2 or 3): coordinates per point. */
int sm_warp_dim(const sm_warp *w);

/* Maps n points (in: n*dim coordinates) to out (n*dim; may not overlap
 * in).  inside (n flags, may be NULL) receives 1 for a point within the
 * source mesh and 0 for an extrapolated one.  strict: the first point
 * outside (in input order) is SM_ERR_INVALID "point I (1-based) is
 * outside the template|deformed mesh (distance D)", and out is then
 * unspecified.  A non-finite coordinate is always SM_ERR_INVALID naming
 * the point.  *noutside (may be NULL) receives the number of points
 * outside.  Cost: about a walk step or two per point (the points are
 * visited in Morton order, each walk starting from the element of the
 * one before).  SM_ERR_INVALID when dir's structures were not built. */
sm_status sm_warp_points(const sm_warp *w, sm_warp_direction dir, int strict, int64_t n,
                         const double *in, double *out, uint8_t *inside, int64_t *noutside,
                         sm_error *err);

/* The deformation gradient at the vertices (forward: F averaged by the
 * template volumes; inverse: F^-1 averaged by the deformed volumes),
 * nverts * dim * dim entries row-major, into a new malloc'd array.
 * An element of zero volume on the side that weighs it is skipped; a
 * vertex with no usable element gets the identity.  SM_ERR_NOMEM. */
sm_status sm_warp_vertex_gradients(const sm_warp *w, sm_warp_direction dir, double **out,
                                   sm_error *err);

/* Carries a field given at the template's vertices (nverts values of
 * ncomp components: 1 scalar, dim vector, dim*(dim+1)/2 symmetric tensor
 * in Medit's order xx, xy, yy[, xz, yz, zz]) in place: scalars unchanged,
 * vectors v -> G v, tensors T -> G T G^T, G the vertex gradient of dir.
 * normalize: vectors are then scaled to unit length (directions, such
 * as fibres; a zero vector stays zero); ignored for other kinds.
 * SM_ERR_INVALID for another ncomp. */
sm_status sm_warp_field(const sm_warp *w, sm_warp_direction dir, int ncomp, int normalize,
                        double *values, sm_error *err);

#endif
