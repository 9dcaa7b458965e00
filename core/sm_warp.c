/* The correspondence used: points and fields through the piecewise-linear
 * map of a match (contract in shapematch/sm_warp.h).
 *
 * Location is the target field's (sm_field_locate: grid seed and walk;
 * sm_field_nearest for points outside), built over the template for the
 * forward map and over a shallow copy of the template with the deformed
 * coordinates for the inverse; the field's values are unused (zeros).
 * The points are visited in Morton order in blocks shared by the
 * threads, each walk starting from the element of the point before, so a
 * point costs a step or two of walk in memory that is still in cache. */
#include "shapematch/sm_warp.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "shapematch/sm_field.h"
#include "sm_field_internal.h" /* elem_cofactors */
#include "sm_morton.h"

/* Points per unit of work of the threads (as sm_field_eval_points). */
#define WARP_BLOCK 4096

struct sm_warp {
    const sm_mesh *tmpl;
    const double *deformed;
    int dim;
    sm_mesh deformed_mesh; /* tmpl's arrays, coords = deformed (not owned) */
    double *zeros;         /* the fields' values (nverts zeros) */
    sm_field *loc[2];      /* by sm_warp_direction, NULL when not built */
};

sm_status sm_warp_new(const sm_mesh *tmpl, const double *deformed, unsigned directions,
                      sm_warp **out, sm_error *err)
{
    if (!out)
        return sm_error_set(err, SM_ERR_INVALID, "sm_warp_new: no output pointer");
    *out = NULL;
    if (!tmpl || !deformed || (tmpl->dim != 2 && tmpl->dim != 3))
        return sm_error_set(err, SM_ERR_INVALID, "sm_warp_new: missing mesh or coordinates");
    if (tmpl->nverts <= 0 || tmpl->nelems <= 0)
        return sm_error_set(err, SM_ERR_INVALID, "the template mesh is empty (%ld vertices, "
                            "%ld elements)", (long)tmpl->nverts, (long)tmpl->nelems);
    const int D = tmpl->dim;
    for (size_t i = 0; i < (size_t)tmpl->nverts * (size_t)D; i++)
        if (!isfinite(deformed[i]))
            return sm_error_set(err, SM_ERR_INVALID,
                                "deformed vertex %ld has a non-finite coordinate",
                                (long)(i / (size_t)D) + 1);
    sm_warp *w = calloc(1, sizeof *w);
    if (!w)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    w->tmpl = tmpl;
    w->deformed = deformed;
    w->dim = D;
    w->deformed_mesh = *tmpl;
    w->deformed_mesh.coords = (double *)deformed; /* read only: the field borrows it */
    w->zeros = calloc((size_t)tmpl->nverts, sizeof *w->zeros);
    if (!w->zeros) {
        free(w);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    }
    const sm_mesh *meshes[2] = {tmpl, &w->deformed_mesh};
    static const char *const names[2] = {"template", "deformed mesh"};
    for (int d = 0; d < 2; d++) {
        if (!(directions & (1u << d)))
            continue;
        sm_status st = sm_field_new(meshes[d], w->zeros, &w->loc[d], err);
        if (st != SM_OK) {
            sm_error_prefix(err, "%s", names[d]);
            sm_warp_free(w);
            return st;
        }
    }
    *out = w;
    return SM_OK;
}

void sm_warp_free(sm_warp *w)
{
    if (!w)
        return;
    sm_field_free(w->loc[0]);
    sm_field_free(w->loc[1]);
    free(w->zeros);
    free(w);
}

int sm_warp_dim(const sm_warp *w)
{
    return w->dim;
}

/* ------------------------------------------------------------------ */
/* Element geometry                                                    */

/* Barycentric coordinates of x in element ev over coords (extrapolated
 * outside it); 0 when the element is flat. */
static int warp_bary(const double *coords, const int32_t *ev, int D, const double *x, double *lam)
{
    double cof[3][3];
    double det = elem_cofactors(coords, ev, cof, D);
    if (!(det != 0.0) || !isfinite(det))
        return 0;
    const double *p0 = coords + (size_t)ev[0] * D;
    double y[3] = {0, 0, 0};
    for (int i = 0; i < D; i++)
        y[i] = x[i] - p0[i];
    lam[0] = 1.0;
    for (int k = 0; k < D; k++) {
        double s = 0.0;
        for (int i = 0; i < D; i++)
            s += cof[k][i] * y[i];
        lam[k + 1] = s / det;
        lam[0] -= lam[k + 1];
    }
    return 1;
}

/* The image of x (barycentric lam in element ev of src) in dst: a
 * vertex's own image when x is that vertex exactly. */
