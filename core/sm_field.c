/* Target field: P1 values on a background simplicial mesh.
 *
 * Point location, in order:
 *   1. visibility walk from the caller's hint (cross the facet with the
 *      most negative barycentric coordinate), skipped when the hint is far;
 *   2. the bucket grid cell of x: a walk from the cell's seed element (the
 *      one containing the cell centre), a few steps at most;
 *   3. an exhaustive scan of the cell's list (elements whose bounding box
 *      meets the cell), which is the final answer: walks only stop early
 *      at gaps, overlaps, holes and concavities.
 * Outside points get value(p) + |x - p|, p the nearest point of the mesh,
 * searched over the facets without neighbour binned in the same grid.
 *
 * Per valid element we keep one record of doubles:
 *   origin (dim)          coordinates of local vertex 0
 *   inverse map (dim*dim) rows of J^-1, J = [v1-v0 | ... | vd-v0], so that
 *                         lambda_k = row_k . (x - origin), k = 1..dim
 *   value at origin (1)
 *   gradient (dim)        so that d(x) = value + gradient . (x - origin)
 * i.e. 9 doubles (72 B) per triangle and 16 doubles (128 B) per
 * tetrahedron, plus dim+1 neighbour indices and one validity byte.  With
 * the grid lists this comes to about 115 B per triangle and 220 B per
 * tetrahedron on Gmsh meshes (sm_field_get_stats reports it).
 * Barycentric coordinates then cost one small mat-vec with no access to
 * the mesh arrays, and the value needs no access to the vertex values.
 * Computing relative to a vertex (not in absolute affine form) keeps the
 * rounding error proportional to the element size even for boxes far from
 * the origin.
 *
 * Orientation does not matter (barycentric coordinates are orientation
 * free), flat elements are skipped, and the structure is read-only after
 * sm_field_new: all scratch lives on the caller's stack. */
#include "sm_field.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

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
 * volume, so finer cells multiply the list entries quickly (about 25 per
 * tetrahedron at one cell per element for Gmsh meshes, 16 at one cell per
 * two); since a lookup walks from the cell's seed element, the number of
 * candidates per cell only matters for the exhaustive scan (points outside
 * the mesh but inside its box), and coarser 3D cells are the better deal. */
#define GRID_CELLS_PER_ELEM_2D 1.0
#define GRID_CELLS_PER_ELEM_3D 0.5
/* The coarse facet grid (far points) has about this many cells per
 * boundary facet: a few facets per non-empty cell. */
#define GRID_CELLS_PER_BFACET 1.0
/* Rings of the element grid searched for the nearest facet before moving
 * to the coarse facet grid. */
#define NEAR_RINGS 2
#define GRID_MAX_CELLS (1 << 24)
#define GRID_MAX_AXIS (1 << 20)

/* A uniform grid over a box; cells are numbered x fastest. */
typedef struct grid {
    int dim;
    double lo[3], hi[3], cell[3], inv_cell[3];
    int32_t n[3];
    int64_t ncells;
    double min_cell;
} grid;

struct sm_field {
    const sm_mesh *bg;
    const double *values;
    int dim;
    int stride;          /* doubles per element record */
    int32_t nelems;
    int32_t nvalid;
    double *rec;         /* nelems * stride (zeros for degenerate elements) */
    uint8_t *valid;      /* nelems: 1 when the element is usable */
    int32_t *neigh;      /* nelems*(dim+1): across the facet opposite local
                          * vertex k, or -1 (boundary, gap, non-manifold) */

    /* element grid over the bounding box of the valid elements */
    grid g;
    int32_t *elem_start; /* ncells+1 */
    int32_t *elem_list;  /* elements whose inflated bbox meets the cell,
                          * the one containing the cell centre first */
    int32_t max_cell_elems;

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
};

/* ------------------------------------------------------------------ */
/* Element records                                                     */

static inline __attribute__((always_inline)) void
bary_of(const double *r, const double *x, double *lam, const int D)
{
    if (D == 2) {
        double y0 = x[0] - r[0], y1 = x[1] - r[1];
        double l1 = r[2] * y0 + r[3] * y1;
        double l2 = r[4] * y0 + r[5] * y1;
        lam[0] = 1.0 - l1 - l2;
        lam[1] = l1;
        lam[2] = l2;
    } else {
        double y0 = x[0] - r[0], y1 = x[1] - r[1], y2 = x[2] - r[2];
        double l1 = r[3] * y0 + r[4] * y1 + r[5] * y2;
        double l2 = r[6] * y0 + r[7] * y1 + r[8] * y2;
        double l3 = r[9] * y0 + r[10] * y1 + r[11] * y2;
        lam[0] = 1.0 - l1 - l2 - l3;
        lam[1] = l1;
        lam[2] = l2;
        lam[3] = l3;
    }
}

