#include "shapematch/sm_clamp.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "shapematch/sm_sdf.h"
#include "shapematch/sm_surface.h"

static int ref_listed(int32_t ref, const int32_t *refs, int n)
{
    for (int i = 0; i < n; i++)
        if (refs[i] == ref)
            return 1;
    return 0;
}

int32_t sm_clamp_mark(const sm_mesh *m, const sm_params *p, uint8_t *clamped)
{
    const int dim = m->dim, nv = dim + 1;
    memset(clamped, 0, (size_t)m->nverts);
    switch (p->clamp) {
    case SM_CLAMP_BALL: {
        double r2 = p->clamp_radius * p->clamp_radius;
        for (int32_t v = 0; v < m->nverts; v++) {
            double s = 0.0;
            for (int c = 0; c < dim; c++) {
                double dx = m->coords[(size_t)v * (size_t)dim + (size_t)c] - p->clamp_center[c];
                s += dx * dx;
            }
            clamped[v] = s <= r2 * (1.0 + 1e-9);
        }
        break;
    }
    case SM_CLAMP_ELEMENTS:
        for (int32_t e = 0; e < m->nelems; e++)
            if (ref_listed(m->elem_refs[e], p->clamp_refs, p->n_clamp_refs))
                for (int i = 0; i < nv; i++)
                    clamped[m->elems[(size_t)e * (size_t)nv + (size_t)i]] = 1;
        break;
    case SM_CLAMP_VERTICES:
        for (int32_t v = 0; v < m->nverts; v++)
            clamped[v] = (uint8_t)ref_listed(m->vert_refs[v], p->clamp_refs, p->n_clamp_refs);
        break;
    case SM_CLAMP_NONE:
    case SM_CLAMP_AUTO: /* resolved into a ball first (sm_clamp_resolve) */
        break;
    }
    int32_t count = 0;
    for (int32_t v = 0; v < m->nverts; v++)
        count += clamped[v];
    return count;
}

int sm_clamp_rank(const sm_mesh *m, const uint8_t *clamped)
{
    const int dim = m->dim;
    const double *x = m->coords;
    int32_t first = -1, far = -1;
    double far_d2 = 0.0;
    for (int32_t v = 0; v < m->nverts; v++) {
        if (!clamped[v])
            continue;
        if (first < 0) {
            first = v;
            continue;
        }
        double d2 = 0.0;
        for (int k = 0; k < dim; k++) {
            double d = x[(size_t)v * (size_t)dim + (size_t)k] - x[(size_t)first * (size_t)dim + (size_t)k];
            d2 += d * d;
        }
        if (d2 > far_d2) {
            far_d2 = d2;
            far = v;
        }
    }
    /* "distinct" relative to the template's size, not to rounding */
    double diam = sm_mesh_diameter(m, x);
    if (far < 0 || !(far_d2 > 1e-20 * diam * diam))
        return 0;
    if (dim == 2)
        return 1;
    double a[3], best = 0.0;
    for (int k = 0; k < 3; k++)
        a[k] = x[(size_t)far * 3 + (size_t)k] - x[(size_t)first * 3 + (size_t)k];
    for (int32_t v = 0; v < m->nverts; v++) {
        if (!clamped[v])
            continue;
        double b[3];
        for (int k = 0; k < 3; k++)
            b[k] = x[(size_t)v * 3 + (size_t)k] - x[(size_t)first * 3 + (size_t)k];
        double c0 = a[1] * b[2] - a[2] * b[1], c1 = a[2] * b[0] - a[0] * b[2],
               c2 = a[0] * b[1] - a[1] * b[0];
        double n2 = c0 * c0 + c1 * c1 + c2 * c2;
        if (n2 > best)
            best = n2;
    }
    /* |a x b|^2 compared with |a|^2 |b|^2 ~ far_d2^2 */
    return best > 1e-20 * far_d2 * far_d2 ? 2 : 1;
}

static int cmp_i32(const void *a, const void *b)
{
    int32_t x = *(const int32_t *)a, y = *(const int32_t *)b;
    return (x > y) - (x < y);
}

/* What an empty clamp could have been: the references that exist (with
 * their physical names) for a clamp by references, and the template's
 * bounding box. */
