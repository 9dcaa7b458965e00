/* The statistical shape model (shapematch/sm_shape_model.h): Procrustes
 * alignment, PCA through the Gram matrix, and the model's measures. */
#include "shapematch/sm_shape_model.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sm_align_internal.h"

/* BLAS and LAPACK through their Fortran entry points (no header on every
 * system; the trailing lengths are gfortran's hidden character lengths). */
void dsyrk_(const char *uplo, const char *trans, const int *n, const int *k, const double *alpha,
            const double *a, const int *lda, const double *beta, double *c, const int *ldc,
            size_t luplo, size_t ltrans);
void dgemm_(const char *ta, const char *tb, const int *m, const int *n, const int *k,
            const double *alpha, const double *a, const int *lda, const double *b,
            const int *ldb, const double *beta, double *c, const int *ldc, size_t lta,
            size_t ltb);
void dsyevr_(const char *jobz, const char *range, const char *uplo, const int *n, double *a,
             const int *lda, const double *vl, const double *vu, const int *il, const int *iu,
             const double *abstol, int *m, double *w, double *z, const int *ldz, int *isuppz,
             double *work, const int *lwork, int *iwork, const int *liwork, int *info,
             size_t ljobz, size_t lrange, size_t luplo);

#define MODE_CUTOFF 1e-12 /* g_k kept when above this fraction of g_1 */
#define GPA_TOL 1e-12

const char *sm_shape_align_name(sm_shape_align a)
{
    switch (a) {
    case SM_SHAPE_ALIGN_NONE: return "none";
    case SM_SHAPE_ALIGN_RIGID: return "rigid";
    case SM_SHAPE_ALIGN_SIMILARITY: return "similarity";
    }
    return "unknown";
}

int sm_shape_align_parse(const char *name, sm_shape_align *out)
{
    static const sm_shape_align all[] = {SM_SHAPE_ALIGN_NONE, SM_SHAPE_ALIGN_RIGID,
                                         SM_SHAPE_ALIGN_SIMILARITY};
    for (size_t i = 0; name && i < sizeof all / sizeof all[0]; i++)
        if (strcmp(name, sm_shape_align_name(all[i])) == 0) {
            *out = all[i];
            return 0;
        }
    return -1;
}

/* ------------------------------------------------------------ Procrustes */

static void centroid(const double *x, int64_t n, int dim, double c[3])
{
    c[0] = c[1] = c[2] = 0;
    for (int64_t p = 0; p < n; p++)
        for (int j = 0; j < dim; j++)
            c[j] += x[p * dim + j];
    for (int j = 0; j < dim; j++)
        c[j] /= (double)(n > 0 ? n : 1);
}

/* sqrt of the summed squared distances to the centroid. */
static double centroid_size(const double *x, int64_t n, int dim)
{
    double c[3], s = 0;
    centroid(x, n, dim, c);
    for (int64_t p = 0; p < n; p++)
        for (int j = 0; j < dim; j++)
            s += (x[p * dim + j] - c[j]) * (x[p * dim + j] - c[j]);
    return sqrt(s);
}

