/* Pre-alignment of the template onto the target: the moments' start with
 * its signed-permutation candidates, then Levenberg-Marquardt on the
 * robust two-sided misfit (see sm_align.h). */
#include "shapematch/sm_align.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "shapematch/sm_clock.h"
#include "sm_align_internal.h"
#include "sm_bvh.h"

/* Points of each side for screening and refining the candidates (every
 * k-th quadrature point, so that a start costs the same for any
 * template), and at most this many on the final passes: enough to
 * average a sampled field's interpolation error, and an exact surface
 * is matched to rounding by any sample. */
#define SCREEN_POINTS 500
#define FULL_POINTS 2000
/* Candidates (by screening cost) refined before the best is kept: the
 * true one is among the first few whenever the axes are distinct, and
 * near-symmetric shapes are nearly as good from any of them. */
#define CANDIDATES_REFINED 3
/* Iterations on the full sample, from the coarse level's answer: an
 * exact fit converges in a few (Gauss-Newton on zero residuals), an
 * inexact one only polishes. */
#define FULL_ITER 8
#define CANDIDATE_ITER 20
#define DEFAULT_MAX_ITER 100
/* Huber's threshold in units of the residuals' robust spread, and its
 * floor as a fraction of the target's size (a perfect fit's residuals
 * are the field's interpolation error, not noise to normalise by). */
#define HUBER_K 1.345
#define HUBER_FLOOR 1e-4
/* An increment is refused (and the damping raised) beyond these:
 * linearisation is meaningless for larger rotations or scalings. */
#define MAX_ROTATION_STEP 0.5
#define MAX_LOG_SCALE_STEP 0.5
/* A step that moves the points by less than this (times the target's
 * size) ends a refinement: on a sampled field the map is then known to
 * ~1e-7, far below the field's own accuracy; on an exact surface, whose
 * residuals vanish at the answer, to ~1e-10. */
#define STEP_TOL_FIELD 1e-7
#define STEP_TOL_EXACT 1e-10
/* ... or one that lowers the misfit by less than this fraction (a
 * sampled field's noise floor; an exact fit's misfit falls by orders of
 * magnitude a step until the step test ends it). */
#define COST_TOL 1e-6
/* Loops over fewer points stay on one thread, like the descent's below
 * 100k elements (docs/performance.md): on a loaded machine a fork and
 * join waits for a descheduled thread. */
#define PARALLEL_MIN 100000

typedef enum stage { STAGE_RIGID, STAGE_SIMILARITY, STAGE_AFFINE } stage;

/* The two sides at one sampling: the template's boundary points (moved
 * onto the target, residual the target's signed distance there) and the
 * target's surface points (residual their signed distance to the moved
 * template's boundary). */
typedef struct level {
    sm__align_pts tpl, tgt;
    int cloud; /* the coarse level: both sides as point samples with
                * their normals, nearest neighbours by brute force */
} level;

typedef struct ctx {
    int dim;
    const sm_field *field;      /* the target's sampled distance, or */
    const sm_sdf *sdf;          /* its exact one */
    const sm_surface *surface;  /* sdf's facets */
    sm_surface *tsurf;          /* the template's boundary as a surface */
    sm_sdf *tsdf;               /* its hierarchy: the target side's nearest points */
    double length;              /* the target's size (floors, step tests) */
    const volatile int *cancel; /* sm_align_opts' */
    double *scratch;            /* |r| for the medians */
    int nomem;                  /* a distance query ran out of memory */
} ctx;

/* The caller asked to stop (polled before each pass over the points). */
static int cancelled(const ctx *c)
{
    return c->cancel && *c->cancel;
}

static void level_free(level *lv)
{
    sm__align_pts_free(&lv->tpl);
    sm__align_pts_free(&lv->tgt);
}

/* A new start: the hints of the last one are no help. */
static void reset_hints(level *lv)
{
    for (int64_t i = 0; i < lv->tpl.n; i++)
        lv->tpl.hints[i] = -1;
    for (int64_t i = 0; i < lv->tgt.n; i++)
        lv->tgt.nearest[i] = -1;
}

static int compare_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double huber(double r, double k)
{
    double a = fabs(r);
    return a <= k ? 0.5 * r * r : k * (a - 0.5 * k);
}

