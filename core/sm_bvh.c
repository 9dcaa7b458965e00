/* Bounding-volume hierarchy over the facets of a target surface, with the
 * exact point-facet distances and the nearest-facet query (sm_sdf.h).
 * Built top-down: a node's facets are split at the midpoint of the longest
 * side of their centroids' box (half by count when that leaves one side
 * empty), leaves hold at most BVH_LEAF facets.  Each node also keeps what
 * the winding number's far field needs (sm_winding.c): the area-weighted
 * normal sum, the centroid and the radius about it (sm__bvh_build; a tree
 * for the nearest-facet search alone, sm__bvh_build_boxes, skips them). */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sm_bvh.h"

#define BVH_LEAF 4

/* The smaller and the larger of a running bound and x: comparisons the
 * compiler keeps inline, where fmin and fmax are library calls (NaN
 * rules); a NaN x leaves the bound as fmin and fmax would. */
static inline double lower(double bound, double x)
{
    return x < bound ? x : bound;
}

static inline double upper(double bound, double x)
{
    return x > bound ? x : bound;
}

/* ---- exact distances ---- */

static double dot3(const double *a, const double *b)
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

double sm_sdf_point_segment2(const double *p, const double *a, const double *b)
{
    double ab[2] = {b[0] - a[0], b[1] - a[1]}, ap[2] = {p[0] - a[0], p[1] - a[1]};
    double l2 = ab[0] * ab[0] + ab[1] * ab[1];
    double t = l2 > 0 ? (ap[0] * ab[0] + ap[1] * ab[1]) / l2 : 0;
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    double dx = ap[0] - t * ab[0], dy = ap[1] - t * ab[1];
    return dx * dx + dy * dy;
}

static double dist2_to(const double *p, const double *q)
{
    double d[3] = {p[0] - q[0], p[1] - q[1], p[2] - q[2]};
    return dot3(d, d);
}

/* Closest point of segment ab to x (2D; sm_bvh.h). */
void sm__closest_on_segment(const double *x, const double *a, const double *b,
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

/* Closest point of triangle abc to x (sm_bvh.h), by the Voronoi regions of the
 * vertices, edges and face (no division by a vanishing quantity: the
 * face case divides by the sum of three positive terms). */
void sm__closest_on_triangle(const double *x, const double *a, const double *b,
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

/* Closest point by Voronoi region of the triangle: the vertices, then the
 * edges, then the face (barycentric coordinates from the same dot
 * products).  bary receives the closest point's barycentric coordinates
 * in (a, b, c). */
double sm__triangle_closest(const double *p, const double *a, const double *b, const double *c,
                            double *bary)
{
    double ab[3], ac[3], ap[3], q[3];
    for (int k = 0; k < 3; k++) {
        ab[k] = b[k] - a[k];
        ac[k] = c[k] - a[k];
        ap[k] = p[k] - a[k];
    }
    double d1 = dot3(ab, ap), d2 = dot3(ac, ap);
    if (d1 <= 0 && d2 <= 0) {
        bary[0] = 1, bary[1] = bary[2] = 0;
        return dist2_to(p, a);
    }
    double bp[3] = {p[0] - b[0], p[1] - b[1], p[2] - b[2]};
    double d3 = dot3(ab, bp), d4 = dot3(ac, bp);
    if (d3 >= 0 && d4 <= d3) {
        bary[1] = 1, bary[0] = bary[2] = 0;
        return dist2_to(p, b);
    }
    double vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) {
        double t = d1 / (d1 - d3);
        for (int k = 0; k < 3; k++)
            q[k] = a[k] + t * ab[k];
        bary[0] = 1 - t, bary[1] = t, bary[2] = 0;
        return dist2_to(p, q);
    }
    double cp[3] = {p[0] - c[0], p[1] - c[1], p[2] - c[2]};
    double d5 = dot3(ab, cp), d6 = dot3(ac, cp);
    if (d6 >= 0 && d5 <= d6) {
        bary[2] = 1, bary[0] = bary[1] = 0;
        return dist2_to(p, c);
    }
    double vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0) {
        double t = d2 / (d2 - d6);
        for (int k = 0; k < 3; k++)
            q[k] = a[k] + t * ac[k];
        bary[0] = 1 - t, bary[1] = 0, bary[2] = t;
        return dist2_to(p, q);
    }
    double va = d3 * d6 - d5 * d4;
    if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
        double t = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        for (int k = 0; k < 3; k++)
            q[k] = b[k] + t * (c[k] - b[k]);
        bary[0] = 0, bary[1] = 1 - t, bary[2] = t;
        return dist2_to(p, q);
    }
    double den = va + vb + vc;
    if (!(den > 0)) { /* degenerate triangle: its nearest edge */
        const double *e[3][2] = {{a, b}, {b, c}, {a, c}};
        const int idx[3][2] = {{0, 1}, {1, 2}, {0, 2}};
        double best = INFINITY;
        for (int j = 0; j < 3; j++) {
            double t, d2e = sm__segment_closest(p, e[j][0], e[j][1], 3, &t);
            if (d2e < best) {
                best = d2e;
                bary[0] = bary[1] = bary[2] = 0;
                bary[idx[j][0]] = 1 - t;
                bary[idx[j][1]] = t;
            }
        }
        return best;
    }
    double v = vb / den, w = vc / den;
    for (int k = 0; k < 3; k++)
        q[k] = a[k] + v * ab[k] + w * ac[k];
    bary[0] = 1 - v - w, bary[1] = v, bary[2] = w;
    return dist2_to(p, q);
}

