/* Target field, bucket grids: the element grid (cell lists and walk
 * seeds) and the two grids of the boundary facets (sm_field.c has the
 * overview, sm_field_internal.h the structure). */
#include "sm_field_internal.h"

#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

/* ------------------------------------------------------------------ */
/* Grids                                                               */
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

/* What a grid bins: the valid elements ids[0..n-1] (boxes from the
 * vertex coordinates, the lists hold the ids), or n boxes of 2*dim
 * doubles, lo then hi (the lists hold their index). */
typedef struct bin_items {
    const sm_field *f;
    const int32_t *ids;
    const double *boxes;
    int32_t n;
} bin_items;

/* Box of item j; the vertices of item j + PREFETCH_AHEAD are requested. */
static inline __attribute__((always_inline)) void
item_box(const bin_items *it, int32_t j, double *a, double *b, const int D)
{
    if (!it->ids) {
        const double *bx = it->boxes + (size_t)j * (size_t)(2 * D);
        memcpy(a, bx, (size_t)D * sizeof *a);
        memcpy(b, bx + D, (size_t)D * sizeof *b);
        return;
    }
    const int32_t *elems = it->f->bg->elems;
    const double *coords = it->f->bg->coords;
    if (j + PREFETCH_AHEAD < it->n) {
        const int32_t *pv = elems + (size_t)it->ids[j + PREFETCH_AHEAD] * (size_t)(D + 1);
        for (int k = 0; k <= D; k++)
            __builtin_prefetch(coords + (size_t)pv[k] * (size_t)D);
    }
    const int32_t *ev = elems + (size_t)it->ids[j] * (size_t)(D + 1);
    for (int i = 0; i < D; i++)
        a[i] = b[i] = coords[(size_t)ev[0] * (size_t)D + (size_t)i];
    for (int k = 1; k <= D; k++)
        for (int i = 0; i < D; i++) {
            double x = coords[(size_t)ev[k] * (size_t)D + (size_t)i];
            a[i] = x < a[i] ? x : a[i];
            b[i] = x > b[i] ? x : b[i];
        }
}

static inline __attribute__((always_inline)) int64_t
count_entries_dim(const grid *g, const bin_items *it, const int D)
{
    int64_t total = 0;
#pragma omp parallel for schedule(static) reduction(+ : total)
    for (int32_t j = 0; j < it->n; j++) {
        double a[3], b[3];
        int32_t c0[3], c1[3];
        item_box(it, j, a, b, D);
        box_cells(g, a, b, c0, c1);
        total += (int64_t)(c1[0] - c0[0] + 1) * (c1[1] - c0[1] + 1) * (c1[2] - c0[2] + 1);
    }
    return total;
}

static int64_t count_entries(const grid *g, const bin_items *it)
{
    return g->dim == 2 ? count_entries_dim(g, it, 2) : count_entries_dim(g, it, 3);
}

/* Shapes g for about `target` cells, coarsening until the lists hold at
 * most `limit` entries; returns the entry count. */
static int64_t grid_fit(grid *g, double target, const bin_items *it, int64_t limit)
{
    double nd[3];
    grid_shape(g, target, nd);
    for (;;) {
        grid_set_axes(g, nd);
        int64_t total = count_entries(g, it);
        if (total <= limit || g->ncells == 1)
            return total;
        for (int i = 0; i < g->dim; i++)
            nd[i] = nd[i] > 1 ? floor(nd[i] * 0.8) : 1;
    }
}

static sm_status grid_lists_alloc(const grid *g, int64_t total, int32_t **start, int32_t **list,
                                  sm_error *err)
{
    if (total > INT32_MAX - 1)
        return sm_error_set(err, SM_ERR_NOMEM,
                            "point location grid too large (%lld entries)", (long long)total);
    *start = sm__alloc_huge(((size_t)g->ncells + 1) * sizeof **start);
    if (*start)
        memset(*start, 0, ((size_t)g->ncells + 1) * sizeof **start);
    *list = sm__alloc_huge((size_t)total * sizeof **list + 1);
    if (!*start || !*list)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the point location grid");
    return SM_OK;
}

