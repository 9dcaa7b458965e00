/* The facet hierarchy behind sm_sdf (internal; see sm_bvh.c). */
#ifndef SM_BVH_H
#define SM_BVH_H

#include <stdint.h>

#include "shapematch/sm_error.h"
#include "shapematch/sm_sdf.h"
#include "shapematch/sm_surface.h"

typedef struct sm_bvh_node {
    double lo[3], hi[3];   /* box of the facets (z = 0 in 2D) */
    double n[3];           /* sum of the facets' area vectors */
    double c[3];           /* area-weighted centroid */
    double r;              /* radius of the box about c */
    int32_t left, right;   /* children, -1 for a leaf */
    int32_t first, count;  /* the node's facets: order[first .. first+count) */
} sm_bvh_node;

typedef struct sm_bvh {
    const sm_surface *s;   /* borrowed */
    int32_t *order;        /* facet ids, grouped by node */
    double *pos;           /* vertex coordinates of facet order[i] at
                            * pos + i * dim * dim (contiguous leaves) */
    sm_bvh_node *nodes;    /* nodes[0] is the root */
    int32_t nnodes;
    int depth;             /* traversal stacks need 2 * depth + 2 entries */
} sm_bvh;

sm_status sm__bvh_build(const sm_surface *s, sm_bvh *t, sm_error *err);
/* The same tree without the far-field moments (n, c, r zero): for
 * sm__bvh_nearest only, the same boxes and so the same answers, built
 * in a fraction of the time (the moments were most of a build). */
sm_status sm__bvh_build_boxes(const sm_surface *s, sm_bvh *t, sm_error *err);
void sm__bvh_free(sm_bvh *t);
/* After the surface's vertices moved (same facets, t->s->coords now the
 * new positions): the leaves' positions and every box again, the tree
 * kept (O(facets), where a build sorts).  The boxes stay exact, so the
 * nearest-facet search stays exact; the far-field moments (n, c, r) are
 * not updated: a refitted tree is for sm__bvh_nearest only. */
void sm__bvh_refit(sm_bvh *t);

/* Squared distance from p to the box [lo, hi] (dim 2 or 3): the one box
 * test of the facet hierarchies, this one and the field's facet tree
 * (sm_field_nearest.c). */
static inline double sm__box_dist2(const double *lo, const double *hi, const double *p, int dim)
{
    double d2 = 0;
    for (int k = 0; k < dim; k++) {
        double e = p[k] < lo[k] ? lo[k] - p[k] : p[k] > hi[k] ? p[k] - hi[k] : 0;
        d2 += e * e;
    }
    return d2;
}

/* Traversal stack entry of the nearest-facet search: a node and the
 * squared distance from p to its box (computed once, when pushed). */
typedef struct sm_bvh_entry {
    double d2;
    int32_t node;
} sm_bvh_entry;

/* Distance from p to the nearest facet; *hint (a facet id or -1) seeds
 * the search and receives the nearest facet.  stack: 2 * depth + 2. */
double sm__bvh_nearest(const sm_bvh *t, const double *p, int32_t *hint, sm_bvh_entry *stack);
double sm__bvh_facet_dist2(const sm_bvh *t, int32_t f, const double *p);
/* Area vector (outward for an outward facet) and centroid of facet f. */
void sm__bvh_facet_moments(const sm_surface *s, int32_t f, double *n, double *c);
double sm__sdf_point_segment3_2(const double *p, const double *a, const double *b);
/* Closest point of triangle abc (3D) to p: squared distance, and its
 * barycentric coordinates in bary[3]. */
double sm__triangle_closest(const double *p, const double *a, const double *b, const double *c,
                            double *bary);
/* Closest point of segment ab (dim 2 or 3) to p: squared distance, and
 * its parameter t in [0, 1] (a + t (b - a)). */
double sm__segment_closest(const double *p, const double *a, const double *b, int dim, double *t);

/* The closest point p of triangle abc (3D) or segment ab (2D) to x: the
 * nearest field's outside extension and the alignment's point-to-surface
 * residuals. */
void sm__closest_on_triangle(const double *x, const double *a, const double *b, const double *c,
                             double *p);
void sm__closest_on_segment(const double *x, const double *a, const double *b, double *p);

/* The surface an sm_sdf was built on (sm_sdf.c). */
const sm_surface *sm__sdf_surface(const sm_sdf *d);

/* Signed distances of n points with their nearest facets: nearest[i]
 * seeds the search (a facet id, or -1: the previous point's answer) and
 * receives the nearest facet.  The sign is the nearest facet's side when
 * the closest point lies inside the facet (the direction to it is the
 * facet's normal), else the winding number's as in sm_sdf_signed: the
 * same sign on an oriented surface, at a fraction of the cost for points
 * near it.  Without sm_sdf_signed's refusals: a surface that no point is
 * inside is no error here (the alignment's points may all lie outside
 * the target).  SM_ERR_NOMEM only. */
sm_status sm__sdf_signed_nearest(const sm_sdf *d, int64_t n, const double *pts, double *out,
                                 int32_t *nearest, sm_error *err);

/* Unsigned distances of n points, each search seeded by nearest[i] (a
 * facet id, or -1: the previous point's answer), which receives the
 * nearest facet: for points that moved little since the last call (the
 * alignment's iterations), a search that starts at the answer. */
void sm__sdf_nearest_hinted(const sm_sdf *d, int64_t n, const double *pts, double *dist,
                            int32_t *nearest);

/* Generalized winding number at p (sm_winding.c). */
double sm__winding_at(const sm_bvh *t, const double *p, int32_t *stack);

#endif
