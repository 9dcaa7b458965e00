#include "sm_shape.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "sm_alloc.h"
#include "sm_morton.h"

struct sm_shape {
    const sm_mesh *mesh;
    const sm_field *field;
    int nq;                /* facet quadrature points: 2 (segment) or 3 (triangle) */
    int32_t nactive;
    int32_t *active;       /* indices of the active boundary facets */
    uint8_t *active_vertex;/* vertex touches an active facet */
    /* One hint (background element found last time) per sample point:
     * between iterations and trials a point moves little, so its walk is
     * short.  Laid out like the point buffers below. */
    int32_t *load_hint;    /* nactive * nq */
    int32_t *swept_hint;   /* nactive * 2 * nq */
    int32_t *vertex_hint;  /* nverts */
    int32_t *elem_hint;    /* nelems * (dim+1) volume quadrature points,
                            * in the order of elem_order */
    /* The active facets (above) and the elements (here) in Morton order
     * of their centroids on the mesh given: the samples of each batch
     * then come in spatial order, so that neighbouring walks read the
     * same background elements while they are in cache (the order of
     * the facets of a mesh is that of their vertex numbers, scattered). */
    int32_t *elem_order;   /* nelems */
    /* Scratch: sample points, their values and weights, reused by every
     * call so that the hot path does not allocate.  Points are gathered
     * first and evaluated in batches (sm_field_eval_many), which overlaps
     * the cache misses of many walks. */
    double *points;        /* largest batch * dim */
    double *values;        /* largest batch */
    double *weights;       /* largest batch */
    double *normals;       /* nactive * (dim + 1): unit normal and measure */
    int32_t *gathered_hint;/* nverts: hints of a gathered subset of vertices */
    int primed;            /* the hints above were seeded (prime_hints) */
    /* d at the facet points of the last sm__shape_load (the current mesh)
     * and at the end points of the last sm__shape_delta_j's step (a trial
     * mesh): Simpson's rule along the motion samples both ends, so a
     * trial reuses the current mesh's samples, and when the trial is
     * accepted the next load reuses the trial's.  A sample is reused only
     * for the very same point (compared bit for bit). */
    double *cur_points, *cur_values;   /* nactive * nq (* dim) */
    double *end_points, *end_values;
    int32_t *end_hint;
    int have_cur, have_end;
};

/* Facet rules on the reference simplex, exact for degree 2 (enough for
 * d*phi_i with d affine).  Weights sum to 1 (multiply by the measure). */
#define SEG_NQ 2
static const double seg_l[SEG_NQ][3] = {{1.0 - 0.21132486540518711775, 0.21132486540518711775, 0},
                                         {1.0 - 0.78867513459481288225, 0.78867513459481288225, 0}};
static const double seg_w[SEG_NQ] = {0.5, 0.5};
#define TRI_NQ 3
static const double tri_l[TRI_NQ][3] = {{2.0 / 3, 1.0 / 6, 1.0 / 6},
                                         {1.0 / 6, 2.0 / 3, 1.0 / 6},
                                         {1.0 / 6, 1.0 / 6, 2.0 / 3}};
static const double tri_w[TRI_NQ] = {1.0 / 3, 1.0 / 3, 1.0 / 3};
/* Simpson's rule on [0,1] along the motion: exact for cubics, as the
 * 2-point Gauss rule, and its end points are samples the descent needs
 * anyway (the current mesh's load and, once accepted, the next's). */
#define SWEPT_NS 3
static const double simpson_t[SWEPT_NS] = {0.0, 0.5, 1.0};
static const double simpson_w[SWEPT_NS] = {1.0 / 6, 4.0 / 6, 1.0 / 6};
/* Degree-2 volume rules (weights sum to 1): edge midpoints of a triangle,
 * the 4-point rule for a tetrahedron. */
static const double tet_a = 0.58541019662496845446, tet_b = 0.13819660112501051518;

static int is_free(int32_t ref, const int32_t *refs, int n)
{
    for (int i = 0; i < n; i++)
        if (refs[i] == ref)
            return 1;
    return 0;
}