/* Cell ranges of the items, in the order the lists are filled. */
typedef struct item_cells {
    int32_t c0[3], c1[3];
    int32_t id;   /* what the cell lists hold */
} item_cells;

/* Cell counts of box ranges by a difference array over the cell corners
 * (+-1 at the 2^dim corners of every range, then running sums along
 * each axis), so that counting costs 2^dim writes a range, however many
 * cells it covers. */
typedef struct cell_counter {
    int64_t m[3], stride[3];
    int32_t *diff;
} cell_counter;

static int counter_init(cell_counter *cc, const grid *g)
{
    cc->m[0] = g->n[0] + 1;
    cc->m[1] = g->n[1] + 1;
    cc->m[2] = g->dim == 3 ? g->n[2] + 1 : 1;
    cc->stride[0] = 1;
    cc->stride[1] = cc->m[0];
    cc->stride[2] = cc->m[0] * cc->m[1];
    cc->diff = calloc((size_t)(cc->m[0] * cc->m[1] * cc->m[2]), sizeof *cc->diff);
    return cc->diff ? 0 : -1;
}

static void counter_add(cell_counter *cc, int dim, const int32_t *c0, const int32_t *c1)
{
    for (int corner = 0; corner < (1 << dim); corner++) {
        int64_t idx = 0;
        int32_t sign = 1;
        for (int i = 0; i < dim; i++)
            if (corner >> i & 1) {
                idx += (c1[i] + 1) * cc->stride[i];
                sign = -sign;
            } else {
                idx += c0[i] * cc->stride[i];
            }
        cc->diff[idx] += sign;
    }
}

/* start[c] = the entries of the cells before c (ncells + 1 entries, the
 * last the total); frees the counter.  Returns the largest count. */
static int32_t counter_starts(cell_counter *cc, const grid *g, int32_t *start)
{
    const int D = g->dim;
    for (int i = 0; i < D; i++) {
        int64_t idx = 0, c[3];
        for (c[2] = 0; c[2] < cc->m[2]; c[2]++)
            for (c[1] = 0; c[1] < cc->m[1]; c[1]++)
                for (c[0] = 0; c[0] < cc->m[0]; c[0]++, idx++)
                    if (c[i] > 0)
                        cc->diff[idx] += cc->diff[idx - cc->stride[i]];
    }
    int64_t cell = 0;
    int32_t sum = 0, most = 0;
    for (int32_t z = 0; z < g->n[2]; z++)
        for (int32_t y = 0; y < g->n[1]; y++) {
            const int32_t *row = cc->diff + z * cc->stride[2] + y * cc->stride[1];
            for (int32_t x = 0; x < g->n[0]; x++, cell++) {
                start[cell] = sum;
                sum += row[x];
                most = row[x] > most ? row[x] : most;
            }
        }
    start[g->ncells] = sum;
    free(cc->diff);
    cc->diff = NULL;
    return most;
}

/* CSR lists from the cell ranges (in their order, which is also the order
 * inside each list).  start[] is zero on entry. */
static sm_status fill_lists(const grid *g, const item_cells *it, int32_t n, int32_t *start,
                            int32_t *list, sm_error *err)
{
    cell_counter cc;
    if (counter_init(&cc, g) != 0)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the point location grid");
    for (int32_t t = 0; t < n; t++)
        counter_add(&cc, g->dim, it[t].c0, it[t].c1);
    counter_starts(&cc, g, start);
    for (int32_t t = 0; t < n; t++) {
        const item_cells *ic = &it[t];
        int32_t c[3];
        for (c[2] = ic->c0[2]; c[2] <= ic->c1[2]; c[2]++)
            for (c[1] = ic->c0[1]; c[1] <= ic->c1[1]; c[1]++) {
                int32_t *pos = start + cell_index(g, (int32_t[3]){ic->c0[0], c[1], c[2]});
                for (int32_t k = 0; k <= ic->c1[0] - ic->c0[0]; k++)
                    list[pos[k]++] = ic->id;
            }
    }
    /* each position now ends its cell, i.e. starts the next one */
    memmove(start + 1, start, (size_t)g->ncells * sizeof *start);
    start[0] = 0;
    return SM_OK;
}

