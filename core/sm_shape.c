#include "sm_shape.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

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
    int32_t *elem_hint;    /* nelems * (dim+1) volume quadrature points */
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
};

/* Facet rules on the reference simplex, exact for degree 2 (enough for
 * d*phi_i with d affine).  Weights sum to 1 (multiply by the measure). */
#define SEG_NQ 2
static const double seg_xi[SEG_NQ] = {0.21132486540518711775, 0.78867513459481288225};
static const double seg_w[SEG_NQ] = {0.5, 0.5};
#define TRI_NQ 3
static const double tri_l[TRI_NQ][3] = {{2.0 / 3, 1.0 / 6, 1.0 / 6},
                                         {1.0 / 6, 2.0 / 3, 1.0 / 6},
                                         {1.0 / 6, 1.0 / 6, 2.0 / 3}};
static const double tri_w[TRI_NQ] = {1.0 / 3, 1.0 / 3, 1.0 / 3};
/* 2-point Gauss on [0,1] along the motion. */
static const double gauss_s[2] = {0.21132486540518711775, 0.78867513459481288225};
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
    int32_t *h = malloc((n ? n : 1) * sizeof(int32_t));
    if (h)
        for (size_t i = 0; i < n; i++)
            h[i] = -1;
    return h;
}

sm_status sm_shape_new(const sm_mesh *m, const sm_field *field, const int32_t *free_refs,
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
        sm_shape_free(s);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    }
    for (int32_t f = 0; f < m->nbfacets; f++) {
        if (is_free(m->bfacet_refs[f], free_refs, nfree))
            continue;
        s->active[s->nactive++] = f;
        for (int c = 0; c < dim; c++)
            s->active_vertex[m->bfacets[(size_t)f * (size_t)dim + (size_t)c]] = 1;
    }
    size_t na = (size_t)s->nactive, nq = (size_t)s->nq;
    size_t batch = na * 2 * nq; /* the swept region has the most points */
    if (nv > batch)
        batch = nv;
    if (ne * (size_t)(dim + 1) > batch)
        batch = ne * (size_t)(dim + 1);
    s->load_hint = hints_new(na * nq);
    s->swept_hint = hints_new(na * 2 * nq);
    s->vertex_hint = hints_new(nv);
    s->elem_hint = hints_new(ne * (size_t)(dim + 1));
    s->points = malloc((batch ? batch : 1) * (size_t)dim * sizeof(double));
    s->values = malloc((batch ? batch : 1) * sizeof(double));
    s->weights = malloc((batch ? batch : 1) * sizeof(double));
    s->normals = malloc((na ? na : 1) * (size_t)(dim + 1) * sizeof(double));
    s->gathered_hint = hints_new(nv);
    if (!s->load_hint || !s->swept_hint || !s->vertex_hint || !s->elem_hint || !s->points ||
        !s->values || !s->weights || !s->normals || !s->gathered_hint) {
        sm_shape_free(s);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    }
    *out = s;
    return SM_OK;
}

void sm_shape_free(sm_shape *s)
{
    if (!s)
        return;
    free(s->active);
    free(s->active_vertex);
    free(s->load_hint);
    free(s->swept_hint);
    free(s->vertex_hint);
    free(s->elem_hint);
    free(s->points);
    free(s->values);
    free(s->weights);
    free(s->normals);
    free(s->gathered_hint);
    free(s);
}

int32_t sm_shape_active_facets(const sm_shape *s)
{
    return s->nactive;
}

static inline const double *vtx(const double *coords, int dim, int32_t v)
{
    return coords + (size_t)v * (size_t)dim;
}

/* Evaluates d at n gathered points, the threads splitting the batch. */
static void eval_batch(const sm_shape *s, int64_t n, const double *points, int32_t *hints,
                       double *values)
{
    const int dim = s->mesh->dim;
#pragma omp parallel
    {
#ifdef _OPENMP
        int nt = omp_get_num_threads(), t = omp_get_thread_num();
#else
        int nt = 1, t = 0;
#endif
        int64_t lo = n * t / nt, hi = n * (t + 1) / nt;
        if (hi > lo)
            sm_field_eval_many(s->field, hi - lo, points + lo * dim, hints + lo, values + lo);
    }
}