static inline __attribute__((always_inline)) double
affine_value(const double *r, const double *x, const int D)
{
    const double *val = r + D + D * D;
    double v = val[0];
    for (int i = 0; i < D; i++)
        v += val[1 + i] * (x[i] - r[i]);
    return v;
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

static const double *vcoord(const sm_field *f, int32_t v)
{
    return f->bg->coords + (size_t)v * (size_t)f->dim;
}

/* Fills the record of element e; returns 0 when it is degenerate (zero or
 * non-finite volume, or a non-finite inverse). */
static int build_record(sm_field *f, int32_t e)
{
    const int D = f->dim;
    const int32_t *ev = f->bg->elems + (size_t)e * (size_t)(D + 1);
    const double *p[4];
    for (int k = 0; k <= D; k++)
        p[k] = vcoord(f, ev[k]);
    double hmax2 = 0.0;
    for (int a = 0; a <= D; a++)
        for (int b = a + 1; b <= D; b++) {
            double l2 = 0.0;
            for (int i = 0; i < D; i++) {
                double t = p[b][i] - p[a][i];
                l2 += t * t;
            }
            if (l2 > hmax2)
                hmax2 = l2;
        }
    double *r = f->rec + (size_t)e * (size_t)f->stride;
    double c[3][3]; /* columns v_k - v_0 */
    for (int k = 0; k < D; k++)
        for (int i = 0; i < D; i++)
            c[k][i] = p[k + 1][i] - p[0][i];
    double M[3][3];
    double det;
    if (D == 2) {
        det = c[0][0] * c[1][1] - c[1][0] * c[0][1];
        if (!(fabs(det) > DEGENERATE_REL * hmax2))
            return 0;
        M[0][0] = c[1][1] / det;
        M[0][1] = -c[1][0] / det;
        M[1][0] = -c[0][1] / det;
        M[1][1] = c[0][0] / det;
    } else {
        double x12[3] = {c[1][1] * c[2][2] - c[1][2] * c[2][1],
                         c[1][2] * c[2][0] - c[1][0] * c[2][2],
                         c[1][0] * c[2][1] - c[1][1] * c[2][0]};
        double x20[3] = {c[2][1] * c[0][2] - c[2][2] * c[0][1],
                         c[2][2] * c[0][0] - c[2][0] * c[0][2],
                         c[2][0] * c[0][1] - c[2][1] * c[0][0]};
        double x01[3] = {c[0][1] * c[1][2] - c[0][2] * c[1][1],
                         c[0][2] * c[1][0] - c[0][0] * c[1][2],
                         c[0][0] * c[1][1] - c[0][1] * c[1][0]};
        det = c[0][0] * x12[0] + c[0][1] * x12[1] + c[0][2] * x12[2];
        if (!(fabs(det) > DEGENERATE_REL * hmax2 * sqrt(hmax2)))
            return 0;
        for (int i = 0; i < 3; i++) {
            M[0][i] = x12[i] / det;
            M[1][i] = x20[i] / det;
            M[2][i] = x01[i] / det;
        }
    }
    const double *val = f->values;
    double v0 = val[ev[0]];
    for (int i = 0; i < D; i++)
        r[i] = p[0][i];
    for (int k = 0; k < D; k++)
        for (int i = 0; i < D; i++)
            r[D + k * D + i] = M[k][i];
    r[D + D * D] = v0;
    for (int i = 0; i < D; i++) {
        double g = 0.0;
        for (int k = 0; k < D; k++)
            g += (val[ev[k + 1]] - v0) * M[k][i];
        r[D + D * D + 1 + i] = g;
    }
    for (int i = 0; i < f->stride; i++)
        if (!isfinite(r[i])) {
            memset(r, 0, (size_t)f->stride * sizeof *r);
            return 0;
        }
    return 1;
}

/* ------------------------------------------------------------------ */
/* Adjacency: facets bucketed by their smallest vertex, sorted by the
 * remaining vertices inside each bucket (O(n) for bounded vertex degree,
 * O(n log n) worst case). */

typedef struct facet_key {
    uint64_t key; /* the other vertices, ascending */
    int32_t id;   /* e*(dim+1)+k */
} facet_key;

static int facet_key_cmp(const void *a, const void *b)
{
    const facet_key *x = a, *y = b;
    if (x->key != y->key)
        return x->key < y->key ? -1 : 1;
    return (x->id > y->id) - (x->id < y->id);
}

static void sort_facets(facet_key *k, int32_t n)
{
    if (n > 24) {
        qsort(k, (size_t)n, sizeof *k, facet_key_cmp);
        return;
    }
    for (int32_t i = 1; i < n; i++) {
        facet_key t = k[i];
        int32_t j = i - 1;
        while (j >= 0 && facet_key_cmp(&k[j], &t) > 0) {
            k[j + 1] = k[j];
            j--;
        }
        k[j + 1] = t;
    }
}

static void facet_vertices(const sm_field *f, int32_t e, int k, int32_t *out)
{
    const int D = f->dim;
    const int32_t *ev = f->bg->elems + (size_t)e * (size_t)(D + 1);
    int n = 0;
    for (int i = 0; i <= D; i++)
        if (i != k)
            out[n++] = ev[i];
    /* ascending */
    for (int i = 1; i < D; i++)
        for (int j = i; j > 0 && out[j - 1] > out[j]; j--) {
            int32_t t = out[j];
            out[j] = out[j - 1];
            out[j - 1] = t;
        }
}

/* Barycentric coordinate k of point x in element e. */
static double lam_k(const sm_field *f, int32_t e, int k, const double *x)
{
    double lam[4];
    const double *r = f->rec + (size_t)e * (size_t)f->stride;
    if (f->dim == 2)
        bary_of(r, x, lam, 2);
    else
        bary_of(r, x, lam, 3);
    return lam[k];
}

static sm_status build_adjacency(sm_field *f, sm_error *err)
{
    const int D = f->dim, nv1 = D + 1;
    const int32_t ne = f->nelems, nverts = f->bg->nverts;
    f->neigh = malloc((size_t)ne * (size_t)nv1 * sizeof *f->neigh + 1);
    if (!f->neigh)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for element adjacency");
    for (size_t i = 0; i < (size_t)ne * (size_t)nv1; i++)
        f->neigh[i] = -1;

    size_t nent = (size_t)f->nvalid * (size_t)nv1;
    int32_t *start = calloc((size_t)nverts + 1, sizeof *start);
    facet_key *keys = malloc(nent * sizeof *keys + 1);
    if (!start || !keys) {
        free(start);
        free(keys);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for element adjacency");
    }
    int32_t fv[3];
    for (int32_t e = 0; e < ne; e++) {
        if (!f->valid[e])
            continue;
        for (int k = 0; k <= D; k++) {
            facet_vertices(f, e, k, fv);
            start[fv[0] + 1]++;
        }
    }
    for (int32_t v = 0; v < nverts; v++)
        start[v + 1] += start[v];
    int32_t *fill = malloc((size_t)nverts * sizeof *fill + 1);
    if (!fill) {
        free(start);
        free(keys);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for element adjacency");
    }
    memcpy(fill, start, (size_t)nverts * sizeof *fill);
    for (int32_t e = 0; e < ne; e++) {
        if (!f->valid[e])
            continue;
        for (int k = 0; k <= D; k++) {
            facet_vertices(f, e, k, fv);
            facet_key *fk = &keys[fill[fv[0]]++];
            fk->key = D == 2 ? (uint64_t)(uint32_t)fv[1]
                             : ((uint64_t)(uint32_t)fv[1] << 32) | (uint32_t)fv[2];
            fk->id = e * nv1 + k;
        }
    }
    free(fill);
    for (int32_t v = 0; v < nverts; v++) {
        int32_t b = start[v], m = start[v + 1] - b;
        sort_facets(keys + b, m);
        for (int32_t i = 0; i < m;) {
            int32_t j = i + 1;
            while (j < m && keys[b + j].key == keys[b + i].key)
                j++;
            if (j - i == 2) {
                /* A facet shared by exactly two elements is a walk edge only
                 * if they lie on opposite sides of it (folded or duplicated
                 * elements do not). */
                int32_t id1 = keys[b + i].id, id2 = keys[b + i + 1].id;
                int32_t e1 = id1 / nv1, e2 = id2 / nv1;
                int k1 = id1 % nv1, k2 = id2 % nv1;
                const int32_t *ev1 = f->bg->elems + (size_t)e1 * (size_t)nv1;
                const int32_t *ev2 = f->bg->elems + (size_t)e2 * (size_t)nv1;
                if (lam_k(f, e1, k1, vcoord(f, ev2[k2])) < 0.0 &&
                    lam_k(f, e2, k2, vcoord(f, ev1[k1])) < 0.0) {
                    f->neigh[id1] = e2;
                    f->neigh[id2] = e1;
                }
            }
            i = j;
        }
    }
    free(start);
    free(keys);
    return SM_OK;
}

/* ------------------------------------------------------------------ */
/* Grids                                                               */

static int32_t axis_cell(const grid *g, int i, double x)
{
    double t = (x - g->lo[i]) * g->inv_cell[i];
    if (!(t >= 0.0))
        return 0;
    if (t >= (double)g->n[i])
        return g->n[i] - 1;
    return (int32_t)t;
}

static int64_t cell_index(const grid *g, const int32_t *c)
{
    return c[0] + (int64_t)g->n[0] * (c[1] + (int64_t)g->n[1] * c[2]);
}

/* Cell range [c0, c1] (inclusive, per axis) covered by the box [a, b]
 * inflated by a fraction of its extent. */
static void box_cells(const grid *g, const double *a, const double *b, int32_t *c0,
                      int32_t *c1)
{
    for (int i = 0; i < g->dim; i++) {
        double pad = BBOX_INFLATE * (b[i] - a[i]) +
                     4.0 * 2.2e-16 * (fabs(a[i]) + fabs(b[i]));
        c0[i] = axis_cell(g, i, a[i] - pad);
        c1[i] = axis_cell(g, i, b[i] + pad);
    }
    for (int i = g->dim; i < 3; i++)
        c0[i] = c1[i] = 0;
}

/* Cells per axis for about `target` cells of cubic shape over the box
 * (computed in logarithms: extents may differ by many orders). */
static void grid_shape(const grid *g, double target, double *nd)
{
    const int D = g->dim;
    if (target > GRID_MAX_CELLS)
        target = GRID_MAX_CELLS;
    if (target < 1.0)
        target = 1.0;
    double logvol = 0.0;
    for (int i = 0; i < D; i++)
        logvol += log(g->hi[i] - g->lo[i]);
    double logc = (logvol - log(target)) / D;
    nd[0] = nd[1] = nd[2] = 1.0;
    for (int i = 0; i < D; i++) {
        double t = exp(log(g->hi[i] - g->lo[i]) - logc);
        nd[i] = t < 1.0 ? 1.0 : t > GRID_MAX_AXIS ? GRID_MAX_AXIS : ceil(t - 1e-9);
    }
    while (nd[0] * nd[1] * nd[2] > GRID_MAX_CELLS) {
        int big = 0;
        for (int i = 1; i < D; i++)
            if (nd[i] > nd[big])
                big = i;
        nd[big] = ceil(nd[big] / 2);
    }
}

static void grid_set_axes(grid *g, const double *nd)
{
    g->ncells = 1;
    g->min_cell = INFINITY;
    for (int i = 0; i < 3; i++) {
        if (i >= g->dim) {
            g->n[i] = 1;
            g->lo[i] = g->hi[i] = 0.0;
            g->cell[i] = g->inv_cell[i] = 1.0;
            continue;
        }
        g->n[i] = (int32_t)nd[i];
        double ext = g->hi[i] - g->lo[i];
        g->cell[i] = ext / g->n[i];
        g->inv_cell[i] = g->n[i] / ext;
        if (g->cell[i] < g->min_cell)
            g->min_cell = g->cell[i];
        g->ncells *= g->n[i];
    }
}

static void simplex_box(const sm_field *f, const int32_t *v, int nv, double *a,
                        double *b)
{
    for (int i = 0; i < f->dim; i++) {
        a[i] = INFINITY;
        b[i] = -INFINITY;
    }
    for (int k = 0; k < nv; k++) {
        const double *p = vcoord(f, v[k]);
        for (int i = 0; i < f->dim; i++) {
            if (p[i] < a[i])
                a[i] = p[i];
            if (p[i] > b[i])
                b[i] = p[i];
        }
    }
}

/* Item j of a binned family: element items[j] (facets = 0, the cell lists
 * then hold the element) or boundary facet j (facets = 1, items are the
 * e*(dim+1)+k ids and the cell lists hold j). */
static void item_box(const sm_field *f, const int32_t *items, int32_t j, int facets,
                     double *a, double *b)
{
    const int D = f->dim;
    if (!facets) {
        simplex_box(f, f->bg->elems + (size_t)items[j] * (size_t)(D + 1), D + 1, a, b);
    } else {
        int32_t id = items[j], fv[3];
        facet_vertices(f, id / (D + 1), id % (D + 1), fv);
        simplex_box(f, fv, D, a, b);
    }
}

static int64_t count_entries(const sm_field *f, const grid *g, const int32_t *items,
                             int32_t nitems, int facets)
{
    int64_t total = 0;
    double a[3], b[3];
    int32_t c0[3], c1[3];
    for (int32_t j = 0; j < nitems; j++) {
        item_box(f, items, j, facets, a, b);
        box_cells(g, a, b, c0, c1);
        int64_t cnt = 1;
        for (int i = 0; i < 3; i++)
            cnt *= (int64_t)(c1[i] - c0[i] + 1);
        total += cnt;
    }
    return total;
}

/* Shapes g for about `target` cells, coarsening until the lists hold at
 * most `limit` entries; returns the entry count. */
static int64_t grid_fit(const sm_field *f, grid *g, double target, const int32_t *items,
                        int32_t nitems, int facets, int64_t limit)
{
    double nd[3];
    grid_shape(g, target, nd);
    for (;;) {
        grid_set_axes(g, nd);
        int64_t total = count_entries(f, g, items, nitems, facets);
        if (total <= limit || g->ncells == 1)
            return total;
        for (int i = 0; i < g->dim; i++)
            nd[i] = nd[i] > 1 ? floor(nd[i] * 0.8) : 1;
    }
}

/* CSR lists of the items per cell, in increasing item order. */
static sm_status bin_items(const sm_field *f, const grid *g, const int32_t *items,
                           int32_t nitems, int facets, int64_t total,
                           int32_t **start_out, int32_t **list_out, sm_error *err)
{
    if (total > INT32_MAX - 1)
        return sm_error_set(err, SM_ERR_NOMEM,
                            "point location grid too large (%lld entries)", (long long)total);
    int32_t *start = calloc((size_t)g->ncells + 1, sizeof *start);
    int32_t *list = malloc((size_t)total * sizeof *list + 1);
    int32_t *fill = NULL;
    if (!start || !list)
        goto nomem;
    double a[3], b[3];
    int32_t c0[3], c1[3], c[3];
    for (int pass = 0; pass < 2; pass++) {
        for (int32_t j = 0; j < nitems; j++) {
            item_box(f, items, j, facets, a, b);
            box_cells(g, a, b, c0, c1);
            for (c[2] = c0[2]; c[2] <= c1[2]; c[2]++)
                for (c[1] = c0[1]; c[1] <= c1[1]; c[1]++)
                    for (c[0] = c0[0]; c[0] <= c1[0]; c[0]++) {
                        int64_t idx = cell_index(g, c);
                        if (pass == 0)
                            start[idx + 1]++;
                        else
                            list[fill[idx]++] = facets ? j : items[j];
                    }
        }
        if (pass == 0) {
            for (int64_t i = 0; i < g->ncells; i++)
                start[i + 1] += start[i];
            fill = malloc((size_t)g->ncells * sizeof *fill + 1);
            if (!fill)
                goto nomem;
            memcpy(fill, start, (size_t)g->ncells * sizeof *fill);
        }
    }
    free(fill);
    *start_out = start;
    *list_out = list;
    return SM_OK;
nomem:
    free(start);
    free(list);
    free(fill);
    return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the point location grid");
}

/* Moves to the front of every cell list the element deepest at the cell
 * centre: the start of the walk for points of that cell. */
static void order_cell_seeds(sm_field *f)
{
    const grid *g = &f->g;
    const int D = f->dim;
    int32_t cc[3] = {0, 0, 0};
    f->max_cell_elems = 0;
    for (int64_t c = 0; c < g->ncells; c++) {
        int32_t j0 = f->elem_start[c], j1 = f->elem_start[c + 1];
        if (j1 - j0 > f->max_cell_elems)
            f->max_cell_elems = j1 - j0;
        double centre[3], lam[4], lmin, best = -INFINITY;
        int32_t bestj = j0;
        for (int i = 0; i < D; i++)
            centre[i] = g->lo[i] + (cc[i] + 0.5) * g->cell[i];
        for (int32_t j = j0; j < j1; j++) {
            const double *r = f->rec + (size_t)f->elem_list[j] * (size_t)f->stride;
            if (D == 2)
                bary_of(r, centre, lam, 2);
            else
                bary_of(r, centre, lam, 3);
            argmin_lam(lam, D, &lmin);
            if (lmin > best) {
                best = lmin;
                bestj = j;
            }
        }
        if (j1 > j0) {
            int32_t t = f->elem_list[j0];
            f->elem_list[j0] = f->elem_list[bestj];
            f->elem_list[bestj] = t;
        }
        for (int i = 0; i < D && ++cc[i] == g->n[i]; i++)
            cc[i] = 0;
    }
}

static sm_status build_grids(sm_field *f, sm_error *err)
{
    const int D = f->dim, nv1 = D + 1;
    grid *g = &f->g;
    g->dim = D;
    for (int i = 0; i < 3; i++) {
        g->lo[i] = INFINITY;
        g->hi[i] = -INFINITY;
    }
    for (int32_t e = 0; e < f->nelems; e++) {
        if (!f->valid[e])
            continue;
        const int32_t *ev = f->bg->elems + (size_t)e * (size_t)nv1;
        for (int k = 0; k <= D; k++) {
            const double *p = vcoord(f, ev[k]);
            for (int i = 0; i < D; i++) {
                if (p[i] < g->lo[i])
                    g->lo[i] = p[i];
                if (p[i] > g->hi[i])
                    g->hi[i] = p[i];
            }
        }
    }
    for (int i = 0; i < D; i++) {
        /* a hair of margin so that points on the box are inside it */
        double pad = 1e-9 * (g->hi[i] - g->lo[i]) +
                     4.0 * 2.2e-16 * (fabs(g->lo[i]) + fabs(g->hi[i]));
        g->lo[i] -= pad;
        g->hi[i] += pad;
        double ext = g->hi[i] - g->lo[i];
        if (!(ext > 0.0) || !isfinite(ext))
            return sm_error_set(err, SM_ERR_INVALID,
                                "background bounding box has an unusable extent %g on axis %d",
                                ext, i);
    }

    /* Elements.  Hostile inputs (huge elements among tiny ones) can make
     * the lists explode: coarsen until they stay a small multiple of the
     * elements. */
    int32_t *items = malloc((size_t)f->nvalid * sizeof *items + 1);
    if (!items)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the point location grid");
    int32_t nit = 0;
    for (int32_t e = 0; e < f->nelems; e++)
        if (f->valid[e])
            items[nit++] = e;
    int64_t limit = 32 * (int64_t)f->nvalid + (1 << 20);
    double per_elem = D == 2 ? GRID_CELLS_PER_ELEM_2D : GRID_CELLS_PER_ELEM_3D;
    int64_t total = grid_fit(f, g, per_elem * f->nvalid, items, nit, 0, limit);
    sm_status st = bin_items(f, g, items, nit, 0, total, &f->elem_start, &f->elem_list, err);
    free(items);
    if (st != SM_OK)
        return st;
    order_cell_seeds(f);

    /* Boundary facets, their coordinates, and both facet grids. */
    int32_t nb = 0;
    for (size_t i = 0; i < (size_t)f->nelems * (size_t)nv1; i++)
        if (f->valid[i / (size_t)nv1] && f->neigh[i] < 0)
            nb++;
    f->bfacet_id = malloc((size_t)nb * sizeof *f->bfacet_id + 1);
    f->bfacet_xyz = malloc((size_t)nb * (size_t)(D * D) * sizeof(double) + 1);
    if (!f->bfacet_id || !f->bfacet_xyz)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the boundary facets");
    nb = 0;
    for (size_t i = 0; i < (size_t)f->nelems * (size_t)nv1; i++)
        if (f->valid[i / (size_t)nv1] && f->neigh[i] < 0)
            f->bfacet_id[nb++] = (int32_t)i;
    f->nbfacets = nb;
    for (int32_t j = 0; j < nb; j++) {
        int32_t fv[3];
        facet_vertices(f, f->bfacet_id[j] / nv1, f->bfacet_id[j] % nv1, fv);
        for (int k = 0; k < D; k++)
            memcpy(f->bfacet_xyz + ((size_t)j * D + k) * D, vcoord(f, fv[k]),
                   (size_t)D * sizeof(double));
    }
    total = count_entries(f, g, f->bfacet_id, nb, 1);
    st = bin_items(f, g, f->bfacet_id, nb, 1, total, &f->facet_start, &f->facet_list, err);
    if (st != SM_OK)
        return st;
    f->cg = *g;
    total = grid_fit(f, &f->cg, GRID_CELLS_PER_BFACET * nb, f->bfacet_id, nb, 1,
                     8 * (int64_t)nb + (1 << 16));
    return bin_items(f, &f->cg, f->bfacet_id, nb, 1, total, &f->cfacet_start,
                     &f->cfacet_list, err);
}

/* ------------------------------------------------------------------ */
/* Construction                                                        */

void sm_field_free(sm_field *f)
{
    if (!f)
        return;
    free(f->rec);
    free(f->valid);
    free(f->neigh);
    free(f->elem_start);
    free(f->elem_list);
    free(f->bfacet_id);
    free(f->bfacet_xyz);
    free(f->facet_start);
    free(f->facet_list);
    free(f->cfacet_start);
    free(f->cfacet_list);
    free(f);
}

sm_status sm_field_new(const sm_mesh *bg, const double *values, sm_field **out,
                       sm_error *err)
{
    if (!out)
        return sm_error_set(err, SM_ERR_INVALID, "sm_field_new: no output pointer");
    *out = NULL;
    if (!bg || !values)
        return sm_error_set(err, SM_ERR_INVALID, "sm_field_new: missing background mesh or values");
    if (bg->dim != 2 && bg->dim != 3)
        return sm_error_set(err, SM_ERR_INVALID,
                            "background mesh dimension %d is not 2 or 3", bg->dim);
    if (bg->nelems <= 0 || bg->nverts <= 0)
        return sm_error_set(err, SM_ERR_INVALID,
                            "background mesh is empty (%ld vertices, %ld elements)",
                            (long)bg->nverts, (long)bg->nelems);
    if (bg->nelems > SM_MAX_ENTITIES || bg->nverts > SM_MAX_ENTITIES)
        return sm_error_set(err, SM_ERR_NOMEM, "background mesh too large");
    if (!bg->coords || !bg->elems)
        return sm_error_set(err, SM_ERR_INVALID, "background mesh has no coordinates or elements");
    const int D = bg->dim;
    for (int32_t v = 0; v < bg->nverts; v++) {
        if (!isfinite(values[v]))
            return sm_error_set(err, SM_ERR_INVALID,
                                "distance value at vertex %ld is not finite (%g)",
                                (long)v + 1, values[v]);
        for (int i = 0; i < D; i++)
            if (!isfinite(bg->coords[(size_t)v * D + i]))
                return sm_error_set(err, SM_ERR_INVALID,
                                    "background vertex %ld has a non-finite coordinate",
                                    (long)v + 1);
    }
    for (size_t i = 0; i < (size_t)bg->nelems * (size_t)(D + 1); i++)
        if (bg->elems[i] < 0 || bg->elems[i] >= bg->nverts)
            return sm_error_set(err, SM_ERR_INVALID,
                                "background element %ld refers to vertex %ld (mesh has %ld)",
                                (long)(i / (size_t)(D + 1)) + 1, (long)bg->elems[i] + 1,
                                (long)bg->nverts);

    sm_field *f = calloc(1, sizeof *f);
    if (!f)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    f->bg = bg;
    f->values = values;
    f->dim = D;
    f->stride = D + D * D + 1 + D;
    f->nelems = bg->nelems;
    f->rec = calloc((size_t)bg->nelems * (size_t)f->stride, sizeof *f->rec);
    f->valid = calloc((size_t)bg->nelems, 1);
    if (!f->rec || !f->valid) {
        sm_field_free(f);
        return sm_error_set(err, SM_ERR_NOMEM,
                            "out of memory for %ld background elements", (long)bg->nelems);
    }
    for (int32_t e = 0; e < f->nelems; e++) {
        f->valid[e] = (uint8_t)build_record(f, e);
        f->nvalid += f->valid[e];
    }
    if (f->nvalid == 0) {
        sm_field_free(f);
        return sm_error_set(err, SM_ERR_INVALID,
                            "background mesh has no element of non-zero volume (%ld elements, all degenerate)",
                            (long)bg->nelems);
    }
    sm_status st = build_adjacency(f, err);
    if (st == SM_OK)
        st = build_grids(f, err);
    if (st != SM_OK) {
        sm_field_free(f);
        return st;
    }
    *out = f;
    return SM_OK;
}

int sm_field_dim(const sm_field *f)
{
    return f->dim;
}

/* ------------------------------------------------------------------ */
/* Location                                                            */

/* Visibility walk from element e: cross the facet with the most negative
 * barycentric coordinate.  Returns the element containing x (bary in lam)
 * or -1 when the walk leaves the mesh or runs out of steps.  With
 * far_lambda > 0, gives up at once when x is that many element heights
 * beyond the start element. */
static inline __attribute__((always_inline)) int32_t
walk_dim(const sm_field *f, const double *x, int32_t e, double far_lambda, double *lam,
         const int D)
{
    double lmin;
    for (int step = 0; step < WALK_MAX_STEPS; step++) {
        bary_of(f->rec + (size_t)e * (size_t)(D + D * D + 1 + D), x, lam, D);
        int k = argmin_lam(lam, D, &lmin);
        if (lmin >= -BARY_TOL)
            return e;
        if (step == 0 && far_lambda > 0.0 && lmin < -far_lambda)
            return -1;
        e = f->neigh[(size_t)e * (D + 1) + k];
        if (e < 0)
            return -1;
    }
    return -1;
}

static inline __attribute__((always_inline)) int32_t
locate_dim(const sm_field *f, const double *x, int32_t hint, double *bary, const int D)
{
    double lam[4], lmin;
    int32_t e = -1;
    for (int i = 0; i < D; i++)
        if (!isfinite(x[i]))
            return -1;
    if (hint >= 0 && hint < f->nelems && f->valid[hint]) {
        e = walk_dim(f, x, hint, WALK_FAR_LAMBDA, lam, D);
        if (e >= 0)
            goto found;
    }
    for (int i = 0; i < D; i++)
        if (!(x[i] >= f->g.lo[i] && x[i] <= f->g.hi[i]))
            return -1;
    int32_t c[3] = {0, 0, 0};
    for (int i = 0; i < D; i++)
        c[i] = axis_cell(&f->g, i, x[i]);
    int64_t idx = cell_index(&f->g, c);
    int32_t j0 = f->elem_start[idx], j1 = f->elem_start[idx + 1];
    if (j0 == j1)
        return -1;
    /* The first element of a cell list contains (or is the nearest to) the
     * cell centre, a few steps from x at most. */
    e = walk_dim(f, x, f->elem_list[j0], 0.0, lam, D);
    if (e >= 0)
        goto found;
    /* The cell lists are exhaustive: scanning one is the final answer
     * (non-convex or non-conforming parts, points outside). */
    double best_min = -INFINITY, best_lam[4] = {0, 0, 0, 0};
    for (int32_t j = j0; j < j1; j++) {
        int32_t cand = f->elem_list[j];
        bary_of(f->rec + (size_t)cand * (size_t)(D + D * D + 1 + D), x, lam, D);
        argmin_lam(lam, D, &lmin);
        if (lmin > best_min) {
            best_min = lmin;
            e = cand;
            memcpy(best_lam, lam, sizeof lam);
            if (lmin >= 0.0)
                break; /* inside or on it: no better answer */
        }
    }
    if (e < 0 || best_min < -BARY_TOL)
        return -1;
    memcpy(lam, best_lam, sizeof lam);
found:
    if (bary)
        memcpy(bary, lam, (size_t)(D + 1) * sizeof *bary);
    return e;
}

int32_t sm_field_locate(const sm_field *f, const double *x, int32_t hint, double *bary)
{
    if (f->dim == 2)
        return locate_dim(f, x, hint, bary, 2);
    return locate_dim(f, x, hint, bary, 3);
}

/* ------------------------------------------------------------------ */
/* Nearest point of the mesh for outside points                        */

static void closest_on_segment(const double *x, const double *a, const double *b,
                               double *p)
{
    double ab[2] = {b[0] - a[0], b[1] - a[1]};
    double ax[2] = {x[0] - a[0], x[1] - a[1]};
    double l2 = ab[0] * ab[0] + ab[1] * ab[1];
    double t = l2 > 0.0 ? (ax[0] * ab[0] + ax[1] * ab[1]) / l2 : 0.0;
    if (!(t > 0.0))
        t = 0.0;
    else if (t > 1.0)
        t = 1.0;
    p[0] = a[0] + t * ab[0];
    p[1] = a[1] + t * ab[1];
}

static double dot3(const double *u, const double *v)
{
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
}

/* Closest point of triangle abc to x, by the Voronoi regions of the
 * vertices, edges and face (no division by a vanishing quantity: the
 * face case divides by the sum of three positive terms). */
static void closest_on_triangle(const double *x, const double *a, const double *b,
                                const double *c, double *p)
{
    double ab[3], ac[3], ax[3], bx[3], cx[3];
    for (int i = 0; i < 3; i++) {
        ab[i] = b[i] - a[i];
        ac[i] = c[i] - a[i];
        ax[i] = x[i] - a[i];
        bx[i] = x[i] - b[i];
        cx[i] = x[i] - c[i];
    }
    double d1 = dot3(ab, ax), d2 = dot3(ac, ax);
    if (d1 <= 0.0 && d2 <= 0.0) {
        memcpy(p, a, 3 * sizeof *p);
        return;
    }
    double d3 = dot3(ab, bx), d4 = dot3(ac, bx);
    if (d3 >= 0.0 && d4 <= d3) {
        memcpy(p, b, 3 * sizeof *p);
        return;
    }
    double vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
        double t = d1 - d3 > 0.0 ? d1 / (d1 - d3) : 0.0;
        for (int i = 0; i < 3; i++)
            p[i] = a[i] + t * ab[i];
        return;
    }
    double d5 = dot3(ab, cx), d6 = dot3(ac, cx);
    if (d6 >= 0.0 && d5 <= d6) {
        memcpy(p, c, 3 * sizeof *p);
        return;
    }
    double vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
        double t = d2 - d6 > 0.0 ? d2 / (d2 - d6) : 0.0;
        for (int i = 0; i < 3; i++)
            p[i] = a[i] + t * ac[i];
        return;
    }
    double va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0) {
        double den = (d4 - d3) + (d5 - d6);
        double t = den > 0.0 ? (d4 - d3) / den : 0.0;
        for (int i = 0; i < 3; i++)
            p[i] = b[i] + t * (c[i] - b[i]);
        return;
    }
    double sum = va + vb + vc;
    double v = sum > 0.0 ? vb / sum : 0.0, w = sum > 0.0 ? vc / sum : 0.0;
    for (int i = 0; i < 3; i++)
        p[i] = a[i] + v * ab[i] + w * ac[i];
}