double sm_sdf_point_triangle2(const double *p, const double *a, const double *b,
                              const double *c)
{
    double bary[3];
    return sm__triangle_closest(p, a, b, c, bary);
}

double sm__segment_closest(const double *p, const double *a, const double *b, int dim, double *t)
{
    double l2 = 0, dot = 0;
    for (int k = 0; k < dim; k++) {
        l2 += (b[k] - a[k]) * (b[k] - a[k]);
        dot += (p[k] - a[k]) * (b[k] - a[k]);
    }
    double s = l2 > 0 ? dot / l2 : 0;
    s = s < 0 ? 0 : s > 1 ? 1 : s;
    double d2 = 0;
    for (int k = 0; k < dim; k++) {
        double e = p[k] - (a[k] + s * (b[k] - a[k]));
        d2 += e * e;
    }
    *t = s;
    return d2;
}

double sm__sdf_point_segment3_2(const double *p, const double *a, const double *b)
{
    double ab[3], ap[3];
    for (int k = 0; k < 3; k++) {
        ab[k] = b[k] - a[k];
        ap[k] = p[k] - a[k];
    }
    double l2 = dot3(ab, ab);
    double t = l2 > 0 ? dot3(ap, ab) / l2 : 0;
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    double q[3] = {a[0] + t * ab[0], a[1] + t * ab[1], a[2] + t * ab[2]};
    return dist2_to(p, q);
}

double sm__bvh_facet_dist2(const sm_bvh *t, int32_t f, const double *p)
{
    const sm_surface *s = t->s;
    const int32_t *v = s->facets + (size_t)f * s->dim;
    if (s->dim == 3)
        return sm_sdf_point_triangle2(p, s->coords + 3 * (size_t)v[0], s->coords + 3 * (size_t)v[1],
                                      s->coords + 3 * (size_t)v[2]);
    return sm_sdf_point_segment2(p, s->coords + 2 * (size_t)v[0], s->coords + 2 * (size_t)v[1]);
}

/* ---- build ---- */

/* Area vector (3D: half the cross product; 2D: the outward normal of
 * length |ab|, for a counter-clockwise boundary) and centroid of f. */
void sm__bvh_facet_moments(const sm_surface *s, int32_t f, double *n, double *c)
{
    const int32_t *v = s->facets + (size_t)f * s->dim;
    int dim = s->dim;
    const double *a = s->coords + (size_t)v[0] * dim, *b = s->coords + (size_t)v[1] * dim;
    if (dim == 2) {
        n[0] = b[1] - a[1];
        n[1] = a[0] - b[0];
        n[2] = 0;
        for (int k = 0; k < 2; k++)
            c[k] = (a[k] + b[k]) / 2;
        c[2] = 0;
        return;
    }
    const double *q = s->coords + (size_t)v[2] * 3;
    double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    double w[3] = {q[0] - a[0], q[1] - a[1], q[2] - a[2]};
    n[0] = (u[1] * w[2] - u[2] * w[1]) / 2;
    n[1] = (u[2] * w[0] - u[0] * w[2]) / 2;
    n[2] = (u[0] * w[1] - u[1] * w[0]) / 2;
    for (int k = 0; k < 3; k++)
        c[k] = (a[k] + b[k] + q[k]) / 3;
}

