/* Private to the target field (core/sm_field*.c): the structure, the
 * tuning constants and the small inline kernels the parts share.  Not
 * installed, not for callers of sm_field.h.
 *
 * The field is built and used in five files, one per part:
 *   sm_field.c            allocation, element validity, construction, stats
 *   sm_field_adjacency.c  neighbours across shared facets
 *   sm_field_grid.c       the bucket grids (element and facet lists, seeds)
 *   sm_field_locate.c     the walk, point location and evaluation
 *   sm_field_nearest.c    nearest point of the mesh for outside points
 * sm_warp.c also uses its element kernels (elem_cofactors) on a
 * template.  Functions shared between the parts carry the internal prefix sm__field_
 * (global symbols of the library, not part of its API). */
#ifndef SM_FIELD_INTERNAL_H
#define SM_FIELD_INTERNAL_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>

#include "shapematch/sm_error.h"
#include "shapematch/sm_field.h"
#include "shapematch/sm_mesh.h"
/* The arrays written right after they are allocated come from
 * sm__alloc_huge, the large scratch and the neighbours from
 * sm__alloc_large (sm_alloc.h: far fewer page faults). */
#include "sm_alloc.h"

/* Barycentric tolerance: a point is in an element when every coordinate is
 * >= -BARY_TOL.  Barycentric coordinates are dimensionless, so this is a
 * tolerance relative to the element size. */
#define BARY_TOL 1e-10
/* An element is degenerate when |det J| <= DEGENERATE_REL * hmax^dim. */
#define DEGENERATE_REL 1e-12
/* Element bounding boxes are inflated by this fraction of their extent
 * when binned, so points accepted within BARY_TOL are in a listed cell. */
#define BBOX_INFLATE 1e-8
/* Walk budget.  A good hint (the element of the same point at the previous
 * iteration) needs a handful of steps; past the budget the grid is
 * cheaper.  A hint whose barycentric coordinates put x more than
 * WALK_FAR_LAMBDA element heights away is not walked from at all: the walk
 * would take about that many steps, each a likely cache miss. */
#define WALK_MAX_STEPS 32
#define WALK_FAR_LAMBDA 8.0
/* Grid sizing: cells per valid element, and hard caps for hostile inputs
 * (few huge elements among tiny ones, extreme aspect ratios).  Elements are
 * binned by bounding box, and a tetrahedron's box is large compared to its
 * volume, so finer cells multiply the list entries quickly (on the
 * paper's graded 345k-tetrahedron background: 13 per tetrahedron at one
 * cell per two elements, 6 at one per eight, 17 and 8 MiB); since a lookup
 * walks from the cell's seed element, the number of candidates per cell
 * only matters for the exhaustive scan (points outside the mesh but
 * inside its box), and coarser 3D cells are the better deal: a lookup
 * without a hint takes a step or two more, and the descent's lookups
 * start from hints. */
#define GRID_CELLS_PER_ELEM_2D 1.0
#define GRID_CELLS_PER_ELEM_3D 0.125
/* The coarse facet grid (far points) has about this many cells per
 * boundary facet: a few facets per non-empty cell. */
#define GRID_CELLS_PER_BFACET 1.0
/* Rings of the element grid searched for the nearest facet before moving
 * to the coarse facet grid. */
#define NEAR_RINGS 2
#define GRID_MAX_CELLS (1 << 24)
#define GRID_MAX_AXIS (1 << 20)
/* Facets are matched in buckets of their smallest vertex, distributed in
 * two rounds of this fan-out: few enough write streams to stay in the
 * first-level cache, and small enough final buckets for their hash
 * tables to. */
#define ADJ_FANOUT_BITS 6
#define ADJ_FANOUT (1 << ADJ_FANOUT_BITS)
/* Elements whose vertex coordinates are requested ahead of their turn. */
#define PREFETCH_AHEAD 8
/* Values of the validity byte: usable, with det J > 0 or < 0. */
#define ELEM_VALID_POSITIVE 1
#define ELEM_VALID_NEGATIVE 2
/* Elements are sorted by blocks of cells, at most this many blocks. */
#define SORT_BLOCKS 1024
/* The parallel passes over the elements work on this many contiguous
 * chunks, whatever the number of threads (so their output does not
 * depend on it). */