void sm_shape_align_onto(double *x, const double *ref, int64_t n, int dim,
                         sm_shape_align kind, double *t13)
{
    double R[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}, t[3] = {0, 0, 0}, s = 1;
    if (kind != SM_SHAPE_ALIGN_NONE) {
        double cx[3], cr[3], H[3][3] = {{0}}, ssx = 0;
        centroid(x, n, dim, cx);
        centroid(ref, n, dim, cr);
        for (int64_t p = 0; p < n; p++)
            for (int a = 0; a < dim; a++) {
                double xa = x[p * dim + a] - cx[a];
                ssx += xa * xa;
                for (int b = 0; b < dim; b++)
                    H[a][b] += xa * (ref[p * dim + b] - cr[b]);
            }
        /* H = U S V^T; R = V D U^T, D flipping the last axis when V U^T
         * would be a reflection */
        double U[3][3], S[3], V[3][3];
        sm__svd(dim, (const double(*)[3])H, U, S, V);
        double D[3] = {1, 1, 1};
        if (sm__det(dim, (const double(*)[3])U) * sm__det(dim, (const double(*)[3])V) < 0)
            D[dim - 1] = -1;
        for (int a = 0; a < dim; a++)
            for (int b = 0; b < dim; b++) {
                double r = 0;
                for (int k = 0; k < dim; k++)
                    r += V[a][k] * D[k] * U[b][k];
                R[a][b] = r;
            }
        if (kind == SM_SHAPE_ALIGN_SIMILARITY && ssx > 0) {
            double tr = 0;
            for (int k = 0; k < dim; k++)
                tr += S[k] * D[k];
            s = tr / ssx;
        }
        for (int a = 0; a < dim; a++) {
            double rc = 0;
            for (int b = 0; b < dim; b++)
                rc += R[a][b] * cx[b];
            t[a] = cr[a] - s * rc;
        }
        for (int64_t p = 0; p < n; p++) {
            double y[3];
            for (int a = 0; a < dim; a++) {
                double r = 0;
                for (int b = 0; b < dim; b++)
                    r += R[a][b] * x[p * dim + b];
                y[a] = s * r + t[a];
            }
            memcpy(x + p * dim, y, (size_t)dim * sizeof *y);
        }
    }
    if (t13) {
        t13[0] = s;
        for (int a = 0; a < 3; a++)
            for (int b = 0; b < 3; b++)
                t13[1 + 3 * a + b] = R[a][b];
        memcpy(t13 + 10, t, sizeof t);
    }
}

/* Scales x about its centroid to centroid size `size`. */
static void rescale(double *x, int64_t n, int dim, double size)
{
    double cur = centroid_size(x, n, dim), c[3];
    if (!(cur > 0))
        return;
    centroid(x, n, dim, c);
    for (int64_t p = 0; p < n; p++)
        for (int j = 0; j < dim; j++)
            x[p * dim + j] = c[j] + (x[p * dim + j] - c[j]) * (size / cur);
}

static void mean_of(const sm_shape_model *m, double *mean)
{
    size_t P = m->nvalues;
    memset(mean, 0, P * sizeof *mean);
    for (int i = 0; i < m->nshapes; i++)
        for (size_t v = 0; v < P; v++)
            mean[v] += m->centered[(size_t)i * P + v];
    for (size_t v = 0; v < P; v++)
        mean[v] /= m->nshapes;
}

/* Every shape aligned onto ref (from the originals). */
static void align_all(sm_shape_model *m, const double *const *shapes, const double *ref,
                      sm_shape_align kind)
{
    size_t P = m->nvalues;
    for (int i = 0; i < m->nshapes; i++) {
        double *x = m->centered + (size_t)i * P;
        memcpy(x, shapes[i], P * sizeof *x);
        sm_shape_align_onto(x, ref, m->npoints, m->dim, kind, m->transforms + 13 * (size_t)i);
    }
}

static double dist2(const double *a, const double *b, size_t n)
{
    double s = 0;
    for (size_t v = 0; v < n; v++)
        s += (a[v] - b[v]) * (a[v] - b[v]);
    return s;
}

/* Generalized Procrustes analysis (header); m->mean is the final mean. */
static sm_status procrustes(sm_shape_model *m, const double *const *shapes,
                            sm_shape_align kind, sm_error *err)
{
    size_t P = m->nvalues;
    int64_t n = m->npoints;
    double *ref = malloc(P * sizeof *ref);
    if (!ref)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the Procrustes mean");
    memcpy(ref, shapes[0], P * sizeof *ref);
    double size0 = centroid_size(shapes[0], n, m->dim);
    for (m->gpa_rounds = 0; kind != SM_SHAPE_ALIGN_NONE && m->gpa_rounds < SM_SHAPE_MODEL_MAX_GPA;) {
        m->gpa_rounds++;
        align_all(m, shapes, ref, kind);
        mean_of(m, m->mean);
        if (kind == SM_SHAPE_ALIGN_SIMILARITY)
            rescale(m->mean, n, m->dim, size0);
        double moved = dist2(m->mean, ref, P);
        memcpy(ref, m->mean, P * sizeof *ref);
        if (moved <= GPA_TOL * GPA_TOL * (size0 * size0 > 0 ? size0 * size0 : 1))
            break;
    }
    if (kind != SM_SHAPE_ALIGN_NONE) {
        /* into the first shape's frame: the mean moved rigidly onto it */
        sm_shape_align_onto(ref, shapes[0], n, m->dim, SM_SHAPE_ALIGN_RIGID, NULL);
        align_all(m, shapes, ref, kind);
    } else {
        for (int i = 0; i < m->nshapes; i++) {
            memcpy(m->centered + (size_t)i * P, shapes[i], P * sizeof(double));
            sm_shape_align_onto(m->centered + (size_t)i * P, NULL, n, m->dim, kind,
                                m->transforms + 13 * (size_t)i);
        }
    }
    mean_of(m, m->mean);
    for (int i = 0; i < m->nshapes; i++) /* X: minus the mean */
        for (size_t v = 0; v < P; v++)
            m->centered[(size_t)i * P + v] -= m->mean[v];
    free(ref);
    return SM_OK;
}