typedef struct build_ctx {
    sm_bvh *t;
    double *cent; /* 3 per facet */
    int moments;  /* the winding number's far field too (sm__bvh_build) */
} build_ctx;

/* An empty box to grow (the axes past dim at 0). */
static void box_empty(sm_bvh_node *nd, int dim)
{
    for (int k = 0; k < 3; k++) {
        nd->lo[k] = k < dim ? DBL_MAX : 0;
        nd->hi[k] = k < dim ? -DBL_MAX : 0;
    }
}

/* A node's box from its facets' corners (a leaf of a tree without the
 * moments: the boxes above are their children's union, the same
 * numbers, as a minimum and a maximum do not round). */
static void facets_box(build_ctx *b, sm_bvh_node *nd)
{
    const sm_surface *s = b->t->s;
    int dim = s->dim;
    box_empty(nd, dim);
    for (int32_t i = nd->first; i < nd->first + nd->count; i++) {
        const int32_t *v = s->facets + (size_t)b->t->order[i] * dim;
        for (int j = 0; j < dim; j++)
            for (int k = 0; k < dim; k++) {
                double x = s->coords[(size_t)v[j] * dim + k];
                nd->lo[k] = lower(nd->lo[k], x);
                nd->hi[k] = upper(nd->hi[k], x);
            }
    }
}

static void node_box(build_ctx *b, sm_bvh_node *nd)
{
    const sm_surface *s = b->t->s;
    int dim = s->dim;
    box_empty(nd, dim);
    double wsum = 0, csum[3] = {0, 0, 0};
    memset(nd->n, 0, sizeof nd->n);
    for (int32_t i = nd->first; i < nd->first + nd->count; i++) {
        int32_t f = b->t->order[i];
        const int32_t *v = s->facets + (size_t)f * dim;
        for (int j = 0; j < dim; j++)
            for (int k = 0; k < dim; k++) {
                double x = s->coords[(size_t)v[j] * dim + k];
                nd->lo[k] = lower(nd->lo[k], x);
                nd->hi[k] = upper(nd->hi[k], x);
            }
        double n[3], c[3];
        sm__bvh_facet_moments(s, f, n, c);
        double area = sqrt(dot3(n, n));
        for (int k = 0; k < 3; k++) {
            nd->n[k] += n[k];
            csum[k] += area * c[k];
        }
        wsum += area;
    }
    for (int k = 0; k < 3; k++)
        nd->c[k] = wsum > 0 ? csum[k] / wsum : (nd->lo[k] + nd->hi[k]) / 2;
    double r2 = 0;
    for (int corner = 0; corner < 8; corner++) {
        double q[3];
        for (int k = 0; k < 3; k++)
            q[k] = (corner >> k) & 1 ? nd->hi[k] : nd->lo[k];
        r2 = fmax(r2, dist2_to(q, nd->c));
    }
    nd->r = sqrt(r2);
}

/* Splits node i's range; returns the split position. */
static int32_t split(build_ctx *b, const sm_bvh_node *nd)
{
    double lo[3] = {DBL_MAX, DBL_MAX, DBL_MAX}, hi[3] = {-DBL_MAX, -DBL_MAX, -DBL_MAX};
    int32_t *o = b->t->order;
    for (int32_t i = nd->first; i < nd->first + nd->count; i++)
        for (int k = 0; k < 3; k++) {
            lo[k] = lower(lo[k], b->cent[3 * (size_t)o[i] + k]);
            hi[k] = upper(hi[k], b->cent[3 * (size_t)o[i] + k]);
        }
    int axis = 0;
    for (int k = 1; k < 3; k++)
        if (hi[k] - lo[k] > hi[axis] - lo[axis])
            axis = k;
    double mid = (lo[axis] + hi[axis]) / 2;
    int32_t i = nd->first, j = nd->first + nd->count - 1;
    while (i <= j) {
        if (b->cent[3 * (size_t)o[i] + axis] < mid) {
            i++;
        } else {
            int32_t tmp = o[i];
            o[i] = o[j];
            o[j--] = tmp;
        }
    }
    if (i == nd->first || i == nd->first + nd->count)
        i = nd->first + nd->count / 2;
    return i;
}