#define BUILD_CHUNKS 16
/* sm_field_eval_many walks this many points together: enough misses in
 * flight to cover the memory latency, few enough to stay in registers
 * and first-level cache. */
#define EVAL_GROUP 16
/* Probes per entry a facet hash table may take before its bucket is
 * sorted instead (a fair table takes about one). */
#define HASH_PROBE_BUDGET 8

/* A uniform grid over a box; cells are numbered x fastest. */
typedef struct grid {
    int dim;
    double lo[3], hi[3], cell[3], inv_cell[3];
    int32_t n[3];
    int64_t ncells;
    double min_cell;
} grid;

typedef struct sm_field_lists sm_field_lists;

struct sm_field {
    const sm_mesh *bg;
    const double *values;
    int dim;
    int32_t nelems;
    int32_t nvalid;
    uint8_t *valid;      /* nelems: 0 for a degenerate element, else
                          * ELEM_VALID_POSITIVE or _NEGATIVE (sign of det J) */
    int32_t *neigh;      /* nelems*(dim+1): across the facet opposite local
                          * vertex k, or -1 (boundary, gap, non-manifold);
                          * from sm__alloc_large (sm__free_large) */

    /* element grid over the bounding box of the valid elements */
    grid g;
    int32_t *cell_seed;  /* ncells: start of the walk for points of the
                          * cell, -1 when no element's box meets the cell */
    int32_t *elem_start; /* ncells+1: where each cell's list starts */
    int32_t max_cell_elems;
    /* The lists themselves (the elements whose inflated box meets each
     * cell, ascending) are only needed when a walk fails: a point
     * outside the mesh, a non-convex or non-conforming one.  Built on
     * first need (sm__field_element_lists), once, under the mutex; the
     * flag, set last, tells the readers they are there. */
    sm_field_lists *lists;

    /* Facets without neighbour (the boundary of the union of the
     * elements, plus gaps), for the nearest point of outside points.  They
     * are binned twice: in the element grid, for points close to the mesh
     * (a couple of rings of small cells), and in a coarser grid sized by
     * their number, for points far from it (e.g. deep in a hole), where
     * rings of small cells would be mostly empty.  Cell entries index
     * bfacet_id / bfacet_xyz. */
    int32_t nbfacets;
    int32_t *bfacet_id;  /* e*(dim+1)+k */
    double *bfacet_xyz;  /* dim*dim: the facet's vertex coordinates */
    int32_t *facet_start;
    int32_t *facet_list;
    grid cg;
    int32_t *cfacet_start;
    int32_t *cfacet_list;
    /* And a bounding-box tree over them, for points far from the mesh
     * where even the coarse rings grow too many (every outside vertex of
     * a mesh given to warp from elsewhere): log-time, where a plain pass
     * over every facet was linear (sm_field_nearest.c). */
    struct facet_node *ftree;
    int32_t nftree;
    int32_t *ftree_order; /* facet indices, grouped by leaf */
    int ftree_depth;
};

/* A node of the facet tree: its box, and its children (left >= 0) or
 * its facets ftree_order[first .. first + count). */
typedef struct facet_node {
    double lo[3], hi[3];
    int32_t left, right, first, count;
} facet_node;


/* First index of chunk c of n items split into BUILD_CHUNKS. */
static inline int32_t chunk_begin(int32_t n, int c)
{
    return (int32_t)((int64_t)n * c / BUILD_CHUNKS);
}

/* ------------------------------------------------------------------ */
/* Barycentric coordinates and values, from the vertices               */

static inline const double *vcoord(const sm_field *f, int32_t v)
{
    return f->bg->coords + (size_t)v * (size_t)f->dim;
}

/* The cofactor rows of element e's Jacobian J = [v1-v0 | ... | vd-v0]
 * (rows of det J * J^-1) and det J, so that lambda_k = cof_(k-1) .
 * (x - v0) / det J for k = 1..dim.  Relative to a vertex, so the
 * rounding error stays proportional to the element size even far from
 * the origin.  Written out per dimension: this runs at every walk step. */