/* ------------------------------------------------------------------- PCA */

/* Eigenpairs of the symmetric n x n matrix a (column-major, upper
 * triangle used, destroyed): the `want` largest, descending, into w and
 * the columns of z (n x want). */
static sm_status sym_eigen_top(int n, double *a, int want, double *w, double *z, sm_error *err)
{
    int il = n - want + 1, iu = n, found = 0, info = 0, lwork = -1, liwork = -1, iw;
    double vl = 0, vu = 0, abstol = 0, wq;
    double *wa = malloc((size_t)n * sizeof *wa), *za = malloc((size_t)n * want * sizeof *za);
    int *isuppz = malloc(2 * (size_t)n * sizeof *isuppz);
    if (!wa || !za || !isuppz) {
        free(wa), free(za), free(isuppz);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for a %d x %d eigenproblem", n, n);
    }
    const char *range = want == n ? "A" : "I";
    dsyevr_("V", range, "U", &n, a, &n, &vl, &vu, &il, &iu, &abstol, &found, wa, za, &n, isuppz,
            &wq, &lwork, &iw, &liwork, &info, 1, 1, 1);
    double *work = NULL;
    int *iwork = NULL;
    if (info == 0) {
        lwork = (int)wq + 1;
        liwork = iw + 1;
        work = malloc((size_t)lwork * sizeof *work);
        iwork = malloc((size_t)liwork * sizeof *iwork);
        if (!work || !iwork)
            info = -1000;
        else
            dsyevr_("V", range, "U", &n, a, &n, &vl, &vu, &il, &iu, &abstol, &found, wa, za, &n,
                    isuppz, work, &lwork, iwork, &liwork, &info, 1, 1, 1);
    }
    sm_status st = SM_OK;
    if (info == -1000)
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory for a %d x %d eigenproblem", n, n);
    else if (info != 0 || found != want)
        st = sm_error_set(err, SM_ERR_NUMERIC, "LAPACK dsyevr failed (info %d) on %d x %d", info,
                          n, n);
    for (int k = 0; st == SM_OK && k < want; k++) { /* ascending -> descending */
        w[k] = wa[want - 1 - k];
        memcpy(z + (size_t)k * n, za + (size_t)(want - 1 - k) * n, (size_t)n * sizeof *z);
    }
    free(wa), free(za), free(isuppz), free(work), free(iwork);
    return st;
}

/* G = X X^T, its eigenpairs, the kept modes, their variances and the
 * scores (header). */