/* Lists of the boxes meeting each cell (in increasing order). */
static sm_status bin_boxes(const grid *g, const bin_items *items, int64_t total,
                           int32_t **start, int32_t **list, sm_error *err)
{
    sm_status st = grid_lists_alloc(g, total, start, list, err);
    if (st != SM_OK)
        return st;
    item_cells *it = malloc((size_t)items->n * sizeof *it + 1);
    if (!it)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the point location grid");
    for (int32_t j = 0; j < items->n; j++) {
        const double *bx = items->boxes + (size_t)j * (size_t)(2 * g->dim);
        box_cells(g, bx, bx + g->dim, it[j].c0, it[j].c1);
        it[j].id = j;
    }
    st = fill_lists(g, it, items->n, *start, *list, err);
    free(it);
    return st;
}

/* Cells holding no box centre take the seed of the nearest cell that does
 * (L1 distance in cells, by the separable distance transform: a forward
 * and a backward sweep along each axis in turn, each visiting the cells
 * in memory order), so that a walk from the seed of any cell starts close
 * by. */
static sm_status spread_seeds(const grid *g, int32_t *seed, sm_error *err)
{
    const int64_t nc = g->ncells;
    int32_t *dist = sm__alloc_huge((size_t)nc * sizeof *dist + 1);
    if (!dist)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the point location grid");
    for (int64_t c = 0; c < nc; c++)
        dist[c] = seed[c] >= 0 ? 0 : INT32_MAX;
    const int64_t step[3] = {1, g->n[0], (int64_t)g->n[0] * g->n[1]};
    for (int i = 0; i < g->dim; i++) {
        for (int dir = 0; dir < 2; dir++) {
            /* t counts the steps of the sweep along each axis (cells in
             * increasing order forward, decreasing backward); the cell one
             * step back along axis i exists when t[i] > 0 */
            int64_t idx = dir == 0 ? 0 : nc - 1, back = dir == 0 ? -step[i] : step[i];
            int32_t t[3];
            for (t[2] = 0; t[2] < g->n[2]; t[2]++)
                for (t[1] = 0; t[1] < g->n[1]; t[1]++)
                    for (t[0] = 0; t[0] < g->n[0]; t[0]++) {
                        if (t[i] > 0) {
                            int64_t from = idx + back;
                            if (dist[from] != INT32_MAX && dist[from] + 1 < dist[idx]) {
                                dist[idx] = dist[from] + 1;
                                seed[idx] = seed[from];
                            }
                        }
                        idx += dir == 0 ? 1 : -1;
                    }
        }
    }
    free(dist);
    return SM_OK;
}

/* The element grid's seeds and list sizes, in one pass over the valid
 * elements (ascending): each element's inflated box range is counted in
 * its cells, and the element whose box centre is nearest to a cell's
 * centre (smallest id on ties) seeds the cell; cells holding no box
 * centre take the seed of the nearest one that does (spread_seeds), and
 * cells no box meets get none (no element can hold their points). */
static sm_status seed_cells(sm_field *f, const bin_items *items, sm_error *err)
{
    const grid *g = &f->g;
    const int D = g->dim;
    const int64_t nc = g->ncells;
    cell_counter cc;
    double *best = malloc((size_t)nc * sizeof *best + 1);
    f->cell_seed = malloc((size_t)nc * sizeof *f->cell_seed + 1);
    f->elem_start = malloc(((size_t)nc + 1) * sizeof *f->elem_start);
    if (!best || !f->cell_seed || !f->elem_start || counter_init(&cc, g) != 0) {
        free(best);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the point location grid");
    }
    for (int64_t c = 0; c < nc; c++) {
        f->cell_seed[c] = -1;
        best[c] = INFINITY;
    }
    for (int32_t j = 0; j < items->n; j++) {
        double a[3], b[3], d2 = 0.0;
        int32_t c[3] = {0, 0, 0}, c0[3], c1[3];
        if (D == 2)
            item_box(items, j, a, b, 2);
        else
            item_box(items, j, a, b, 3);
        for (int i = 0; i < D; i++) {
            double mid = 0.5 * (a[i] + b[i]);
            c[i] = axis_cell(g, i, mid);
            double t = mid - (g->lo[i] + (c[i] + 0.5) * g->cell[i]);
            d2 += t * t;
        }
        int64_t cell = cell_index(g, c);
        if (d2 < best[cell]) { /* ascending ids: the first wins ties */
            best[cell] = d2;
            f->cell_seed[cell] = items->ids[j];
        }
        box_cells(g, a, b, c0, c1);
        counter_add(&cc, D, c0, c1);
    }
    free(best);
    f->max_cell_elems = counter_starts(&cc, g, f->elem_start);
    sm_status st = spread_seeds(g, f->cell_seed, err);
    for (int64_t c = 0; st == SM_OK && c < nc; c++)
        if (f->elem_start[c + 1] == f->elem_start[c])
            f->cell_seed[c] = -1; /* no element can hold a point of the cell */
    return st;
}