/* Huber's threshold from a side's median absolute residual. */
static double huber_threshold(const ctx *c, const sm__align_pts *p)
{
    for (int64_t i = 0; i < p->n; i++)
        c->scratch[i] = fabs(p->r[i]);
    qsort(c->scratch, (size_t)p->n, sizeof *c->scratch, compare_double);
    double med = p->n ? c->scratch[p->n / 2] : 0;
    return fmax(HUBER_K * 1.4826 * med, HUBER_FLOOR * c->length);
}

static void normalize(int dim, double *v)
{
    double n = 0;
    for (int k = 0; k < dim; k++)
        n += v[k] * v[k];
    n = sqrt(n);
    for (int k = 0; n > 0 && k < dim; k++)
        v[k] /= n;
}

/* The closest point q of facet f of s to x, and the facet's unit outward
 * normal. */
static void facet_closest(const sm_surface *s, int32_t f, const double *x, double *q,
                          double *normal)
{
    const int dim = s->dim;
    const int32_t *v = s->facets + (size_t)f * dim;
    const double *a = s->coords + (size_t)v[0] * dim, *b = s->coords + (size_t)v[1] * dim;
    if (dim == 2)
        sm__closest_on_segment(x, a, b, q);
    else
        sm__closest_on_triangle(x, a, b, s->coords + (size_t)v[2] * dim, q);
    double centre[3];
    sm__bvh_facet_moments(s, f, normal, centre);
    normalize(dim, normal);
}

/* The direction of a signed distance r at x whose closest surface point
 * is q: (x - q) / |x - q| times r's sign, the facet's normal n when x is
 * on the surface (a zero residual has no direction of its own). */
static void direction(int dim, const double *x, const double *q, const double *n, double r,
                      double tiny, double *g)
{
    double e[3] = {0, 0, 0}, len = 0;
    for (int k = 0; k < dim; k++) {
        e[k] = x[k] - q[k];
        len += e[k] * e[k];
    }
    len = sqrt(len);
    for (int k = 0; k < dim; k++)
        g[k] = len > tiny ? (r < 0 ? -e[k] : e[k]) / len : n[k];
}

/* ---------------------------------------------------------- the misfit */

/* The template side at t: y = t(x), r = d(y) and, with grad, its
 * gradient (the field's, or the exact distance's direction). */
static void eval_template(ctx *c, sm__align_pts *p, const sm_transform *t, int grad)
{
    const int dim = c->dim;
    sm_transform_apply(t, p->n, p->x, p->y);
    if (c->field) {
#pragma omp parallel for schedule(static) if (p->n > PARALLEL_MIN)
        for (int64_t i = 0; i < p->n; i++) {
            if (grad) {
                p->r[i] = sm_field_eval_grad(c->field, p->y + i * dim, &p->hints[i], p->g + i * dim);
            } else {
                int32_t hint = p->hints[i];
                p->r[i] = sm_field_eval(c->field, p->y + i * dim, &hint);
            }
        }
        return;
    }
    sm_error err;
    if (sm__sdf_signed_nearest(c->sdf, p->n, p->y, p->r, p->nearest, &err) != SM_OK) {
        c->nomem = 1;
        for (int64_t i = 0; i < p->n; i++)
            p->r[i] = NAN;
        return;
    }
    for (int64_t i = 0; grad && i < p->n; i++) {
        double q[3], n[3];
        facet_closest(c->surface, p->nearest[i], p->y + i * dim, q, n);
        direction(dim, p->y + i * dim, q, n, p->r[i], 1e-12 * c->length, p->g + i * dim);
    }
}

/* The inverse of t (det a > 0 for every transform the alignment makes). */
static void invert(const sm_transform *t, sm_transform *inv)
{
    const int dim = t->dim;
    double a[3][3] = {{0}}, det = sm__det(dim, (const double(*)[3])t->a);
    sm_transform_identity(inv, dim);
    if (dim == 2) {
        a[0][0] = t->a[1][1] / det, a[0][1] = -t->a[0][1] / det;
        a[1][0] = -t->a[1][0] / det, a[1][1] = t->a[0][0] / det;
    } else {
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++) {
                int i1 = (j + 1) % 3, i2 = (j + 2) % 3, j1 = (i + 1) % 3, j2 = (i + 2) % 3;
                a[i][j] = (t->a[i1][j1] * t->a[i2][j2] - t->a[i1][j2] * t->a[i2][j1]) / det;
            }
    }
    for (int i = 0; i < dim; i++) {
        inv->b[i] = 0;
        for (int j = 0; j < dim; j++) {
            inv->a[i][j] = a[i][j];
            inv->b[i] -= a[i][j] * t->b[j];
        }
    }
}

