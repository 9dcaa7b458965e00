/* Orientation of whole pieces of a target surface (internal; see
 * sm_surface_orient.c), after sm_surface_repair made each piece
 * consistent within itself. */
#ifndef SM_SURFACE_ORIENT_H
#define SM_SURFACE_ORIENT_H

#include <stdint.h>

#include "shapematch/sm_error.h"
#include "shapematch/sm_surface.h"

/* Above this many open pieces their mutual coupling (a dense matrix) is
 * not formed, nor above this many pairs of boundary elements of different
 * pieces (the coupling's cost: 2D end points, 3D edges, each pair a few
 * square roots or a logarithm; 5e7 take about a second), and each open
 * piece is turned by its own volume about the centroid. */
#define SM_ORIENT_MAX_COUPLED 1024
#define SM_ORIENT_MAX_PAIRS 5e7

typedef struct sm_orient_counts {
    int64_t open_pieces; /* pieces with a boundary (holes, borders) */
    int64_t by_volume;   /* open pieces turned by their own volume only */
} sm_orient_counts;

/* comp[f]: the piece of facet f in [0, npieces), or -1 for a facet left
 * out (a duplicate); all_closed: every edge (2D: vertex) of the facets
 * not left out is on exactly two of them, so every piece is closed.
 * Decides for each piece whether to turn it over (turn[c] = 1; npieces
 * entries), without changing s:
 *   - a closed piece (its facets' boundary chain is zero) so that it
 *     encloses a positive volume (area in 2D);
 *   - the open pieces consistently with each other: by the coupling of
 *     their boundaries (the flux of one's winding-number gradient through
 *     the other), the strongest couplings first (a maximum spanning tree),
 *     then single turns that lower the total, then all together so that
 *     their volume about their common centroid is positive. */
sm_status sm__surface_orient_pieces(const sm_surface *s, const int32_t *comp, int32_t npieces,
                                    int all_closed, uint8_t *turn, sm_orient_counts *counts,
                                    sm_error *err);

#endif