static void build(build_ctx *b, int32_t node, int depth)
{
    sm_bvh *t = b->t;
    sm_bvh_node *nd = &t->nodes[node];
    if (b->moments) {
        node_box(b, nd); /* before the split reorders the range: the sums' order */
    } else {
        memset(nd->n, 0, sizeof nd->n);
        memset(nd->c, 0, sizeof nd->c);
        nd->r = 0;
        if (nd->count <= BVH_LEAF)
            facets_box(b, nd);
    }
    if (depth > t->depth)
        t->depth = depth;
    nd->left = nd->right = -1;
    if (nd->count <= BVH_LEAF)
        return;
    int32_t m = split(b, nd);
    int32_t first = nd->first, count = nd->count;
    int32_t l = t->nnodes++, r = t->nnodes++;
    t->nodes[l].first = first;
    t->nodes[l].count = m - first;
    t->nodes[r].first = m;
    t->nodes[r].count = first + count - m;
    t->nodes[node].left = l;
    t->nodes[node].right = r;
    build(b, l, depth + 1);
    build(b, r, depth + 1);
    if (!b->moments) {
        nd = &t->nodes[node];
        for (int k = 0; k < 3; k++) {
            nd->lo[k] = lower(t->nodes[l].lo[k], t->nodes[r].lo[k]);
            nd->hi[k] = upper(t->nodes[l].hi[k], t->nodes[r].hi[k]);
        }
    }
}

static sm_status build_tree(const sm_surface *s, sm_bvh *t, int moments, sm_error *err)
{
    memset(t, 0, sizeof *t);
    t->s = s;
    if (s->nfacets <= 0)
        return sm_error_set(err, SM_ERR_INVALID, "the surface has no facets");
    build_ctx b = {t, malloc(3 * (size_t)s->nfacets * sizeof(double)), moments};
    t->order = malloc((size_t)s->nfacets * sizeof(int32_t));
    t->nodes = malloc(2 * (size_t)s->nfacets * sizeof(sm_bvh_node));
    if (!b.cent || !t->order || !t->nodes) {
        free(b.cent);
        sm__bvh_free(t);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the hierarchy of %ld facets",
                            (long)s->nfacets);
    }
    for (int32_t f = 0; f < s->nfacets; f++) {
        double n[3];
        sm__bvh_facet_moments(s, f, n, b.cent + 3 * (size_t)f);
        t->order[f] = f;
    }
    t->nnodes = 1;
    t->nodes[0].first = 0;
    t->nodes[0].count = s->nfacets;
    build(&b, 0, 1);
    free(b.cent);
    int dim = s->dim;
    t->pos = malloc((size_t)s->nfacets * dim * dim * sizeof *t->pos);
    if (!t->pos) {
        sm__bvh_free(t);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the hierarchy of %ld facets",
                            (long)s->nfacets);
    }
    for (int32_t i = 0; i < s->nfacets; i++)
        for (int j = 0; j < dim; j++)
            memcpy(t->pos + ((size_t)i * dim + j) * dim,
                   s->coords + (size_t)s->facets[(size_t)t->order[i] * dim + j] * dim,
                   dim * sizeof *t->pos);
    return SM_OK;
}

sm_status sm__bvh_build(const sm_surface *s, sm_bvh *t, sm_error *err)
{
    return build_tree(s, t, 1, err);
}

sm_status sm__bvh_build_boxes(const sm_surface *s, sm_bvh *t, sm_error *err)
{
    return build_tree(s, t, 0, err);
}

void sm__bvh_refit(sm_bvh *t)
{
    const sm_surface *s = t->s;
    const int dim = s->dim;
    for (int32_t i = 0; i < s->nfacets; i++)
        for (int j = 0; j < dim; j++)
            memcpy(t->pos + ((size_t)i * dim + j) * dim,
                   s->coords + (size_t)s->facets[(size_t)t->order[i] * dim + j] * dim,
                   dim * sizeof *t->pos);
    /* children come after their parent (build): bottom-up in reverse */
    for (int32_t n = t->nnodes - 1; n >= 0; n--) {
        sm_bvh_node *nd = &t->nodes[n];
        if (nd->left >= 0) {
            const sm_bvh_node *l = &t->nodes[nd->left], *r = &t->nodes[nd->right];
            for (int k = 0; k < 3; k++) {
                nd->lo[k] = lower(l->lo[k], r->lo[k]);
                nd->hi[k] = upper(l->hi[k], r->hi[k]);
            }
            continue;
        }
        for (int k = 0; k < 3; k++) {
            nd->lo[k] = k < dim ? DBL_MAX : 0;
            nd->hi[k] = k < dim ? -DBL_MAX : 0;
        }
        const double *x = t->pos + (size_t)nd->first * dim * dim;
        for (int32_t i = 0; i < nd->count * dim; i++)
            for (int k = 0; k < dim; k++) {
                nd->lo[k] = lower(nd->lo[k], x[(size_t)i * dim + k]);
                nd->hi[k] = upper(nd->hi[k], x[(size_t)i * dim + k]);
            }
    }
}

