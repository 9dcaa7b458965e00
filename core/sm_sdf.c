/* Signed distance to a surface: the public side of sm_bvh.c (nearest
 * facet) and sm_winding.c (sign), parallel over the query points. */
#include "shapematch/sm_sdf.h"

#include <math.h>
#include <stdlib.h>

#include "sm_bvh.h"

struct sm_sdf {
    sm_bvh t;
};

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

/* Points are split into contiguous chunks, one per thread, so that the
 * nearest-facet hint follows the input order. */
void sm_sdf_distance(const sm_sdf *d, int64_t n, const double *pts, double *dist,
                     int32_t *nearest)
{
    const sm_bvh *t = &d->t;
    int dim = t->s->dim;
#pragma omp parallel
    {
        int32_t *stack = malloc((2 * (size_t)t->depth + 4) * sizeof *stack);
        int32_t hint = -1;
#pragma omp for schedule(static)
        for (int64_t i = 0; i < n; i++) {
            if (!stack) {
                dist[i] = NAN;
                continue;
            }
            double p[3] = {pts[dim * i], pts[dim * i + 1], dim == 3 ? pts[dim * i + 2] : 0};
            dist[i] = sm__bvh_nearest(t, p, &hint, stack);
            if (nearest)
                nearest[i] = hint;
        }
        free(stack);
    }
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
    double *w = malloc(((size_t)n + 1) * sizeof *w);
    if (!w)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for %lld points", (long long)n);
    sm_sdf_distance(d, n, pts, out, NULL);
    sm_sdf_winding(d, n, pts, w);
    int64_t inside = 0, bad = 0;
    for (int64_t i = 0; i < n; i++) {
        if (!isfinite(out[i]) || !isfinite(w[i]))
            bad++;
        if (w[i] > 0.5) {
            out[i] = -out[i];
            inside++;
        }
    }
    free(w);
    if (bad)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory in %lld distance queries",
                            (long long)bad);
    if (n > 0 && inside == 0)
        return sm_error_set(err, SM_ERR_INVALID,
                            "no point is inside the surface (winding number > 1/2 nowhere): "
                            "it encloses nothing the points can see, or it is oriented "
                            "inward; the sign cannot be decided");
    return SM_OK;
}
