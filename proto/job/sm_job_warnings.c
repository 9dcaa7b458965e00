/* The warnings of a job (see sm_job_warnings.h). */
#include "job/sm_job_warnings.h"

#include <math.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

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

/* Box of the background vertices where d < 0: the target as the
 * distance describes it, whatever it came from.  0 when there is none. */
static int target_box(const sm_job_inputs *in, double lo[3], double hi[3])
{
    const sm_mesh *bg = in->background;
    const int dim = bg->dim;
    int found = 0;
    for (int32_t v = 0; v < bg->nverts; v++) {
        if (!(in->distance->values[v] < 0))
            continue;
        for (int c = 0; c < dim; c++) {
            double x = bg->coords[(size_t)v * dim + c];
            if (!found || x < lo[c])
                lo[c] = x;
            if (!found || x > hi[c])
                hi[c] = x;
        }
        found = 1;
    }
    return found;
}

static double box_diagonal(int dim, const double lo[3], const double hi[3])
{
    double s = 0;
    for (int c = 0; c < dim; c++)
        s += (hi[c] - lo[c]) * (hi[c] - lo[c]);
    return sqrt(s);
}

/* The volume of the intersection of two boxes over the smaller box's. */
static double box_overlap(int dim, const double alo[3], const double ahi[3], const double blo[3],
                          const double bhi[3])
{
    double inter = 1, va = 1, vb = 1;
    for (int c = 0; c < dim; c++) {
        double w = fmin(ahi[c], bhi[c]) - fmax(alo[c], blo[c]);
        inter *= w > 0 ? w : 0;
        va *= ahi[c] - alo[c];
        vb *= bhi[c] - blo[c];
    }
    double v = fmin(va, vb);
    return v > 0 ? inter / v : 0;
}

/* Template and target in units a power of ten apart: their sizes differ
 * by SIZE_RATIO_UNITS or more (a match changes a shape's size by a few
 * times at most; a unit changes it by 10, 100, 1000). */
sm_job_sizes sm_job_compare_sizes(int dim, const double tlo[3], const double thi[3],
                                  const double glo[3], const double ghi[3])
{
    sm_job_sizes s = {.template_diag = box_diagonal(dim, tlo, thi),
                      .target_diag = box_diagonal(dim, glo, ghi)};
    if (s.template_diag > 0 && s.target_diag > 0) {
        s.ratio = s.target_diag / s.template_diag;
        s.units_differ =
            s.ratio >= SM_JOB_SIZE_RATIO_UNITS || s.ratio <= 1.0 / SM_JOB_SIZE_RATIO_UNITS;
    }
    return s;
}

void sm_job_units_text(const sm_job_sizes *s, char *buf, size_t cap)
{
    double r = s->ratio;
    double power = pow(10.0, round(log10(r > 1 ? r : 1 / r)));
    snprintf(buf, cap,
             "the target is %.4g times %s than the template (box diagonals %.4g and %.4g), "
             "about %g times: are they in different units (e.g. %s in millimetres, %s in "
             "metres)?",
             r > 1 ? r : 1 / r, r > 1 ? "larger" : "smaller", s->target_diag, s->template_diag,
             power, r > 1 ? "the target" : "the template", r > 1 ? "the template" : "the target");
}

static void check_units(sm_job_warnings *out, int dim, const double tlo[3], const double thi[3],
                        const double glo[3], const double ghi[3])
{
    sm_job_sizes s = sm_job_compare_sizes(dim, tlo, thi, glo, ghi);
    if (!s.units_differ)
        return;
    char text[256];
    sm_job_units_text(&s, text, sizeof text);
    add(out, "units", s.ratio,
        "%s Scale one of them onto the other's unit (or give --align similarity)", text);
}

/* misaligned: the template is clearly off the target, one rule for every
 * way of being off: its box centre outside the target's box with under
 * a quarter of its vertices inside the target, or almost
 * none of its vertices inside the target with boxes that barely overlap
 * (the descent only pulls a template that overlaps the target).  The
 * advice is the alignment; after one, the alignment itself missed. */