/* Squared distance from x to grid cell c. */
static double cell_dist2(const grid *g, const int32_t *c, const double *x)
{
    double d2 = 0.0;
    for (int i = 0; i < g->dim; i++) {
        double a = g->lo[i] + c[i] * g->cell[i], b = a + g->cell[i];
        double t = x[i] < a ? a - x[i] : x[i] > b ? x[i] - b : 0.0;
        d2 += t * t;
    }
    return d2;
}

typedef struct nearest_state {
    double best2;   /* squared distance of the best facet so far */
    int32_t facet;  /* e*(dim+1)+k, or -1 */
    double p[3];
    int64_t cells_visited;
} nearest_state;

/* Candidate boundary facet b for the nearest point; ties go to the
 * smallest facet id, so the answer does not depend on the visiting order. */
static void try_facet(const sm_field *f, int32_t b, const double *x, nearest_state *s)
{
    const int D = f->dim;
    const double *v = f->bfacet_xyz + (size_t)b * (size_t)(D * D);
    int32_t id = f->bfacet_id[b];
    double p[3];
    if (D == 2)
        closest_on_segment(x, v, v + 2, p);
    else
        closest_on_triangle(x, v, v + 3, v + 6, p);
    double d2 = 0.0;
    for (int i = 0; i < D; i++)
        d2 += (x[i] - p[i]) * (x[i] - p[i]);
    if (d2 < s->best2 || (d2 == s->best2 && s->facet >= 0 && id < s->facet)) {
        s->best2 = d2;
        s->facet = id;
        memcpy(s->p, p, sizeof p);
    }
}