static int32_t *hints_new(size_t n)
{
    int32_t *h = sm__alloc_huge((n ? n : 1) * sizeof(int32_t));
    if (h)
        for (size_t i = 0; i < n; i++)
            h[i] = -1;
    return h;
}

/* The n cells ids[0..n-1] (ids NULL: 0..n-1) of nc vertices each
 * (cells: the vertex lists of all of them, by id) in Morton order of
 * their centroids on m's coordinates, into out (which may be ids). */
static int spatial_order(const sm_mesh *m, int32_t n, const int32_t *ids, int nc,
                         const int32_t *cells, int32_t *out)
{
    const int dim = m->dim;
    double *c = calloc(((size_t)n + 1) * (size_t)dim, sizeof *c);
    int32_t *copy = malloc(((size_t)n + 1) * sizeof *copy);
    if (!c || !copy) {
        free(c);
        free(copy);
        return -1;
    }
    for (int32_t j = 0; j < n; j++) {
        int32_t id = ids ? ids[j] : j;
        copy[j] = id;
        for (int a = 0; a < dim; a++) {
            double sum = 0.0;
            for (int i = 0; i < nc; i++)
                sum += m->coords[(size_t)cells[(size_t)id * (size_t)nc + (size_t)i] * (size_t)dim +
                                 (size_t)a];
            c[(size_t)j * (size_t)dim + (size_t)a] = sum / nc;
        }
    }
    int64_t *order = sm__morton_order(dim, n, c);
    free(c);
    if (!order) {
        free(copy);
        return -1;
    }
    for (int32_t j = 0; j < n; j++)
        out[j] = copy[order[j]];
    free(order);
    free(copy);
    return 0;
}

sm_status sm__shape_new(const sm_mesh *m, const sm_field *field, const int32_t *free_refs,
                       int nfree, sm_shape **out, sm_error *err)
{
    *out = NULL;
    if (!m->bfacets)
        return sm_error_set(err, SM_ERR_INVALID, "mesh boundary not built");
    sm_shape *s = calloc(1, sizeof *s);
    if (!s)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    const int dim = m->dim;
    s->mesh = m;
    s->field = field;
    s->nq = dim == 2 ? SEG_NQ : TRI_NQ;
    size_t nb = (size_t)m->nbfacets, nv = (size_t)m->nverts, ne = (size_t)m->nelems;
    s->active = malloc((nb ? nb : 1) * sizeof(int32_t));
    s->active_vertex = calloc(nv ? nv : 1, 1);
    if (!s->active || !s->active_vertex) {
        sm__shape_free(s);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    }
    for (int32_t f = 0; f < m->nbfacets; f++) {
        if (is_free(m->bfacet_refs[f], free_refs, nfree))
            continue;
        s->active[s->nactive++] = f;
        for (int c = 0; c < dim; c++)
            s->active_vertex[m->bfacets[(size_t)f * (size_t)dim + (size_t)c]] = 1;
    }
    s->elem_order = malloc((ne ? ne : 1) * sizeof(int32_t));
    if (!s->elem_order || spatial_order(m, s->nactive, s->active, dim, m->bfacets, s->active) != 0 ||
        spatial_order(m, m->nelems, NULL, dim + 1, m->elems, s->elem_order) != 0) {
        sm__shape_free(s);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    }
    size_t na = (size_t)s->nactive, nq = (size_t)s->nq;
    size_t batch = na * SWEPT_NS * nq; /* the swept region's points */
    if (nv > batch)
        batch = nv;
    if (ne * (size_t)(dim + 1) > batch)
        batch = ne * (size_t)(dim + 1);
    s->load_hint = hints_new(na * nq);
    s->swept_hint = hints_new(na * 2 * nq);
    s->vertex_hint = hints_new(nv);
    s->elem_hint = hints_new(ne * (size_t)(dim + 1));
    /* written at once by the first samplings: huge pages and prefaulted
     * blocks (sm_alloc.h), not a page fault per 4 KiB */
    s->points = sm__alloc_huge((batch ? batch : 1) * (size_t)dim * sizeof(double));
    s->values = sm__alloc_huge((batch ? batch : 1) * sizeof(double));
    s->weights = sm__alloc_huge((batch ? batch : 1) * sizeof(double));
    s->normals = malloc((na ? na : 1) * (size_t)(dim + 1) * sizeof(double));
    s->gathered_hint = hints_new(nv);
    size_t nfp = (na ? na : 1) * nq;
    s->cur_points = sm__alloc_huge(nfp * (size_t)dim * sizeof(double));
    s->cur_values = sm__alloc_huge(nfp * sizeof(double));
    s->end_points = sm__alloc_huge(nfp * (size_t)dim * sizeof(double));
    s->end_values = sm__alloc_huge(nfp * sizeof(double));
    s->end_hint = hints_new(nfp);
    if (!s->load_hint || !s->swept_hint || !s->vertex_hint || !s->elem_hint || !s->points ||
        !s->values || !s->weights || !s->normals || !s->gathered_hint || !s->cur_points ||
        !s->cur_values || !s->end_points || !s->end_values || !s->end_hint) {
        sm__shape_free(s);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    }
    *out = s;
    return SM_OK;
}

