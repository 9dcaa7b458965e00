/* The target: a signed distance function d given as P1 values on a fixed
 * background simplicial mesh (any bounding box, possibly non-conforming).
 *
 * Point location uses a uniform bucket grid over the background bounding
 * box plus a straight walk through element neighbours from a hint element
 * (typically the element found for the same point at the previous
 * iteration), so a sample costs about O(1). */
#ifndef SM_FIELD_H
#define SM_FIELD_H

#include <stdint.h>

#include "sm_error.h"
#include "sm_mesh.h"

typedef struct sm_field sm_field;

/* Builds the search structures.  bg must have dim 2 or 3 and valid
 * connectivity; values has bg->nverts entries.  The field keeps pointers
 * to bg and values (borrowed: they must outlive the field).  The field is
 * read-only after construction, so concurrent evaluation is safe. */
sm_status sm_field_new(const sm_mesh *bg, const double *values,
                       sm_field **out, sm_error *err);
void sm_field_free(sm_field *f);

/* Element of the background mesh containing x (within a small relative
 * tolerance), or -1 when x is outside every element.  hint is an element
 * index to start the walk from, or -1.  bary (dim+1 entries, may be NULL)
 * receives the barycentric coordinates of x in that element. */
int32_t sm_field_locate(const sm_field *f, const double *x, int32_t hint,
                        double *bary);

/* Value of d at x.  *hint (may be NULL) is read as the walk's start and
 * updated with the element found.  Points outside the background mesh get
 * a positive extension: the value at the nearest point of the background
 * mesh plus the distance to it (so never a crash, never a silent 0).
 * Never NaN: a non-finite x gives +INFINITY (and leaves *hint alone).
 * For an outside point *hint becomes the element holding the nearest
 * point.  Any hint (stale, out of range, -1) gives the same value up to
 * rounding; only the cost changes. */
double sm_field_eval(const sm_field *f, const double *x, int32_t *hint);

/* sm_field_eval on n points in turn (xs: n*dim coordinates; hints: n
 * entries, each read and updated as by sm_field_eval, or NULL; values: n
 * results; the three arrays must not overlap), with exactly the same
 * results.  Each point has its own hint, so the points are independent,
 * and the walks of a group of points advance together: their cache
 * misses overlap, which makes many scattered points (the vertices or
 * quadrature points of a mesh, each with the element found for it at the
 * previous iteration) several times cheaper than one call each. */
void sm_field_eval_many(const sm_field *f, int64_t n, const double *xs, int32_t *hints,
                        double *values);

/* d at n points that come without hints (xs: n*dim; values: n), such as
 * the vertices of a mesh in its generator's numbering: the points are
 * visited in Morton order, each walk starting from the element of the
 * point before, so that it takes a step or two and finds what it reads
 * still in cache (a lookup from the grid costs several times more).
 * hints (may be NULL) receives the element each point was found in, as
 * sm_field_eval leaves it.  The order is cut in blocks of 4096 points,
 * shared by the OpenMP threads; the values are sm_field_eval's (up to
 * rounding, as with any hint) and do not depend on the threads. */
void sm_field_eval_points(const sm_field *f, int64_t n, const double *xs, int32_t *hints,
                          double *values);

/* Dimension of the background mesh (2 or 3): the number of coordinates
 * of a point and of entries of a gradient. */
int sm_field_dim(const sm_field *f);

/* Value and gradient of d at x (grad has dim entries; hint as for
 * sm_field_eval).  Inside: the P1 gradient of the element found.  Outside:
 * the gradient of the extension where it is smooth, i.e. the unit vector
 * from the nearest point p to x plus the tangential part of the P1
 * gradient at p. */
double sm_field_eval_grad(const sm_field *f, const double *x, int32_t *hint,
                          double *grad);

/* Nearest point of the background mesh to x (dim entries) and its
 * distance (0 when x is inside within the location tolerance); returns
 * the element holding that point, or -1 for a non-finite x. */
int32_t sm_field_nearest(const sm_field *f, const double *x, double *nearest,
                         double *distance);

/* The geometry and size of the search structures, for tests and
 * benchmarks. */
typedef struct sm_field_stats {
    int32_t grid[3];          /* cells per axis (grid[2] = 1 in 2D) */
    int64_t ncells;
    int64_t elem_entries;     /* total length of the cell -> element lists */
    int32_t max_cell_elems;   /* longest cell list */
    int32_t nboundary_facets; /* facets with no neighbour (outside search) */
    int64_t facet_entries;    /* total length of the cell -> facet lists */
    int64_t coarse_cells;     /* coarse facet grid (far outside points) */
    int64_t coarse_facet_entries;
    int32_t ndegenerate;      /* zero-volume elements, skipped */
    double lo[3], hi[3];      /* grid box (bounding box of the valid elements) */
    size_t bytes;             /* memory held by the field */
} sm_field_stats;
void sm_field_get_stats(const sm_field *f, sm_field_stats *st);

#endif
