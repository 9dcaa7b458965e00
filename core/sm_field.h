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
 * mesh plus the distance to it (so never a crash, never a silent 0). */
double sm_field_eval(const sm_field *f, const double *x, int32_t *hint);

/* Number of elements visited by walks so far is not tracked (read-only
 * structure); these expose the grid geometry for tests and benchmarks. */
int sm_field_dim(const sm_field *f);

#endif
