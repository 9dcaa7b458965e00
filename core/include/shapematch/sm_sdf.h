/* Signed distance to a target surface (sm_surface.h): the exact
 * Euclidean distance to the nearest triangle (3D) or segment (2D), and
 * its sign from the generalized winding number, negative inside.
 *
 * Distance: a bounding-volume hierarchy over the facets; the queries
 * are visited in Morton (Z-curve) order and each starts from the nearest
 * facet of the previous one (a neighbour in space), then visits boxes
 * nearest first and prunes those farther than the best so far.  The
 * point-facet distance is computed in double precision from the closest
 * point's region (vertex, edge or face), so the result is the brute-force
 * minimum over all facets, not an approximation.  Queries run in
 * parallel (OpenMP).
 *
 * Sign: the generalized winding number w(p) (Jacobson et al. 2013) — the
 * solid angle (3D) or angle (2D) the oriented surface subtends at p,
 * divided by 4 pi (2 pi) — is 1 inside a closed outward surface and 0
 * outside, and degrades gracefully with holes, duplicated patches and
 * small self-intersections.  It is evaluated hierarchically over the same
 * hierarchy (in the manner of Barill et al. 2018, our own code): a box far
 * from p (distance > SM_SDF_FAR_RATIO times its radius) contributes its
 * dipole (area-weighted normal at its centroid), near boxes are summed
 * exactly facet by facet.  p is inside when w > 1/2.  The facets should
 * first be oriented consistently and outward (sm_surface_repair). */
#ifndef SM_SDF_H
#define SM_SDF_H

#include <stdint.h>

#include "sm_error.h"
#include "sm_mesh.h"
#include "sm_surface.h"

#define SM_SDF_FAR_RATIO 2.0

typedef struct sm_sdf sm_sdf;

/* Builds the hierarchy over s (borrowed: s must outlive the sm_sdf and
 * stay unchanged).  s must have finite coordinates and valid indices (as
 * sm_surface_read gives). */
sm_status sm_sdf_new(const sm_surface *s, sm_sdf **out, sm_error *err);
void sm_sdf_free(sm_sdf *d);

/* Unsigned distance of n points (n * dim coordinates) into dist (n);
 * nearest (n, or NULL) receives the index of a nearest facet. */
void sm_sdf_distance(const sm_sdf *d, int64_t n, const double *pts, double *dist,
                     int32_t *nearest);

/* Generalized winding number of n points into w (n). */
void sm_sdf_winding(const sm_sdf *d, int64_t n, const double *pts, double *w);

/* Signed distance (negative inside, where w > 1/2) of n points into out.
 * A surface that encloses nothing (no point with w > 1/2, or a total
 * enclosed volume that is zero) is SM_ERR_INVALID with a message. */
sm_status sm_sdf_signed(const sm_sdf *d, int64_t n, const double *pts, double *out,
                        sm_error *err);

/* sm_sdf_signed, and *wound (may be NULL) receives how many points had
 * their winding number evaluated.  The points are visited in Morton
 * order (the nearest-facet hint of one seeds the next).  On a closed
 * surface (every edge traversed once each way, or in 2D every vertex
 * entered as often as left — sm_surface_repair makes a watertight
 * surface so) the winding number is constant off the surface on each
 * connected region, so a point takes the sign of the previous one when
 * the segment between them lies in the open balls of radius d about
 * them (|pq| < dp + dq: no surface point there); the others, and every
 * point of a surface with holes or duplicated facets, get their own
 * winding number.  The result is the same as evaluating the winding
 * number everywhere (tests/unit/test_sdf.c checks it). */
sm_status sm_sdf_signed_stats(const sm_sdf *d, int64_t n, const double *pts, double *out,
                              int64_t *wound, sm_error *err);

/* A background mesh for a surface target when the user has none: the
 * box lo..hi (dim entries; the caller pads it) cut into cubes (squares)
 * of side close to h, each split into 6 tetrahedra (2 triangles) along
 * its main diagonal (Kuhn), so neighbouring cells conform.  Uniform, not
 * graded.  More than SM_BACKGROUND_MAX_VERTS vertices is SM_ERR_INVALID
 * (asks for a larger h). */
#define SM_BACKGROUND_MAX_VERTS 8000000
sm_status sm_background_new(int dim, const double *lo, const double *hi, double h,
                            sm_mesh **out, sm_error *err);

/* A background graded toward the surface of d: cells (quadtree in 2D,
 * octree in 3D, each Kuhn split) of side at most h where the surface is
 * within about a cell size, doubling away from it up to a few coarse
 * cells across the box; non-conforming (hanging vertices at the level
 * changes, which sm_field accepts).  The P1 interpolation error of the
 * distance near the surface is that of a uniform grid of size h, with
 * far fewer vertices (bench/bg_bench.c measures both).  Too many
 * vertices (> SM_BACKGROUND_MAX_VERTS) is SM_ERR_INVALID. */
sm_status sm_background_graded_new(int dim, const double *lo, const double *hi, double h,
                                   const sm_sdf *d, sm_mesh **out, sm_error *err);

/* The same with the distance from fn (n points of dim coordinates into
 * dist; user passed through): for a target with a distance of its own
 * (a label map's: sm_image.h).  fn may overestimate by little: a cell
 * is split when the distance at its centre is below its half-diagonal
 * plus its side. */
typedef void (*sm_distance_fn)(void *user, int64_t n, const double *pts, double *dist);
sm_status sm_background_graded_fn_new(int dim, const double *lo, const double *hi, double h,
                                      sm_distance_fn fn, void *user, sm_mesh **out,
                                      sm_error *err);

/* Exact distance squared from p to triangle abc (3D) / segment ab (2D). */
double sm_sdf_point_triangle2(const double *p, const double *a, const double *b,
                              const double *c);
double sm_sdf_point_segment2(const double *p, const double *a, const double *b);

#endif
