/* Signed distance to a surface: the public side of sm_bvh.c (nearest
 * facet) and sm_winding.c (sign), parallel over the query points. */
#include "shapematch/sm_sdf.h"

#include <math.h>
#include <stdlib.h>

#include "sm_bvh.h"
#include "sm_morton.h"

struct sm_sdf {
    sm_bvh t;
    int closed; /* the facets' boundary chain is zero (see closed_chain) */
};

typedef struct edge_sign {
    uint64_t key;
    int sign;
} edge_sign;

static int cmp_edge_sign(const void *a, const void *b)
{
    uint64_t x = ((const edge_sign *)a)->key, y = ((const edge_sign *)b)->key;
    return x < y ? -1 : x > y;
}

/* 1 when the oriented facets form a cycle: every edge (3D) or vertex
 * (2D) is traversed as often in one direction as in the other.  Then the
 * winding number is constant off the surface on each connected region,
 * which is what lets sm_sdf_signed carry a sign from point to point
 * (0 also when out of memory: the sign is then computed everywhere). */
static int closed_chain(const sm_surface *s)
{
    int dim = s->dim;
    int64_t n = (int64_t)s->nfacets * (dim == 3 ? 3 : 2);
    edge_sign *e = malloc((size_t)n * sizeof *e);
    if (!e)
        return 0;
    int64_t m = 0;
    for (int32_t f = 0; f < s->nfacets; f++) {
        const int32_t *v = s->facets + (size_t)f * dim;
        for (int j = 0; j < dim; j++) {
            uint64_t a = (uint64_t)v[j], b = (uint64_t)v[(j + 1) % dim];
            if (dim == 2) { /* a vertex: +1 where a segment starts, -1 where it ends */
                e[m++] = (edge_sign){a, 1};
                e[m++] = (edge_sign){b, -1};
                break;
            }
            e[m++] = a < b ? (edge_sign){(a << 32) | b, 1} : (edge_sign){(b << 32) | a, -1};
        }
    }
    qsort(e, (size_t)m, sizeof *e, cmp_edge_sign);
    int closed = 1;
    for (int64_t i = 0, j; i < m && closed; i = j) {
        int sum = 0;
        for (j = i; j < m && e[j].key == e[i].key; j++)
            sum += e[j].sign;
        closed = sum == 0;
    }
    free(e);
    return closed;
}

sm_status sm_sdf_new(const sm_surface *s, sm_sdf **out, sm_error *err)
{
    *out = NULL;
    sm_sdf *d = calloc(1, sizeof *d);
    if (!d)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    sm_status st = sm__bvh_build(s, &d->t, err);
    if (st != SM_OK) {
        free(d);
        return st;
    }
    d->closed = closed_chain(s);
    *out = d;
    return SM_OK;
}

void sm_sdf_free(sm_sdf *d)
{
    if (!d)
        return;
    sm__bvh_free(&d->t);
    free(d);
}


void sm_sdf_winding(const sm_sdf *d, int64_t n, const double *pts, double *w)
{
    const sm_bvh *t = &d->t;
    int dim = t->s->dim;
#pragma omp parallel
    {
        int32_t *stack = malloc((2 * (size_t)t->depth + 4) * sizeof *stack);
#pragma omp for schedule(dynamic, 256)
        for (int64_t i = 0; i < n; i++) {
            double p[3] = {pts[dim * i], pts[dim * i + 1], dim == 3 ? pts[dim * i + 2] : 0};
            w[i] = stack ? sm__winding_at(t, p, stack) : NAN;
        }
        free(stack);
    }
}

/* ---- signed distance ---- */

/* 1 when the segment pq stays off the surface: it lies in the union of
 * the open balls of radius dp about p and dq about q, which hold no
 * surface point (dp, dq: the distances to the surface), i.e. when
 * |pq| < dp + dq. */
static int same_region(const double *p, const double *q, int dim, double dp, double dq)
{
    double e2 = 0;
    for (int a = 0; a < dim; a++)
        e2 += (p[a] - q[a]) * (p[a] - q[a]);
    /* with a margin: a segment through a surface point that both balls
     * touch (|pq| = dp + dq, as a background grid point pair and a
     * planar piece of a marching-tetrahedra surface give) rounds to
     * e2 < r^2 about half the time, which carried the sign across */
    double r = (dp + dq) * (1 - 1e-9);
    return e2 < r * r;
}

typedef struct sign_count {
    int64_t inside, bad, wound;
} sign_count;

/* Distances and signs of the points order[lo..hi), in that order; on a
 * closed surface a point in the same region as the previous one takes
 * its sign, the others get their winding number. */
