/* The alignment's point sets and volume moments (sm_align_internal.h):
 * quadrature points of the template's boundary and of the target's
 * surface (a triangle surface, or the zero level set of a sampled
 * distance), and the moments of the volumes they bound. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sm_align_internal.h"
#include "sm_bvh.h"

void sm__align_pts_free(sm__align_pts *p)
{
    free(p->x);
    free(p->w);
    free(p->y);
    free(p->u);
    free(p->r);
    free(p->g);
    free(p->nrm);
    free(p->hints);
    free(p->nearest);
    memset(p, 0, sizeof *p);
}

sm_status sm__align_pts_alloc(sm__align_pts *p, int dim, int64_t n, sm_error *err)
{
    memset(p, 0, sizeof *p);
    p->dim = dim;
    p->n = n;
    size_t m = (size_t)n + 1;
    p->x = malloc(m * dim * sizeof *p->x);
    p->w = malloc(m * sizeof *p->w);
    p->y = malloc(m * dim * sizeof *p->y);
    p->u = malloc(m * dim * sizeof *p->u);
    p->r = malloc(m * sizeof *p->r);
    p->g = malloc(m * dim * sizeof *p->g);
    p->nrm = malloc(m * dim * sizeof *p->nrm);
    p->hints = malloc(m * sizeof *p->hints);
    p->nearest = malloc(m * sizeof *p->nearest);
    if (!p->x || !p->w || !p->y || !p->u || !p->r || !p->g || !p->nrm || !p->hints || !p->nearest) {
        sm__align_pts_free(p);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the alignment's points");
    }
    return SM_OK;
}

void sm__align_pts_done(sm__align_pts *p)
{
    p->wsum = 0;
    for (int64_t i = 0; i < p->n; i++) {
        p->wsum += p->w[i];
        p->hints[i] = p->nearest[i] = -1;
    }
}

sm_status sm__align_pts_sample(const sm__align_pts *from, int64_t cap, sm__align_pts *to,
                               sm_error *err)
{
    int64_t step = from->n > cap ? (from->n + cap - 1) / cap : 1;
    int64_t n = (from->n + step - 1) / step;
    sm_status st = sm__align_pts_alloc(to, from->dim, n, err);
    if (st != SM_OK)
        return st;
    const int dim = from->dim;
    for (int64_t i = 0; i < n; i++) {
        memcpy(to->x + i * dim, from->x + i * step * dim, dim * sizeof *to->x);
        memcpy(to->nrm + i * dim, from->nrm + i * step * dim, dim * sizeof *to->nrm);
        to->w[i] = from->w[i * step];
    }
    sm__align_pts_done(to);
    return SM_OK;
}

/* The rule's points of the facet with vertices v (dim of them, each dim
 * coordinates), weight measure / points each, at p->x + k * dim. */
static void facet_points(int dim, const double *v[3], double measure, const double *normal,
                         sm__align_pts *p, int64_t k)
{
    /* 2D: 2 Gauss points per edge; 3D: the 3-point rule per triangle
     * (barycentric 2/3, 1/6, 1/6): exact for quadratics, so the misfit of
     * an exactly aligned P1 field is its interpolation error only */
    static const double g2[2] = {0.21132486540518713, 0.78867513459481287};
    const int per = dim == 2 ? 2 : 3;
    for (int q = 0; q < per; q++) {
        double lam[3];
        if (dim == 2) {
            lam[0] = g2[q];
            lam[1] = 1 - g2[q];
        } else {
            lam[0] = lam[1] = lam[2] = 1.0 / 6;
            lam[q] = 2.0 / 3;
        }
        double *x = p->x + (k + q) * dim;
        for (int c = 0; c < dim; c++) {
            x[c] = 0;
            for (int i = 0; i < dim; i++)
                x[c] += lam[i] * v[i][c];
        }
        p->w[k + q] = measure / per;
        memcpy(p->nrm + (k + q) * dim, normal, dim * sizeof *normal);
    }
}

