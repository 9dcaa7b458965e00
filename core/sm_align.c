/* Pre-alignment of the template onto the target's distance field: the
 * moments' start with its signed-permutation candidates, then
 * Levenberg-Marquardt on the robust boundary misfit (see sm_align.h). */
#include "shapematch/sm_align.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "shapematch/sm_clock.h"
#include "sm_align_internal.h"

/* Points for screening and refining the candidates: every k-th
 * quadrature point, so that a start costs the same for any template. */
#define SCREEN_POINTS 1000
/* Candidates (by screening cost) refined before the best is kept: the
 * true one is among the first few whenever the axes are distinct, and
 * near-symmetric shapes are nearly as good from any of them. */
#define CANDIDATES_REFINED 3
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
#define STEP_TOL 1e-7
/* Loops over fewer points stay on one thread, like the descent's below
 * 100k elements (docs/performance.md): the 3D example's 27k points take
 * ~0.01 s a pass, and on a loaded machine a fork and join waits for a
 * descheduled thread (examples/3d moved: 5 s of wall time for the
 * alignment with 2 threads at load 13, 1.2 s of CPU for the whole
 * command). */
#define PARALLEL_MIN 100000

typedef enum stage { STAGE_RIGID, STAGE_SIMILARITY, STAGE_AFFINE } stage;

/* Boundary quadrature points of the template and their weights. */
typedef struct quad {
    int dim;
    int64_t n;
    double *x, *w;
    /* per point work: moved point, residual, gradient, hint */
    double *y, *r, *g;
    int32_t *hints;
    double length;  /* the target's size (for floors and step tests) */
    const volatile int *cancel; /* sm_align_opts' */
} quad;

/* The caller asked to stop (polled before each pass over the points). */
static int cancelled(const quad *q)
{
    return q->cancel && *q->cancel;
}

static void quad_free(quad *q)
{
    free(q->x);
    free(q->w);
    free(q->y);
    free(q->r);
    free(q->g);
    free(q->hints);
}

static sm_status quad_build(const sm_mesh *m, quad *q, sm_error *err)
{
    const int dim = m->dim;
    /* 2D: 2 Gauss points per edge; 3D: the 3-point rule per triangle
     * (barycentric 2/3, 1/6, 1/6): exact for quadratics, so the misfit of
     * an exactly aligned P1 field is its interpolation error only */
    const int per = dim == 2 ? 2 : 3;
    static const double g2[2] = {0.21132486540518713, 0.78867513459481287};
    memset(q, 0, sizeof *q);
    q->dim = dim;
    q->n = (int64_t)m->nbfacets * per;
    size_t n = (size_t)q->n + 1;
    q->x = malloc(n * dim * sizeof *q->x);
    q->w = malloc(n * sizeof *q->w);
    q->y = malloc(n * dim * sizeof *q->y);
    q->r = malloc(n * sizeof *q->r);
    q->g = malloc(n * dim * sizeof *q->g);
    q->hints = malloc(n * sizeof *q->hints);
    if (!q->x || !q->w || !q->y || !q->r || !q->g || !q->hints) {
        quad_free(q);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the alignment's points");
    }
    for (int32_t f = 0; f < m->nbfacets; f++) {
        double normal[3];
        double area = sm_bfacet_normal(m, m->coords, f, normal);
        const int32_t *v = m->bfacets + (size_t)f * dim;
        for (int k = 0; k < per; k++) {
            double lam[3];
            if (dim == 2) {
                lam[0] = g2[k];
                lam[1] = 1 - g2[k];
            } else {
                lam[0] = lam[1] = lam[2] = 1.0 / 6;
                lam[k] = 2.0 / 3;
            }
            double *x = q->x + ((size_t)f * per + k) * dim;
            for (int c = 0; c < dim; c++) {
                x[c] = 0;
                for (int i = 0; i < dim; i++)
                    x[c] += lam[i] * m->coords[(size_t)v[i] * dim + c];
            }
            q->w[(size_t)f * per + k] = area / per;
        }
    }
    return SM_OK;
}

/* ------------------------------------------------------------- moments */

typedef struct moments {
    double volume;
    double centroid[3];
    double cov[3][3];     /* second central moment / volume */
} moments;

/* Accumulates a simplex of weight frac (vertices relative to ref):
 * int x x^T over a simplex = V/((d+1)(d+2)) (sum v v^T + s s^T), s the
 * vertex sum. */
