/* Orientation repair and the health report of a target surface
 * (sm_surface.h).  Edges are keyed by their sorted end points (3D) or
 * their vertex (2D) and sorted, which gives each edge's facets at once:
 * one facet is an open edge, three or more a non-manifold one, two an
 * adjacency, consistent when the facets run through the edge in opposite
 * directions (3D) or one ends where the other starts (2D).  Duplicate
 * facets are left out of the adjacency (otherwise every edge of a
 * duplicated patch is non-manifold and the patch falls apart into single
 * facets) and take their first copy's orientation at the end.  Whole
 * pieces are turned over by sm_surface_orient.c. */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "shapematch/sm_surface.h"
#include "sm_bvh.h"
#include "sm_surface_orient.h"

typedef struct edge_rec {
    int32_t a, b;  /* key (b = 0 in 2D) */
    int32_t f;
    int32_t dir;   /* 3D: a was the facet's first end; 2D: the facet starts here */
} edge_rec;

static int cmp_edge(const void *x, const void *y)
{
    const edge_rec *p = x, *q = y;
    if (p->a != q->a)
        return p->a < q->a ? -1 : 1;
    if (p->b != q->b)
        return p->b < q->b ? -1 : 1;
    return (p->f > q->f) - (p->f < q->f);
}

typedef struct adj {
    int32_t *start;  /* nfacets + 1 */
    int32_t *nb;     /* neighbour facet */
    uint8_t *same;   /* 1 when the neighbour runs the same way (inconsistent) */
} adj;

static int64_t edge_records(const sm_surface *s, const int32_t *dup_of, edge_rec *e)
{
    int64_t n = 0;
    for (int32_t f = 0; f < s->nfacets; f++) {
        if (dup_of[f] >= 0)
            continue;
        const int32_t *v = s->facets + (size_t)f * s->dim;
        for (int k = 0; k < s->dim; k++) {
            if (s->dim == 2) {
                e[n++] = (edge_rec){v[k], 0, f, k == 0};
                continue;
            }
            int32_t a = v[k], b = v[(k + 1) % 3];
            if (a == b)
                continue;
            e[n++] = (edge_rec){a < b ? a : b, a < b ? b : a, f, a < b};
        }
    }
    qsort(e, (size_t)n, sizeof *e, cmp_edge);
    return n;
}

/* Counts open and non-manifold edges; builds the adjacency over the
 * manifold ones. */
static sm_status build_adjacency(const sm_surface *s, const edge_rec *e, int64_t ne, adj *g,
                                 sm_surface_health *h, sm_error *err)
{
    g->start = calloc((size_t)s->nfacets + 2, sizeof *g->start);
    g->nb = malloc(((size_t)ne + 1) * sizeof *g->nb);
    g->same = malloc((size_t)ne + 1);
    if (!g->start || !g->nb || !g->same)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory repairing the surface");
    for (int pass = 0; pass < 2; pass++) {
        for (int64_t i = 0; i < ne;) {
            int64_t j = i;
            while (j < ne && e[j].a == e[i].a && e[j].b == e[i].b)
                j++;
            if (pass == 0 && j - i == 1)
                h->open_edges++;
            if (pass == 0 && j - i > 2)
                h->nonmanifold_edges++;
            if (j - i == 2) {
                const edge_rec *x = &e[i], *y = &e[i + 1];
                if (pass == 0) {
                    g->start[x->f + 1]++;
                    g->start[y->f + 1]++;
                } else {
                    int same = x->dir == y->dir;
                    g->nb[g->start[x->f]] = y->f;
                    g->same[g->start[x->f]++] = (uint8_t)same;
                    g->nb[g->start[y->f]] = x->f;
                    g->same[g->start[y->f]++] = (uint8_t)same;
                }
            }
            i = j;
        }
        if (pass == 0)
            for (int32_t f = 0; f < s->nfacets; f++)
                g->start[f + 1] += g->start[f];
    }
    /* the second pass advanced each start to the next facet's */
    for (int32_t f = s->nfacets; f > 0; f--)
        g->start[f] = g->start[f - 1];
    g->start[0] = 0;
    return SM_OK;
}

