/* The nearest-site transform behind the label map's distance
 * (sm_image_sdf.c); core-private. */
#ifndef SM_EDT_H
#define SM_EDT_H

#include <stdint.h>

#include "shapematch/sm_error.h"

/* For every voxel centre of an n[0] x n[1] x n[2] grid of spacings h[3],
 * the site nearest it (Euclidean with those spacings; ties either way):
 * site s (of nsites) sits at voxel site_ijk[3 s .. 3 s + 2].  near (n[0]*n[1]*n[2])
 * holds s at site s's voxel and -1 elsewhere on entry, the nearest site
 * of every voxel on return (-1 only when there is no site).  The
 * separable lower envelope of parabolas of sm_edt.c, carrying the
 * minimiser instead of the distance, so that the caller measures the
 * distance to what the site stands for (its nearest surface point).
 * Only SM_ERR_NOMEM fails. */
sm_status sm__edt_nearest(const int64_t n[3], const double h[3], const int32_t *site_ijk,
                          int64_t nsites, int32_t *near, sm_error *err);

#endif