void sm__bvh_free(sm_bvh *t)
{
    free(t->order);
    free(t->nodes);
    free(t->pos);
    t->order = NULL;
    t->nodes = NULL;
    t->pos = NULL;
}

/* ---- nearest facet ---- */

/* Squared distance from p to the box of the triangle at x (its three
 * corners): in a leaf, a triangle whose box is beyond the best so far is
 * not tested (half the tests of the final measure's searches). */
static double triangle_box_dist2(const double *x, const double *p)
{
    double d2 = 0;
    for (int k = 0; k < 3; k++) {
        double lo = x[k], hi = x[k];
        lo = lower(lower(lo, x[3 + k]), x[6 + k]);
        hi = upper(upper(hi, x[3 + k]), x[6 + k]);
        double below = lo - p[k], above = p[k] - hi;
        double e = below > above ? below : above;
        e = e > 0 ? e : 0;
        d2 += e * e;
    }
    return d2;
}

/* Nearest child first: the nearer child is descended into at once and
 * the farther pushed with its box distance, so each box is measured
 * once; a node or a triangle is skipped when its box is farther than the
 * best so far by more than the rounding of the two distances (BEYOND:
 * a facet's computed distance may fall an ulp short of its box's), so
 * the answer is an exhaustive pass's, visited in the same order as ever
 * (ties keep the first facet found, which the descent's hints rely on). */
#define BEYOND(d2, best) ((d2) > (best) * (1 + 1e-9))
double sm__bvh_nearest(const sm_bvh *t, const double *p, int32_t *hint, sm_bvh_entry *stack)
{
    const int dim = t->s->dim;
    double best = DBL_MAX;
    int32_t bestf = -1;
    if (*hint >= 0) {
        best = sm__bvh_facet_dist2(t, *hint, p);
        bestf = *hint;
    }
    int top = 0;
    int32_t node = 0;
    double node_d2 = sm__box_dist2(t->nodes[0].lo, t->nodes[0].hi, p, dim);
    for (;;) {
        if (bestf < 0 || !BEYOND(node_d2, best)) {
            const sm_bvh_node *nd = &t->nodes[node];
            if (nd->left < 0) {
                for (int32_t i = nd->first; i < nd->first + nd->count; i++) {
                    const double *x = t->pos + (size_t)i * dim * dim;
                    if (dim == 3 && bestf >= 0 && BEYOND(triangle_box_dist2(x, p), best))
                        continue;
                    double d2 = dim == 3 ? sm_sdf_point_triangle2(p, x, x + 3, x + 6)
                                         : sm_sdf_point_segment2(p, x, x + 2);
                    if (d2 < best) {
                        best = d2;
                        bestf = t->order[i];
                    }
                }
            } else {
                const sm_bvh_node *l = &t->nodes[nd->left], *r = &t->nodes[nd->right];
                double dl = sm__box_dist2(l->lo, l->hi, p, dim);
                double dr = sm__box_dist2(r->lo, r->hi, p, dim);
                int left_first = dl < dr;
                int32_t nearc = left_first ? nd->left : nd->right;
                int32_t farc = left_first ? nd->right : nd->left;
                double dn = left_first ? dl : dr, df = left_first ? dr : dl;
                if (bestf < 0 || !BEYOND(df, best))
                    stack[top++] = (sm_bvh_entry){df, farc};
                if (bestf < 0 || !BEYOND(dn, best)) {
                    node = nearc;
                    node_d2 = dn;
                    continue;
                }
            }
        }
        if (top == 0)
            break;
        sm_bvh_entry e = stack[--top];
        node = e.node;
        node_d2 = e.d2;
    }
    *hint = bestf;
    return sqrt(best);
}