static void flip_facet(sm_surface *s, int32_t f)
{
    int32_t *v = s->facets + (size_t)f * s->dim;
    int32_t t = v[0];
    v[0] = v[1];
    v[1] = t;
}

/* Orientation parity of a facet's vertex order against the sorted order
 * (2D: a < b; 3D: an even permutation of the sorted three). */
static int parity(const sm_surface *s, int32_t f)
{
    const int32_t *v = s->facets + (size_t)f * s->dim;
    if (s->dim == 2)
        return v[0] < v[1];
    return (v[0] < v[1]) ^ (v[1] < v[2]) ^ (v[0] < v[2]);
}

/* Propagates orientation per piece from its first facet (comp[f]: its
 * piece, -1 for duplicates, which have no adjacency). */
static int32_t propagate(sm_surface *s, const adj *g, const int32_t *dup_of, int32_t *comp,
                         int32_t *queue, uint8_t *flip)
{
    int32_t n = s->nfacets, nc = 0;
    for (int32_t f = 0; f < n; f++) {
        comp[f] = -1;
        flip[f] = 0;
    }
    for (int32_t seed = 0; seed < n; seed++) {
        if (comp[seed] >= 0 || dup_of[seed] >= 0)
            continue;
        int32_t head = 0, tail = 0;
        comp[seed] = nc;
        queue[tail++] = seed;
        while (head < tail) {
            int32_t f = queue[head++];
            for (int32_t k = g->start[f]; k < g->start[f + 1]; k++) {
                int32_t o = g->nb[k];
                if (comp[o] >= 0)
                    continue;
                comp[o] = nc;
                /* same: the two ran the same way through the edge as read */
                flip[o] = flip[f] ^ g->same[k];
                queue[tail++] = o;
            }
        }
        nc++;
    }
    for (int32_t f = 0; f < n; f++)
        if (flip[f])
            flip_facet(s, f);
    return nc;
}

/* Orients the pieces within and as wholes, aligns the duplicates, and
 * counts what changed against the input's orientation. */
static sm_status orient(sm_surface *s, const adj *g, const int32_t *dup_of, sm_surface_health *h,
                        sm_error *err)
{
    int32_t n = s->nfacets;
    int32_t *comp = malloc(((size_t)n + 1) * sizeof *comp);
    int32_t *queue = malloc(((size_t)n + 1) * sizeof *queue);
    uint8_t *before = malloc((size_t)n + 1), *flip = malloc((size_t)n + 1), *turn = NULL;
    int64_t *changed = NULL, *size = NULL;
    sm_status st = SM_OK;
    if (!comp || !queue || !before || !flip) {
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory repairing the surface");
        goto done;
    }
    for (int32_t f = 0; f < n; f++)
        before[f] = (uint8_t)parity(s, f);
    int32_t nc = propagate(s, g, dup_of, comp, queue, flip);
    h->components = nc;
    turn = malloc((size_t)nc + 1);
    changed = calloc((size_t)nc + 1, sizeof *changed);
    size = calloc((size_t)nc + 1, sizeof *size);
    sm_orient_counts oc;
    int closed = h->open_edges == 0 && h->nonmanifold_edges == 0;
    if (!turn || !changed || !size)
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory repairing the surface");
    if (st == SM_OK)
        st = sm__surface_orient_pieces(s, comp, nc, closed, turn, &oc, err);
    if (st != SM_OK)
        goto done;
    h->open_components = oc.open_pieces;
    h->open_by_volume = oc.by_volume;
    for (int32_t f = 0; f < n; f++)
        if (comp[f] >= 0 && turn[comp[f]])
            flip_facet(s, f);
    for (int32_t f = 0; f < n; f++)
        if (dup_of[f] >= 0 && parity(s, f) != parity(s, dup_of[f]))
            flip_facet(s, f);
    for (int32_t f = 0; f < n; f++) {
        int ch = parity(s, f) != before[f];
        h->reoriented += ch;
        if (comp[f] >= 0) {
            changed[comp[f]] += ch;
            size[comp[f]]++;
        }
    }
    for (int32_t c = 0; c < nc; c++) {
        int turned = 2 * changed[c] > size[c];
        h->pieces_turned += turned;
        h->reoriented_within += turned ? size[c] - changed[c] : changed[c];
    }
done:
    free(comp);
    free(queue);
    free(before);
    free(flip);
    free(turn);
    free(changed);
    free(size);
    return st;
}

