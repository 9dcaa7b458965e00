/* The warnings of a job (see sm_job_warnings.h). */
#include "sm_job_warnings.h"

#include <math.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>

#include "shapematch/sm_clamp.h"
#include "shapematch/sm_field.h"
#include "shapematch/sm_io.h"

/* alpha L^2 / E below this: the no-clamp descent crawls (2D example:
 * 0.005 did not converge in 500 iterations, 0.5 and above converge) */
#define ALPHA_SCALE_MIN 0.1

static void add(sm_job_warnings *out, const char *code, double figure, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
static void add(sm_job_warnings *out, const char *code, double figure, const char *fmt, ...)
{
    if (out->n >= SM_JOB_WARNINGS_MAX)
        return;
    sm_job_warning *w = &out->w[out->n++];
    w->code = code;
    w->figure = figure;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(w->message, sizeof w->message, fmt, ap);
    va_end(ap);
}

/* Background vertices with the smallest and largest coordinate on each
 * axis: on the background's hull, far from a target inside it. */
static int hull_negative(const sm_mesh *bg, const double *d, int *nhull)
{
    const int dim = bg->dim;
    int32_t ext[6] = {0, 0, 0, 0, 0, 0};
    for (int32_t v = 1; v < bg->nverts; v++)
        for (int c = 0; c < dim; c++) {
            if (bg->coords[(size_t)v * dim + c] < bg->coords[(size_t)ext[2 * c] * dim + c])
                ext[2 * c] = v;
            if (bg->coords[(size_t)v * dim + c] > bg->coords[(size_t)ext[2 * c + 1] * dim + c])
                ext[2 * c + 1] = v;
        }
    int neg = 0;
    for (int k = 0; k < 2 * dim; k++)
        neg += d[ext[k]] < 0;
    *nhull = 2 * dim;
    return neg;
}

sm_status sm_job_check_sign(const sm_job_inputs *in, sm_job_warnings *out, sm_error *err)
{
    const sm_mesh *m = in->prepared;
    if (!m || !in->field || !in->background || !in->distance || m->nverts == 0)
        return SM_OK;
    uint8_t *clamped = calloc((size_t)m->nverts + 1, 1);
    double *d = malloc(((size_t)m->nverts + 1) * sizeof *d);
    if (!clamped || !d) {
        free(clamped);
        free(d);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    }
    if (in->params.clamp != SM_CLAMP_NONE)
        sm_clamp_mark(m, &in->params, clamped);
    sm_field_eval_points(in->field, m->nverts, m->coords, NULL, d);
    int32_t pos = 0, nclamp = 0, clamp_pos = 0;
    for (int32_t v = 0; v < m->nverts; v++) {
        pos += d[v] > 0;
        nclamp += clamped[v] != 0;
        clamp_pos += clamped[v] && d[v] > 0;
    }
    free(clamped);
    free(d);
    int nhull;
    int neg = hull_negative(in->background, in->distance->values, &nhull);
    double frac = (double)pos / m->nverts;
    if (neg == nhull && frac > 0.5)
        return sm_error_set(err, SM_ERR_INVALID,
                            "target_sol: the signed distance looks inverted (negative at all %d "
                            "extreme vertices of the background, positive at %.0f%% of the "
                            "template's vertices); it must be negative inside the target",
                            nhull, 100 * frac);
    if (neg == nhull)
        add(out, "sign-inverted", frac,
            "the distance is negative at all %d extreme vertices of the background: is it "
            "positive inside the target? (it must be negative inside)", nhull);
    else if (nclamp > 0 && clamp_pos == nclamp && frac > 0.9)
        add(out, "sign-inverted", frac,
            "the distance is positive on the whole clamp set and at %.0f%% of the template's "
            "vertices: is it positive inside the target? (it must be negative inside)",
            100 * frac);
    return SM_OK;
}

/* Size of an element as the edge of the regular simplex of its volume. */
static double elem_size(const sm_mesh *bg, int32_t e)
{
    double vol = fabs(sm_elem_volume(bg, bg->coords, e));
    return bg->dim == 2 ? sqrt(4.0 * vol / sqrt(3.0)) : cbrt(6.0 * sqrt(2.0) * vol);
}

void sm_job_check_result(const sm_job_inputs *in, const double *coords, const sm_result *r,
                         int finished, sm_job_warnings *out, double *resolution)
{
    const sm_mesh *m = in->prepared;
    const int dim = m->dim;
    int64_t n = 0, outside = 0;
    double where[3] = {0, 0, 0}, hsum = 0;
    int32_t hint = -1;
    for (int32_t k = 0; k < m->nbfacets; k++) {
        double x[3] = {0, 0, 0};
        for (int i = 0; i < dim; i++)
            for (int c = 0; c < dim; c++)
                x[c] += coords[(size_t)m->bfacets[(size_t)k * dim + i] * dim + c] / dim;
        int32_t e = sm_field_locate(in->field, x, hint, NULL);
        n++;
        if (e < 0) {
            outside++;
            for (int c = 0; c < dim; c++)
                where[c] += x[c];
        } else {
            hint = e;
            hsum += elem_size(in->background, e);
        }
    }
    if (outside > 0) {
        char at[96];
        if (dim == 3)
            snprintf(at, sizeof at, "(%.4g, %.4g, %.4g)", where[0] / outside, where[1] / outside,
                     where[2] / outside);
        else
            snprintf(at, sizeof at, "(%.4g, %.4g)", where[0] / outside, where[1] / outside);
        add(out, "outside-background", (double)outside / n,
            "%.1f%% of the boundary (%lld of %lld facet centers) lies outside the background "
            "mesh, around %s: d is only extrapolated there, so the boundary error there means "
            "little; enlarge the background",
            100.0 * outside / n, (long long)outside, (long long)n, at);
    }
    double h = n > outside ? hsum / (double)(n - outside) : 0;
    *resolution = h;
    if (finished && h > 0 && r->boundary_rms > h)
        add(out, "above-resolution", r->boundary_rms / h,
            "the final RMS boundary error %.3g is %.1f times the size of the background "
            "elements at the boundary (%.3g): the match is far from what the background "
            "resolves (more iterations, another clamp, or a target the template cannot reach?)",
            r->boundary_rms, r->boundary_rms / h, h);
    if (in->params.clamp == SM_CLAMP_NONE && r->diameter > 0) {
        double scale = r->alpha * r->diameter * r->diameter / in->params.young;
        if (scale < ALPHA_SCALE_MIN)
            add(out, "alpha-small", scale,
                "alpha %.3g is small for the problem's scale (alpha L^2 / E = %.3g with L = %.3g): "
                "the unclamped descent barely moves; leave --alpha out (0: E / L^2 = %.3g)",
                r->alpha, scale, r->diameter, in->params.young / (r->diameter * r->diameter));
    }
}

void sm_job_warnings_text(const sm_job_warnings *ws, char *buf, size_t cap)
{
    size_t used = 0;
    if (cap)
        buf[0] = '\0';
    for (int i = 0; i < ws->n && used + 1 < cap; i++) {
        int k = snprintf(buf + used, cap - used, "%swarning: %s: %s", i ? "; " : "",
                         ws->w[i].code, ws->w[i].message);
        if (k < 0)
            break;
        used += (size_t)k < cap - used ? (size_t)k : cap - used - 1;
    }
}

void sm_job_warning_event(const sm_job_warning *w, sm_event *ev)
{
    sm_event_init(ev, SM_EVENT_WARNING);
    snprintf(ev->code, sizeof ev->code, "%s", w->code);
    snprintf(ev->message, sizeof ev->message, "%s", w->message);
    ev->figure = w->figure;
}