static void add_simplex(int dim, const double *v[4], const double *ref, double vol, double frac,
                        double *mass, double first[3], double second[3][3])
{
    double p[4][3], s[3] = {0, 0, 0};
    for (int i = 0; i <= dim; i++)
        for (int c = 0; c < dim; c++) {
            p[i][c] = v[i][c] - ref[c];
            s[c] += p[i][c];
        }
    double m = vol * frac, k = m / ((dim + 1) * (dim + 2));
    *mass += m;
    for (int r = 0; r < dim; r++) {
        first[r] += m * s[r] / (dim + 1);
        for (int c = 0; c < dim; c++) {
            double acc = s[r] * s[c];
            for (int i = 0; i <= dim; i++)
                acc += p[i][r] * p[i][c];
            second[r][c] += k * acc;
        }
    }
}

static void finish_moments(int dim, const double *ref, double mass, const double first[3],
                           const double second[3][3], moments *out)
{
    memset(out, 0, sizeof *out);
    out->volume = mass;
    double c[3] = {0, 0, 0};
    for (int r = 0; r < dim; r++)
        c[r] = first[r] / mass;
    for (int r = 0; r < dim; r++) {
        out->centroid[r] = ref[r] + c[r];
        for (int k = 0; k < dim; k++)
            out->cov[r][k] = second[r][k] / mass - c[r] * c[k];
    }
}

/* The volume of the elements (values NULL), or of the region values < 0
 * (an element partly inside counts by the fraction sum(d-)/sum|d| of its
 * vertex values, the linear estimate of the cut; its error is an
 * O(h) layer at the boundary, which the refinement removes). */
static int mesh_moments(const sm_mesh *m, const double *values, moments *out)
{
    const int dim = m->dim;
    double mass = 0, first[3] = {0, 0, 0}, second[3][3] = {{0}};
    const double *ref = m->coords;
    for (int32_t e = 0; e < m->nelems; e++) {
        const int32_t *ev = m->elems + (size_t)e * (dim + 1);
        double frac = 1;
        if (values) {
            double neg = 0, abs_sum = 0;
            for (int i = 0; i <= dim; i++) {
                neg += fmax(-values[ev[i]], 0);
                abs_sum += fabs(values[ev[i]]);
            }
            if (!(neg > 0))
                continue;
            frac = neg / abs_sum;
        }
        const double *v[4];
        for (int i = 0; i <= dim; i++)
            v[i] = m->coords + (size_t)ev[i] * dim;
        add_simplex(dim, v, ref, fabs(sm_elem_volume(m, m->coords, e)), frac, &mass, first,
                    second);
    }
    if (!(mass > 0) || !isfinite(mass))
        return -1;
    finish_moments(dim, ref, mass, first, second, out);
    return 0;
}

/* ---------------------------------------------------------- the misfit */

/* y = t(x) for points from, from + step, ... (n_used of them). */
static void move_points(const quad *q, const sm_transform *t, int64_t step)
{
    const int dim = q->dim;
#pragma omp parallel for schedule(static) if (q->n / step > PARALLEL_MIN)
    for (int64_t i = 0; i < q->n; i += step)
        sm_transform_apply(t, 1, q->x + i * dim, q->y + i * dim);
}

/* sum w d(t x)^2 / sum w over every step-th point (no hints: a
 * candidate lies anywhere). */
static double mean_square(const quad *q, const sm_field *f, const sm_transform *t, int64_t step)
{
    move_points(q, t, step);
    double num = 0, den = 0;
    const int dim = q->dim;
#pragma omp parallel for schedule(static) reduction(+ : num, den) if (q->n / step > PARALLEL_MIN)
    for (int64_t i = 0; i < q->n; i += step) {
        int32_t hint = q->hints[i];
        double d = sm_field_eval(f, q->y + i * dim, &hint);
        num += q->w[i] * d * d;
        den += q->w[i];
    }
    return den > 0 ? num / den : INFINITY;
}

static int compare_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Huber's threshold from the residuals' median absolute value. */
static double huber_threshold(const quad *q, int64_t step, double *scratch)
{
    int64_t k = 0;
    for (int64_t i = 0; i < q->n; i += step)
        scratch[k++] = fabs(q->r[i]);
    qsort(scratch, (size_t)k, sizeof *scratch, compare_double);
    double med = k ? scratch[k / 2] : 0;
    return fmax(HUBER_K * 1.4826 * med, HUBER_FLOOR * q->length);
}

static double huber(double r, double k)
{
    double a = fabs(r);
    return a <= k ? 0.5 * r * r : k * (a - 0.5 * k);
}