void sm__shape_free(sm_shape *s)
{
    if (!s)
        return;
    free(s->active);
    free(s->active_vertex);
    free(s->load_hint);
    free(s->swept_hint);
    free(s->vertex_hint);
    free(s->elem_hint);
    free(s->elem_order);
    free(s->points);
    free(s->values);
    free(s->weights);
    free(s->normals);
    free(s->gathered_hint);
    free(s->cur_points);
    free(s->cur_values);
    free(s->end_points);
    free(s->end_values);
    free(s->end_hint);
    free(s);
}

int32_t sm__shape_active_facets(const sm_shape *s)
{
    return s->nactive;
}

static inline const double *vtx(const double *coords, int dim, int32_t v)
{
    return coords + (size_t)v * (size_t)dim;
}

/* The calling thread's share [*lo, *hi) of n items, in a parallel
 * region: contiguous, in thread order (each thread's walks follow one
 * another through neighbouring points). */
static void thread_share(int64_t n, int64_t *lo, int64_t *hi)
{
#ifdef _OPENMP
    int nt = omp_get_num_threads(), t = omp_get_thread_num();
#else
    int nt = 1, t = 0;
#endif
    *lo = n * t / nt;
    *hi = n * (t + 1) / nt;
}

/* Evaluates d at n gathered points, the threads splitting the batch. */
static void eval_batch(const sm_shape *s, int64_t n, const double *points, int32_t *hints,
                       double *values)
{
    const int dim = s->mesh->dim;
#pragma omp parallel
    {
        int64_t lo, hi;
        thread_share(n, &lo, &hi);
        if (hi > lo)
            sm_field_eval_many(s->field, hi - lo, points + lo * dim, hints + lo, values + lo);
    }
}

/* The points at half the step (n at half, hints and values at
 * hints[0..n), values[0..n)) and then at its end (points half + n * dim,
 * hints and values at [n..2n)), each end walk starting from the element
 * its half walk found.  Block by block, the end walks follow the half
 * walks of the same points while their elements are still in cache (two
 * passes over all the points read most of them from memory twice).
 * Each walk is its point's alone, from the same element as in two
 * passes, so the values are the same. */
#define SWEPT_BLOCK 1024
static void eval_swept(const sm_shape *s, int64_t n, const double *half, int32_t *hints,
                       double *values)
{
    const int dim = s->mesh->dim;
    const double *end = half + n * dim;
#pragma omp parallel
    {
        int64_t lo, hi;
        thread_share(n, &lo, &hi);
        for (int64_t a = lo; a < hi; a += SWEPT_BLOCK) {
            int64_t b = a + SWEPT_BLOCK < hi ? a + SWEPT_BLOCK : hi;
            sm_field_eval_many(s->field, b - a, half + a * dim, hints + a, values + a);
            memcpy(hints + n + a, hints + a, (size_t)(b - a) * sizeof *hints);
            sm_field_eval_many(s->field, b - a, end + a * dim, hints + n + a, values + n + a);
        }
    }
}

/* The first evaluation of a point without a hint starts from the grid
 * (a few hundred ns each, most of the set-up's sampling: 4 points per
 * element for the volume J, 3 per facet for the load).  So before the
 * first one, d is evaluated at every vertex (sm_field_eval_points: in
 * Morton order, each walk from its predecessor's element), and every
 * quadrature point starts from the element found for the vertex it lies
 * closest to. */
