/* Marching tetrahedra on a grid of voxel centres for the label map's
 * surface (sm_image_sdf.c); core-private. */
#ifndef SM_IMAGE_MARCH_H
#define SM_IMAGE_MARCH_H

#include <stddef.h>
#include <stdint.h>

#include "shapematch/sm_error.h"
#include "shapematch/sm_surface.h"

typedef struct mt_builder {
    const float *f;
    int64_t n[3];
    const int64_t *lo, *hi; /* the active box (sm_image_target's) */
    double level;
    const double *map;
    double *coords;   /* 3 per vertex */
    int32_t *tris;
    int64_t nv, capv, nt, capt;
    int64_t *keys;    /* edge hash: key + 1 (0: empty) */
    int32_t *vals;
    int64_t hcap;
    int64_t cell;     /* the cell being marched, */
    int64_t *tcell;   /* and each triangle's */
    int64_t capc;
    int fail;
} mt_builder;

/* The level set of b->f at b->level over the cells with a corner in the
 * box b->lo..b->hi (the others have every corner on one side) as a
 * closed triangle surface in the world of b->map, each triangle turned
 * away from the inside and its cell in b->tcell (nondecreasing: cell by
 * cell, 6 Kuhn tetrahedra each, so neighbouring cells agree).  The
 * cells are marched in parallel in chunks of whole slices, each with
 * its own arrays, and joined numbered as one march in order would (the
 * same surface on any number of threads).  The caller frees b->tcell
 * after (b's other arrays are left NULL).  SM_ERR_INVALID when no cell
 * is crossed. */
sm_status sm__image_march(mt_builder *b, sm_surface **out, sm_error *err);

/* *p grown (doubling, from 1024) to hold need items of size bytes: 0
 * when out of memory (*p unchanged then). */
int sm__image_grow(void **p, int64_t *cap, int64_t need, size_t size);

/* The world point x of grid index (i, j, k) (fractional indices allowed)
 * under map, row-major 3 x 4 (index -> world). */
static inline void sm__grid_world(const double *map, double i, double j, double k, double *x)
{
    for (int row = 0; row < 3; row++)
        x[row] = map[4 * row] * i + map[4 * row + 1] * j + map[4 * row + 2] * k + map[4 * row + 3];
}

#endif