static void elem_apply(const double *src, const double *dst, const int32_t *ev, int D,
                       const double *x, const double *lam, double *out)
{
    for (int k = 0; k <= D; k++) {
        const double *p = src + (size_t)ev[k] * D;
        int same = 1;
        for (int i = 0; i < D; i++)
            same = same && p[i] == x[i];
        if (same) {
            memcpy(out, dst + (size_t)ev[k] * D, (size_t)D * sizeof *out);
            return;
        }
    }
    const double *q0 = dst + (size_t)ev[0] * D;
    for (int i = 0; i < D; i++) {
        double s = q0[i];
        for (int k = 1; k <= D; k++)
            s += lam[k] * (dst[(size_t)ev[k] * D + i] - q0[i]);
        out[i] = s;
    }
}

/* ------------------------------------------------------------------ */
/* Points                                                              */

/* Maps one finite point; returns 1 inside, 0 outside, -1 when no element
 * holds a nearest point (cannot happen for finite x and a mesh with a
 * valid element). */
static int map_point(const sm_warp *w, sm_warp_direction dir, const double *x, int32_t *hint,
                     double *out)
{
    const int D = w->dim;
    const double *src = dir == SM_WARP_FORWARD ? w->tmpl->coords : w->deformed;
    const double *dst = dir == SM_WARP_FORWARD ? w->deformed : w->tmpl->coords;
    const sm_field *f = w->loc[dir];
    double lam[4];
    int32_t e = sm_field_locate(f, x, *hint, lam);
    int inside = e >= 0;
    if (!inside) {
        double near[3], dist;
        e = sm_field_nearest(f, x, near, &dist);
        if (e < 0 || !warp_bary(src, w->tmpl->elems + (size_t)e * (size_t)(D + 1), D, x, lam))
            return -1;
    }
    *hint = e;
    elem_apply(src, dst, w->tmpl->elems + (size_t)e * (size_t)(D + 1), D, x, lam, out);
    return inside;
}

sm_status sm_warp_points(const sm_warp *w, sm_warp_direction dir, int strict, int64_t n,
                         const double *in, double *out, uint8_t *inside, int64_t *noutside,
                         sm_error *err)
{
    if (noutside)
        *noutside = 0;
    if (dir != SM_WARP_FORWARD && dir != SM_WARP_INVERSE)
        return sm_error_set(err, SM_ERR_INVALID, "sm_warp_points: bad direction %d", (int)dir);
    if (!w->loc[dir])
        return sm_error_set(err, SM_ERR_INVALID, "sm_warp_points: the %s map was not prepared",
                            dir == SM_WARP_FORWARD ? "forward" : "inverse");
    if (n < 0 || (n > 0 && (!in || !out)))
        return sm_error_set(err, SM_ERR_INVALID, "sm_warp_points: bad arguments");
    const int D = w->dim;
    for (int64_t i = 0; i < n; i++)
        for (int k = 0; k < D; k++)
            if (!isfinite(in[(size_t)i * D + k]))
                return sm_error_set(err, SM_ERR_INVALID,
                                    "point %lld has a non-finite coordinate", (long long)i + 1);
    uint8_t *flags = inside ? inside : malloc((size_t)n + 1);
    int64_t *order = sm__morton_order(D, n, in); /* NULL: the input order, slower */
    if (!flags) {
        free(order);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for %lld points", (long long)n);
    }
    int64_t nout = 0, failed = INT64_MAX; /* the first point that could not be mapped */
#pragma omp parallel for schedule(dynamic, 1) reduction(+ : nout) reduction(min : failed)
    for (int64_t b = 0; b < (n + WARP_BLOCK - 1) / WARP_BLOCK; b++) {
        int64_t lo = b * WARP_BLOCK, hi = lo + WARP_BLOCK < n ? lo + WARP_BLOCK : n;
        int32_t hint = -1;
        for (int64_t j = lo; j < hi; j++) {
            int64_t i = order ? order[j] : j;
            int r = map_point(w, dir, in + (size_t)i * D, &hint, out + (size_t)i * D);
            flags[i] = r > 0;
            nout += r <= 0;
            if (r < 0 && i < failed)
                failed = i;
        }
    }
    free(order);
    sm_status st = SM_OK;
    const char *mesh = dir == SM_WARP_FORWARD ? "template" : "deformed mesh";
    if (failed != INT64_MAX) {
        st = sm_error_set(err, SM_ERR_NUMERIC, "point %lld: no element of the %s to map it by",
                          (long long)failed + 1, mesh);
    } else if (strict && nout > 0) {
        int64_t i = 0;
        while (flags[i])
            i++;
        double near[3], dist = 0.0;
        sm_field_nearest(w->loc[dir], in + (size_t)i * D, near, &dist);
        st = sm_error_set(err, SM_ERR_INVALID, "point %lld is outside the %s (distance %.6g)",
                          (long long)i + 1, mesh, dist);
    }
    if (noutside)
        *noutside = nout;
    if (!inside)
        free(flags);
    return st;
}

/* ------------------------------------------------------------------ */
/* Gradients and fields                                                */