static void check_misaligned(const sm_job_inputs *in, sm_job_warnings *out, double frac,
                             const double tlo[3], const double thi[3], const double glo[3],
                             const double ghi[3])
{
    const int dim = in->prepared->dim;
    int centre_out = 0;
    double gap = 0;
    for (int c = 0; c < dim; c++) {
        double mid = 0.5 * (tlo[c] + thi[c]);
        centre_out = centre_out || mid < glo[c] || mid > ghi[c];
        double dc = 0.5 * (glo[c] + ghi[c]) - mid;
        gap += dc * dc;
    }
    int apart = 1 - frac < SM_JOB_INSIDE_MIN &&
                box_overlap(dim, tlo, thi, glo, ghi) < SM_JOB_OVERLAP_MIN;
    if (!(centre_out && 1 - frac < SM_JOB_INSIDE_MIN_CENTRE) && !apart)
        return;
    if (in->params.align == SM_ALIGN_NONE)
        add(out, "misaligned", frac,
            "the template is off the target (%.0f%% of its vertices outside it, centres %.4g "
            "apart%s): the descent only pulls a template that overlaps the target; align it "
            "first with --align rigid or similarity (params align; --landmarks to help), or "
            "move it yourself",
            100 * frac, sqrt(gap), centre_out ? ", its centre outside the target's box" : "");
    else
        add(out, "misaligned", frac,
            "the template is still off the target after --align %s (%.0f%% of its vertices "
            "outside it, centres %.4g apart): give --landmarks, or try another --align mode",
            sm_align_mode_name(in->params.align), 100 * frac, sqrt(gap));
}

/* The target surface's health: holes and several closed shells change
 * what the distance describes.  The pieces between holes are components
 * too, but they are one surface with gaps (surface-open), not several. */
static void check_surface(const sm_job_inputs *in, sm_job_warnings *out)
{
    const sm_surface_health *h = &in->health;
    if (!in->has_surface)
        return;
    if (h->open_edges > 0)
        add(out, "surface-open", (double)h->open_edges,
            "the target surface is not closed (%lld open edges: holes, in %lld open piece(s)): "
            "inside and outside come from the winding number, which bridges small holes, but "
            "across a large one the sign of d and so the target's boundary are guesses; close "
            "the surface (fill its holes) before matching",
            (long long)h->open_edges, (long long)h->open_components);
    int64_t closed = h->components - h->open_components;
    if (closed > 1)
        add(out, "surface-components", (double)closed,
            "the target surface has %lld separate closed components: the template is matched "
            "onto all of them at once (their union, minus the inner ones); keep only the "
            "target's",
            (long long)closed);
}

/* image-frame: a NIfTI written by nibabel (RAS world coordinates) read
 * as LPS, or the reverse, puts the label mirrored in x and y: a template
 * given in the image's world then fits the other frame, and --align
 * would silently align it there (a half turn about z). */
static void check_image_frame(const sm_job_inputs *in, sm_job_warnings *out)
{
    const double *rms = in->frame_rms;
    if (!(rms[0] > 0) || !(rms[1] >= 0))
        return;
    double lo[3], hi[3];
    sm_mesh_bbox(in->template_mesh, in->template_mesh->coords, lo, hi);
    double diag = box_diagonal(in->dim, lo, hi);
    if (!(rms[1] < SM_JOB_FRAME_RATIO * rms[0] && rms[1] < SM_JOB_FRAME_FIT * diag))
        return;
    int ras = in->image.space == SM_IMAGE_SPACE_RAS;
    add(out, "image-frame", rms[1] > 0 ? rms[0] / rms[1] : INFINITY,
        "the template fits the label far better in the other image space (boundary RMS %.4g "
        "in %s as read, %.4g in %s): if the image's coordinates are %s (%s), give "
        "--image-space %s (params image_space)%s",
        rms[0], ras ? "RAS" : "LPS", rms[1], ras ? "LPS" : "RAS", ras ? "LPS" : "RAS",
        ras ? "DICOM, ITK, Slicer" : "nibabel, FreeSurfer, FSL", ras ? "lps" : "ras",
        in->params.align != SM_ALIGN_NONE ? "; --align aligns onto the mirrored label" : "");
}

