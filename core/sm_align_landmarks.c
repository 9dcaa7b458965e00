/* The alignment's transforms, landmark starts (Kabsch, Umeyama) and the
 * landmark CSV reader (see sm_align.h). */
#include "shapematch/sm_align.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sm_align_internal.h"

void sm_transform_identity(sm_transform *t, int dim)
{
    memset(t, 0, sizeof *t);
    t->dim = dim;
    for (int i = 0; i < 3; i++)
        t->a[i][i] = 1;
}

void sm_transform_apply(const sm_transform *t, int64_t n, const double *in, double *out)
{
    const int dim = t->dim;
    for (int64_t i = 0; i < n; i++) {
        double x[3] = {0, 0, 0}, y[3];
        for (int c = 0; c < dim; c++)
            x[c] = in[i * dim + c];
        for (int r = 0; r < dim; r++) {
            y[r] = t->b[r];
            for (int c = 0; c < dim; c++)
                y[r] += t->a[r][c] * x[c];
        }
        for (int c = 0; c < dim; c++)
            out[i * dim + c] = y[c];
    }
}

double sm_transform_scale(const sm_transform *t)
{
    double det = fabs(sm__det(t->dim, (const double(*)[3])t->a));
    return t->dim == 2 ? sqrt(det) : cbrt(det);
}

void sm_transform_homogeneous(const sm_transform *t, double *m)
{
    const int d = t->dim, w = d + 1;
    for (int r = 0; r < w; r++)
        for (int c = 0; c < w; c++)
            m[r * w + c] = r == d ? (c == d ? 1 : 0) : c == d ? t->b[r] : t->a[r][c];
}

/* Centroid and the affine rank of n points (0: one point, 1: on a line,
 * 2: in a plane, 3), from their covariance's eigenvalues against the
 * largest. */
static int point_rank(int dim, int32_t n, const double *p, double centroid[3], double *var)
{
    double cov[3][3] = {{0}}, val[3], vec[3][3];
    for (int c = 0; c < 3; c++)
        centroid[c] = 0;
    for (int32_t i = 0; i < n; i++)
        for (int c = 0; c < dim; c++)
            centroid[c] += p[(size_t)i * dim + c] / n;
    for (int32_t i = 0; i < n; i++)
        for (int r = 0; r < dim; r++)
            for (int c = 0; c < dim; c++)
                cov[r][c] += (p[(size_t)i * dim + r] - centroid[r]) *
                             (p[(size_t)i * dim + c] - centroid[c]) / n;
    sm__sym_eigen(dim, (const double(*)[3])cov, val, vec);
    *var = 0;
    for (int c = 0; c < dim; c++)
        *var += val[c];
    int rank = 0;
    for (int c = 0; c < dim; c++)
        rank += val[c] > 1e-10 * val[0] && val[c] > 0; /* above rounding (~1e-16 val[0]) by far */
    return rank;
}

static sm_status check_points(int dim, int32_t n, const double *p, const char *which,
                              double centroid[3], double *var, sm_error *err)
{
    for (size_t i = 0; i < (size_t)n * dim; i++)
        if (!isfinite(p[i]))
            return sm_error_set(err, SM_ERR_INVALID,
                                "landmarks: %s point %zu has a non-finite coordinate", which,
                                i / dim + 1);
    int rank = point_rank(dim, n, p, centroid, var);
    if (rank < dim - 1)
        return sm_error_set(err, SM_ERR_INVALID,
                            "landmarks: the %s points are %s: they do not fix a rotation", which,
                            dim == 3 ? "collinear" : "all at one place");
    return SM_OK;
}

sm_status sm_align_landmarks(int dim, int32_t n, const double *src, const double *dst,
                             sm_align_mode mode, sm_transform *out, sm_error *err)
{
    if (dim != 2 && dim != 3)
        return sm_error_set(err, SM_ERR_INVALID, "landmarks: dimension %d (must be 2 or 3)", dim);
    if (mode == SM_ALIGN_NONE || !sm_align_mode_name(mode))
        return sm_error_set(err, SM_ERR_INVALID,
                            "landmarks need an alignment: give --align rigid, similarity or "
                            "affine");
    if (n < dim)
        return sm_error_set(err, SM_ERR_INVALID,
                            "landmarks: %ld pair(s); a %dD alignment needs at least %d", (long)n,
                            dim, dim);
    double cs[3], cd[3], var_s, var_d;
    sm_status st = check_points(dim, n, src, "template", cs, &var_s, err);
    if (st == SM_OK)
        st = check_points(dim, n, dst, "target", cd, &var_d, err);
    if (st != SM_OK)
        return st;
    /* cross-covariance H = sum (dst - cd)(src - cs)^T / n; the rotation
     * maximizing tr(R^T H) is U D V^T with D fixing det R = +1 (Kabsch;
     * Umeyama 1991 for the scale) */
    double h[3][3] = {{0}}, u[3][3], s[3], v[3][3];
    for (int32_t i = 0; i < n; i++)
        for (int r = 0; r < dim; r++)
            for (int c = 0; c < dim; c++)
                h[r][c] += (dst[(size_t)i * dim + r] - cd[r]) * (src[(size_t)i * dim + c] - cs[c]) / n;
    sm__svd(dim, (const double(*)[3])h, u, s, v);
    double sign = sm__det(dim, (const double(*)[3])u) * sm__det(dim, (const double(*)[3])v) < 0
                      ? -1
                      : 1;
    double dgn[3] = {1, 1, 1};
    dgn[dim - 1] = sign;
    double rot[3][3] = {{0}};
    for (int r = 0; r < dim; r++)
        for (int c = 0; c < dim; c++)
            for (int k = 0; k < dim; k++)
                rot[r][c] += u[r][k] * dgn[k] * v[c][k];
    double scale = 1;
    if (mode != SM_ALIGN_RIGID) {
        /* tr(R^T H) / var: summed from H itself, not from the singular
         * values (a zero one comes out of the squares as ~1e-8) */
        double tr = 0;
        for (int r = 0; r < dim; r++)
            for (int c = 0; c < dim; c++)
                tr += rot[r][c] * h[r][c];
        scale = tr / var_s;
        if (!(scale > 0) || !isfinite(scale))
            return sm_error_set(err, SM_ERR_INVALID,
                                "landmarks: the pairs give no positive scale (are the target's "
                                "mirrored?)");
    }
    sm_transform_identity(out, dim);
    for (int r = 0; r < dim; r++)
        for (int c = 0; c < dim; c++)
            out->a[r][c] = scale * rot[r][c];
    for (int r = 0; r < dim; r++) {
        out->b[r] = cd[r];
        for (int c = 0; c < dim; c++)
            out->b[r] -= out->a[r][c] * cs[c];
    }
    return SM_OK;
}