sm_status sm__align_mesh_boundary_pts(const sm_mesh *m, sm__align_pts *p, sm_error *err)
{
    const int dim = m->dim, per = dim == 2 ? 2 : 3;
    sm_status st = sm__align_pts_alloc(p, dim, (int64_t)m->nbfacets * per, err);
    if (st != SM_OK)
        return st;
    for (int32_t f = 0; f < m->nbfacets; f++) {
        double normal[3];
        double area = sm_bfacet_normal(m, m->coords, f, normal);
        const int32_t *fv = m->bfacets + (size_t)f * dim;
        const double *v[3];
        for (int i = 0; i < dim; i++)
            v[i] = m->coords + (size_t)fv[i] * dim;
        facet_points(dim, v, area, normal, p, (int64_t)f * per);
    }
    sm__align_pts_done(p);
    return SM_OK;
}

sm_status sm__align_surface_pts(const sm_surface *s, sm__align_pts *p, sm_error *err)
{
    const int dim = s->dim, per = dim == 2 ? 2 : 3;
    sm_status st = sm__align_pts_alloc(p, dim, (int64_t)s->nfacets * per, err);
    if (st != SM_OK)
        return st;
    for (int32_t f = 0; f < s->nfacets; f++) {
        double n[3], c[3];
        sm__bvh_facet_moments(s, f, n, c);
        const int32_t *fv = s->facets + (size_t)f * dim;
        const double *v[3];
        for (int i = 0; i < dim; i++)
            v[i] = s->coords + (size_t)fv[i] * dim;
        double a = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        for (int c2 = 0; c2 < 3 && a > 0; c2++)
            n[c2] /= a;
        facet_points(dim, v, a, n, p, (int64_t)f * per);
    }
    sm__align_pts_done(p);
    return SM_OK;
}

/* The point where the field crosses zero on edge ab. */
static void crossing(int dim, const double *a, const double *b, double da, double db, double *x)
{
    double t = da / (da - db);
    for (int c = 0; c < dim; c++)
        x[c] = a[c] + t * (b[c] - a[c]);
}

/* Appends the centroid of the cut piece q[0..np) (a segment, a triangle)
 * weighted by its measure, its normal turned along out (from the inside
 * to the outside). */
static void add_piece(int dim, double q[][3], int np, const double *out, sm__align_pts *p)
{
    double meas, n[3] = {0, 0, 0};
    if (dim == 2) {
        n[0] = q[1][1] - q[0][1];
        n[1] = q[0][0] - q[1][0];
        meas = hypot(n[0], n[1]);
    } else {
        double u[3], v[3];
        for (int c = 0; c < 3; c++) {
            u[c] = q[1][c] - q[0][c];
            v[c] = q[2][c] - q[0][c];
        }
        n[0] = u[1] * v[2] - u[2] * v[1];
        n[1] = u[2] * v[0] - u[0] * v[2];
        n[2] = u[0] * v[1] - u[1] * v[0];
        meas = 0.5 * sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    }
    if (!(meas > 0))
        return;
    double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]), side = 0;
    for (int c = 0; c < dim; c++)
        side += n[c] * out[c];
    for (int c = 0; c < dim; c++)
        p->nrm[p->n * dim + c] = (side < 0 ? -n[c] : n[c]) / len;
    double *x = p->x + p->n * dim;
    for (int c = 0; c < dim; c++) {
        x[c] = 0;
        for (int i = 0; i < np; i++)
            x[c] += q[i][c] / np;
    }
    p->w[p->n++] = meas;
}