typedef struct facet_bins {
    const grid *g;
    const int32_t *start, *list;
} facet_bins;

static void scan_cell(const sm_field *f, const facet_bins *fb, const int32_t *c,
                      const double *x, nearest_state *s)
{
    s->cells_visited++;
    if (cell_dist2(fb->g, c, x) >= s->best2)
        return;
    int64_t idx = cell_index(fb->g, c);
    for (int32_t j = fb->start[idx]; j < fb->start[idx + 1]; j++)
        try_facet(f, fb->list[j], x, s);
}

/* Rings of cells around the cell of the projection p0 of x onto the grid
 * box, until the next ring cannot hold anything closer: for q in the box
 * |x-q|^2 >= |x-p0|^2 + |p0-q|^2, and a cell of ring r is at least
 * (r-1)*min_cell from p0.  Returns 1 when the answer is final, 0 when it
 * stopped at max_ring or after cell_budget cells. */
static int ring_search(const sm_field *f, const facet_bins *fb, const double *x,
                       int32_t max_ring, int64_t cell_budget, nearest_state *s)
{
    const grid *g = fb->g;
    const int D = g->dim;
    double p0[3] = {0, 0, 0}, d02 = 0.0;
    int32_t sc[3] = {0, 0, 0};
    int32_t last = 0;
    for (int i = 0; i < D; i++) {
        p0[i] = x[i] < g->lo[i] ? g->lo[i] : x[i] > g->hi[i] ? g->hi[i] : x[i];
        d02 += (x[i] - p0[i]) * (x[i] - p0[i]);
        sc[i] = axis_cell(g, i, p0[i]);
        int32_t m = sc[i] > g->n[i] - 1 - sc[i] ? sc[i] : g->n[i] - 1 - sc[i];
        if (m > last)
            last = m;
    }
    int64_t visited0 = s->cells_visited;
    for (int32_t r = 0; r <= last; r++) {
        if (r >= 1) {
            double gap = (double)(r - 1) * g->min_cell;
            if (d02 + gap * gap >= s->best2)
                return 1;
        }
        if (r > max_ring || s->cells_visited - visited0 > cell_budget)
            return 0;
        int32_t lo[3], hi[3], c[3] = {0, 0, 0};
        for (int i = 0; i < D; i++) {
            lo[i] = sc[i] - r < 0 ? 0 : sc[i] - r;
            hi[i] = sc[i] + r > g->n[i] - 1 ? g->n[i] - 1 : sc[i] + r;
        }
        if (D == 2) {
            for (c[0] = lo[0]; c[0] <= hi[0]; c[0]++) {
                if (c[0] == sc[0] - r || c[0] == sc[0] + r) {
                    for (c[1] = lo[1]; c[1] <= hi[1]; c[1]++)
                        scan_cell(f, fb, c, x, s);
                } else {
                    c[1] = sc[1] - r;
                    if (c[1] >= 0)
                        scan_cell(f, fb, c, x, s);
                    c[1] = sc[1] + r;
                    if (r > 0 && c[1] < g->n[1])
                        scan_cell(f, fb, c, x, s);
                }
            }
        } else {
            for (c[0] = lo[0]; c[0] <= hi[0]; c[0]++)
                for (c[1] = lo[1]; c[1] <= hi[1]; c[1]++) {
                    if (c[0] == sc[0] - r || c[0] == sc[0] + r || c[1] == sc[1] - r ||
                        c[1] == sc[1] + r) {
                        for (c[2] = lo[2]; c[2] <= hi[2]; c[2]++)
                            scan_cell(f, fb, c, x, s);
                    } else {
                        c[2] = sc[2] - r;
                        if (c[2] >= 0)
                            scan_cell(f, fb, c, x, s);
                        c[2] = sc[2] + r;
                        if (r > 0 && c[2] < g->n[2])
                            scan_cell(f, fb, c, x, s);
                    }
                }
        }
    }
    return 1;
}