static inline __attribute__((always_inline)) double
elem_cofactors(const double *xyz, const int32_t *ev, double cof[3][3], const int D)
{
    const double *p0 = xyz + (size_t)ev[0] * D, *p1 = xyz + (size_t)ev[1] * D,
                 *p2 = xyz + (size_t)ev[2] * D;
    if (D == 2) {
        double a0 = p1[0] - p0[0], a1 = p1[1] - p0[1];
        double b0 = p2[0] - p0[0], b1 = p2[1] - p0[1];
        cof[0][0] = b1;
        cof[0][1] = -b0;
        cof[1][0] = -a1;
        cof[1][1] = a0;
        return a0 * b1 - b0 * a1;
    }
    const double *p3 = xyz + (size_t)ev[3] * D;
    double a0 = p1[0] - p0[0], a1 = p1[1] - p0[1], a2 = p1[2] - p0[2];
    double b0 = p2[0] - p0[0], b1 = p2[1] - p0[1], b2 = p2[2] - p0[2];
    double c0 = p3[0] - p0[0], c1 = p3[1] - p0[1], c2 = p3[2] - p0[2];
    cof[0][0] = b1 * c2 - b2 * c1; /* b x c */
    cof[0][1] = b2 * c0 - b0 * c2;
    cof[0][2] = b0 * c1 - b1 * c0;
    cof[1][0] = c1 * a2 - c2 * a1; /* c x a */
    cof[1][1] = c2 * a0 - c0 * a2;
    cof[1][2] = c0 * a1 - c1 * a0;
    cof[2][0] = a1 * b2 - a2 * b1; /* a x b */
    cof[2][1] = a2 * b0 - a0 * b2;
    cof[2][2] = a0 * b1 - a1 * b0;
    return a0 * cof[0][0] + a1 * cof[0][1] + a2 * cof[0][2];
}

/* Barycentric coordinates of x in the valid element e.  The field keeps
 * no per-element record: the vertex coordinates (24 B a vertex, and a
 * tetrahedral mesh has about a sixth as many vertices as elements) take
 * a twentieth of what a record of the inverse map took (128 B a
 * tetrahedron) and stay in cache far longer; the few dozen flops of the
 * inverse are the price. */
static inline __attribute__((always_inline)) void
elem_bary(const sm_field *f, int32_t e, const double *x, double *lam, const int D)
{
    const int32_t *ev = f->bg->elems + (size_t)e * (size_t)(D + 1);
    double cof[3][3];
    double inv = 1.0 / elem_cofactors(f->bg->coords, ev, cof, D);
    const double *p0 = f->bg->coords + (size_t)ev[0] * D;
    double y0 = x[0] - p0[0], y1 = x[1] - p0[1];
    if (D == 2) {
        lam[1] = (cof[0][0] * y0 + cof[0][1] * y1) * inv;
        lam[2] = (cof[1][0] * y0 + cof[1][1] * y1) * inv;
        lam[0] = 1.0 - lam[1] - lam[2];
        return;
    }
    double y2 = x[2] - p0[2];
    lam[1] = (cof[0][0] * y0 + cof[0][1] * y1 + cof[0][2] * y2) * inv;
    lam[2] = (cof[1][0] * y0 + cof[1][1] * y1 + cof[1][2] * y2) * inv;
    lam[3] = (cof[2][0] * y0 + cof[2][1] * y1 + cof[2][2] * y2) * inv;
    lam[0] = 1.0 - lam[1] - lam[2] - lam[3];
}

/* The P1 value at the point of barycentric coordinates lam in element e. */
static inline __attribute__((always_inline)) double
elem_value(const sm_field *f, int32_t e, const double *lam, const int D)
{
    const int32_t *ev = f->bg->elems + (size_t)e * (size_t)(D + 1);
    const double *val = f->values;
    double v0 = val[ev[0]];
    if (D == 2)
        return v0 + lam[1] * (val[ev[1]] - v0) + lam[2] * (val[ev[2]] - v0);
    return v0 + lam[1] * (val[ev[1]] - v0) + lam[2] * (val[ev[2]] - v0) +
           lam[3] * (val[ev[3]] - v0);
}