static void signed_range(const sm_sdf *d, const double *pts, const int64_t *order, int64_t lo,
                         int64_t hi, double *out, int32_t *nearest, sign_count *c)
{
    const sm_bvh *t = &d->t;
    int dim = t->s->dim;
    sm_bvh_entry *stack = malloc((2 * (size_t)t->depth + 4) * sizeof *stack);
    int32_t *wstack = malloc((2 * (size_t)t->depth + 4) * sizeof *wstack);
    int32_t hint = -1;
    const double *prev = NULL;
    double prevd = 0;
    int prev_in = 0;
    for (int64_t j = lo; j < hi; j++) {
        int64_t i = order[j];
        const double *x = pts + i * dim;
        double p[3] = {x[0], x[1], dim == 3 ? x[2] : 0};
        if (!stack || !wstack) {
            out[i] = NAN;
            c->bad++;
            continue;
        }
        double dist = sm__bvh_nearest(t, p, &hint, stack);
        if (nearest)
            nearest[i] = hint;
        int in;
        if (d->closed && prev && isfinite(dist) && same_region(prev, x, dim, prevd, dist)) {
            in = prev_in;
        } else {
            double w = sm__winding_at(t, p, wstack);
            c->bad += !isfinite(w);
            in = w > 0.5;
            c->wound++;
        }
        c->bad += !isfinite(dist);
        c->inside += in;
        out[i] = in ? -dist : dist;
        prev = x;
        prevd = dist;
        prev_in = in;
    }
    free(stack);
    free(wstack);
}

/* The points in Morton order (input order when that cannot be
 * allocated), in blocks of 4096 handed out to the threads, so that the
 * nearest-facet hint comes from a neighbour. */
void sm_sdf_distance(const sm_sdf *d, int64_t n, const double *pts, double *dist,
                     int32_t *nearest)
{
    const sm_bvh *t = &d->t;
    int dim = t->s->dim;
    int64_t *order = sm__morton_order(dim, n, pts);
#pragma omp parallel if (n > 4096)
    {
        sm_bvh_entry *stack = malloc((2 * (size_t)t->depth + 4) * sizeof *stack);
#pragma omp for schedule(dynamic, 1)
        for (int64_t b = 0; b < (n + 4095) / 4096; b++) {
            int32_t hint = -1;
            for (int64_t j = b * 4096; j < n && j < b * 4096 + 4096; j++) {
                int64_t i = order ? order[j] : j;
                if (!stack) {
                    dist[i] = NAN;
                    continue;
                }
                double p[3] = {pts[dim * i], pts[dim * i + 1], dim == 3 ? pts[dim * i + 2] : 0};
                dist[i] = sm__bvh_nearest(t, p, &hint, stack);
                if (nearest)
                    nearest[i] = hint;
            }
        }
        free(stack);
    }
    free(order);
}

/* Total enclosed volume (area in 2D) by the divergence theorem. */
static double enclosed(const sm_surface *s)
{
    double v = 0;
    for (int32_t f = 0; f < s->nfacets; f++) {
        double nrm[3], c[3];
        sm__bvh_facet_moments(s, f, nrm, c);
        v += (nrm[0] * c[0] + nrm[1] * c[1] + nrm[2] * c[2]) / s->dim;
    }
    return v;
}

sm_status sm_sdf_signed(const sm_sdf *d, int64_t n, const double *pts, double *out,
                        sm_error *err)
{
    return sm_sdf_signed_stats(d, n, pts, out, NULL, err);
}

/* The signed distances (and nearest facets, when nearest is not NULL)
 * of n points in Morton order; *inside counts the points inside. */
static sm_status signed_points(const sm_sdf *d, int64_t n, const double *pts, double *out,
                               int32_t *nearest, int64_t *wound, int64_t *inside, sm_error *err)
{
    const sm_surface *s = d->t.s;
    *inside = 0;
    if (wound)
        *wound = 0;
    if (n <= 0)
        return SM_OK;
    int64_t *order = sm__morton_order(s->dim, n, pts);
    if (!order)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for %lld points", (long long)n);
    sign_count total = {0, 0, 0};
#pragma omp parallel if (n > 4096)
    {
        /* blocks of 4096 consecutive points of the order, handed out
         * dynamically so that the threads stay balanced */
        sign_count c = {0, 0, 0};
#pragma omp for schedule(dynamic, 1) nowait
        for (int64_t b = 0; b < (n + 4095) / 4096; b++)
            signed_range(d, pts, order, b * 4096, b * 4096 + 4096 < n ? b * 4096 + 4096 : n, out,
                         nearest, &c);
#pragma omp critical
        {
            total.inside += c.inside;
            total.bad += c.bad;
            total.wound += c.wound;
        }
    }
    free(order);
    if (wound)
        *wound = total.wound;
    if (total.bad)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory in %lld distance queries",
                            (long long)total.bad);
    *inside = total.inside;
    return SM_OK;
}