/* Nearest point on the facets without neighbour: a few rings of the fine
 * element grid (points close to the mesh, the common case), then rings of
 * the coarse facet grid with the best distance so far as the bound, and,
 * if even those grow too many (far from a non-convex background), one
 * plain pass over the facets, which bounds the cost. */
static void nearest_facet(const sm_field *f, const double *x, nearest_state *s)
{
    s->best2 = INFINITY;
    s->facet = -1;
    s->cells_visited = 0;
    const facet_bins fine = {&f->g, f->facet_start, f->facet_list};
    if (ring_search(f, &fine, x, NEAR_RINGS, INT64_MAX, s))
        return;
    const facet_bins coarse = {&f->cg, f->cfacet_start, f->cfacet_list};
    if (ring_search(f, &coarse, x, INT32_MAX, f->nbfacets / 2 + 64, s))
        return;
    for (int32_t b = 0; b < f->nbfacets; b++)
        try_facet(f, b, x, s);
}

static double extension(const sm_field *f, const double *x, int32_t *hint, double *grad)
{
    const int D = f->dim;
    nearest_state s;
    nearest_facet(f, x, &s);
    if (s.facet < 0) {
        /* only when every distance overflows (|x| ~ 1e154 and beyond) */
        if (grad)
            for (int i = 0; i < D; i++)
                grad[i] = 0.0;
        return INFINITY;
    }
    int32_t e = s.facet / (D + 1);
    const double *r = f->rec + (size_t)e * (size_t)f->stride;
    double dist = sqrt(s.best2);
    if (hint)
        *hint = e;
    if (grad) {
        /* grad = n + (I - n n^T) g, n the unit vector from p to x */
        const double *g = r + D + D * D + 1;
        double n[3] = {0, 0, 0}, gn = 0.0;
        if (dist > 0.0)
            for (int i = 0; i < D; i++) {
                n[i] = (x[i] - s.p[i]) / dist;
                gn += g[i] * n[i];
            }
        for (int i = 0; i < D; i++)
            grad[i] = n[i] + g[i] - gn * n[i];
    }
    return (D == 2 ? affine_value(r, s.p, 2) : affine_value(r, s.p, 3)) + dist;
}