/* The target side at t: each target point z pulled back (u = t^-1 z),
 * its closest point x on the template's boundary, y = t(x) that point
 * moved, and r = +-|z - y| (negative inside the moved template: the
 * signed distance of z to it, exact for rigid and similarity maps),
 * g its direction. */
static void eval_target(ctx *c, sm__align_pts *p, const sm_transform *t)
{
    const int dim = c->dim;
    sm_transform inv;
    invert(t, &inv);
    sm_transform_apply(&inv, p->n, p->x, p->u);
    sm__sdf_nearest_hinted(c->tsdf, p->n, p->u, p->r, p->nearest);
    for (int64_t i = 0; i < p->n; i++) {
        double q[3], n[3], side = 0, m[3] = {0, 0, 0};
        const double *u = p->u + i * dim;
        if (p->nearest[i] < 0 || !isfinite(p->r[i])) {
            c->nomem = 1;
            p->r[i] = NAN;
            continue;
        }
        facet_closest(c->tsurf, p->nearest[i], u, q, n);
        for (int k = 0; k < dim; k++)
            side += n[k] * (u[k] - q[k]);
        sm_transform_apply(t, 1, q, p->y + i * dim);
        double e2 = 0;
        for (int k = 0; k < dim; k++) {
            double e = p->x[i * dim + k] - p->y[i * dim + k];
            e2 += e * e;
        }
        p->r[i] = side < 0 ? -sqrt(e2) : sqrt(e2);
        /* the moved facet's normal: a^-T n */
        for (int k = 0; k < dim; k++)
            for (int j = 0; j < dim; j++)
                m[k] += inv.a[j][k] * n[j];
        normalize(dim, m);
        direction(dim, p->x + i * dim, p->y + i * dim, m, p->r[i], 1e-12 * c->length,
                  p->g + i * dim);
    }
}

/* The index of the point of pts (n of them) nearest to x. */
static int64_t nearest_point(int dim, const double *pts, int64_t n, const double *x)
{
    int64_t best = 0;
    double best2 = INFINITY;
    for (int64_t j = 0; j < n; j++) {
        double d2 = 0;
        for (int k = 0; k < dim; k++)
            d2 += (pts[j * dim + k] - x[k]) * (pts[j * dim + k] - x[k]);
        if (d2 < best2)
            best2 = d2, best = j;
    }
    return best;
}

/* The coarse level at t: symmetric point-to-plane residuals between the
 * two samples, each point against its nearest neighbour on the other
 * side and that one's normal (the target's as given, the template's
 * moved: a^-T n).  Cheap at any distance, where an exact nearest-facet
 * search from a far start visits most of a surface: the candidates are
 * screened and refined here, the exact residuals take over near the
 * answer. */
static void eval_cloud(ctx *c, level *lv, const sm_transform *t)
{
    const int dim = c->dim;
    sm__align_pts *p = &lv->tpl, *q = &lv->tgt;
    sm_transform inv;
    invert(t, &inv);
    sm_transform_apply(t, p->n, p->x, p->y);
    for (int64_t i = 0; i < p->n; i++) { /* moved normals, into u */
        double *m = p->u + i * dim;
        for (int k = 0; k < dim; k++) {
            m[k] = 0;
            for (int j = 0; j < dim; j++)
                m[k] += inv.a[j][k] * p->nrm[i * dim + j];
        }
        normalize(dim, m);
    }
#pragma omp parallel for schedule(static) if (p->n * q->n > (int64_t)100 * PARALLEL_MIN)
    for (int64_t i = 0; i < p->n; i++) {
        int64_t j = nearest_point(dim, q->x, q->n, p->y + i * dim);
        double r = 0;
        for (int k = 0; k < dim; k++) {
            p->g[i * dim + k] = q->nrm[j * dim + k];
            r += q->nrm[j * dim + k] * (p->y[i * dim + k] - q->x[j * dim + k]);
        }
        p->r[i] = r;
    }
    for (int64_t j = 0; j < q->n; j++) {
        int64_t i = nearest_point(dim, p->y, p->n, q->x + j * dim);
        double r = 0;
        for (int k = 0; k < dim; k++) {
            q->y[j * dim + k] = p->y[i * dim + k];
            q->g[j * dim + k] = p->u[i * dim + k];
            r += p->u[i * dim + k] * (q->x[j * dim + k] - p->y[i * dim + k]);
        }
        q->r[j] = r;
    }
}