/* The first evaluation of a point without a hint starts from the grid
 * (a few hundred ns each, most of the set-up's sampling: 4 points per
 * element for the volume J, 3 per facet for the load).  So before the
 * first one, d is evaluated at every vertex in turn, each walk starting
 * from the previous vertex's element (mesh generators number vertices
 * in runs of neighbours), and every quadrature point starts from the
 * element found for the vertex it lies closest to. */
static void prime_hints(sm_shape *s, const double *coords)
{
    const sm_mesh *m = s->mesh;
    const int dim = m->dim, nq = s->nq, nv = dim + 1;
    int32_t hint = -1;
    for (int32_t v = 0; v < m->nverts; v++) {
        (void)sm_field_eval(s->field, vtx(coords, dim, v), &hint);
        s->vertex_hint[v] = hint;
    }
    for (int32_t k = 0; k < s->nactive; k++) {
        /* facet quadrature point q weighs facet vertex q most */
        const int32_t *fv = m->bfacets + (size_t)s->active[k] * (size_t)dim;
        for (int q = 0; q < nq; q++)
            s->load_hint[(size_t)k * (size_t)nq + (size_t)q] = s->vertex_hint[fv[q % dim]];
    }
    for (int32_t e = 0; e < m->nelems; e++) {
        /* volume point i weighs vertex i most (2D: edge midpoint i, i+1) */
        const int32_t *ev = m->elems + (size_t)e * (size_t)nv;
        for (int i = 0; i < nv; i++)
            s->elem_hint[(size_t)e * (size_t)nv + (size_t)i] = s->vertex_hint[ev[i]];
    }
    s->primed = 1;
}

/* Barycentric coordinates and weight of facet quadrature point q. */
static void facet_rule(int dim, int q, double *lam, double *w)
{
    if (dim == 2) {
        lam[0] = 1.0 - seg_xi[q];
        lam[1] = seg_xi[q];
        *w = seg_w[q];
    } else {
        lam[0] = tri_l[q][0];
        lam[1] = tri_l[q][1];
        lam[2] = tri_l[q][2];
        *w = tri_w[q];
    }
}