sm_status sm__align_level_set_pts(const sm_mesh *bg, const double *values, sm__align_pts *p,
                                  sm_error *err)
{
    const int dim = bg->dim, nv = dim + 1;
    int64_t cut = 0;
    for (int32_t e = 0; e < bg->nelems; e++) {
        int in = 0;
        for (int i = 0; i < nv; i++)
            in += values[bg->elems[(size_t)e * nv + i]] < 0;
        cut += in > 0 && in < nv;
    }
    /* a 2-2 cut of a tetrahedron is a quadrilateral: two triangles */
    sm_status st = sm__align_pts_alloc(p, dim, 2 * cut, err);
    if (st != SM_OK)
        return st;
    p->n = 0;
    for (int32_t e = 0; e < bg->nelems; e++) {
        const int32_t *ev = bg->elems + (size_t)e * nv;
        int inside[4], outside[4], ni = 0, no = 0;
        for (int i = 0; i < nv; i++) {
            if (values[ev[i]] < 0)
                inside[ni++] = ev[i];
            else
                outside[no++] = ev[i];
        }
        if (ni == 0 || no == 0)
            continue;
        double q[4][3] = {{0}}, out[3] = {0, 0, 0};
        int np = 0;
        /* inside to outside: the vertex means' difference */
        for (int c = 0; c < dim; c++) {
            for (int i = 0; i < no; i++)
                out[c] += bg->coords[(size_t)outside[i] * dim + c] / no;
            for (int i = 0; i < ni; i++)
                out[c] -= bg->coords[(size_t)inside[i] * dim + c] / ni;
        }
        /* the crossings in cyclic order: for a 2-2 cut, edges (i0,o0),
         * (i0,o1), (i1,o1), (i1,o0) go round the quadrilateral */
        static const int quad[4][2] = {{0, 0}, {0, 1}, {1, 1}, {1, 0}};
        if (ni == 2 && no == 2) {
            for (int k = 0; k < 4; k++, np++) {
                int a = inside[quad[k][0]], b = outside[quad[k][1]];
                crossing(dim, bg->coords + (size_t)a * dim, bg->coords + (size_t)b * dim,
                         values[a], values[b], q[np]);
            }
            double t2[3][3];
            memcpy(t2[0], q[0], sizeof t2[0]);
            memcpy(t2[1], q[2], sizeof t2[1]);
            memcpy(t2[2], q[3], sizeof t2[2]);
            add_piece(dim, q, 3, out, p);
            add_piece(dim, t2, 3, out, p);
            continue;
        }
        for (int i = 0; i < ni; i++)
            for (int o = 0; o < no; o++, np++) {
                int a = inside[i], b = outside[o];
                crossing(dim, bg->coords + (size_t)a * dim, bg->coords + (size_t)b * dim,
                         values[a], values[b], q[np]);
            }
        add_piece(dim, q, np, out, p);
    }
    sm__align_pts_done(p);
    return SM_OK;
}

/* ------------------------------------------------------------- moments */

/* Accumulates a simplex of (signed) measure vol times frac (vertices
 * relative to ref): int x x^T over a simplex = V/((d+1)(d+2)) (sum v v^T
 * + s s^T), s the vertex sum. */
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

static int finish_moments(int dim, const double *ref, double mass, const double first[3],
                          const double second[3][3], sm__moments *out)
{
    if (!(mass > 0) || !isfinite(mass))
        return -1;
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
    return 0;
}

int sm__align_mesh_moments(const sm_mesh *m, const double *values, sm__moments *out)
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
    return finish_moments(dim, ref, mass, first, second, out);
}

int sm__align_surface_moments(const sm_surface *s, sm__moments *out)
{
    const int dim = s->dim;
    if (s->nverts <= 0)
        return -1;
    double mass = 0, first[3] = {0, 0, 0}, second[3][3] = {{0}};
    /* the apex: the box centre, so that the signed simplices stay small */
    double ref[3] = {0, 0, 0}, lo[3] = {INFINITY, INFINITY, INFINITY},
           hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int32_t v = 0; v < s->nverts; v++)
        for (int c = 0; c < dim; c++) {
            lo[c] = fmin(lo[c], s->coords[(size_t)v * dim + c]);
            hi[c] = fmax(hi[c], s->coords[(size_t)v * dim + c]);
        }
    for (int c = 0; c < dim; c++)
        ref[c] = 0.5 * (lo[c] + hi[c]);
    for (int32_t f = 0; f < s->nfacets; f++) {
        const int32_t *fv = s->facets + (size_t)f * dim;
        const double *v[4] = {ref};
        for (int i = 0; i < dim; i++)
            v[i + 1] = s->coords + (size_t)fv[i] * dim;
        double vol;
        if (dim == 2) {
            vol = 0.5 * ((v[1][0] - ref[0]) * (v[2][1] - ref[1]) -
                         (v[1][1] - ref[1]) * (v[2][0] - ref[0]));
        } else {
            double a[3], b[3], c[3];
            for (int k = 0; k < 3; k++) {
                a[k] = v[1][k] - ref[k];
                b[k] = v[2][k] - ref[k];
                c[k] = v[3][k] - ref[k];
            }
            vol = (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) +
                   a[2] * (b[0] * c[1] - b[1] * c[0])) /
                  6;
        }
        add_simplex(dim, v, ref, vol, 1, &mass, first, second);
    }
    return finish_moments(dim, ref, mass, first, second, out);
}