struct sm_field_lists {
    pthread_mutex_t lock;
    atomic_int ready;
    int32_t *list;
    size_t bytes;
};

void sm__field_lists_free(sm_field_lists *l)
{
    if (!l)
        return;
    pthread_mutex_destroy(&l->lock);
    free(l->list);
    free(l);
}

size_t sm__field_lists_bytes(const sm_field *f)
{
    return atomic_load_explicit(&f->lists->ready, memory_order_acquire) ? f->lists->bytes : 0;
}

/* The lists, filled in one pass over the valid elements in ascending
 * order with the ranges seed_cells counted (the same boxes). */
static int32_t *fill_element_lists(const sm_field *f)
{
    const grid *g = &f->g;
    const int D = g->dim;
    const int64_t nc = g->ncells;
    int32_t *list = malloc((size_t)f->elem_start[nc] * sizeof *list + 1);
    int32_t *pos = malloc((size_t)nc * sizeof *pos + 1);
    if (!list || !pos) {
        free(list);
        free(pos);
        return NULL;
    }
    memcpy(pos, f->elem_start, (size_t)nc * sizeof *pos);
    for (int32_t e = 0; e < f->nelems; e++) {
        if (!f->valid[e])
            continue;
        const bin_items item = {f, &e, NULL, 1};
        double a[3], b[3];
        int32_t c0[3], c1[3], c[3];
        if (D == 2)
            item_box(&item, 0, a, b, 2);
        else
            item_box(&item, 0, a, b, 3);
        box_cells(g, a, b, c0, c1);
        for (c[2] = c0[2]; c[2] <= c1[2]; c[2]++)
            for (c[1] = c0[1]; c[1] <= c1[1]; c[1]++)
                for (c[0] = c0[0]; c[0] <= c1[0]; c[0]++)
                    list[pos[cell_index(g, c)]++] = e;
    }
    free(pos);
    return list;
}

const int32_t *sm__field_element_lists(const sm_field *f)
{
    sm_field_lists *l = f->lists;
    if (atomic_load_explicit(&l->ready, memory_order_acquire))
        return l->list;
    pthread_mutex_lock(&l->lock);
    if (!atomic_load_explicit(&l->ready, memory_order_relaxed) &&
        (l->list = fill_element_lists(f)) != NULL) {
        l->bytes = (size_t)f->elem_start[f->g.ncells] * sizeof *l->list;
        atomic_store_explicit(&l->ready, 1, memory_order_release);
    }
    int32_t *list = l->list;
    pthread_mutex_unlock(&l->lock);
    return list;
}