static sm_status pca(sm_shape_model *m, sm_error *err)
{
    int N = m->nshapes, P = (int)m->nvalues;
    double *G = calloc((size_t)N * N, sizeof *G), *g = malloc((size_t)N * sizeof *g);
    double *V = malloc((size_t)N * N * sizeof *V);
    sm_status st = SM_OK;
    if (!G || !g || !V)
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory for the %d x %d Gram matrix", N, N);
    double one = 1, zero = 0;
    if (st == SM_OK) {
        dsyrk_("U", "T", &N, &P, &one, m->centered, &P, &zero, G, &N, 1, 1);
        double trace = 0;
        for (int i = 0; i < N; i++)
            trace += G[(size_t)i * N + i];
        m->total_variance = N > 1 ? trace / (N - 1) : 0;
        st = sym_eigen_top(N, G, N, g, V, err);
    }
    int K = 0;
    while (st == SM_OK && K < N - 1 && g[K] > 0 && g[K] > MODE_CUTOFF * g[0])
        K++;
    m->nmodes = K;
    if (st == SM_OK && K > 0) {
        m->modes = malloc((size_t)K * m->nvalues * sizeof *m->modes);
        m->variance = malloc((size_t)K * sizeof *m->variance);
        m->scores = malloc((size_t)N * K * sizeof *m->scores);
        if (!m->modes || !m->variance || !m->scores)
            st = sm_error_set(err, SM_ERR_NOMEM, "out of memory for %d modes of %zu values", K,
                              m->nvalues);
    }
    if (st == SM_OK && K > 0) {
        dgemm_("N", "N", &P, &K, &N, &one, m->centered, &P, V, &N, &zero, m->modes, &P, 1, 1);
        for (int k = 0; k < K; k++) {
            double sq = sqrt(g[k]);
            for (size_t v = 0; v < m->nvalues; v++)
                m->modes[(size_t)k * m->nvalues + v] /= sq;
            m->variance[k] = g[k] / (N - 1);
            for (int i = 0; i < N; i++)
                m->scores[(size_t)i * K + k] = sq * V[(size_t)k * N + i];
        }
    }
    free(G), free(g), free(V);
    return st;
}

void sm_shape_model_instance(const sm_shape_model *m, const double *b, int nb, double *out)
{
    memcpy(out, m->mean, m->nvalues * sizeof *out);
    for (int k = 0; k < nb && k < m->nmodes; k++) {
        double c = b[k] * sqrt(m->variance[k]);
        const double *u = m->modes + (size_t)k * m->nvalues;
        for (size_t v = 0; v < m->nvalues; v++)
            out[v] += c * u[v];
    }
}

/* ------------------------------------------------------------ measures */

/* dist() of the header for a difference vector e (P values). */
static double point_dist(const double *e, int64_t npoints, int dim)
{
    double s = 0;
    for (int64_t p = 0; p < npoints; p++) {
        double q = 0;
        for (int j = 0; j < dim; j++)
            q += e[p * dim + j] * e[p * dim + j];
        s += sqrt(q);
    }
    return npoints > 0 ? s / (double)npoints : 0;
}

/* Leave-one-out in score space (header): for held-out i the others'
 * covariance is diag(g) - N/(N-1) y_i y_i^T, and x_i minus the others'
 * mean is U (N/(N-1)) y_i. */
static sm_status generalization(sm_shape_model *m, sm_error *err)
{
    int N = m->nshapes, K = m->nmodes, E = m->neval, P = (int)m->nvalues;
    int held = N < m->eval_shapes ? N : m->eval_shapes;
    double *C = malloc((size_t)K * K * sizeof *C), *w = malloc((size_t)E * sizeof *w);
    double *W = malloc((size_t)K * E * sizeof *W), *R = malloc((size_t)K * E * sizeof *R);
    double *D = malloc((size_t)m->nvalues * E * sizeof *D), *d = malloc((size_t)K * sizeof *d);
    sm_status st = SM_OK;
    if (!C || !w || !W || !R || !D || !d)
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory for the generalization");
    double one = 1, zero = 0, f = (double)N / (N - 1);
    for (int h = 0; st == SM_OK && h < held; h++) {
        int i = (int)((int64_t)h * N / held);
        const double *y = m->scores + (size_t)i * K;
        for (int a = 0; a < K; a++) {
            for (int b = 0; b < K; b++)
                C[(size_t)b * K + a] = (a == b ? m->variance[a] * (N - 1) : 0) - f * y[a] * y[b];
            d[a] = f * y[a];
        }
        st = sym_eigen_top(K, C, E, w, W, err);
        for (int M = 1; st == SM_OK && M <= E; M++) { /* residual of d with M modes */
            double *r = R + (size_t)(M - 1) * K;
            memcpy(r, d, (size_t)K * sizeof *r);
            for (int k = 0; k < M; k++) {
                if (!(w[k] > MODE_CUTOFF * w[0]))
                    break; /* the others have fewer modes */
                const double *wk = W + (size_t)k * K;
                double c = 0;
                for (int a = 0; a < K; a++)
                    c += wk[a] * d[a];
                for (int a = 0; a < K; a++)
                    r[a] -= c * wk[a];
            }
        }
        if (st != SM_OK)
            break;
        dgemm_("N", "N", &P, &E, &K, &one, m->modes, &P, R, &K, &zero, D, &P, 1, 1);
        for (int M = 1; M <= E; M++)
            m->generalization[M - 1] +=
                point_dist(D + (size_t)(M - 1) * m->nvalues, m->npoints, m->dim) / held;
    }
    free(C), free(w), free(W), free(R), free(D), free(d);
    return st;
}

