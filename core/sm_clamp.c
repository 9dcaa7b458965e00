#include "shapematch/sm_clamp.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

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