double sm_field_eval_grad(const sm_field *f, const double *x, int32_t *hint, double *grad)
{
    const int D = f->dim;
    for (int i = 0; i < D; i++)
        if (!isfinite(x[i])) {
            if (grad)
                for (int j = 0; j < D; j++)
                    grad[j] = 0.0;
            return INFINITY;
        }
    int32_t e = sm_field_locate(f, x, hint ? *hint : -1, NULL);
    if (e < 0)
        return extension(f, x, hint, grad);
    if (hint)
        *hint = e;
    const double *r = f->rec + (size_t)e * (size_t)f->stride;
    if (grad)
        memcpy(grad, r + D + D * D + 1, (size_t)D * sizeof *grad);
    return D == 2 ? affine_value(r, x, 2) : affine_value(r, x, 3);
}

double sm_field_eval(const sm_field *f, const double *x, int32_t *hint)
{
    if (f->dim == 2) {
        int32_t e = locate_dim(f, x, hint ? *hint : -1, NULL, 2);
        if (e >= 0) {
            if (hint)
                *hint = e;
            return affine_value(f->rec + (size_t)e * 9, x, 2);
        }
    } else {
        int32_t e = locate_dim(f, x, hint ? *hint : -1, NULL, 3);
        if (e >= 0) {
            if (hint)
                *hint = e;
            return affine_value(f->rec + (size_t)e * 16, x, 3);
        }
    }
    for (int i = 0; i < f->dim; i++)
        if (!isfinite(x[i]))
            return INFINITY;
    return extension(f, x, hint, NULL);
}