/* Both sides at t (the template side's gradients only with grad: the
 * cost alone needs none). */
static void eval_level(ctx *c, level *lv, const sm_transform *t, int grad)
{
    if (lv->cloud) {
        eval_cloud(c, lv, t);
        return;
    }
    eval_template(c, &lv->tpl, t, grad);
    eval_target(c, &lv->tgt, t);
}

/* sum w rho(r) / sum w over a side (rho Huber's with threshold k, or
 * r^2 for k infinite); infinite for a failed query. */
static double side_cost(const sm__align_pts *p, double k)
{
    if (!(p->wsum > 0))
        return 0;
    double sum = 0;
    for (int64_t i = 0; i < p->n; i++)
        sum += p->w[i] * (isinf(k) ? p->r[i] * p->r[i] : huber(p->r[i], k));
    return isfinite(sum) ? sum / p->wsum : INFINITY;
}

/* The two-sided mean square at t: the template's boundary to the
 * target, plus the target's surface to the moved template. */
static double mean_square(ctx *c, level *lv, const sm_transform *t)
{
    eval_level(c, lv, t, 0);
    return side_cost(&lv->tpl, INFINITY) + side_cost(&lv->tgt, INFINITY);
}

/* ------------------------------------------------------ the refinement */

static int stage_params(int dim, stage s)
{
    if (s == STAGE_AFFINE)
        return dim + dim * dim;
    return dim + (dim == 3 ? 3 : 1) + (s == STAGE_SIMILARITY);
}

/* d r / d params at a point moved to c + v with gradient g: translation,
 * then rotation (v x g; 2D: the perpendicular), then log-scale (g.v);
 * affine: translation, then g_j v_k. */
static void jacobian_row(int dim, stage s, const double *v, const double *g, double *row)
{
    int k = 0;
    for (int c = 0; c < dim; c++)
        row[k++] = g[c];
    if (s == STAGE_AFFINE) {
        for (int j = 0; j < dim; j++)
            for (int c = 0; c < dim; c++)
                row[k++] = g[j] * v[c];
        return;
    }
    if (dim == 2) {
        row[k++] = -g[0] * v[1] + g[1] * v[0];
    } else {
        row[k++] = v[1] * g[2] - v[2] * g[1];
        row[k++] = v[2] * g[0] - v[0] * g[2];
        row[k++] = v[0] * g[1] - v[1] * g[0];
    }
    if (s == STAGE_SIMILARITY)
        row[k++] = g[0] * v[0] + g[1] * v[1] + (dim == 3 ? g[2] * v[2] : 0);
}

/* The increment delta as y -> c + m (y - c) + delta_t, into t; -1 when
 * it is too large to trust or leaves an unusable matrix. */