/* The label of an image target: cut by the image's border, or in
 * several pieces (a stray voxel of the label, two organs of one value). */
static void check_image(const sm_job_inputs *in, sm_job_warnings *out)
{
    const sm_label_stats *s = &in->image.stats;
    if (!in->has_image) { /* label, level, image_space select an image's
                           * voxels: without one they change nothing */
        const sm_params *p = &in->params;
        int given = (p->label != 0) + (p->level != 0.5) + (p->smooth != 1.0) +
                    (p->image_space != SM_IMAGE_SPACE_LPS);
        if (given)
            add(out, "image-params-unused", (double)given,
                "label, level, smooth and image_space are for a target image (--target-image, the part "
                "target_image): this job's target is not one, and %d of them given change "
                "nothing", given);
        return;
    }
    check_image_frame(in, out);
    if (s->touches_border)
        add(out, "label-touches-border", (double)s->voxels,
            "the label reaches the image's border: it is closed there, so the target may be cut "
            "where the image ends");
    if (s->components > 1)
        add(out, "label-components", (double)s->components,
            "the label has %lld separate components (26-connected): the template is matched "
            "onto all of them at once; keep only the target's (another label value, or remove "
            "the stray voxels)",
            (long long)s->components);
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
    double clamp_dmin = INFINITY;
    for (int32_t v = 0; v < m->nverts; v++) {
        pos += d[v] > 0;
        nclamp += clamped[v] != 0;
        clamp_pos += clamped[v] && d[v] > 0;
        if (clamped[v] && d[v] < clamp_dmin)
            clamp_dmin = d[v];
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
    /* only the far field tells an inverted sign from a template that lies
     * outside the target: both make d positive on the template */
    if (neg == nhull)
        add(out, "sign-inverted", frac,
            "the distance is negative at all %d extreme vertices of the background: is it "
            "positive inside the target? (it must be negative inside)", nhull);
    double tlo[3], thi[3], glo[3], ghi[3];
    sm_mesh_bbox(m, m->coords, tlo, thi);
    int have_target = target_box(in, glo, ghi);
    if (in->has_surface) { /* the surface's own box: exact, and there even
                            * when the background misses the target */
        memcpy(glo, in->health.lo, sizeof glo);
        memcpy(ghi, in->health.hi, sizeof ghi);
        have_target = 1;
    }
    if (in->has_image) { /* the label's voxel centres: the target's box */
        memcpy(glo, in->image.stats.lo, sizeof glo);
        memcpy(ghi, in->image.stats.hi, sizeof ghi);
        have_target = 1;
    }
    if (have_target)
        check_units(out, m->dim, tlo, thi, glo, ghi);
    if (have_target && neg < nhull)
        check_misaligned(in, out, frac, tlo, thi, glo, ghi);
    if (nclamp > 0 && clamp_pos == nclamp && neg < nhull)
        add(out, "clamp-outside", clamp_dmin,
            "the clamp set (%ld vertices) lies outside the target (d >= %.3g at all of them): "
            "clamped vertices do not move, so the template cannot reach the target; put the "
            "clamp inside the target",
            (long)nclamp, clamp_dmin);
    if (in->clamp_default) {
        const double *c = in->params.clamp_center;
        char at[96];
        if (m->dim == 3)
            snprintf(at, sizeof at, "(%.6g, %.6g, %.6g)", c[0], c[1], c[2]);
        else
            snprintf(at, sizeof at, "(%.6g, %.6g)", c[0], c[1]);
        add(out, "clamp-default", in->params.clamp_radius,
            "no clamp given: the ball of radius %.4g at %s, the template's deepest point "
            "(%.4g from its boundary), holds %ld vertices fixed; give --clamp-ball, "
            "--clamp-elements, --clamp-vertices or --no-clamp to choose",
            in->params.clamp_radius, at, in->clamp_inradius, (long)in->nclamped);
    }
    check_surface(in, out);
    check_image(in, out);
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
    int above = finished && h > 0 && r->boundary_rms > h;
    if (above)
        add(out, "above-resolution", r->boundary_rms / h,
            "the final RMS boundary error %.3g is %.1f times the size of the background "
            "elements at the boundary (%.3g): the match is far from what the background "
            "resolves (more iterations, another clamp, or a target the template cannot reach?)",
            r->boundary_rms, r->boundary_rms / h, h);
    /* a surface with holes is a likely cause: the sign is only as good as
     * the orientation repair could make it there (figure: open edges) */
    if (above && in->has_surface && in->health.open_edges > 0)
        add(out, "surface-holes", (double)in->health.open_edges,
            "the target surface has %lld open edges (holes) in %lld open piece(s): the sign of "
            "its distance may be wrong near them (inside taken for outside), which keeps the "
            "boundary away; check it with `shapematch sdf --surface S -o DIR` (d < 0 inside in "
            "DIR/background.sol) and close the holes",
            (long long)in->health.open_edges, (long long)in->health.open_components);
    if (in->params.clamp == SM_CLAMP_NONE && r->diameter > 0) {
        double scale = r->alpha * r->diameter * r->diameter / in->params.young;
        if (scale < ALPHA_SCALE_MIN)
            add(out, "alpha-small", scale,
                "alpha %.3g is small for the problem's scale (alpha L^2 / E = %.3g with L = %.3g): "
                "the unclamped descent barely moves; leave --alpha out (0: E / L^2 = %.3g)",
                r->alpha, scale, r->diameter, in->params.young / (r->diameter * r->diameter));
    }
}

/* "(x, y, z)" or "(x, y)". */
static void point_text(char *buf, size_t cap, int dim, const double *p)
{
    if (dim == 3)
        snprintf(buf, cap, "(%.4g, %.4g, %.4g)", p[0], p[1], p[2]);
    else
        snprintf(buf, cap, "(%.4g, %.4g)", p[0], p[1]);
}

int sm_job_check_coverage(const sm_job_inputs *in, const sm_coverage *cov, const sm_result *r,
                          double resolution, int finished, sm_job_warnings *out)
{
    const sm_distance *d = &r->distance;
    if (!cov || !(resolution > 0) || d->method == SM_DISTANCE_NONE)
        return 1;
    const int dim = in->dim;
    double reach = SM_JOB_COVERED_FACTOR * resolution;
    sm_coverage_topology topo;
    sm_coverage_get_topology(cov, &topo);
    int genus = topo.known && dim == 3 && topo.target_genus != topo.template_genus;
    int pieces = topo.known && topo.target_pieces != topo.template_pieces;
    int covered = d->target_to_result.p99 <= reach && d->result_to_target.p99 <= reach &&
                  !genus && !pieces;
    if (covered || !finished)
        return covered;
    char cause[128] = "";
    if (genus)
        snprintf(cause, sizeof cause,
                 "; the target has genus %lld, the template %lld: no deformation makes or closes "
                 "a handle", (long long)topo.target_genus, (long long)topo.template_genus);
    else if (pieces)
        snprintf(cause, sizeof cause,
                 "; the target has %lld closed surface(s), the template %lld: no deformation "
                 "changes that", (long long)topo.target_pieces, (long long)topo.template_pieces);
    /* where: the target's part beyond reach, else the result's part
     * beyond it (a sheet across a hole), else (a topology the figures
     * pass) the same at the resolution itself */
    sm_coverage_missed part;
    int side = 0;
    double at = reach;
    sm_coverage_missed_part(cov, 0, at, &part);
    if (part.samples == 0)
        sm_coverage_missed_part(cov, side = 1, at, &part);
    if (part.samples == 0) {
        at = resolution;
        sm_coverage_missed_part(cov, side = 0, at, &part);
        if (part.samples == 0)
            sm_coverage_missed_part(cov, side = 1, at, &part);
    }
    char lo[64], hi[64], centre[64];
    point_text(lo, sizeof lo, dim, part.lo);
    point_text(hi, sizeof hi, dim, part.hi);
    point_text(centre, sizeof centre, dim, part.centre);
    add(out, "target-not-reached", part.fraction,
        "%.1f%% of the %s is farther than %.3g from the %s, up to %.3g, around %s in the box "
        "%s-%s%s",
        100.0 * part.fraction, side ? "result's boundary" : "target", at,
        side ? "target" : "result", part.max, centre, lo, hi, cause);
    return 0;
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