static void prime_hints(sm_shape *s, const double *coords)
{
    const sm_mesh *m = s->mesh;
    const int dim = m->dim, nq = s->nq, nv = dim + 1;
    sm_field_eval_points(s->field, m->nverts, coords, s->vertex_hint, s->values);
    for (int32_t k = 0; k < s->nactive; k++) {
        /* facet quadrature point q weighs facet vertex q most */
        const int32_t *fv = m->bfacets + (size_t)s->active[k] * (size_t)dim;
        for (int q = 0; q < nq; q++)
            s->load_hint[(size_t)k * (size_t)nq + (size_t)q] = s->vertex_hint[fv[q % dim]];
    }
    for (int32_t p = 0; p < m->nelems; p++) {
        /* volume point i weighs vertex i most (2D: edge midpoint i, i+1) */
        const int32_t *ev = m->elems + (size_t)s->elem_order[p] * (size_t)nv;
        for (int i = 0; i < nv; i++)
            s->elem_hint[(size_t)p * (size_t)nv + (size_t)i] = s->vertex_hint[ev[i]];
    }
    s->primed = 1;
}

/* Barycentric coordinates and weight of facet quadrature point q. */
static void facet_rule(int dim, int q, double *lam, double *w)
{
    const double *l = dim == 2 ? seg_l[q] : tri_l[q];
    for (int i = 0; i < dim; i++)
        lam[i] = l[i];
    *w = dim == 2 ? seg_w[q] : tri_w[q];
}

/* Facet quadrature point q of a facet whose vertices are at a[0..dim-1]:
 * the one expression of every facet point, so that the end of a step and
 * the mesh it leads to give the same point to the bit. */
static inline __attribute__((always_inline)) void facet_point(const int D, double a[3][3], int q,
                                                              double *x)
{
    const double *lam = D == 2 ? seg_l[q] : tri_l[q];
    for (int c = 0; c < D; c++) {
        x[c] = 0.0;
        for (int i = 0; i < D; i++)
            x[c] += lam[i] * a[i][c];
    }
}

/* d at the facet points pts (nactive * nq): taken from a previous sample
 * of exactly these points when there is one (the end of the accepted
 * step), else evaluated with hints. */
static void sample_facet_points(sm_shape *s, const double *pts, double *values)
{
    const int dim = s->mesh->dim;
    const size_t n = (size_t)s->nactive * (size_t)s->nq;
    if (s->have_end && memcmp(pts, s->end_points, n * (size_t)dim * sizeof *pts) == 0) {
        memcpy(values, s->end_values, n * sizeof *values);
        memcpy(s->load_hint, s->end_hint, n * sizeof *s->load_hint);
        return;
    }
    eval_batch(s, (int64_t)n, pts, s->load_hint, values);
}