static int apply_increment(int dim, stage s, const double *delta, const double c[3],
                           const sm_transform *from, sm_transform *to)
{
    double m[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    if (s == STAGE_AFFINE) {
        for (int j = 0; j < dim; j++)
            for (int k = 0; k < dim; k++)
                m[j][k] += delta[dim + j * dim + k];
    } else {
        double w[3] = {0, 0, 0}, theta;
        if (dim == 2) {
            theta = fabs(delta[2]);
            double cs = cos(delta[2]), sn = sin(delta[2]);
            m[0][0] = cs, m[0][1] = -sn, m[1][0] = sn, m[1][1] = cs;
        } else {
            for (int i = 0; i < 3; i++)
                w[i] = delta[3 + i];
            theta = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
            if (theta > 0) { /* Rodrigues */
                double kx = w[0] / theta, ky = w[1] / theta, kz = w[2] / theta;
                double K[3][3] = {{0, -kz, ky}, {kz, 0, -kx}, {-ky, kx, 0}};
                double sn = sin(theta), cs1 = 1 - cos(theta);
                for (int i = 0; i < 3; i++)
                    for (int j = 0; j < 3; j++) {
                        double k2 = 0;
                        for (int l = 0; l < 3; l++)
                            k2 += K[i][l] * K[l][j];
                        m[i][j] += sn * K[i][j] + cs1 * k2;
                    }
            }
        }
        if (theta > MAX_ROTATION_STEP)
            return -1;
        if (s == STAGE_SIMILARITY) {
            double ls = delta[stage_params(dim, s) - 1];
            if (fabs(ls) > MAX_LOG_SCALE_STEP)
                return -1;
            for (int i = 0; i < dim; i++)
                for (int j = 0; j < dim; j++)
                    m[i][j] *= exp(ls);
        }
    }
    sm_transform_identity(to, dim);
    for (int i = 0; i < dim; i++) {
        to->b[i] = c[i] + delta[i];
        for (int j = 0; j < dim; j++) {
            double a = 0;
            for (int k = 0; k < dim; k++)
                a += m[i][k] * from->a[k][j];
            to->a[i][j] = a;
            to->b[i] += m[i][j] * (from->b[j] - c[j]);
        }
    }
    if (s == STAGE_AFFINE) {
        double u[3][3], sv[3], v[3][3];
        sm__svd(dim, (const double(*)[3])to->a, u, sv, v);
        if (!(sm__det(dim, (const double(*)[3])to->a) > 0) ||
            !(sv[0] <= SM_ALIGN_AFFINE_COND_MAX * sv[dim - 1]))
            return -1;
    }
    return 0;
}

/* How far an increment moves the points at most, about: the
 * translation plus the matrix change times the points' radius. */
static double increment_size(int dim, stage s, const double *delta, double radius)
{
    double t = 0, m = 0;
    for (int c = 0; c < dim; c++)
        t += delta[c] * delta[c];
    for (int k = dim; k < stage_params(dim, s); k++)
        m += delta[k] * delta[k];
    return sqrt(t) + sqrt(m) * radius;
}

/* Adds a side's rows to the normal equations (sgn: +1 when the residual
 * grows as its points move along g, the template side; -1 when it
 * shrinks, the target side), with the IRLS weights of Huber's rho;
 * returns the side's cost. */
static double accumulate(const sm__align_pts *p, int sgn, stage s, double k, const double cc[3],
                         double *jtj, double *jtr, double *radius)
{
    if (!(p->wsum > 0))
        return 0;
    const int dim = p->dim, np = stage_params(dim, s);
    double cost = 0, row[12];
    for (int64_t i = 0; i < p->n; i++) {
        double v[3] = {0, 0, 0}, r = p->r[i], v2 = 0, w = p->w[i] / p->wsum;
        for (int j = 0; j < dim; j++) {
            v[j] = p->y[i * dim + j] - cc[j];
            v2 += v[j] * v[j];
        }
        *radius = fmax(*radius, v2);
        jacobian_row(dim, s, v, p->g + i * dim, row);
        /* IRLS weight of Huber's rho: psi(r)/r */
        double wr = w * (fabs(r) <= k ? 1 : k / fabs(r));
        cost += w * huber(r, k);
        for (int a = 0; a < np; a++) {
            jtr[a] += wr * sgn * row[a] * r;
            for (int b = 0; b <= a; b++)
                jtj[a * np + b] += wr * row[a] * row[b];
        }
    }
    return cost;
}

/* The Huber cost of t with the thresholds k (values only). */
static double huber_cost(ctx *c, level *lv, const sm_transform *t, const double k[2])
{
    eval_level(c, lv, t, 0);
    return side_cost(&lv->tpl, k[0]) + side_cost(&lv->tgt, k[1]);
}

/* Levenberg-Marquardt on the two-sided Huber misfit; t updated in place.
 * Stops at the step and cost tests above, when no damping gives a
 * decrease, or after max_iter.
 * Returns the iterations taken. */
static int refine(ctx *c, level *lv, stage s, int max_iter, sm_transform *t)
{
    const int dim = c->dim, np = stage_params(dim, s);
    double lambda = 1e-3;
    int it;
    for (it = 0; it < max_iter && !cancelled(c); it++) {
        eval_level(c, lv, t, 1);
        /* the increments' pivot: the moved template's centre */
        double cc[3] = {0, 0, 0};
        for (int64_t i = 0; i < lv->tpl.n; i++)
            for (int k = 0; k < dim; k++)
                cc[k] += lv->tpl.w[i] * lv->tpl.y[i * dim + k] / lv->tpl.wsum;
        double k[2] = {huber_threshold(c, &lv->tpl), huber_threshold(c, &lv->tgt)};
        double jtj[144] = {0}, jtr[12] = {0}, radius = 0;
        double cost = accumulate(&lv->tpl, 1, s, k[0], cc, jtj, jtr, &radius);
        double ignored = 0;
        cost += accumulate(&lv->tgt, -1, s, k[1], cc, jtj, jtr, &ignored);
        if (!isfinite(cost))
            return it;
        for (int a = 0; a < np; a++)
            for (int b = a + 1; b < np; b++)
                jtj[a * np + b] = jtj[b * np + a];
        radius = sqrt(radius);
        int accepted = 0;
        double new_cost = cost, moved = 0;
        for (int trial = 0; trial < 12 && !accepted && !cancelled(c); trial++) {
            double m[144], rhs[12], delta[12];
            memcpy(m, jtj, sizeof m);
            for (int a = 0; a < np; a++) {
                m[a * np + a] += lambda * fmax(jtj[a * np + a], 1e-300);
                rhs[a] = -jtr[a];
            }
            sm_transform next;
            if (sm__solve_dense(np, m, rhs, delta) == 0 &&
                apply_increment(dim, s, delta, cc, t, &next) == 0) {
                new_cost = huber_cost(c, lv, &next, k);
                if (new_cost < cost) {
                    *t = next;
                    moved = increment_size(dim, s, delta, radius);
                    accepted = 1;
                    lambda = fmax(lambda / 3, 1e-9);
                    break;
                }
            }
            lambda *= 4;
        }
        double tol = c->sdf ? STEP_TOL_EXACT : STEP_TOL_FIELD;
        if (!accepted || moved <= tol * c->length || cost - new_cost <= COST_TOL * cost)
            return it + accepted;
    }
    return it;
}

/* ----------------------------------------------------- the candidates */

typedef struct candidate {
    sm_transform t;
    double cost;
} candidate;

static int by_cost(const void *a, const void *b)
{
    return compare_double(&((const candidate *)a)->cost, &((const candidate *)b)->cost);
}

/* The signed permutations q of the principal axes that make
 * r = Rg q Rt^T a rotation, each as s r with the centroids matched. */
static int moment_candidates(int dim, const sm__moments *mt, const sm__moments *mg, double scale,
                             candidate *out)
{
    double vt[3], rt[3][3], vg[3], rg[3][3];
    sm__sym_eigen(dim, (const double(*)[3])mt->cov, vt, rt);
    sm__sym_eigen(dim, (const double(*)[3])mg->cov, vg, rg);
    static const int perms3[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
    static const int perms2[2][3] = {{0, 1, 2}, {1, 0, 2}};
    const int nperm = dim == 3 ? 6 : 2;
    int n = 0;
    for (int p = 0; p < nperm; p++)
        for (int signs = 0; signs < (1 << dim); signs++) {
            const int *perm = dim == 3 ? perms3[p] : perms2[p];
            double qm[3][3] = {{0}};
            for (int i = 0; i < dim; i++)
                qm[i][perm[i]] = (signs >> i) & 1 ? -1 : 1;
            double r[3][3] = {{0}};
            for (int i = 0; i < dim; i++)
                for (int j = 0; j < dim; j++)
                    for (int k = 0; k < dim; k++)
                        for (int l = 0; l < dim; l++)
                            r[i][j] += rg[i][k] * qm[k][l] * rt[j][l];
            if (sm__det(dim, (const double(*)[3])r) < 0)
                continue;
            sm_transform *t = &out[n++].t;
            sm_transform_identity(t, dim);
            for (int i = 0; i < dim; i++) {
                t->b[i] = mg->centroid[i];
                for (int j = 0; j < dim; j++) {
                    t->a[i][j] = scale * r[i][j];
                    t->b[i] -= scale * r[i][j] * mt->centroid[j];
                }
            }
        }
    return n;
}

/* The target's volume moments: of the volume its surface encloses, or of
 * the region d < 0 of its sampled distance. */
static sm_status target_moments(const sm_align_opts *o, sm__moments *mg, sm_error *err)
{
    if (o->surface) {
        if (sm__align_surface_moments(sm__sdf_surface(o->surface), mg) != 0)
            return sm_error_set(err, SM_ERR_INVALID,
                                "alignment: the target surface encloses no volume, nothing to "
                                "align onto");
        return SM_OK;
    }
    if (sm__align_mesh_moments(o->background, o->distance, mg) != 0)
        return sm_error_set(err, SM_ERR_INVALID,
                            "alignment: the target has no inside (d >= 0 at every vertex of the "
                            "background), nothing to align onto");
    return SM_OK;
}

/* The moments' start: the best of the refined candidates. */
static sm_status moment_start(const sm_align_opts *o, ctx *c, level *screen, stage s,
                              sm_transform *best, int *ncand, int *iters, sm_error *err)
{
    const int dim = o->template_mesh->dim;
    sm__moments mt, mg;
    if (sm__align_mesh_moments(o->template_mesh, NULL, &mt) != 0)
        return sm_error_set(err, SM_ERR_INVALID, "alignment: the template has no volume");
    sm_status st = target_moments(o, &mg, err);
    if (st != SM_OK)
        return st;
    double scale = s == STAGE_RIGID ? 1 : pow(mg.volume / mt.volume, 1.0 / dim);
    double trace = 0;
    for (int k = 0; k < dim; k++)
        trace += mg.cov[k][k];
    c->length = sqrt(fmax(trace, 0)) > 0 ? sqrt(trace) : 1;
    candidate cand[24];
    int n = moment_candidates(dim, &mt, &mg, scale, cand);
    for (int i = 0; i < n; i++) {
        reset_hints(screen);
        cand[i].cost = cancelled(c) ? 0 : mean_square(c, screen, &cand[i].t);
    }
    qsort(cand, (size_t)n, sizeof *cand, by_cost);
    int keep = n < CANDIDATES_REFINED ? n : CANDIDATES_REFINED;
    for (int i = 0; i < keep && !cancelled(c); i++) {
        reset_hints(screen);
        *iters += refine(c, screen, s, CANDIDATE_ITER, &cand[i].t);
        cand[i].cost = mean_square(c, screen, &cand[i].t);
    }
    qsort(cand, (size_t)keep, sizeof *cand, by_cost);
    *best = cand[0].t;
    *ncand = n;
    return SM_OK;
}

/* The template's boundary as a surface (its coordinates and outward
 * facets) and its hierarchy. */
static sm_status template_surface(const sm_mesh *m, ctx *c, sm_error *err)
{
    sm_status st = sm_surface_alloc(&c->tsurf, m->dim, m->nverts, m->nbfacets, err);
    if (st != SM_OK)
        return st;
    memcpy(c->tsurf->coords, m->coords, (size_t)m->nverts * m->dim * sizeof *m->coords);
    memcpy(c->tsurf->facets, m->bfacets, (size_t)m->nbfacets * m->dim * sizeof *m->bfacets);
    return sm_sdf_new(c->tsurf, &c->tsdf, err);
}

/* Both sides' points: every sampled (at most FULL_POINTS each) and the
 * screening sample (SCREEN_POINTS each). */
static sm_status build_levels(const sm_align_opts *o, level *full, level *screen, sm_error *err)
{
    sm__align_pts all;
    sm_status st = sm__align_mesh_boundary_pts(o->template_mesh, &all, err);
    if (st != SM_OK)
        return st;
    st = sm__align_pts_sample(&all, FULL_POINTS, &full->tpl, err);
    if (st == SM_OK)
        st = sm__align_pts_sample(&all, SCREEN_POINTS, &screen->tpl, err);
    sm__align_pts_free(&all);
    if (st != SM_OK)
        return st;
    st = o->surface ? sm__align_surface_pts(sm__sdf_surface(o->surface), &all, err)
                    : sm__align_level_set_pts(o->background, o->distance, &all, err);
    if (st != SM_OK)
        return st;
    st = sm__align_pts_sample(&all, FULL_POINTS, &full->tgt, err);
    if (st == SM_OK)
        st = sm__align_pts_sample(&all, SCREEN_POINTS, &screen->tgt, err);
    sm__align_pts_free(&all);
    screen->cloud = 1;
    return st;
}

static sm_status check_opts(const sm_align_opts *o, sm_error *err)
{
    const sm_mesh *m = o->template_mesh;
    if (!sm_align_mode_name(o->mode) || o->mode == SM_ALIGN_NONE)
        return sm_error_set(err, SM_ERR_INVALID, "alignment: mode %d is not an alignment",
                            (int)o->mode);
    int field_ok = o->target && o->background && o->distance &&
                   (m && sm_field_dim(o->target) == m->dim && o->background->dim == m->dim);
    int surface_ok = o->surface && m && sm__sdf_surface(o->surface)->dim == m->dim;
    if (!m || m->nbfacets <= 0 || (!field_ok && !surface_ok))
        return sm_error_set(err, SM_ERR_INVALID,
                            "alignment: needs a template with its boundary and a target field or "
                            "surface of the same dimension");
    if (o->start && o->start->dim != m->dim)
        return sm_error_set(err, SM_ERR_INVALID, "alignment: the start is %dD, the template %dD",
                            o->start->dim, m->dim);
    return SM_OK;
}

/* The stages after the start: each on the screening sample to
 * convergence, then on the full one from there (a few iterations: the
 * sample's optimum is close). */
static int refine_stages(const sm_align_opts *o, ctx *c, level *full, level *screen, stage s,
                         sm_transform *t)
{
    int max_iter = o->max_iter > 0 ? o->max_iter : DEFAULT_MAX_ITER, iters = 0;
    reset_hints(screen);
    reset_hints(full);
    iters += refine(c, screen, s, max_iter, t);
    iters += refine(c, full, s, max_iter < FULL_ITER ? max_iter : FULL_ITER, t);
    if (o->mode == SM_ALIGN_AFFINE) {
        iters += refine(c, screen, STAGE_AFFINE, max_iter, t);
        iters += refine(c, full, STAGE_AFFINE, max_iter < FULL_ITER ? max_iter : FULL_ITER, t);
    }
    return iters;
}

sm_status sm_align_run(const sm_align_opts *o, sm_align_result *out, sm_error *err)
{
    double t0 = sm_clock_seconds();
    memset(out, 0, sizeof *out);
    sm_status st = check_opts(o, err);
    if (st != SM_OK)
        return st;
    const sm_mesh *m = o->template_mesh;
    const int dim = m->dim;
    ctx c = {.dim = dim, .cancel = o->cancel};
    if (o->surface) {
        c.sdf = o->surface;
        c.surface = sm__sdf_surface(o->surface);
    } else {
        c.field = o->target;
    }
    level full = {0}, screen = {0};
    if ((st = build_levels(o, &full, &screen, err)) != SM_OK ||
        (st = template_surface(m, &c, err)) != SM_OK)
        goto done;
    int64_t most = full.tpl.n > full.tgt.n ? full.tpl.n : full.tgt.n;
    if (!(c.scratch = malloc(((size_t)most + 1) * sizeof *c.scratch))) {
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory for the alignment");
        goto done;
    }
    stage s = o->mode == SM_ALIGN_RIGID ? STAGE_RIGID : STAGE_SIMILARITY;
    sm_transform t;
    sm_transform_identity(&t, dim);
    eval_template(&c, &full.tpl, &t, 0);
    out->rms_before = sqrt(side_cost(&full.tpl, INFINITY));
    c.length = sm_mesh_diameter(m, m->coords);
    if (o->start) {
        t = *o->start;
        c.length *= sm_transform_scale(&t);
        out->candidates = 1;
    } else if ((st = moment_start(o, &c, &screen, s, &t, &out->candidates, &out->iterations,
                                  err)) != SM_OK) {
        goto done;
    }
    out->iterations += refine_stages(o, &c, &full, &screen, s, &t);
    out->transform = t;
    out->scale = sm_transform_scale(&t);
    out->cancelled = cancelled(&c);
    out->rms_after = out->target_rms_after = NAN;
    if (!out->cancelled) {
        eval_template(&c, &full.tpl, &t, 0);
        eval_target(&c, &full.tgt, &t);
        out->rms_after = sqrt(side_cost(&full.tpl, INFINITY));
        out->target_rms_after = sqrt(side_cost(&full.tgt, INFINITY));
    }
    if (c.nomem)
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory in the alignment's distance queries");
done:
    free(c.scratch);
    sm_sdf_free(c.tsdf);
    sm_surface_free(c.tsurf);
    level_free(&full);
    level_free(&screen);
    out->seconds = sm_clock_seconds() - t0;
    return st;
}