static int cmp_tuple(const void *x, const void *y)
{
    const int32_t *p = x, *q = y;
    for (int k = 0; k < 4; k++) /* the vertices, then the facet (first copy first) */
        if (p[k] != q[k])
            return p[k] < q[k] ? -1 : 1;
    return 0;
}

/* Counts duplicate and degenerate facets; dup_of[f]: the first facet on
 * the same vertices as f when f is a later copy, else -1. */
static sm_status count_defects(const sm_surface *s, sm_surface_health *h, int32_t *dup_of,
                               sm_error *err)
{
    int dim = s->dim;
    int32_t *t = malloc(((size_t)s->nfacets * 4 + 1) * sizeof *t);
    if (!t)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory checking the surface");
    for (int32_t f = 0; f < s->nfacets; f++) {
        int32_t v[4] = {s->facets[(size_t)f * dim], s->facets[(size_t)f * dim + 1],
                        dim == 3 ? s->facets[(size_t)f * dim + 2] : -1, f};
        for (int i = 0; i < 3; i++) /* sort the three */
            for (int j = i + 1; j < 3; j++)
                if (v[j] < v[i]) {
                    int32_t x = v[i];
                    v[i] = v[j];
                    v[j] = x;
                }
        memcpy(t + 4 * (size_t)f, v, sizeof v);
        dup_of[f] = -1;
        double nrm[3], c[3];
        sm__bvh_facet_moments(s, f, nrm, c);
        if (nrm[0] == 0 && nrm[1] == 0 && nrm[2] == 0)
            h->degenerate++;
    }
    qsort(t, (size_t)s->nfacets, 4 * sizeof *t, cmp_tuple);
    for (int32_t f = 1, first = 0; f < s->nfacets; f++) {
        const int32_t *p = t + 4 * (size_t)f, *q = t + 4 * (size_t)first;
        if (p[0] == q[0] && p[1] == q[1] && p[2] == q[2]) {
            h->duplicates++;
            dup_of[p[3]] = q[3];
        } else {
            first = f;
        }
    }
    free(t);
    return SM_OK;
}

sm_status sm_surface_repair(sm_surface *s, sm_surface_health *out, sm_error *err)
{
    sm_surface_health h;
    memset(&h, 0, sizeof h);
    for (int k = 0; k < 3; k++) {
        h.lo[k] = k < s->dim && s->nverts ? DBL_MAX : 0;
        h.hi[k] = k < s->dim && s->nverts ? -DBL_MAX : 0;
    }
    for (int32_t i = 0; i < s->nverts; i++)
        for (int k = 0; k < s->dim; k++) {
            h.lo[k] = fmin(h.lo[k], s->coords[(size_t)i * s->dim + k]);
            h.hi[k] = fmax(h.hi[k], s->coords[(size_t)i * s->dim + k]);
        }
    edge_rec *e = malloc(((size_t)s->nfacets * 3 + 1) * sizeof *e);
    int32_t *dup_of = malloc(((size_t)s->nfacets + 1) * sizeof *dup_of);
    adj g = {NULL, NULL, NULL};
    sm_status st = e && dup_of ? SM_OK : sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    if (st == SM_OK)
        st = count_defects(s, &h, dup_of, err);
    if (st == SM_OK) {
        int64_t ne = edge_records(s, dup_of, e);
        st = build_adjacency(s, e, ne, &g, &h, err);
    }
    if (st == SM_OK)
        st = orient(s, &g, dup_of, &h, err);
    free(e);
    free(dup_of);
    free(g.start);
    free(g.nb);
    free(g.same);
    if (st == SM_OK && out)
        *out = h;
    return st;
}