void sm__shape_load(sm_shape *s, const double *coords, double *load, sm_boundary_error *be)
{
    const sm_mesh *m = s->mesh;
    const int dim = m->dim, nq = s->nq;
    const int32_t na = s->nactive;
    if (!s->primed)
        prime_hints(s, coords);
    /* gather the quadrature points, remember normal and measure */
#pragma omp parallel for schedule(static)
    for (int32_t k = 0; k < na; k++) {
        double *nk = s->normals + (size_t)k * (size_t)(dim + 1);
        nk[dim] = sm_bfacet_normal(m, coords, s->active[k], nk);
        const int32_t *fv = m->bfacets + (size_t)s->active[k] * (size_t)dim;
        double a[3][3];
        for (int i = 0; i < dim; i++)
            for (int c = 0; c < dim; c++)
                a[i][c] = vtx(coords, dim, fv[i])[c];
        double *pts = s->cur_points + (size_t)k * (size_t)nq * (size_t)dim;
        for (int q = 0; q < nq; q++) {
            if (dim == 2)
                facet_point(2, a, q, pts + (size_t)q * 2);
            else
                facet_point(3, a, q, pts + (size_t)q * 3);
        }
    }
    sample_facet_points(s, s->cur_points, s->cur_values);
    s->have_cur = 1;
    s->have_end = 0;

    /* scatter (serial: facets share vertices) */
    memset(load, 0, (size_t)m->nverts * (size_t)dim * sizeof(double));
    double sum_sq = 0.0, maxabs = 0.0, measure = 0.0;
    for (int32_t k = 0; k < na; k++) {
        const int32_t *fv = m->bfacets + (size_t)s->active[k] * (size_t)dim;
        const double *nk = s->normals + (size_t)k * (size_t)(dim + 1);
        for (int q = 0; q < nq; q++) {
            double lam[3], w;
            facet_rule(dim, q, lam, &w);
            double d = s->cur_values[(size_t)k * (size_t)nq + (size_t)q];
            double wd = w * nk[dim] * d;
            sum_sq += wd * d;
            measure += w * nk[dim];
            if (fabs(d) > maxabs)
                maxabs = fabs(d);
            for (int i = 0; i < dim; i++)
                for (int c = 0; c < dim; c++)
                    load[(size_t)fv[i] * (size_t)dim + (size_t)c] -= wd * lam[i] * nk[c];
        }
    }
    /* d at the boundary vertices themselves, for the max */
    int64_t nbv = 0;
    for (int32_t v = 0; v < m->nverts; v++)
        if (s->active_vertex[v]) {
            memcpy(s->points + nbv * dim, vtx(coords, dim, v), (size_t)dim * sizeof(double));
            s->gathered_hint[nbv++] = s->vertex_hint[v];
        }
    eval_batch(s, nbv, s->points, s->gathered_hint, s->values);
    nbv = 0;
    for (int32_t v = 0; v < m->nverts; v++)
        if (s->active_vertex[v]) {
            s->vertex_hint[v] = s->gathered_hint[nbv];
            if (fabs(s->values[nbv]) > maxabs)
                maxabs = fabs(s->values[nbv]);
            nbv++;
        }
    be->l2 = sqrt(sum_sq);
    be->max = maxabs;
    be->measure = measure;
}

/* The points of active facet k at the pseudo-times of Simpson's rule and
 * their weights (the rule's times the rate at which the point sweeps
 * area, 2D: length, times the facet rule's weight), so that summing d
 * times the weights integrates d over the region the facet sweeps: point
 * (k, q) at time t_j is pts[j * nfp + k * nq + q]. */
static inline __attribute__((always_inline)) void
swept_points(const sm_shape *s, const double *coords, const double *disp, int32_t k, size_t nfp,
             double *pts, double *weights, const int D)
{
    const int nq = s->nq;
    const int32_t *fv = s->mesh->bfacets + (size_t)s->active[k] * (size_t)D;
    double p[3][3], u[3][3], th[3][3];
    for (int i = 0; i < D; i++)
        for (int c = 0; c < D; c++) {
            p[i][c] = vtx(coords, D, fv[i])[c];
            u[i][c] = vtx(disp, D, fv[i])[c];
        }
    for (int q = 0; q < nq; q++) { /* the point's velocity */
        const double *lam = D == 2 ? seg_l[q] : tri_l[q];
        for (int c = 0; c < D; c++) {
            th[q][c] = 0.0;
            for (int i = 0; i < D; i++)
                th[q][c] += lam[i] * u[i][c];
        }
    }
    for (int j = 0; j < SWEPT_NS; j++) {
        double a[3][3], nrm[3];
        for (int i = 0; i < D; i++)
            for (int c = 0; c < D; c++)
                a[i][c] = p[i][c] + simpson_t[j] * u[i][c];
        if (D == 2) { /* outward normal times length: (t_y, -t_x) */
            nrm[0] = a[1][1] - a[0][1];
            nrm[1] = -(a[1][0] - a[0][0]);
        } else { /* half the cross product: area times the normal */
            double e1[3], e2[3];
            for (int c = 0; c < 3; c++) {
                e1[c] = a[1][c] - a[0][c];
                e2[c] = a[2][c] - a[0][c];
            }
            nrm[0] = 0.5 * (e1[1] * e2[2] - e1[2] * e2[1]);
            nrm[1] = 0.5 * (e1[2] * e2[0] - e1[0] * e2[2]);
            nrm[2] = 0.5 * (e1[0] * e2[1] - e1[1] * e2[0]);
        }
        for (int q = 0; q < nq; q++) {
            size_t idx = (size_t)j * nfp + (size_t)k * (size_t)nq + (size_t)q;
            facet_point(D, a, q, pts + idx * (size_t)D);
            double rate = 0.0;
            for (int c = 0; c < D; c++)
                rate += nrm[c] * th[q][c];
            weights[idx] = simpson_w[j] * (D == 2 ? seg_w[q] : tri_w[q]) * rate;
        }
    }
}