/* The grids, over the bounding box lo, hi of the valid elements. */
sm_status sm__field_build_grids(sm_field *f, const double *lo, const double *hi, sm_error *err)
{
    const int D = f->dim, nv1 = D + 1;
    grid *g = &f->g;
    g->dim = D;
    for (int i = 0; i < D; i++) {
        /* a hair of margin so that points on the box are inside it */
        double pad = 1e-9 * (hi[i] - lo[i]) + 4.0 * 2.2e-16 * (fabs(lo[i]) + fabs(hi[i]));
        g->lo[i] = lo[i] - pad;
        g->hi[i] = hi[i] + pad;
        double ext = g->hi[i] - g->lo[i];
        if (!(ext > 0.0) || !isfinite(ext))
            return sm_error_set(err, SM_ERR_INVALID,
                                "background bounding box has an unusable extent %g on axis %d",
                                ext, i);
    }

    /* Elements.  Hostile inputs (huge elements among tiny ones) can make
     * the lists explode: coarsen until they stay a small multiple of the
     * elements. */
    int32_t *ids = sm__alloc_huge((size_t)f->nvalid * sizeof *ids + 1);
    if (!ids)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the point location grid");
    int32_t nit = 0;
    for (int32_t e = 0; e < f->nelems; e++)
        if (f->valid[e])
            ids[nit++] = e;
    const bin_items elements = {f, ids, NULL, nit};
    int64_t limit = 32 * (int64_t)f->nvalid + (1 << 20);
    double per_elem = D == 2 ? GRID_CELLS_PER_ELEM_2D : GRID_CELLS_PER_ELEM_3D;
    sm_status st = SM_OK;
    f->lists = calloc(1, sizeof *f->lists);
    if (!f->lists || pthread_mutex_init(&f->lists->lock, NULL) != 0) {
        free(f->lists);
        f->lists = NULL;
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory for the point location grid");
    }
    if (st == SM_OK && grid_fit(g, per_elem * f->nvalid, &elements, limit) > INT32_MAX - 1)
        st = sm_error_set(err, SM_ERR_NOMEM, "point location grid too large");
    if (st == SM_OK)
        st = seed_cells(f, &elements, err);
    free(ids);
    if (st != SM_OK)
        return st;

    /* Boundary facets, their coordinates, and both facet grids. */
    int32_t nb = 0;
    for (int32_t e = 0; e < f->nelems; e++)
        if (f->valid[e])
            for (int k = 0; k <= D; k++)
                nb += f->neigh[(size_t)e * (size_t)nv1 + (size_t)k] < 0;
    f->bfacet_id = malloc((size_t)nb * sizeof *f->bfacet_id + 1);
    f->bfacet_xyz = malloc((size_t)nb * (size_t)(D * D) * sizeof(double) + 1);
    double *fboxes = malloc((size_t)nb * (size_t)(2 * D) * sizeof *fboxes + 1);
    if (!f->bfacet_id || !f->bfacet_xyz || !fboxes) {
        free(fboxes);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the boundary facets");
    }
    nb = 0;
    for (int32_t e = 0; e < f->nelems; e++)
        if (f->valid[e])
            for (int k = 0; k <= D; k++)
                if (f->neigh[(size_t)e * (size_t)nv1 + (size_t)k] < 0)
                    f->bfacet_id[nb++] = e * nv1 + k;
    f->nbfacets = nb;
    for (int32_t j = 0; j < nb; j++) {
        int32_t fv[3];
        sm__field_facet_vertices(f, f->bfacet_id[j] / nv1, f->bfacet_id[j] % nv1, fv);
        double *a = fboxes + (size_t)j * (size_t)(2 * D), *b = a + D;
        for (int k = 0; k < D; k++) {
            const double *p = vcoord(f, fv[k]);
            memcpy(f->bfacet_xyz + ((size_t)j * D + k) * D, p, (size_t)D * sizeof(double));
            for (int i = 0; i < D; i++) {
                a[i] = k == 0 || p[i] < a[i] ? p[i] : a[i];
                b[i] = k == 0 || p[i] > b[i] ? p[i] : b[i];
            }
        }
    }
    const bin_items facets = {f, NULL, fboxes, nb};
    int64_t total = count_entries(g, &facets);
    st = bin_boxes(g, &facets, total, &f->facet_start, &f->facet_list, err);
    if (st == SM_OK) {
        f->cg = *g;
        total = grid_fit(&f->cg, GRID_CELLS_PER_BFACET * nb, &facets, 8 * (int64_t)nb + (1 << 16));
        st = bin_boxes(&f->cg, &facets, total, &f->cfacet_start, &f->cfacet_list, err);
    }
    if (st == SM_OK)
        st = sm__field_build_facet_tree(f, fboxes, err);
    free(fboxes);
    return st;
}