sm_status sm_warp_vertex_gradients(const sm_warp *w, sm_warp_direction dir, double **out,
                                   sm_error *err)
{
    *out = NULL;
    const int D = w->dim, DD = D * D;
    const sm_mesh *m = w->tmpl;
    const double *src = dir == SM_WARP_FORWARD ? m->coords : w->deformed;
    const double *dst = dir == SM_WARP_FORWARD ? w->deformed : m->coords;
    double *g = calloc((size_t)m->nverts * (size_t)DD, sizeof *g);
    double *wsum = calloc((size_t)m->nverts, sizeof *wsum);
    if (!g || !wsum) {
        free(g);
        free(wsum);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the vertex gradients");
    }
    /* serial over the elements: the scatter to shared vertices costs
     * less than the synchronization would (O(elements), once) */
    for (int32_t e = 0; e < m->nelems; e++) {
        const int32_t *ev = m->elems + (size_t)e * (size_t)(D + 1);
        double cof[3][3];
        double det = elem_cofactors(src, ev, cof, D);
        if (!(det != 0.0) || !isfinite(det))
            continue;
        /* F_ij = sum_k (q_{k+1} - q_0)_i cof[k][j] / det */
        double F[9];
        const double *q0 = dst + (size_t)ev[0] * D;
        for (int i = 0; i < D; i++)
            for (int j = 0; j < D; j++) {
                double s = 0.0;
                for (int k = 0; k < D; k++)
                    s += (dst[(size_t)ev[k + 1] * D + i] - q0[i]) * cof[k][j];
                F[i * D + j] = s / det;
            }
        double vol = fabs(det); /* the volume up to the factor D!, common to all */
        for (int k = 0; k <= D; k++) {
            double *gv = g + (size_t)ev[k] * DD;
            for (int t = 0; t < DD; t++)
                gv[t] += vol * F[t];
            wsum[ev[k]] += vol;
        }
    }
    for (int32_t v = 0; v < m->nverts; v++) {
        double *gv = g + (size_t)v * DD;
        if (wsum[v] > 0.0) {
            for (int t = 0; t < DD; t++)
                gv[t] /= wsum[v];
        } else {
            for (int i = 0; i < D; i++)
                gv[i * D + i] = 1.0;
        }
    }
    free(wsum);
    *out = g;
    return SM_OK;
}

/* T -> G T G^T on a symmetric tensor in Medit's order (xx, xy, yy[, xz,
 * yz, zz]). */
static void push_tensor(const double *G, int D, double *t)
{
    static const int idx2[2][2] = {{0, 1}, {1, 2}};
    static const int idx3[3][3] = {{0, 1, 3}, {1, 2, 4}, {3, 4, 5}};
    double T[3][3], GT[3][3];
    for (int i = 0; i < D; i++)
        for (int j = 0; j < D; j++)
            T[i][j] = t[D == 2 ? idx2[i][j] : idx3[i][j]];
    for (int i = 0; i < D; i++)
        for (int j = 0; j < D; j++) {
            double s = 0.0;
            for (int k = 0; k < D; k++)
                s += G[i * D + k] * T[k][j];
            GT[i][j] = s;
        }
    for (int i = 0; i < D; i++)
        for (int j = i; j < D; j++) {
            double s = 0.0;
            for (int k = 0; k < D; k++)
                s += GT[i][k] * G[j * D + k];
            t[D == 2 ? idx2[i][j] : idx3[i][j]] = s;
        }
}

sm_status sm_warp_field(const sm_warp *w, sm_warp_direction dir, int ncomp, int normalize,
                        double *values, sm_error *err)
{
    const int D = w->dim;
    const int ntensor = D * (D + 1) / 2;
    if (dir != SM_WARP_FORWARD && dir != SM_WARP_INVERSE)
        return sm_error_set(err, SM_ERR_INVALID, "sm_warp_field: bad direction %d", (int)dir);
    if (ncomp == 1)
        return SM_OK; /* scalars: the same material point, the same value */
    if (ncomp != D && ncomp != ntensor)
        return sm_error_set(err, SM_ERR_INVALID,
                            "a field of %d components per vertex is neither a scalar, a %dD "
                            "vector nor a symmetric tensor (%d)",
                            ncomp, D, ntensor);
    double *G;
    sm_status st = sm_warp_vertex_gradients(w, dir, &G, err);
    if (st != SM_OK)
        return st;
    const int32_t nv = w->tmpl->nverts;
#pragma omp parallel for schedule(static)
    for (int32_t v = 0; v < nv; v++) {
        const double *Gv = G + (size_t)v * (size_t)(D * D);
        double *x = values + (size_t)v * (size_t)ncomp;
        if (ncomp != D) { /* 2D: ncomp 2 is a vector, 3 a tensor */
            push_tensor(Gv, D, x);
            continue;
        }
        double y[3], len = 0.0;
        for (int i = 0; i < D; i++) {
            double s = 0.0;
            for (int k = 0; k < D; k++)
                s += Gv[i * D + k] * x[k];
            y[i] = s;
            len += s * s;
        }
        len = sqrt(len);
        for (int i = 0; i < D; i++)
            x[i] = normalize && len > 0.0 ? y[i] / len : y[i];
    }
    free(G);
    return SM_OK;
}