static void empty_hint(const sm_mesh *m, const sm_params *p, char *out, size_t cap)
{
    size_t at = 0;
    out[0] = '\0';
    const int32_t *refs = p->clamp == SM_CLAMP_ELEMENTS   ? m->elem_refs
                          : p->clamp == SM_CLAMP_VERTICES ? m->vert_refs : NULL;
    int32_t n = p->clamp == SM_CLAMP_ELEMENTS ? m->nelems : m->nverts;
    int32_t *sorted = refs ? malloc(((size_t)n + 1) * sizeof *sorted) : NULL;
    if (sorted) {
        memcpy(sorted, refs, (size_t)n * sizeof *sorted);
        qsort(sorted, (size_t)n, sizeof *sorted, cmp_i32);
        at += (size_t)snprintf(out + at, cap - at, "; the %s references are",
                               p->clamp == SM_CLAMP_ELEMENTS ? "element" : "vertex");
        int shown = 0;
        for (int32_t i = 0; i < n && at < cap; i++) {
            if (i > 0 && sorted[i] == sorted[i - 1])
                continue;
            if (++shown > 12) {
                at += (size_t)snprintf(out + at, cap - at, " ...");
                break;
            }
            at += (size_t)snprintf(out + at, cap - at, "%s %ld", shown > 1 ? "," : "",
                                   (long)sorted[i]);
            for (int32_t k = 0; k < m->nnames && at < cap; k++)
                if (m->names[k].tag == sorted[i] &&
                    (p->clamp != SM_CLAMP_ELEMENTS || m->names[k].dim == m->dim))
                    at += (size_t)snprintf(out + at, cap - at, " (\"%s\")", m->names[k].name);
        }
        free(sorted);
    }
    double lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
    for (int32_t v = 0; v < m->nverts; v++)
        for (int c = 0; c < m->dim; c++) {
            double x = m->coords[(size_t)v * (size_t)m->dim + (size_t)c];
            lo[c] = v == 0 || x < lo[c] ? x : lo[c];
            hi[c] = v == 0 || x > hi[c] ? x : hi[c];
        }
    if (at < cap && m->dim == 2)
        snprintf(out + at, cap - at, "; the template spans [%g, %g] x [%g, %g]", lo[0], hi[0],
                 lo[1], hi[1]);
    else if (at < cap)
        snprintf(out + at, cap - at, "; the template spans [%g, %g] x [%g, %g] x [%g, %g]",
                 lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]);
}

sm_status sm_clamp_check(const sm_mesh *m, const sm_params *p, int32_t *nclamped, sm_error *err)
{
    if (nclamped)
        *nclamped = 0;
    if (p->clamp == SM_CLAMP_NONE)
        return SM_OK;
    if (p->clamp == SM_CLAMP_AUTO)
        return sm_error_set(err, SM_ERR_INVALID, "the default clamp (kind auto) is chosen on the "
                            "template first (sm_clamp_resolve)");
    uint8_t *clamped = malloc((size_t)m->nverts + 1);
    if (!clamped)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    int32_t count = sm_clamp_mark(m, p, clamped);
    int rank = sm_clamp_rank(m, clamped);
    free(clamped);
    if (nclamped)
        *nclamped = count;
    const char *what = p->clamp == SM_CLAMP_BALL       ? "lies in the ball"
                       : p->clamp == SM_CLAMP_ELEMENTS ? "belongs to an element with these references"
                                                       : "has one of these references";
    if (count == 0) {
        char hint[SM_ERROR_MSG_LEN / 2];
        empty_hint(m, p, hint, sizeof hint);
        return sm_error_set(err, SM_ERR_INVALID, "the clamp set is empty: no template vertex %s%s",
                            what, hint);
    }
    if (count == m->nverts)
        return sm_error_set(err, SM_ERR_INVALID, "every template vertex %s: nothing could move", what);
    if (rank < m->dim - 1)
        return sm_error_set(err, SM_ERR_INVALID,
                            "the clamp holds %s %ld vert%s: rigid rotations stay free (the "
                            "elasticity system is singular); clamp at least %d %s vertices",
                            count == 1 ? "only" : "collinear", (long)count, count == 1 ? "ex" : "ices",
                            m->dim, m->dim == 2 ? "distinct" : "non-collinear");
    return SM_OK;
}