static double uniform01(uint64_t *s)
{
    uint64_t x = *s;
    x ^= x >> 12;
    x ^= x << 25;
    x ^= x >> 27;
    *s = x;
    return ((double)((x * 0x2545F4914F6CDD1DULL) >> 11) + 0.5) * 0x1.0p-53;
}

static double normal01(uint64_t *s)
{
    double u = uniform01(s), v = uniform01(s);
    return sqrt(-2 * log(u)) * cos(6.283185307179586 * v);
}

/* dist() of the header between a and b (P values each). */
static double point_dist_ab(const double *a, const double *b, int64_t npoints, int dim)
{
    double s = 0;
    for (int64_t p = 0; p < npoints; p++) {
        double q = 0;
        for (int j = 0; j < dim; j++)
            q += (a[p * dim + j] - b[p * dim + j]) * (a[p * dim + j] - b[p * dim + j]);
        s += sqrt(q);
    }
    return npoints > 0 ? s / (double)npoints : 0;
}

/* Random shapes against the nearest training shape (header).  Each
 * sample draws neval normal scores b_1..b_neval once; its shape with M
 * modes uses the first M, so the curves for M = 1, 2, ... share their
 * draws and each sample is built up one mode at a time (a sample costs
 * O(neval (P + N)) after O(N K) for its squared distances in score
 * space, not O(neval^2 P)). */
static sm_status specificity(sm_shape_model *m, sm_error *err)
{
    int N = m->nshapes, K = m->nmodes, E = m->neval;
    size_t P = m->nvalues;
    double *b = malloc((size_t)E * sizeof *b), *smp = malloc(P * sizeof *smp);
    double *q = malloc((size_t)N * sizeof *q), *sum = calloc((size_t)E, sizeof *sum);
    if (!b || !smp || !q || !sum) {
        free(b), free(smp), free(q), free(sum);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the specificity");
    }
    uint64_t state = m->seed;
    for (int s = 0; s < m->samples; s++) {
        for (int k = 0; k < E; k++)
            b[k] = normal01(&state) * sqrt(m->variance[k]);
        /* q_i = |b restricted to M modes - y_i|^2, from M = 0 */
        for (int i = 0; i < N; i++) {
            double t = 0;
            for (int k = 0; k < K; k++)
                t += m->scores[(size_t)i * K + k] * m->scores[(size_t)i * K + k];
            q[i] = t;
        }
        memset(smp, 0, P * sizeof *smp); /* the sample minus the mean */
        for (int M = 1; M <= E; M++) {
            int k = M - 1, best = 0;
            const double *u = m->modes + (size_t)k * P;
            for (size_t v = 0; v < P; v++)
                smp[v] += b[k] * u[v];
            for (int i = 0; i < N; i++) {
                double y = m->scores[(size_t)i * K + k];
                q[i] += (b[k] - y) * (b[k] - y) - y * y;
                if (q[i] < q[best])
                    best = i;
            }
            /* sample - x_best = (sample - mean) - X_best */
            sum[k] += point_dist_ab(smp, m->centered + (size_t)best * P, m->npoints, m->dim);
        }
    }
    for (int k = 0; k < E; k++)
        m->specificity[k] = sum[k] / m->samples;
    free(b), free(smp), free(q), free(sum);
    return SM_OK;
}

static sm_status measures(sm_shape_model *m, sm_error *err)
{
    int E = m->neval;
    m->compactness = calloc((size_t)E + 1, sizeof(double));
    m->generalization = calloc((size_t)E + 1, sizeof(double));
    m->specificity = calloc((size_t)E + 1, sizeof(double));
    if (!m->compactness || !m->generalization || !m->specificity)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the model's measures");
    double c = 0;
    for (int k = 0; k < E; k++) {
        c += m->variance[k];
        m->compactness[k] = m->total_variance > 0 ? c / m->total_variance : 0;
    }
    sm_status st = SM_OK;
    if (E > 0 && m->nshapes >= 3)
        st = generalization(m, err);
    if (st == SM_OK && E > 0 && m->nshapes >= 2)
        st = specificity(m, err);
    return st;
}