void sm__sdf_nearest_hinted(const sm_sdf *d, int64_t n, const double *pts, double *dist,
                            int32_t *nearest)
{
    const sm_bvh *t = &d->t;
    int dim = t->s->dim;
#pragma omp parallel if (n > 4096)
    {
        sm_bvh_entry *stack = malloc((2 * (size_t)t->depth + 4) * sizeof *stack);
        int32_t prev = -1;
#pragma omp for schedule(static)
        for (int64_t i = 0; i < n; i++) {
            if (!stack) {
                dist[i] = NAN;
                continue;
            }
            double p[3] = {pts[dim * i], pts[dim * i + 1], dim == 3 ? pts[dim * i + 2] : 0};
            int32_t hint = nearest[i] >= 0 ? nearest[i] : prev;
            dist[i] = sm__bvh_nearest(t, p, &hint, stack);
            nearest[i] = prev = hint;
        }
        free(stack);
    }
}

const sm_surface *sm__sdf_surface(const sm_sdf *d)
{
    return d->t.s;
}

sm_status sm__sdf_signed_nearest(const sm_sdf *d, int64_t n, const double *pts, double *out,
                                 int32_t *nearest, sm_error *err)
{
    const sm_bvh *t = &d->t;
    const sm_surface *s = t->s;
    const int dim = s->dim;
    int64_t bad = 0;
#pragma omp parallel if (n > 4096) reduction(+ : bad)
    {
        sm_bvh_entry *stack = malloc((2 * (size_t)t->depth + 4) * sizeof *stack);
        int32_t *wstack = malloc((2 * (size_t)t->depth + 4) * sizeof *wstack);
        int32_t prev = -1;
#pragma omp for schedule(static)
        for (int64_t i = 0; i < n; i++) {
            if (!stack || !wstack) {
                out[i] = NAN;
                bad++;
                continue;
            }
            const double *x = pts + i * dim;
            double p[3] = {x[0], x[1], dim == 3 ? x[2] : 0}, q[3] = {0, 0, 0}, nrm[3], c[3];
            int32_t hint = nearest[i] >= 0 ? nearest[i] : prev;
            double dist = sm__bvh_nearest(t, p, &hint, stack);
            nearest[i] = prev = hint;
            const int32_t *fv = s->facets + (size_t)hint * dim;
            const double *a = s->coords + (size_t)fv[0] * dim, *b = s->coords + (size_t)fv[1] * dim;
            if (dim == 2)
                sm__closest_on_segment(p, a, b, q);
            else
                sm__closest_on_triangle(p, a, b, s->coords + (size_t)fv[2] * dim, q);
            sm__bvh_facet_moments(s, hint, nrm, c);
            double proj = 0, len = 0;
            for (int k = 0; k < dim; k++) {
                proj += nrm[k] * (p[k] - q[k]);
                len += nrm[k] * nrm[k];
            }
            proj /= sqrt(len);
            /* a closest point inside the facet: the facet's side is the
             * sign; near an edge or a vertex, the winding number */
            int in = fabs(proj) >= 0.999 * dist ? proj < 0 : sm__winding_at(t, p, wstack) > 0.5;
            out[i] = in ? -dist : dist;
        }
        free(stack);
        free(wstack);
    }
    if (bad)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory in %lld distance queries",
                            (long long)bad);
    return SM_OK;
}

sm_status sm_sdf_signed_stats(const sm_sdf *d, int64_t n, const double *pts, double *out,
                              int64_t *wound, sm_error *err)
{
    const sm_surface *s = d->t.s;
    const sm_bvh_node *root = &d->t.nodes[0];
    double box = 1;
    for (int k = 0; k < s->dim; k++)
        box *= root->hi[k] - root->lo[k];
    double vol = enclosed(s);
    if (!(fabs(vol) > 1e-9 * box))
        return sm_error_set(err, SM_ERR_INVALID,
                            "the surface encloses nothing (enclosed %s %g for a bounding box "
                            "of %g): the sign of the distance cannot be decided",
                            s->dim == 3 ? "volume" : "area", vol, box);
    int64_t inside = 0;
    sm_status st = signed_points(d, n, pts, out, NULL, wound, &inside, err);
    if (st != SM_OK)
        return st;
    if (n > 0 && inside == 0)
        return sm_error_set(err, SM_ERR_INVALID,
                            "no point is inside the surface (winding number > 1/2 nowhere): "
                            "it encloses nothing the points can see, or it is oriented "
                            "inward; the sign cannot be decided");
    return SM_OK;
}