void sm_shape_load(sm_shape *s, const double *coords, double *load, sm_boundary_error *be)
{
    const sm_mesh *m = s->mesh;
    const int dim = m->dim, nq = s->nq;
    const int32_t na = s->nactive;
    if (!s->primed)
        prime_hints(s, coords);
    /* gather the quadrature points, remember normal and measure */
#pragma omp parallel for schedule(static)
    for (int32_t k = 0; k < na; k++) {
        const int32_t *fv = m->bfacets + (size_t)s->active[k] * (size_t)dim;
        double *nk = s->normals + (size_t)k * (size_t)(dim + 1);
        nk[dim] = sm_bfacet_normal(m, coords, s->active[k], nk);
        for (int q = 0; q < nq; q++) {
            double lam[3], w;
            facet_rule(dim, q, lam, &w);
            double *x = s->points + ((size_t)k * (size_t)nq + (size_t)q) * (size_t)dim;
            for (int c = 0; c < dim; c++) {
                x[c] = 0.0;
                for (int i = 0; i < dim; i++)
                    x[c] += lam[i] * vtx(coords, dim, fv[i])[c];
            }
        }
    }
    eval_batch(s, (int64_t)na * nq, s->points, s->load_hint, s->values);

    /* scatter (serial: facets share vertices) */
    memset(load, 0, (size_t)m->nverts * (size_t)dim * sizeof(double));
    double sum_sq = 0.0, maxabs = 0.0, measure = 0.0;
    for (int32_t k = 0; k < na; k++) {
        const int32_t *fv = m->bfacets + (size_t)s->active[k] * (size_t)dim;
        const double *nk = s->normals + (size_t)k * (size_t)(dim + 1);
        for (int q = 0; q < nq; q++) {
            double lam[3], w;
            facet_rule(dim, q, lam, &w);
            double d = s->values[(size_t)k * (size_t)nq + (size_t)q];
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

double sm_shape_delta_j(sm_shape *s, const double *coords, const double *disp)
{
    const sm_mesh *m = s->mesh;
    const int dim = m->dim, nq = s->nq;
    const int32_t na = s->nactive;
    if (!s->primed)
        prime_hints(s, coords);
    /* gather the points of the swept regions with their Jacobian weights:
     * point (k, g, q) is facet quadrature point q at pseudo-time gauss_s[g] */
#pragma omp parallel for schedule(static)
    for (int32_t k = 0; k < na; k++) {
        const int32_t *fv = m->bfacets + (size_t)s->active[k] * (size_t)dim;
        double p[3][3], u[3][3];
        for (int i = 0; i < dim; i++)
            for (int c = 0; c < dim; c++) {
                p[i][c] = vtx(coords, dim, fv[i])[c];
                u[i][c] = vtx(disp, dim, fv[i])[c];
            }
        for (int g = 0; g < 2; g++) {
            double a[3][3];
            for (int i = 0; i < dim; i++)
                for (int c = 0; c < dim; c++)
                    a[i][c] = p[i][c] + gauss_s[g] * u[i][c];
            for (int q = 0; q < nq; q++) {
                size_t idx = ((size_t)k * 2 + (size_t)g) * (size_t)nq + (size_t)q;
                double lam[3], w, th[3] = {0, 0, 0}, jac;
                double *x = s->points + idx * (size_t)dim;
                facet_rule(dim, q, lam, &w);
                for (int c = 0; c < dim; c++) {
                    x[c] = 0.0;
                    for (int i = 0; i < dim; i++) {
                        x[c] += lam[i] * a[i][c];
                        th[c] += lam[i] * u[i][c];
                    }
                }
                if (dim == 2) {
                    /* outward normal times length is (t_y, -t_x) */
                    double t0 = a[1][0] - a[0][0], t1 = a[1][1] - a[0][1];
                    jac = t1 * th[0] - t0 * th[1];
                } else {
                    double e1[3], e2[3];
                    for (int c = 0; c < 3; c++) {
                        e1[c] = a[1][c] - a[0][c];
                        e2[c] = a[2][c] - a[0][c];
                    }
                    /* |e1 x e2| is twice the area; reference triangle area 1/2 */
                    jac = 0.5 * ((e1[1] * e2[2] - e1[2] * e2[1]) * th[0] +
                                 (e1[2] * e2[0] - e1[0] * e2[2]) * th[1] +
                                 (e1[0] * e2[1] - e1[1] * e2[0]) * th[2]);
                }
                s->weights[idx] = 0.5 * w * jac; /* 0.5: Gauss weight in s */
                /* from the element of the matching facet point at coords:
                 * a fraction of the step away, where the same point of
                 * the previous trial (another step, often another
                 * iteration) is farther, by up to the whole step */
                s->swept_hint[idx] = s->load_hint[(size_t)k * (size_t)nq + (size_t)q];
            }
        }
    }
    int64_t n = (int64_t)na * 2 * nq;
    eval_batch(s, n, s->points, s->swept_hint, s->values);
    double total = 0.0;
    for (int64_t i = 0; i < n; i++)
        total += s->weights[i] * s->values[i];
    return total;
}

double sm_shape_volume_j(sm_shape *s, const double *coords)
{
    const sm_mesh *m = s->mesh;
    const int dim = m->dim, nv = dim + 1;
    if (!s->primed)
        prime_hints(s, coords);
#pragma omp parallel for schedule(static)
    for (int32_t e = 0; e < m->nelems; e++) {
        const int32_t *ev = m->elems + (size_t)e * (size_t)nv;
        double w = fabs(sm_elem_volume(m, coords, e)) / nv;
        for (int i = 0; i < nv; i++) {
            size_t idx = (size_t)e * (size_t)nv + (size_t)i;
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

void sm_shape_sample_vertices(sm_shape *s, const double *coords, double *values)
{
    if (!s->primed)
        prime_hints(s, coords);
    eval_batch(s, s->mesh->nverts, coords, s->vertex_hint, values);
}