/* The Huber cost of t with threshold k (values only; hints kept). */
static double huber_cost(const quad *q, const sm_field *f, const sm_transform *t, int64_t step,
                         double k)
{
    move_points(q, t, step);
    const int dim = q->dim;
    double sum = 0;
#pragma omp parallel for schedule(static) reduction(+ : sum) if (q->n / step > PARALLEL_MIN)
    for (int64_t i = 0; i < q->n; i += step) {
        int32_t hint = q->hints[i];
        sum += q->w[i] * huber(sm_field_eval(f, q->y + i * dim, &hint), k);
    }
    return sum;
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

/* Residuals and gradients at t for every step-th point; returns the
 * centre of the moved points (the increments' pivot). */
static void eval_with_gradient(const quad *q, const sm_field *f, const sm_transform *t,
                               int64_t step, double c[3])
{
    const int dim = q->dim;
    move_points(q, t, step);
#pragma omp parallel for schedule(static) if (q->n / step > PARALLEL_MIN)
    for (int64_t i = 0; i < q->n; i += step)
        q->r[i] = sm_field_eval_grad(f, q->y + i * dim, &q->hints[i], q->g + i * dim);
    double wsum = 0;
    c[0] = c[1] = c[2] = 0;
    for (int64_t i = 0; i < q->n; i += step) {
        wsum += q->w[i];
        for (int k = 0; k < dim; k++)
            c[k] += q->w[i] * q->y[i * dim + k];
    }
    for (int k = 0; k < dim; k++)
        c[k] /= wsum;
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

/* Levenberg-Marquardt on the Huber misfit; t updated in place.  Stops
 * when a step moves the points by less than STEP_TOL times the target's
 * size (the matrix is then known to ~1e-7, far below the field's own
 * accuracy), when no damping gives a decrease, or after max_iter.
 * Returns the iterations taken. */
static int refine(quad *q, const sm_field *f, stage s, int64_t step, int max_iter,
                  sm_transform *t, double *scratch)
{
    const int dim = q->dim, np = stage_params(dim, s);
    double lambda = 1e-3;
    int it;
    for (it = 0; it < max_iter && !cancelled(q); it++) {
        double c[3];
        eval_with_gradient(q, f, t, step, c);
        double k = huber_threshold(q, step, scratch);
        double jtj[144] = {0}, jtr[12] = {0}, cost = 0, row[12], radius = 0;
        for (int64_t i = 0; i < q->n; i += step) {
            double v[3] = {0, 0, 0}, r = q->r[i], v2 = 0;
            for (int j = 0; j < dim; j++) {
                v[j] = q->y[i * dim + j] - c[j];
                v2 += v[j] * v[j];
            }
            radius = fmax(radius, v2);
            jacobian_row(dim, s, v, q->g + i * dim, row);
            /* IRLS weight of Huber's rho: psi(r)/r */
            double wr = q->w[i] * (fabs(r) <= k ? 1 : k / fabs(r));
            cost += q->w[i] * huber(r, k);
            for (int a = 0; a < np; a++) {
                jtr[a] += wr * row[a] * r;
                for (int b = 0; b <= a; b++)
                    jtj[a * np + b] += wr * row[a] * row[b];
            }
        }
        for (int a = 0; a < np; a++)
            for (int b = a + 1; b < np; b++)
                jtj[a * np + b] = jtj[b * np + a];
        radius = sqrt(radius);
        int accepted = 0;
        double new_cost = cost, moved = 0;
        for (int trial = 0; trial < 12 && !accepted && !cancelled(q); trial++) {
            double m[144], rhs[12], delta[12];
            memcpy(m, jtj, sizeof m);
            for (int a = 0; a < np; a++) {
                m[a * np + a] += lambda * fmax(jtj[a * np + a], 1e-300);
                rhs[a] = -jtr[a];
            }
            sm_transform next;
            if (sm__solve_dense(np, m, rhs, delta) == 0 &&
                apply_increment(dim, s, delta, c, t, &next) == 0) {
                new_cost = huber_cost(q, f, &next, step, k);
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
        if (!accepted || moved <= STEP_TOL * q->length || cost - new_cost <= 1e-14 * cost)
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
static int moment_candidates(int dim, const moments *mt, const moments *mg, double scale,
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

/* The moments' start: the best of the refined candidates. */
static sm_status moment_start(const sm_align_opts *o, quad *q, stage s, int64_t step,
                              double *scratch, sm_transform *best, int *ncand, int *iters,
                              sm_error *err)
{
    const int dim = o->template_mesh->dim;
    moments mt, mg;
    if (mesh_moments(o->template_mesh, NULL, &mt) != 0)
        return sm_error_set(err, SM_ERR_INVALID, "alignment: the template has no volume");
    if (mesh_moments(o->background, o->distance, &mg) != 0)
        return sm_error_set(err, SM_ERR_INVALID,
                            "alignment: the target has no inside (d >= 0 at every vertex of the "
                            "background), nothing to align onto");
    double scale = s == STAGE_RIGID ? 1 : pow(mg.volume / mt.volume, 1.0 / dim);
    double trace = 0;
    for (int c = 0; c < dim; c++)
        trace += mg.cov[c][c];
    q->length = sqrt(fmax(trace, 0)) > 0 ? sqrt(trace) : 1;
    candidate cand[24];
    int n = moment_candidates(dim, &mt, &mg, scale, cand);
    for (int i = 0; i < n; i++) {
        for (int64_t k = 0; k < q->n; k++)
            q->hints[k] = -1;
        cand[i].cost = cancelled(q) ? 0 : mean_square(q, o->target, &cand[i].t, step);
    }
    qsort(cand, (size_t)n, sizeof *cand, by_cost);
    int keep = n < CANDIDATES_REFINED ? n : CANDIDATES_REFINED;
    for (int i = 0; i < keep && !cancelled(q); i++) {
        for (int64_t k = 0; k < q->n; k++)
            q->hints[k] = -1;
        *iters += refine(q, o->target, s, step, CANDIDATE_ITER, &cand[i].t, scratch);
        cand[i].cost = mean_square(q, o->target, &cand[i].t, step);
    }
    qsort(cand, (size_t)keep, sizeof *cand, by_cost);
    *best = cand[0].t;
    *ncand = n;
    return SM_OK;
}

sm_status sm_align_run(const sm_align_opts *o, sm_align_result *out, sm_error *err)
{
    double t0 = sm_clock_seconds();
    memset(out, 0, sizeof *out);
    const sm_mesh *m = o->template_mesh;
    if (!sm_align_mode_name(o->mode) || o->mode == SM_ALIGN_NONE)
        return sm_error_set(err, SM_ERR_INVALID, "alignment: mode %d is not an alignment",
                            (int)o->mode);
    if (!m || !o->target || !o->background || !o->distance || m->nbfacets <= 0 ||
        sm_field_dim(o->target) != m->dim || o->background->dim != m->dim)
        return sm_error_set(err, SM_ERR_INVALID,
                            "alignment: needs a template with its boundary and a target field of "
                            "the same dimension");
    if (o->start && o->start->dim != m->dim)
        return sm_error_set(err, SM_ERR_INVALID, "alignment: the start is %dD, the template %dD",
                            o->start->dim, m->dim);
    quad q;
    sm_status st = quad_build(m, &q, err);
    if (st != SM_OK)
        return st;
    double *scratch = malloc(((size_t)q.n + 1) * sizeof *scratch);
    if (!scratch) {
        quad_free(&q);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the alignment");
    }
    const int dim = m->dim;
    q.cancel = o->cancel;
    int64_t step = q.n > SCREEN_POINTS ? q.n / SCREEN_POINTS : 1;
    int max_iter = o->max_iter > 0 ? o->max_iter : DEFAULT_MAX_ITER;
    stage s = o->mode == SM_ALIGN_RIGID ? STAGE_RIGID : STAGE_SIMILARITY;
    for (int64_t k = 0; k < q.n; k++)
        q.hints[k] = -1;
    sm_transform t;
    sm_transform_identity(&t, dim);
    out->rms_before = sqrt(mean_square(&q, o->target, &t, 1));
    q.length = sm_mesh_diameter(m, m->coords);
    if (o->start) {
        t = *o->start;
        q.length *= sm_transform_scale(&t);
        out->candidates = 1;
    } else {
        st = moment_start(o, &q, s, step, scratch, &t, &out->candidates, &out->iterations, err);
    }
    if (st == SM_OK) {
        for (int64_t k = 0; k < q.n; k++)
            q.hints[k] = -1;
        /* on the subsample to convergence, then on every point from
         * there (a few iterations: the subsample's optimum is close) */
        out->iterations += refine(&q, o->target, s, step, max_iter, &t, scratch);
        if (step > 1)
            out->iterations += refine(&q, o->target, s, 1, max_iter, &t, scratch);
        if (o->mode == SM_ALIGN_AFFINE) {
            out->iterations += refine(&q, o->target, STAGE_AFFINE, step, max_iter, &t, scratch);
            if (step > 1)
                out->iterations += refine(&q, o->target, STAGE_AFFINE, 1, max_iter, &t, scratch);
        }
        out->transform = t;
        out->scale = sm_transform_scale(&t);
        out->cancelled = cancelled(&q);
        out->rms_after = out->cancelled ? NAN : sqrt(mean_square(&q, o->target, &t, 1));
    }
    free(scratch);
    quad_free(&q);
    out->seconds = sm_clock_seconds() - t0;
    return st;
}
