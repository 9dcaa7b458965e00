/* Target field, point location and evaluation: the walk through element
 * neighbours, the grid lookup, and the evaluation of the value (one point,
 * with gradient, many points) built on them (sm_field.c has the overview,
 * sm_field_internal.h the structure). */
#include "sm_field_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sm_morton.h"

/* ------------------------------------------------------------------ */
/* Location                                                            */

/* Visibility walk from element e: cross the facet with the most negative
 * barycentric coordinate.  Returns the element containing x (bary in lam)
 * or -1 when the walk leaves the mesh or runs out of steps.  With
 * far_lambda > 0, gives up at once when x is that many element heights
 * beyond the start element.  The neighbours of e are requested before
 * its vertices are read: both are cache misses, and this way they
 * overlap. */
static inline __attribute__((always_inline)) int32_t
walk_dim(const sm_field *f, const double *x, int32_t e, double far_lambda, double *lam,
         const int D)
{
    const int32_t *neigh = f->neigh;
    double lmin;
    for (int step = 0; step < WALK_MAX_STEPS; step++) {
        __builtin_prefetch(neigh + (size_t)e * (D + 1));
        elem_bary(f, e, x, lam, D);
        int k = argmin_lam(lam, D, &lmin);
        if (lmin >= -BARY_TOL)
            return e;
        if (step == 0 && far_lambda > 0.0 && lmin < -far_lambda)
            return -1;
        e = neigh[(size_t)e * (D + 1) + k];
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
    int32_t seed = f->cell_seed[idx];
    if (seed < 0)
        return -1; /* no element's box meets the cell */
    e = walk_dim(f, x, seed, 0.0, lam, D);
    if (e >= 0)
        goto found;
    /* The cell lists are exhaustive: scanning one is the final answer
     * (non-convex or non-conforming parts, points outside).  Without
     * them (no memory for them), every valid element is a candidate. */
    const int32_t *lists = sm__field_element_lists(f);
    int32_t j0 = lists ? f->elem_start[idx] : 0, j1 = lists ? f->elem_start[idx + 1] : f->nelems;
    double best_min = -INFINITY, best_lam[4] = {0, 0, 0, 0};
    e = -1;
    for (int32_t j = j0; j < j1; j++) {
        int32_t cand = lists ? lists[j] : j;
        if (!f->valid[cand])
            continue;
        elem_bary(f, cand, x, lam, D);
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
/* Evaluation                                                          */

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
    double lam[4];
    int32_t e = sm_field_locate(f, x, hint ? *hint : -1, lam);
    if (e < 0)
        return sm__field_extension(f, x, hint, grad);
    if (hint)
        *hint = e;
    if (D == 2) {
        if (grad)
            elem_gradient(f, e, grad, 2);
        return elem_value(f, e, lam, 2);
    }
    if (grad)
        elem_gradient(f, e, grad, 3);
    return elem_value(f, e, lam, 3);
}

double sm_field_eval(const sm_field *f, const double *x, int32_t *hint)
{
    double lam[4];
    if (f->dim == 2) {
        int32_t e = locate_dim(f, x, hint ? *hint : -1, lam, 2);
        if (e >= 0) {
            if (hint)
                *hint = e;
            return elem_value(f, e, lam, 2);
        }
    } else {
        int32_t e = locate_dim(f, x, hint ? *hint : -1, lam, 3);
        if (e >= 0) {
            if (hint)
                *hint = e;
            return elem_value(f, e, lam, 3);
        }
    }
    for (int i = 0; i < f->dim; i++)
        if (!isfinite(x[i]))
            return INFINITY;
    return sm__field_extension(f, x, hint, NULL);
}

/* sm_field_eval_many keeps EVAL_GROUP walks in flight: a step of a
 * slot's walk takes two visits, one requesting the vertices of the
 * element whose vertex list and neighbours were requested a round
 * earlier, the next computing with them and requesting the next
 * element's (or, when the walk ends, the next point's hint's).  The misses of all the slots
 * overlap instead of following each other.  Each walk is exactly
 * walk_dim's from the point's hint (same steps, same exits); a point whose
 * walk fails, or that cannot use its hint, gets sm_field_eval, so every
 * result is that of sm_field_eval. */
typedef struct eval_slot {
    int64_t point; /* -1: free */
    int32_t elem;
    int step;
    int vertices_requested; /* the element's vertex rows were requested */
} eval_slot;

static inline __attribute__((always_inline)) void
request_elem(const sm_field *f, int32_t e, const int D)
{
    __builtin_prefetch(f->bg->elems + (size_t)e * (size_t)(D + 1));
    __builtin_prefetch(f->neigh + (size_t)e * (size_t)(D + 1));
}

/* Second stage of a step: the element's vertex list has arrived, its
 * coordinates and values are requested. */
static inline __attribute__((always_inline)) void
request_vertices(const sm_field *f, int32_t e, const int D)
{
    const int32_t *ev = f->bg->elems + (size_t)e * (size_t)(D + 1);
    for (int k = 0; k <= D; k++) {
        __builtin_prefetch(vcoord(f, ev[k]));
        __builtin_prefetch(f->values + ev[k]);
    }
}

/* Next point from *next on that can start a walk from its hint (the
 * others are evaluated at once); -1 when none is left. */
static inline __attribute__((always_inline)) int64_t
next_walk(const sm_field *f, int64_t n, const double *xs, int32_t *hints, double *values,
          int64_t *next, const int D)
{
    while (*next < n) {
        int64_t i = (*next)++;
        const double *x = xs + (size_t)i * (size_t)D;
        int32_t h = hints ? hints[i] : -1;
        int ok = h >= 0 && h < f->nelems;
        for (int k = 0; k < D; k++)
            ok = ok && isfinite(x[k]);
        if (ok && f->valid[h]) {
            request_elem(f, h, D);
            return i;
        }
        values[i] = sm_field_eval(f, x, hints ? &hints[i] : NULL);
    }
    return -1;
}

static inline __attribute__((always_inline)) void
eval_many_dim(const sm_field *f, int64_t n, const double *xs, int32_t *hints, double *values,
              const int D)
{
    eval_slot slot[EVAL_GROUP];
    int64_t next = 0;
    int busy = 0;
    for (int s = 0; s < EVAL_GROUP; s++) {
        slot[s].point = next_walk(f, n, xs, hints, values, &next, D);
        if (slot[s].point >= 0) {
            slot[s].elem = hints[slot[s].point];
            slot[s].step = 0;
            slot[s].vertices_requested = 0;
            busy++;
        }
    }
    while (busy > 0) {
        for (int s = 0; s < EVAL_GROUP; s++) {
            eval_slot *sl = &slot[s];
            if (sl->point < 0)
                continue;
            if (!sl->vertices_requested) {
                request_vertices(f, sl->elem, D);
                sl->vertices_requested = 1;
                continue;
            }
            sl->vertices_requested = 0;
            const double *x = xs + (size_t)sl->point * (size_t)D;
            double lam[4], lmin;
            elem_bary(f, sl->elem, x, lam, D);
            int k = argmin_lam(lam, D, &lmin);
            int done = 1;
            if (lmin >= -BARY_TOL) {
                values[sl->point] = elem_value(f, sl->elem, lam, D);
                hints[sl->point] = sl->elem;
            } else {
                int32_t e = sl->step == 0 && lmin < -WALK_FAR_LAMBDA
                                ? -1
                                : f->neigh[(size_t)sl->elem * (size_t)(D + 1) + (size_t)k];
                if (e >= 0 && ++sl->step < WALK_MAX_STEPS) {
                    sl->elem = e;
                    request_elem(f, e, D);
                    done = 0;
                } else {
                    values[sl->point] = sm_field_eval(f, x, &hints[sl->point]);
                }
            }
            if (done) {
                sl->point = next_walk(f, n, xs, hints, values, &next, D);
                if (sl->point >= 0) {
                    sl->elem = hints[sl->point];
                    sl->step = 0;
                    sl->vertices_requested = 0;
                } else {
                    busy--;
                }
            }
        }
    }
}

void sm_field_eval_many(const sm_field *f, int64_t n, const double *xs, int32_t *hints,
                        double *values)
{
    if (f->dim == 2)
        eval_many_dim(f, n, xs, hints, values, 2);
    else
        eval_many_dim(f, n, xs, hints, values, 3);
}

/* sm_field_eval_points cuts the Morton order in blocks of POINTS_BLOCK
 * points (the unit of work of the threads) and each block in
 * EVAL_GROUP chains of consecutive points, walked side by side like
 * sm_field_eval_many's walks (so that their misses overlap), each walk
 * starting from the element its chain's previous point was found in
 * (the first point of a chain: from the grid). */
#define POINTS_BLOCK 4096

typedef struct chain {
    int64_t at, end;  /* position in the order, end of the chain */
    int64_t point;    /* -1: the chain is done */
    int32_t elem, last;
    int step, vertices_requested;
} chain;

/* Starts the chain's next point: its walk from the element of the one
 * before, or, when that cannot be used, sm_field_eval at once (and on
 * to the next).  0 when the chain is done. */
static inline __attribute__((always_inline)) int
chain_next(const sm_field *f, chain *c, const int64_t *order, const double *xs, int32_t *hints,
           double *values, const int D)
{
    while (c->at < c->end) {
        int64_t i = order ? order[c->at] : c->at;
        c->at++;
        const double *x = xs + (size_t)i * (size_t)D;
        int ok = c->last >= 0 && f->valid[c->last];
        for (int k = 0; k < D; k++)
            ok = ok && isfinite(x[k]);
        if (ok) {
            c->point = i;
            c->elem = c->last;
            c->step = 0;
            c->vertices_requested = 0;
            request_elem(f, c->elem, D);
            return 1;
        }
        int32_t h = c->last;
        values[i] = sm_field_eval(f, x, &h);
        hints[i] = h;
        c->last = h;
    }
    c->point = -1;
    return 0;
}

static inline __attribute__((always_inline)) void
eval_chains_dim(const sm_field *f, int64_t lo, int64_t hi, const int64_t *order, const double *xs,
                int32_t *hints, double *values, const int D)
{
    chain ch[EVAL_GROUP];
    int busy = 0;
    for (int s = 0; s < EVAL_GROUP; s++) {
        ch[s].at = lo + (hi - lo) * s / EVAL_GROUP;
        ch[s].end = lo + (hi - lo) * (s + 1) / EVAL_GROUP;
        ch[s].last = -1;
        busy += chain_next(f, &ch[s], order, xs, hints, values, D);
    }
    while (busy > 0) {
        for (int s = 0; s < EVAL_GROUP; s++) {
            chain *c = &ch[s];
            if (c->point < 0)
                continue;
            if (!c->vertices_requested) {
                request_vertices(f, c->elem, D);
                c->vertices_requested = 1;
                continue;
            }
            c->vertices_requested = 0;
            const double *x = xs + (size_t)c->point * (size_t)D;
            double lam[4], lmin;
            elem_bary(f, c->elem, x, lam, D);
            int k = argmin_lam(lam, D, &lmin);
            if (lmin < -BARY_TOL) {
                int32_t e = c->step == 0 && lmin < -WALK_FAR_LAMBDA
                                ? -1
                                : f->neigh[(size_t)c->elem * (size_t)(D + 1) + (size_t)k];
                if (e >= 0 && ++c->step < WALK_MAX_STEPS) {
                    c->elem = e;
                    request_elem(f, e, D);
                    continue;
                }
                int32_t h = c->last; /* as sm_field_eval from that hint */
                values[c->point] = sm_field_eval(f, x, &h);
                c->elem = h;
            } else {
                values[c->point] = elem_value(f, c->elem, lam, D);
            }
            hints[c->point] = c->elem;
            c->last = c->elem;
            busy -= !chain_next(f, c, order, xs, hints, values, D);
        }
    }
}

void sm_field_eval_points(const sm_field *f, int64_t n, const double *xs, int32_t *hints,
                          double *values)
{
    const int D = f->dim;
    int64_t *order = sm__morton_order(D, n, xs); /* NULL: the input order */
    int32_t *own = hints ? NULL : malloc(((size_t)n + 1) * sizeof *own);
    int32_t *h = hints ? hints : own;
    if (!h) { /* no room for the hints: one point at a time */
        int32_t hint = -1;
        for (int64_t j = 0; j < n; j++) {
            int64_t i = order ? order[j] : j;
            values[i] = sm_field_eval(f, xs + (size_t)i * (size_t)D, &hint);
        }
        free(order);
        return;
    }
#pragma omp parallel for schedule(dynamic, 1)
    for (int64_t b = 0; b < (n + POINTS_BLOCK - 1) / POINTS_BLOCK; b++) {
        int64_t lo = b * POINTS_BLOCK, hi = lo + POINTS_BLOCK < n ? lo + POINTS_BLOCK : n;
        if (D == 2)
            eval_chains_dim(f, lo, hi, order, xs, h, values, 2);
        else
            eval_chains_dim(f, lo, hi, order, xs, h, values, 3);
    }
    free(own);
    free(order);
}
