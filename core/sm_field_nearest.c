/* Target field, nearest point of the mesh for outside points: the
 * closest point on the boundary facets, searched in rings of the facet
 * grids, and the extension of the value outside the mesh (sm_field.c has
 * the overview, sm_field_internal.h the structure). */
#include "sm_field_internal.h"

#include "sm_bvh.h"
#include "sm_morton.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Squared distance from x to grid cell c. */
static double cell_dist2(const grid *g, const int32_t *c, const double *x)
{
    double lo[3], hi[3];
    for (int i = 0; i < g->dim; i++) {
        lo[i] = g->lo[i] + c[i] * g->cell[i];
        hi[i] = lo[i] + g->cell[i];
    }
    return sm__box_dist2(lo, hi, x, g->dim);
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
        sm__closest_on_segment(x, v, v + 2, p);
    else
        sm__closest_on_triangle(x, v, v + 3, v + 6, p);
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


/* ---- the facet tree ----
 * Facets in Morton order of their box centres, the tree their halves
 * (leaves of at most FACET_LEAF), each node's box the union of its
 * facets': built in O(n) after the radix sort. */
#define FACET_LEAF 4

typedef struct tree_build {
    sm_field *f;
    const double *boxes;
    int32_t next;
} tree_build;

static int32_t build_node(tree_build *b, int32_t first, int32_t count, int depth)
{
    sm_field *f = b->f;
    const int D = f->dim;
    int32_t id = b->next++;
    facet_node *nd = &f->ftree[id];
    if (depth > f->ftree_depth)
        f->ftree_depth = depth;
    nd->first = first;
    nd->count = count;
    nd->left = nd->right = -1;
    for (int i = 0; i < 3; i++) {
        nd->lo[i] = INFINITY;
        nd->hi[i] = -INFINITY;
    }
    if (count <= FACET_LEAF) {
        for (int32_t j = first; j < first + count; j++) {
            const double *box = b->boxes + (size_t)f->ftree_order[j] * (size_t)(2 * D);
            for (int i = 0; i < D; i++) {
                nd->lo[i] = fmin(nd->lo[i], box[i]);
                nd->hi[i] = fmax(nd->hi[i], box[D + i]);
            }
        }
    } else {
        int32_t half = count / 2;
        int32_t l = build_node(b, first, half, depth + 1);
        int32_t r = build_node(b, first + half, count - half, depth + 1);
        nd = &f->ftree[id];
        nd->left = l;
        nd->right = r;
        for (int i = 0; i < D; i++) {
            nd->lo[i] = fmin(f->ftree[l].lo[i], f->ftree[r].lo[i]);
            nd->hi[i] = fmax(f->ftree[l].hi[i], f->ftree[r].hi[i]);
        }
    }
    if (D == 2)
        nd->lo[2] = nd->hi[2] = 0;
    return id;
}

sm_status sm__field_build_facet_tree(sm_field *f, const double *boxes, sm_error *err)
{
    const int D = f->dim;
    int32_t nb = f->nbfacets;
    f->ftree_depth = 0;
    f->nftree = 0;
    if (nb == 0)
        return SM_OK;
    double *centres = calloc((size_t)nb * (size_t)D, sizeof *centres);
    int64_t *order = NULL;
    if (centres) {
        for (int32_t j = 0; j < nb; j++)
            for (int i = 0; i < D; i++)
                centres[(size_t)j * D + i] = 0.5 * (boxes[(size_t)j * (2 * D) + i] +
                                                    boxes[(size_t)j * (2 * D) + D + i]);
        order = sm__morton_order(D, nb, centres);
    }
    free(centres);
    /* a binary tree of leaves of 1 to FACET_LEAF facets: under 2 nb nodes */
    f->ftree = malloc(2 * (size_t)nb * sizeof *f->ftree);
    f->ftree_order = malloc((size_t)nb * sizeof *f->ftree_order);
    if (!order || !f->ftree || !f->ftree_order) {
        free(order);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the boundary facets' tree");
    }
    for (int32_t j = 0; j < nb; j++)
        f->ftree_order[j] = (int32_t)order[j];
    free(order);
    tree_build b = {f, boxes, 0};
    build_node(&b, 0, nb, 0);
    f->nftree = b.next;
    return SM_OK;
}

/* Every facet that could be as near as the best so far, through the
 * tree: the answer of a pass over every facet (try_facet's order-free
 * rule, ties to the smallest id), as a box is skipped only when it is
 * farther than the best by more than the rounding of the two distances
 * (a facet's computed closest point may lie an ulp outside its box). */
static void tree_search(const sm_field *f, const double *x, nearest_state *s)
{
    const int D = f->dim;
    int32_t stack[128];
    int top = 0;
    if (f->nftree == 0)
        return;
    stack[top++] = 0;
    while (top > 0) {
        const facet_node *nd = &f->ftree[stack[--top]];
        if (sm__box_dist2(nd->lo, nd->hi, x, D) > s->best2 * (1 + 1e-9))
            continue;
        if (nd->left < 0) {
            for (int32_t j = nd->first; j < nd->first + nd->count; j++)
                try_facet(f, f->ftree_order[j], x, s);
            continue;
        }
        /* the nearer child last: searched first */
        double dl = sm__box_dist2(f->ftree[nd->left].lo, f->ftree[nd->left].hi, x, D);
        double dr = sm__box_dist2(f->ftree[nd->right].lo, f->ftree[nd->right].hi, x, D);
        if (top + 2 > (int)(sizeof stack / sizeof *stack)) {
            /* deeper than a Morton-halved tree of 2^31 facets gets:
             * cannot happen; the plain pass keeps the answer */
            for (int32_t b = 0; b < f->nbfacets; b++)
                try_facet(f, b, x, s);
            return;
        }
        stack[top++] = dl <= dr ? nd->right : nd->left;
        stack[top++] = dl <= dr ? nd->left : nd->right;
    }
}

/* Nearest point on the facets without neighbour: a few rings of the fine
 * element grid (points close to the mesh, the common case), then, for
 * the field's extension, rings of the coarse facet grid with the best
 * distance so far as the bound, and, if even those grow too many (far
 * from a non-convex background), the facet tree, which bounds the cost.
 * The warp's nearest element (by_tree) goes from the fine rings straight
 * to the tree: its outside points are often far from the mesh (a mesh
 * from elsewhere), where the coarse rings cost most before giving up (a
 * plain pass over every facet after them took 0.2 ms a point for the 3D
 * example's template). */
static void nearest_facet(const sm_field *f, const double *x, int by_tree, nearest_state *s)
{
    s->best2 = INFINITY;
    s->facet = -1;
    s->cells_visited = 0;
    const facet_bins fine = {&f->g, f->facet_start, f->facet_list};
    if (ring_search(f, &fine, x, NEAR_RINGS, INT64_MAX, s))
        return;
    const facet_bins coarse = {&f->cg, f->cfacet_start, f->cfacet_list};
    if (!by_tree && ring_search(f, &coarse, x, INT32_MAX, f->nbfacets / 2 + 64, s))
        return;
    tree_search(f, x, s);
}

double sm__field_extension(const sm_field *f, const double *x, int32_t *hint, double *grad)
{
    const int D = f->dim;
    nearest_state s;
    nearest_facet(f, x, 0, &s);
    if (s.facet < 0) {
        /* only when every distance overflows (|x| ~ 1e154 and beyond) */
        if (grad)
            for (int i = 0; i < D; i++)
                grad[i] = 0.0;
        return INFINITY;
    }
    int32_t e = s.facet / (D + 1);
    double dist = sqrt(s.best2);
    if (hint)
        *hint = e;
    if (grad) {
        /* grad = n + (I - n n^T) g, n the unit vector from p to x */
        double g[3];
        if (D == 2)
            elem_gradient(f, e, g, 2);
        else
            elem_gradient(f, e, g, 3);
        double n[3] = {0, 0, 0}, gn = 0.0;
        if (dist > 0.0)
            for (int i = 0; i < D; i++) {
                n[i] = (x[i] - s.p[i]) / dist;
                gn += g[i] * n[i];
            }
        for (int i = 0; i < D; i++)
            grad[i] = n[i] + g[i] - gn * n[i];
    }
    double lam[4];
    if (D == 2) {
        elem_bary(f, e, s.p, lam, 2);
        return elem_value(f, e, lam, 2) + dist;
    }
    elem_bary(f, e, s.p, lam, 3);
    return elem_value(f, e, lam, 3) + dist;
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
    nearest_facet(f, x, 1, &s);
    if (s.facet < 0)
        return -1;
    if (nearest)
        memcpy(nearest, s.p, (size_t)D * sizeof *nearest);
    if (distance)
        *distance = sqrt(s.best2);
    return s.facet / (D + 1);
}