/* ------------------------------------------------------------- the build */

static sm_status check_inputs(const double *const *shapes, int nshapes, int64_t npoints,
                              int dim, sm_error *err)
{
    if (!shapes || nshapes < 1 || npoints < 1 || (dim != 2 && dim != 3))
        return sm_error_set(err, SM_ERR_INVALID,
                            "a shape model needs at least one shape of at least one point in "
                            "2D or 3D (got %d shapes of %lld points, dimension %d)",
                            nshapes, (long long)npoints, dim);
    if (npoints > INT32_MAX / 3 || (int64_t)nshapes * npoints * dim > (int64_t)1 << 40)
        return sm_error_set(err, SM_ERR_INVALID, "shape model too large: %d shapes of %lld points",
                            nshapes, (long long)npoints);
    for (int i = 0; i < nshapes; i++) {
        if (!shapes[i])
            return sm_error_set(err, SM_ERR_INVALID, "shape %d is missing", i + 1);
        for (int64_t v = 0; v < npoints * dim; v++)
            if (!isfinite(shapes[i][v]))
                return sm_error_set(err, SM_ERR_INVALID,
                                    "shape %d: coordinate %lld of point %lld is not finite",
                                    i + 1, (long long)(v % dim), (long long)(v / dim) + 1);
    }
    return SM_OK;
}

sm_status sm_shape_model_build(const double *const *shapes, int nshapes, int64_t npoints,
                               int dim, const sm_shape_model_opts *opts,
                               sm_shape_model **out, sm_error *err)
{
    *out = NULL;
    sm_status st = check_inputs(shapes, nshapes, npoints, dim, err);
    if (st != SM_OK)
        return st;
    sm_shape_model_opts o = opts ? *opts : (sm_shape_model_opts){.align = SM_SHAPE_ALIGN_RIGID};
    if (o.align != SM_SHAPE_ALIGN_NONE && o.align != SM_SHAPE_ALIGN_RIGID &&
        o.align != SM_SHAPE_ALIGN_SIMILARITY)
        return sm_error_set(err, SM_ERR_INVALID, "unknown shape alignment %d", (int)o.align);
    sm_shape_model *m = calloc(1, sizeof *m);
    if (!m)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    m->dim = dim;
    m->nshapes = nshapes;
    m->npoints = npoints;
    m->nvalues = (size_t)npoints * (size_t)dim;
    m->eval_shapes = o.eval_shapes > 0 ? o.eval_shapes : SM_SHAPE_MODEL_EVAL_SHAPES;
    m->samples = o.samples > 0 ? o.samples : SM_SHAPE_MODEL_SAMPLES;
    m->seed = o.seed ? o.seed : SM_SHAPE_MODEL_SEED;
    m->centered = malloc((size_t)nshapes * m->nvalues * sizeof *m->centered);
    m->transforms = malloc((size_t)nshapes * 13 * sizeof *m->transforms);
    m->mean = malloc(m->nvalues * sizeof *m->mean);
    if (!m->centered || !m->transforms || !m->mean)
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory for %d shapes of %lld points",
                          nshapes, (long long)npoints);
    if (st == SM_OK)
        st = procrustes(m, shapes, o.align, err);
    if (st == SM_OK)
        st = pca(m, err);
    if (st == SM_OK) {
        int e = o.eval_modes > 0 ? o.eval_modes : SM_SHAPE_MODEL_EVAL_MODES;
        m->neval = e < m->nmodes ? e : m->nmodes;
        st = measures(m, err);
    }
    if (st != SM_OK) {
        sm_shape_model_free(m);
        return st;
    }
    *out = m;
    return SM_OK;
}

void sm_shape_model_free(sm_shape_model *m)
{
    if (!m)
        return;
    free(m->centered), free(m->transforms), free(m->mean), free(m->modes);
    free(m->variance), free(m->scores);
    free(m->compactness), free(m->generalization), free(m->specificity);
    free(m);
}