double sm__shape_delta_j(sm_shape *s, const double *coords, const double *disp)
{
    const sm_mesh *m = s->mesh;
    const int dim = m->dim, nq = s->nq;
    const int32_t na = s->nactive;
    const size_t nfp = (size_t)na * (size_t)nq;
    if (!s->primed)
        prime_hints(s, coords);
    /* the points at t = 0 (the start, compared with the current mesh's
     * samples), 1/2 and 1 (the end): point (k, q) at pseudo-time t_j is
     * points[j * nfp + k * nq + q], with its Jacobian weight */
#pragma omp parallel for schedule(static)
    for (int32_t k = 0; k < na; k++) {
        if (dim == 2)
            swept_points(s, coords, disp, k, nfp, s->points, s->weights, 2);
        else
            swept_points(s, coords, disp, k, nfp, s->points, s->weights, 3);
    }
    /* the points at half the step start from the element of the same
     * point at the start, those at the end from the one found at half:
     * each walk crosses half the step (early steps span several
     * background elements) */
    memcpy(s->swept_hint, s->load_hint, nfp * sizeof *s->swept_hint);
    double *start_values = s->values, *half_values = s->values + nfp;
    if (s->have_cur &&
        memcmp(s->points, s->cur_points, nfp * (size_t)dim * sizeof *s->points) == 0)
        memcpy(start_values, s->cur_values, nfp * sizeof *start_values);
    else
        eval_batch(s, (int64_t)nfp, s->points, s->load_hint, start_values);
    eval_swept(s, (int64_t)nfp, s->points + nfp * (size_t)dim, s->swept_hint, half_values);
    /* keep the end: the next load reuses it if this step is taken */
    memcpy(s->end_points, s->points + 2 * nfp * (size_t)dim, nfp * (size_t)dim * sizeof(double));
    memcpy(s->end_values, s->values + 2 * nfp, nfp * sizeof(double));
    memcpy(s->end_hint, s->swept_hint + nfp, nfp * sizeof(int32_t));
    s->have_end = 1;
    double total = 0.0;
    for (size_t i = 0; i < (size_t)SWEPT_NS * nfp; i++)
        total += s->weights[i] * s->values[i];
    return total;
}

double sm__shape_volume_j(sm_shape *s, const double *coords)
{
    const sm_mesh *m = s->mesh;
    const int dim = m->dim, nv = dim + 1;
    if (!s->primed)
        prime_hints(s, coords);
#pragma omp parallel for schedule(static)
    for (int32_t p = 0; p < m->nelems; p++) {
        const int32_t e = s->elem_order[p];
        const int32_t *ev = m->elems + (size_t)e * (size_t)nv;
        double w = fabs(sm_elem_volume(m, coords, e)) / nv;
        for (int i = 0; i < nv; i++) {
            size_t idx = (size_t)p * (size_t)nv + (size_t)i;
            double *x = s->points + idx * (size_t)dim;
            for (int c = 0; c < dim; c++) {
                if (dim == 2) /* edge midpoints */
                    x[c] = 0.5 * (vtx(coords, 2, ev[i])[c] + vtx(coords, 2, ev[(i + 1) % 3])[c]);
                else {
                    x[c] = 0.0;
                    for (int j = 0; j < 4; j++)
                        x[c] += (i == j ? tet_a : tet_b) * vtx(coords, 3, ev[j])[c];
                }
            }
            s->weights[idx] = w;
        }
    }
    int64_t n = (int64_t)m->nelems * nv;
    eval_batch(s, n, s->points, s->elem_hint, s->values);
    double total = 0.0;
    for (int64_t i = 0; i < n; i++)
        total += s->weights[i] * s->values[i];
    return total;
}
