/* Points in Morton (Z-curve) order (internal, not part of the public
 * API): neighbours in the order are mostly neighbours in space, so work
 * that carries something from one point to the next (a nearest-facet
 * hint, the sign of a distance, the element a walk ends in) finds it
 * close by, and the memory it touches stays in cache. */
#ifndef SM_MORTON_H
#define SM_MORTON_H

#include <stdint.h>

/* The indices 0..n-1 of the points pts (n*dim coordinates; non-finite
 * ones count as the box's low corner) in Morton order of their bounding
 * box, ties in index order; a radix sort, O(n).  malloc'ed (free), NULL
 * when out of memory. */
int64_t *sm__morton_order(int dim, int64_t n, const double *pts);

#endif