/* The distance to the boundary of m (its facets as a surface) at each
 * vertex and element centroid: the deepest of them in *where. */
static sm_status deepest_point(const sm_mesh *m, double *where, double *depth, sm_error *err)
{
    const int dim = m->dim, nv = dim + 1;
    sm_surface *s = NULL;
    sm_sdf *d = NULL;
    int64_t n = (int64_t)m->nverts + m->nelems;
    double *pts = malloc((size_t)n * (size_t)dim * sizeof *pts);
    double *dist = malloc((size_t)n * sizeof *dist);
    sm_status st = pts && dist ? sm_surface_alloc(&s, dim, m->nverts, m->nbfacets, err)
                               : sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    if (st == SM_OK) {
        memcpy(s->coords, m->coords, (size_t)m->nverts * (size_t)dim * sizeof *s->coords);
        memcpy(s->facets, m->bfacets, (size_t)m->nbfacets * (size_t)dim * sizeof *s->facets);
        st = sm_sdf_new(s, &d, err);
    }
    if (st == SM_OK) {
        memcpy(pts, m->coords, (size_t)m->nverts * (size_t)dim * sizeof *pts);
        for (int32_t e = 0; e < m->nelems; e++)
            for (int c = 0; c < dim; c++) {
                double x = 0;
                for (int i = 0; i < nv; i++)
                    x += m->coords[(size_t)m->elems[(size_t)e * nv + i] * dim + c];
                pts[((size_t)m->nverts + e) * dim + c] = x / nv;
            }
        sm_sdf_distance(d, n, pts, dist, NULL);
        int64_t best = 0;
        for (int64_t i = 1; i < n; i++)
            if (dist[i] > dist[best])
                best = i;
        memcpy(where, pts + (size_t)best * dim, (size_t)dim * sizeof *where);
        *depth = dist[best];
    }
    sm_sdf_free(d);
    sm_surface_free(s);
    free(pts);
    free(dist);
    return st;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

sm_status sm_clamp_default_ball(const sm_mesh *m, double center[3], double *radius,
                                double *inradius, sm_error *err)
{
    const int dim = m->dim;
    if (!m->bfacets || m->nbfacets < 1 || m->nverts < dim + 2)
        return sm_error_set(err, SM_ERR_INVALID, "the default clamp needs the template's "
                            "boundary and at least %d vertices", dim + 2);
    center[0] = center[1] = center[2] = 0;
    sm_status st = deepest_point(m, center, inradius, err);
    if (st != SM_OK)
        return st;
    /* a quarter of the inradius, or the (dim+2)-th nearest vertex's
     * distance when that is farther: a clamp of a few vertices that are
     * not coplanar leaves no rotation free */
    double *d2 = malloc((size_t)m->nverts * sizeof *d2);
    if (!d2)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    for (int32_t v = 0; v < m->nverts; v++) {
        double s = 0;
        for (int c = 0; c < dim; c++) {
            double x = m->coords[(size_t)v * dim + c] - center[c];
            s += x * x;
        }
        d2[v] = s;
    }
    qsort(d2, (size_t)m->nverts, sizeof *d2, cmp_double);
    *radius = fmax(0.25 * *inradius, sqrt(d2[dim + 1]) * (1 + 1e-6));
    free(d2);
    return SM_OK;
}

sm_status sm_clamp_resolve(const sm_mesh *m, sm_params *p, double *inradius, sm_error *err)
{
    if (p->clamp != SM_CLAMP_AUTO)
        return SM_OK;
    double r, depth;
    sm_status st = sm_clamp_default_ball(m, p->clamp_center, &r, &depth, err);
    if (st != SM_OK)
        return st;
    p->clamp = SM_CLAMP_BALL;
    p->clamp_radius = r;
    /* the deepest point may hold too few vertices in a coarse, flat
     * mesh: grow the ball until the check holds */
    for (int k = 0; k < 8 && sm_clamp_check(m, p, NULL, NULL) != SM_OK; k++)
        p->clamp_radius *= 1.5;
    if (inradius)
        *inradius = depth;
    return SM_OK;
}
