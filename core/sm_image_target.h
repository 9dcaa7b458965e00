/* The label map's target (sm_image.h's sm_image_target) inside the core:
 * its fields, the crossed cells' index, and what sm_image_grid.c (the
 * distance on the crop's grid) shares with sm_image_sdf.c (the rest);
 * core-private. */
#ifndef SM_IMAGE_TARGET_H
#define SM_IMAGE_TARGET_H

#include <stdint.h>

#include "shapematch/sm_image.h"
#include "shapematch/sm_sdf.h"
#include "shapematch/sm_surface.h"

/* A crossed cell: its triangles and their box (rounded outward to float:
 * a lower bound of the distance to any of them for one test). */
typedef struct cell_tris {
    int32_t cell, first, count;
    float lo[3], hi[3];
} cell_tris;

struct sm_image_target {
    int64_t n[3];      /* the crop, in voxels */
    int64_t act_lo[3], act_hi[3]; /* the crop's voxels where the field can
                                   * differ from its value far outside:
                                   * the selection's box and the blur's
                                   * reach */
    double map[12];    /* crop index -> world (the image's frame) */
    double inv[12];    /* world -> crop index */
    double h[3];       /* spacing along the crop's axes */
    double smin;       /* a lower bound of the map's smallest singular
                        * value: world length of a unit index step */
    double step[3];    /* per axis, a lower bound of the world distance
                        * of index gap 1 (orthogonal axes: the spacing;
                        * else smin): a gap g is sqrt(sum (g step)^2) */
    float *edt;        /* signed voxel-centre EDT on the crop */
    float *field;      /* the (smoothed) field the surface is a level of */
    double level;
    double band;       /* world units: exact within */
    int grid_band;     /* the grid's band refined (whole_image: the grid
                        * is the output; else points there are exact) */
    sm_surface *surface;
    /* the surface's triangles by the crop cell that made them (marching
     * emits them cell by cell, in order): the crossed cells, and a table
     * from a cell to its place there (open addressing, key cell + 1) */
    cell_tris *cells;
    int64_t ncells;
    int64_t *slice_cells; /* n[2] + 1: the first crossed cell of each slice */
    int32_t *ckeys, *crun;
    int64_t ccap;
    uint64_t *cbits;   /* one bit a crop cell: it has triangles (most
                        * cells a search visits have none) */
    sm_sdf *sdf;       /* opts->hierarchy only */
};

/* The crossed cells' table: open addressing on cell + 1. */
static inline uint64_t sm__cell_hash(int64_t key, int64_t cap)
{
    return ((uint64_t)key * 0x9E3779B97F4A7C15ull >> 20) & (uint64_t)(cap - 1);
}

/* The crossed cell c (crop cell index), NULL when c has no triangles. */
static inline const cell_tris *sm__cell_triangles(const sm_image_target *t, int64_t c)
{
    if (!(t->cbits[c >> 6] >> (c & 63) & 1))
        return NULL;
    uint64_t s = sm__cell_hash(c + 1, t->ccap);
    while (t->ckeys[s]) {
        if (t->ckeys[s] == c + 1)
            return t->cells + t->crun[s];
        s = (s + 1) & (uint64_t)(t->ccap - 1);
    }
    return NULL;
}

/* The squared distance from p to cell c's triangles' box (a lower bound
 * of the distance to each of them). */
static inline double sm__cell_box2(const cell_tris *c, const double *p)
{
    double box2 = 0;
    for (int r = 0; r < 3; r++) {
        double g = p[r] < c->lo[r] ? c->lo[r] - p[r] : p[r] > c->hi[r] ? p[r] - c->hi[r] : 0;
        box2 += g * g;
    }
    return box2;
}

/* *best2 lowered to the squared distance from p to the triangles first
 * .. first + count - 1 nearer than it, *bestf to the nearest of them. */
void sm__image_range_nearest(const sm_image_target *t, int32_t first, int32_t count,
                             const double *p, double *best2, int32_t *bestf);

/* The same for cell c's triangles (NULL: none) when their box is nearer. */
static inline void sm__cell_nearest(const sm_image_target *t, const cell_tris *c, const double *p,
                                    double *best2, int32_t *bestf)
{
    if (c && sm__cell_box2(c, p) < *best2)
        sm__image_range_nearest(t, c->first, c->count, p, best2, bestf);
}

/* The crossed cell whose triangles hold triangle f. */
const cell_tris *sm__image_triangle_cell(const sm_image_target *t, int32_t f);

/* The exact distance from world point p to the surface, from a triangle
 * bestf at squared distance best2 already known (-1, INFINITY: none);
 * *closest (when not NULL): its nearest point, *nearest (when not NULL)
 * its triangle. */
double sm__image_surface_distance_from(const sm_image_target *t, const double *p, double best2,
                                       int32_t bestf, double *closest, int32_t *nearest);

/* The signed distance at every crop voxel centre into t->edt
 * (sm_image_grid.c); f, level: the field and its level. */
sm_status sm__image_distance_field(sm_image_target *t, const float *f, double level,
                                   sm_error *err);

#endif