/* The (constant) P1 gradient in the valid element e. */
static inline __attribute__((always_inline)) void
elem_gradient(const sm_field *f, int32_t e, double *grad, const int D)
{
    const int32_t *ev = f->bg->elems + (size_t)e * (size_t)(D + 1);
    double cof[3][3];
    double inv = 1.0 / elem_cofactors(f->bg->coords, ev, cof, D);
    const double *val = f->values;
    for (int i = 0; i < D; i++) {
        double g = 0.0;
        for (int k = 0; k < D; k++)
            g += (val[ev[k + 1]] - val[ev[0]]) * cof[k][i];
        grad[i] = g * inv;
    }
}

static inline __attribute__((always_inline)) int
argmin_lam(const double *lam, const int D, double *lmin)
{
    int k = 0;
    double m = lam[0];
    for (int i = 1; i <= D; i++)
        if (lam[i] < m) {
            m = lam[i];
            k = i;
        }
    *lmin = m;
    return k;
}

/* The vertices of an element in ascending order (s) with their local
 * indices (loc); returns the parity of the permutation (1 when odd). */
static inline __attribute__((always_inline)) int
sorted_vertices(const int32_t *ev, const int nv, int32_t *s, int *loc)
{
    int parity = 0;
    for (int i = 0; i < nv; i++) {
        int32_t v = ev[i];
        int j = i;
        while (j > 0 && s[j - 1] > v) {
            s[j] = s[j - 1];
            loc[j] = loc[j - 1];
            parity ^= 1;
            j--;
        }
        s[j] = v;
        loc[j] = i;
    }
    return parity;
}

/* ------------------------------------------------------------------ */
/* Grid geometry                                                       */

static inline int32_t axis_cell(const grid *g, int i, double x)
{
    double t = (x - g->lo[i]) * g->inv_cell[i];
    if (!(t >= 0.0))
        return 0;
    if (t >= (double)g->n[i])
        return g->n[i] - 1;
    return (int32_t)t;
}

static inline int64_t cell_index(const grid *g, const int32_t *c)
{
    return c[0] + (int64_t)g->n[0] * (c[1] + (int64_t)g->n[1] * c[2]);
}

/* Neighbours across shared facets (sm_field_adjacency.c): fills f->neigh
 * from the bucket counts of the element pass (shift: the bucket of vertex
 * v is v >> shift); counts is overwritten. */
sm_status sm__field_build_adjacency(sm_field *f, int shift, size_t *counts, sm_error *err);

/* Vertices of facet k (opposite local vertex k) of element e, ascending
 * (sm_field_adjacency.c). */
void sm__field_facet_vertices(const sm_field *f, int32_t e, int k, int32_t *out);

/* The element grid, the boundary facets and both facet grids over the
 * bounding box lo, hi of the valid elements (sm_field_grid.c); needs the
 * validity and neighbours. */
sm_status sm__field_build_grids(sm_field *f, const double *lo, const double *hi, sm_error *err);

/* The element lists of the grid, elem_list[elem_start[c] ..
 * elem_start[c+1]) for cell c, built on the first call (thread-safe);
 * NULL when they cannot be allocated (sm_field_grid.c). */
const int32_t *sm__field_element_lists(const sm_field *f);
void sm__field_lists_free(sm_field_lists *l);
/* Bytes held by the lists (0 until built). */
size_t sm__field_lists_bytes(const sm_field *f);
/* The facet tree over the nbfacets boundary facets, whose boxes are
 * boxes (2 * dim a facet: lo then hi); SM_ERR_NOMEM only. */
sm_status sm__field_build_facet_tree(sm_field *f, const double *boxes, sm_error *err);

/* Value (and gradient, when grad is not NULL) of the extension at a point
 * x outside the mesh: the value at the nearest point plus the distance to
 * it (sm_field_nearest.c); *hint (may be NULL) becomes the element holding
 * the nearest point. */
double sm__field_extension(const sm_field *f, const double *x, int32_t *hint, double *grad);

#endif