int32_t sm_field_nearest(const sm_field *f, const double *x, double *nearest,
                         double *distance)
{
    const int D = f->dim;
    for (int i = 0; i < D; i++)
        if (!isfinite(x[i]))
            return -1;
    int32_t e = sm_field_locate(f, x, -1, NULL);
    if (e >= 0) {
        if (nearest)
            memcpy(nearest, x, (size_t)D * sizeof *nearest);
        if (distance)
            *distance = 0.0;
        return e;
    }
    nearest_state s;
    nearest_facet(f, x, &s);
    if (s.facet < 0)
        return -1;
    if (nearest)
        memcpy(nearest, s.p, (size_t)D * sizeof *nearest);
    if (distance)
        *distance = sqrt(s.best2);
    return s.facet / (D + 1);
}

void sm_field_get_stats(const sm_field *f, sm_field_stats *st)
{
    memset(st, 0, sizeof *st);
    for (int i = 0; i < 3; i++) {
        st->grid[i] = f->g.n[i];
        st->lo[i] = f->g.lo[i];
        st->hi[i] = f->g.hi[i];
    }
    st->ncells = f->g.ncells;
    st->elem_entries = f->elem_start[f->g.ncells];
    st->max_cell_elems = f->max_cell_elems;
    st->nboundary_facets = f->nbfacets;
    st->facet_entries = f->facet_start[f->g.ncells];
    st->coarse_cells = f->cg.ncells;
    st->coarse_facet_entries = f->cfacet_start[f->cg.ncells];
    st->ndegenerate = f->nelems - f->nvalid;
    size_t ne = (size_t)f->nelems;
    st->bytes = sizeof *f + ne * (size_t)f->stride * sizeof(double) + ne +
                ne * (size_t)(f->dim + 1) * sizeof(int32_t) +
                (size_t)f->nbfacets * (sizeof(int32_t) + (size_t)(f->dim * f->dim) * sizeof(double)) +
                (2 * ((size_t)f->g.ncells + 1) + (size_t)f->cg.ncells + 1) * sizeof(int32_t) +
                (size_t)(st->elem_entries + st->facet_entries + st->coarse_facet_entries) *
                    sizeof(int32_t);
}
