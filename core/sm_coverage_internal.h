/* What the descent (sm_match.c) uses of a coverage (sm_coverage.h): the
 * target-side term T(x) = sum_y w_y (|y - p_y(x)| - delta)_+^2 over the
 * target's samples y, p_y the closest point of the boundary at vertex
 * positions x, delta half the template boundary's mean edge.  The dead zone delta makes T exactly 0 once the whole
 * target is within a facet's reach of the boundary: there the descent is
 * the paper's, whose J places the boundary on the target more precisely
 * than a fit to samples (a chord of the target's curve), and T only acts
 * where the boundary misses part of the target.
 *
 * The closest points are found at every trial of the step search
 * (sm__coverage_correspond) and kept as a facet and barycentric
 * coordinates; the load is the gradient of T with them held fixed
 * (sm__coverage_add_load), which is T's own gradient where each closest
 * point is unique (it moves smoothly with x and the distance is
 * stationary along the boundary there).  The step search's Armijo test
 * takes the true T at each trial, so an accepted step decreases
 * E = J + weight * T: the descent decreases one well-defined energy.
 * (T with the correspondences held fixed bounds T from above, but so
 * loosely once the boundary slides along the target that it shortened
 * the accepted steps about tenfold: sm_match.c, line_search.) */
#ifndef SM_COVERAGE_INTERNAL_H
#define SM_COVERAGE_INTERNAL_H

#include "shapematch/sm_coverage.h"

/* Finds each target sample's closest point on the boundary at coords and
 * keeps it; returns the target side's figures (rms, max, mean, p99 over
 * the samples) and *term = T(coords).  SM_ERR_NOMEM. */
sm_status sm__coverage_correspond(sm_coverage *c, const double *coords, sm_distance_side *fig,
                                  double *term, sm_error *err);

/* load += -weight * grad T at the correspondences kept (nverts * dim):
 * 2 weight w_y (1 - delta / |y - p_y|) b_i (y - p_y) on vertex i of y's
 * facet, for the samples beyond delta. */
void sm__coverage_add_load(const sm_coverage *c, const double *coords, double weight,
                           double *load);

/* out = the load spread over the boundary's vertex graph: passes times,
 * each vertex's share split equally between itself and its boundary
 * neighbours (the total force is kept).  The term's gradient is a set
 * of point loads, which an elastic solve turns into a spike (a point
 * load's displacement is singular in 2D and 3D); spread over a few rings
 * of the boundary it acts as a traction, as J's load does.  load and out
 * have nverts * dim entries and may not overlap. */
void sm__coverage_spread(sm_coverage *c, const double *load, double *out, int passes);

#endif
