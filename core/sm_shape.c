#include "sm_shape.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

struct sm_shape {
    const sm_mesh *mesh;
    const sm_field *field;
    int32_t nactive;
    int32_t *active;       /* indices of the active boundary facets */
    int32_t *load_hint;    /* background element last found, per facet quadrature point */
    int32_t *swept_hint;   /* same, per quadrature point of the swept region */
    int32_t *vertex_hint;  /* per vertex */
    int32_t *elem_hint;    /* per element (volume quadrature) */
    uint8_t *active_vertex;/* vertex touches an active facet */
    double *contrib;       /* per active facet load contributions (dim*dim) */
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
#define NQ_MAX 3
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

sm_status sm_shape_new(const sm_mesh *m, const sm_field *field, const int32_t *free_refs,
                       int nfree, sm_shape **out, sm_error *err)
{
    *out = NULL;
    if (!m->bfacets)
        return sm_error_set(err, SM_ERR_INVALID, "mesh boundary not built");
    sm_shape *s = calloc(1, sizeof *s);
    if (!s)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    s->mesh = m;
    s->field = field;
    size_t nb = (size_t)m->nbfacets + 1, nv = (size_t)m->nverts + 1, ne = (size_t)m->nelems + 1;
    s->active = malloc(nb * sizeof(int32_t));
    /* one hint per quadrature point: consecutive evaluations of the same
     * point (between iterations and trials) then walk only a few elements */
    s->load_hint = malloc(nb * NQ_MAX * sizeof(int32_t));
    s->swept_hint = malloc(nb * 2 * NQ_MAX * sizeof(int32_t));
    s->vertex_hint = malloc(nv * sizeof(int32_t));
    s->elem_hint = malloc(ne * sizeof(int32_t));
    s->active_vertex = calloc(nv, 1);
    s->contrib = malloc(nb * (size_t)(m->dim * m->dim) * sizeof(double));
    if (!s->active || !s->load_hint || !s->swept_hint || !s->vertex_hint || !s->elem_hint || !s->active_vertex ||
        !s->contrib) {
        sm_shape_free(s);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    }
    for (int32_t f = 0; f < m->nbfacets; f++) {
        if (is_free(m->bfacet_refs[f], free_refs, nfree))
            continue;
        s->active[s->nactive++] = f;
        for (int c = 0; c < m->dim; c++)
            s->active_vertex[m->bfacets[(size_t)f * (size_t)m->dim + (size_t)c]] = 1;
    }
    for (size_t i = 0; i < nb * NQ_MAX; i++)
        s->load_hint[i] = -1;
    for (size_t i = 0; i < nb * 2 * NQ_MAX; i++)
        s->swept_hint[i] = -1;
    for (size_t i = 0; i < nv; i++)
        s->vertex_hint[i] = -1;
    for (size_t i = 0; i < ne; i++)
        s->elem_hint[i] = -1;
    *out = s;
    return SM_OK;
}

void sm_shape_free(sm_shape *s)
{
    if (!s)
        return;
    free(s->active);
    free(s->load_hint);
    free(s->swept_hint);
    free(s->vertex_hint);
    free(s->elem_hint);
    free(s->active_vertex);
    free(s->contrib);
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

void sm_shape_load(sm_shape *s, const double *coords, double *load, sm_boundary_error *be)
{
    const sm_mesh *m = s->mesh;
    const int dim = m->dim;
    const int nq = dim == 2 ? SEG_NQ : TRI_NQ;
    double *contrib = s->contrib; /* per active facet: dim vertices x dim components */
    double sum_sq = 0.0, maxabs = 0.0;
    /* facets are independent (each owns its hint and its slot of contrib),
     * so they are sampled in parallel and scattered afterwards */
#pragma omp parallel for schedule(static) reduction(+ : sum_sq) reduction(max : maxabs)
    for (int32_t k = 0; k < s->nactive; k++) {
        int32_t f = s->active[k];
        const int32_t *fv = m->bfacets + (size_t)f * (size_t)dim;
        double n[3];
        double measure = sm_bfacet_normal(m, coords, f, n);
        double *ck = contrib + (size_t)k * (size_t)(dim * dim);
        for (int i = 0; i < dim * dim; i++)
            ck[i] = 0.0;
        for (int q = 0; q < nq; q++) {
            double lam[3], w, x[3] = {0, 0, 0};
            if (dim == 2) {
                lam[0] = 1.0 - seg_xi[q];
                lam[1] = seg_xi[q];
                w = seg_w[q];
            } else {
                memcpy(lam, tri_l[q], sizeof lam);
                w = tri_w[q];
            }
            for (int i = 0; i < dim; i++)
                for (int c = 0; c < dim; c++)
                    x[c] += lam[i] * vtx(coords, dim, fv[i])[c];
            double d = sm_field_eval(s->field, x, &s->load_hint[(size_t)k * NQ_MAX + (size_t)q]);
            double wd = w * measure * d;
            sum_sq += w * measure * d * d;
            if (fabs(d) > maxabs)
                maxabs = fabs(d);
            for (int i = 0; i < dim; i++)
                for (int c = 0; c < dim; c++)
                    ck[i * dim + c] -= wd * lam[i] * n[c];
        }
    }
#pragma omp parallel for schedule(static) reduction(max : maxabs)
    for (int32_t v = 0; v < m->nverts; v++) {
        if (!s->active_vertex[v])
            continue;
        double d = sm_field_eval(s->field, vtx(coords, dim, v), &s->vertex_hint[v]);
        if (fabs(d) > maxabs)
            maxabs = fabs(d);
    }
    memset(load, 0, (size_t)m->nverts * (size_t)dim * sizeof(double));
    for (int32_t k = 0; k < s->nactive; k++) {
        const int32_t *fv = m->bfacets + (size_t)s->active[k] * (size_t)dim;
        const double *ck = contrib + (size_t)k * (size_t)(dim * dim);
        for (int i = 0; i < dim; i++)
            for (int c = 0; c < dim; c++)
                load[(size_t)fv[i] * (size_t)dim + (size_t)c] += ck[i * dim + c];
    }
    be->l2 = sqrt(sum_sq);
    be->max = maxabs;
}

/* Integral of d over the region swept by one facet moving from p to
 * p + u (signed: positive when moving outward). */
static double swept_integral(sm_shape *s, const double *coords, const double *disp, int32_t k)
{
    const sm_mesh *m = s->mesh;
    const int dim = m->dim;
    int32_t f = s->active[k];
    const int32_t *fv = m->bfacets + (size_t)f * (size_t)dim;
    double p[3][3], u[3][3];
    for (int i = 0; i < dim; i++)
        for (int c = 0; c < dim; c++) {
            p[i][c] = vtx(coords, dim, fv[i])[c];
            u[i][c] = vtx(disp, dim, fv[i])[c];
        }
    double total = 0.0;
    for (int g = 0; g < 2; g++) {
        double sg = gauss_s[g];
        /* facet vertices at pseudo-time sg */
        double a[3][3];
        for (int i = 0; i < dim; i++)
            for (int c = 0; c < dim; c++)
                a[i][c] = p[i][c] + sg * u[i][c];
        if (dim == 2) {
            double t[2] = {a[1][0] - a[0][0], a[1][1] - a[0][1]};
            for (int q = 0; q < SEG_NQ; q++) {
                double xi = seg_xi[q];
                double x[2], th[2];
                for (int c = 0; c < 2; c++) {
                    x[c] = (1 - xi) * a[0][c] + xi * a[1][c];
                    th[c] = (1 - xi) * u[0][c] + xi * u[1][c];
                }
                /* outward normal times length is (t_y, -t_x) */
                double jac = t[1] * th[0] - t[0] * th[1];
                int32_t *hint = &s->swept_hint[((size_t)k * 2 + (size_t)g) * NQ_MAX + (size_t)q];
                if (*hint < 0)
                    *hint = s->load_hint[(size_t)k * NQ_MAX + (size_t)q];
                total += 0.5 * seg_w[q] * jac * sm_field_eval(s->field, x, hint);
            }
        } else {
            double e1[3], e2[3], cr[3];
            for (int c = 0; c < 3; c++) {
                e1[c] = a[1][c] - a[0][c];
                e2[c] = a[2][c] - a[0][c];
            }
            cr[0] = e1[1] * e2[2] - e1[2] * e2[1];
            cr[1] = e1[2] * e2[0] - e1[0] * e2[2];
            cr[2] = e1[0] * e2[1] - e1[1] * e2[0];
            for (int q = 0; q < TRI_NQ; q++) {
                double x[3] = {0, 0, 0}, th[3] = {0, 0, 0};
                for (int i = 0; i < 3; i++)
                    for (int c = 0; c < 3; c++) {
                        x[c] += tri_l[q][i] * a[i][c];
                        th[c] += tri_l[q][i] * u[i][c];
                    }
                /* |cross| is twice the area; reference triangle area 1/2 */
                double jac = 0.5 * (cr[0] * th[0] + cr[1] * th[1] + cr[2] * th[2]);
                int32_t *hint = &s->swept_hint[((size_t)k * 2 + (size_t)g) * NQ_MAX + (size_t)q];
                if (*hint < 0)
                    *hint = s->load_hint[(size_t)k * NQ_MAX + (size_t)q];
                total += 0.5 * tri_w[q] * jac * sm_field_eval(s->field, x, hint);
            }
        }
    }
    return total;
}

double sm_shape_delta_j(sm_shape *s, const double *coords, const double *disp)
{
    double total = 0.0;
#pragma omp parallel for schedule(static) reduction(+ : total)
    for (int32_t k = 0; k < s->nactive; k++)
        total += swept_integral(s, coords, disp, k);
    return total;
}

double sm_shape_volume_j(sm_shape *s, const double *coords)
{
    const sm_mesh *m = s->mesh;
    const int dim = m->dim, nv = dim + 1;
    double total = 0.0;
#pragma omp parallel for schedule(static) reduction(+ : total)
    for (int32_t e = 0; e < m->nelems; e++) {
        const int32_t *ev = m->elems + (size_t)e * (size_t)nv;
        double vol = fabs(sm_elem_volume(m, coords, e));
        double sum = 0.0;
        if (dim == 2) {
            for (int i = 0; i < 3; i++) {
                const double *a = vtx(coords, 2, ev[i]), *b = vtx(coords, 2, ev[(i + 1) % 3]);
                double x[2] = {0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])};
                sum += sm_field_eval(s->field, x, &s->elem_hint[e]) / 3.0;
            }
        } else {
            for (int i = 0; i < 4; i++) {
                double x[3] = {0, 0, 0};
                for (int j = 0; j < 4; j++)
                    for (int c = 0; c < 3; c++)
                        x[c] += (i == j ? tet_a : tet_b) * vtx(coords, 3, ev[j])[c];
                sum += sm_field_eval(s->field, x, &s->elem_hint[e]) / 4.0;
            }
        }
        total += vol * sum;
    }
    return total;
}

void sm_shape_sample_vertices(sm_shape *s, const double *coords, double *values)
{
    const sm_mesh *m = s->mesh;
#pragma omp parallel for schedule(static)
    for (int32_t v = 0; v < m->nverts; v++)
        values[v] = sm_field_eval(s->field, vtx(coords, m->dim, v), &s->vertex_hint[v]);
}
