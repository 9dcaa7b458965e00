#include "sm_relax.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Descent steps per vertex and pass, and the halvings of one step. */
#define RELAX_STEPS 4
#define RELAX_HALVINGS 8
/* The first trial moves a vertex by this fraction of its mean edge; the
 * finite differences of the gradient use a much smaller one (the
 * qualities are smooth and scale-free, so a relative step suffices). */
#define RELAX_FIRST_MOVE 0.2
#define RELAX_FD_STEP 1e-5

struct sm_relax {
    const sm_mesh *mesh;
    const uint8_t *fixed;
    int32_t *first;   /* nverts + 1: CSR of the elements around a vertex */
    int32_t *elems;   /* first[nverts] */
    uint8_t *pick;    /* nverts: vertex chosen in this pass */
    int32_t *order;   /* nverts: the chosen vertices */
};

sm_status sm__relax_new(const sm_mesh *m, const uint8_t *fixed, sm_relax **out, sm_error *err)
{
    *out = NULL;
    sm_relax *r = calloc(1, sizeof *r);
    const int nv = m->dim + 1;
    const size_t total = (size_t)m->nelems * (size_t)nv;
    if (r) {
        r->first = calloc((size_t)m->nverts + 1, sizeof *r->first);
        r->elems = malloc((total + 1) * sizeof *r->elems);
        r->pick = calloc((size_t)m->nverts + 1, 1);
        r->order = malloc(((size_t)m->nverts + 1) * sizeof *r->order);
    }
    if (!r || !r->first || !r->elems || !r->pick || !r->order) {
        sm__relax_free(r);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the relaxation of %ld vertices",
                            (long)m->nverts);
    }
    r->mesh = m;
    r->fixed = fixed;
    for (size_t i = 0; i < total; i++)
        r->first[m->elems[i] + 1]++;
    for (int32_t v = 0; v < m->nverts; v++)
        r->first[v + 1] += r->first[v];
    for (int32_t e = 0; e < m->nelems; e++)
        for (int i = 0; i < nv; i++) {
            int32_t v = m->elems[(size_t)e * (size_t)nv + (size_t)i];
            r->elems[r->first[v]++] = e;
        }
    for (int32_t v = m->nverts; v > 0; v--) /* undo the fill's shift */
        r->first[v] = r->first[v - 1];
    r->first[0] = 0;
    *out = r;
    return SM_OK;
}

void sm__relax_free(sm_relax *r)
{
    if (!r)
        return;
    free(r->first);
    free(r->elems);
    free(r->pick);
    free(r->order);
    free(r);
}

/* Sum of the inverse qualities of v's elements (INFINITY when one is
 * flat or inverted) and their worst quality. */
static double barrier(const sm_relax *r, const double *coords, int32_t v, double *qworst)
{
    double f = 0.0, qw = INFINITY;
    for (int32_t k = r->first[v]; k < r->first[v + 1]; k++) {
        double q = sm_elem_quality(r->mesh, coords, r->elems[k]);
        if (q < qw)
            qw = q;
        f = q > 0 ? f + 1.0 / q : INFINITY;
    }
    *qworst = qw;
    return f;
}

/* Mean length of the edges from v (the scale of its moves). */
static double edge_scale(const sm_relax *r, const double *coords, int32_t v)
{
    const sm_mesh *m = r->mesh;
    const int dim = m->dim, nv = dim + 1;
    const double *p = coords + (size_t)v * (size_t)dim;
    double sum = 0.0;
    int n = 0;
    for (int32_t k = r->first[v]; k < r->first[v + 1]; k++) {
        const int32_t *ev = m->elems + (size_t)r->elems[k] * (size_t)nv;
        for (int i = 0; i < nv; i++) {
            if (ev[i] == v)
                continue;
            const double *o = coords + (size_t)ev[i] * (size_t)dim;
            double s = 0.0;
            for (int c = 0; c < dim; c++)
                s += (o[c] - p[c]) * (o[c] - p[c]);
            sum += sqrt(s);
            n++;
        }
    }
    return n ? sum / n : 0.0;
}

/* A few descent steps of v on its barrier; returns the steps taken. */
static int relax_vertex(const sm_relax *r, double *coords, int32_t v)
{
    const int dim = r->mesh->dim;
    double *p = coords + (size_t)v * (size_t)dim;
    double qw, f = barrier(r, coords, v, &qw);
    const double scale = edge_scale(r, coords, v);
    if (!isfinite(f) || !(scale > 0))
        return 0;
    int moves = 0;
    for (int it = 0; it < RELAX_STEPS; it++) {
        double g[3], p0[3], gn = 0.0, qd, h = RELAX_FD_STEP * scale;
        for (int c = 0; c < dim; c++)
            p0[c] = p[c];
        for (int c = 0; c < dim; c++) {
            p[c] = p0[c] + h;
            double fp = barrier(r, coords, v, &qd);
            p[c] = p0[c] - h;
            double fm = barrier(r, coords, v, &qd);
            p[c] = p0[c];
            if (!isfinite(fp) || !isfinite(fm))
                return moves;
            g[c] = (fp - fm) / (2 * h);
            gn += g[c] * g[c];
        }
        gn = sqrt(gn);
        if (!(gn > 0))
            return moves;
        double s = RELAX_FIRST_MOVE * scale;
        int taken = 0;
        for (int k = 0; k < RELAX_HALVINGS && !taken; k++, s *= 0.5) {
            for (int c = 0; c < dim; c++)
                p[c] = p0[c] - s * g[c] / gn;
            double qt, ft = barrier(r, coords, v, &qt);
            if (ft < f && qt >= qw) {
                f = ft;
                qw = qt;
                taken = 1;
            }
        }
        if (!taken) {
            for (int c = 0; c < dim; c++)
                p[c] = p0[c];
            return moves;
        }
        moves++;
    }
    return moves;
}

int sm__relax_run(sm_relax *r, double *coords, double q_below, int sweeps)
{
    const sm_mesh *m = r->mesh;
    const int nv = m->dim + 1;
    int moves = 0;
    for (int pass = 0; pass < sweeps; pass++) {
        memset(r->pick, 0, (size_t)m->nverts);
#pragma omp parallel for schedule(static)
        for (int32_t e = 0; e < m->nelems; e++) {
            if (!(sm_elem_quality(m, coords, e) < q_below))
                continue;
            for (int i = 0; i < nv; i++) {
                int32_t v = m->elems[(size_t)e * (size_t)nv + (size_t)i];
                if (!m->on_boundary[v] && !(r->fixed && r->fixed[v])) {
#pragma omp atomic write
                    r->pick[v] = 1;
                }
            }
        }
        int32_t n = 0;
        for (int32_t v = 0; v < m->nverts; v++)
            if (r->pick[v])
                r->order[n++] = v;
        if (n == 0)
            break;
        /* in vertex order, each move seeing the ones before (Gauss-Seidel):
         * deterministic whatever the thread count */
        int pass_moves = 0;
        for (int32_t k = 0; k < n; k++)
            pass_moves += relax_vertex(r, coords, r->order[k]);
        moves += pass_moves;
        if (pass_moves == 0)
            break;
    }
    return moves;
}
