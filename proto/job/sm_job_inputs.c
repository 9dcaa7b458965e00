/* Reading and checking a job's inputs (see sm_job_inputs.h). */
#include "job/sm_job_inputs.h"

#include "job/sm_job_align.h"

#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <omp.h>

#include "shapematch/sm_align.h"
#include "shapematch/sm_clock.h"
#include "shapematch/sm_clamp.h"
#include "shapematch/sm_sdf.h"
#include "job/sm_job_image.h"
#include "sm_job_threads.h"
#include "sm_job_warnings.h"
#include "sm_proto_json.h"
#include "sm_proto_params.h"

void sm_job_inputs_free(sm_job_inputs *in)
{
    if (!in)
        return;
    sm_match_free(in->match);
    in->match = NULL;
    sm_coverage_free(in->coverage); /* before the field and mesh it reads */
    in->coverage = NULL;
    sm_field_free(in->field);
    sm_sol_free(in->distance);
    sm_mesh_free(in->background);
    sm_mesh_free(in->prepared);
    sm_mesh_free(in->template_mesh);
    sm_surface_free(in->surface);
    in->surface = NULL;
    free(in->landmarks[0]);
    free(in->landmarks[1]);
    in->landmarks[0] = in->landmarks[1] = NULL;
    in->nlandmarks = 0;
    sm_sdf_free(in->target_sdf);
    sm_surface_free(in->target_surface);
    sm_image_target_free(in->image_target);
    free(in->plan_path);
    in->target_sdf = NULL;
    in->target_surface = NULL;
    in->image_target = NULL;
    in->plan_path = NULL;
    in->target_deferred = 0;
    in->field = NULL;
    in->distance = NULL;
    in->background = NULL;
    in->prepared = NULL;
    in->template_mesh = NULL;
}

/* A part's contents: the copy of what the caller holds in memory, or its
 * file read. */
static sm_status take_mesh(const char *path, const sm_mesh *given, sm_read_limits *limits,
                           sm_mesh **out, sm_error *err)
{
    return given ? sm_mesh_clone(given, out, err) : sm_mesh_read_limited(path, limits, out, err);
}

static sm_status take_sol(const char *path, const sm_sol *given, sm_read_limits *limits,
                          sm_sol **out, sm_error *err)
{
    if (!given)
        return sm_sol_read_limited(path, limits, out, err);
    sm_status st = sm_sol_alloc(out, given->dim, given->nverts, given->ncomp, err);
    if (st == SM_OK)
        memcpy((*out)->values, given->values,
               (size_t)given->nverts * (size_t)given->ncomp * sizeof(double));
    return st;
}

static sm_status take_surface(const char *path, const sm_surface *given, sm_read_limits *limits,
                              sm_surface **out, sm_error *err)
{
    if (!given)
        return sm_surface_read_limited(path, limits, out, err);
    sm_status st = sm_surface_alloc(out, given->dim, given->nverts, given->nfacets, err);
    if (st == SM_OK) {
        sm_surface *s = *out;
        memcpy(s->coords, given->coords, (size_t)given->nverts * (size_t)given->dim * sizeof(double));
        memcpy(s->facets, given->facets, (size_t)given->nfacets * (size_t)given->dim * sizeof(int32_t));
        memcpy(s->facet_refs, given->facet_refs, (size_t)given->nfacets * sizeof(int32_t));
    }
    return st;
}

/* "PART: message" with every occurrence of path replaced by PART. */
static sm_status part_error(sm_error *err, const char *part, const char *path)
{
    char msg[SM_ERROR_MSG_LEN];
    size_t k = 0, plen = path ? strlen(path) : 0;
    const char *src = err->msg;
    while (*src && k + 1 < sizeof msg) {
        if (plen && strncmp(src, path, plen) == 0) {
            size_t n = strlen(part);
            if (k + n >= sizeof msg)
                break;
            memcpy(msg + k, part, n);
            k += n;
            src += plen;
        } else {
            msg[k++] = *src++;
        }
    }
    msg[k] = '\0';
    size_t n = strlen(part);
    if (strncmp(msg, part, n) == 0 && msg[n] == ':') {
        /* the readers say "FILE:LINE: what": make it "PART: line LINE: what" */
        const char *p = msg + n + 1;
        const char *digits = p;
        while (*p >= '0' && *p <= '9')
            p++;
        if (p > digits && *p == ':')
            return sm_error_set(err, err->code, "%s: line %.*s:%s", part, (int)(p - digits), digits, p + 1);
        /* already "PART: what" ("FILE: byte N: what", "FILE: what") */
        return sm_error_set(err, err->code, "%s", msg);
    }
    return sm_error_set(err, err->code, "%s: %s", part, msg);
}

/* A core error about one input file, named the way naming says: "PART:
 * ..." with the path replaced, or "PART: PATH...: ..." with the path as
 * given (added when the core's message does not show it). */
static sm_status file_error(sm_error *err, sm_job_naming naming, sm_part part, const char *path,
                            sm_job_inputs *in)
{
    in->failed = part;
    const char *name = sm_part_name(part);
    if (naming == SM_JOB_NAME_PARTS)
        return part_error(err, name, path);
    if (strstr(err->msg, path))
        sm_error_prefix(err, "%s", name);
    else
        sm_error_prefix(err, "%s: %s", name, path);
    return err->code;
}

/* How a message names a file of its own: "target_sol" or
 * "target_sol 'b.sol'". */
static const char *label(char *buf, size_t cap, sm_job_naming naming, sm_part part,
                         const char *path)
{
    if (naming == SM_JOB_NAME_PARTS)
        snprintf(buf, cap, "%s", sm_part_name(part));
    else
        snprintf(buf, cap, "%s '%s'", sm_part_name(part), path);
    return buf;
}

/* The distance: scalar, one finite value per background vertex. */
static sm_status check_distance(const sm_job_files *files, sm_job_naming naming,
                                sm_job_inputs *out, sm_error *err)
{
    char sol[512], bg[512];
    label(sol, sizeof sol, naming, SM_PART_TARGET_SOL, files->target_sol);
    if (files->target_sol_given) /* named already: "target_sol (array)" */
        snprintf(sol, sizeof sol, "%s", files->target_sol);
    out->failed = SM_PART_TARGET_SOL;
    if (out->distance->ncomp != 1)
        return sm_error_set(err, SM_ERR_INVALID,
                            "%s: a scalar signed distance is expected, got a field of %d "
                            "components",
                            sol, out->distance->ncomp);
    if (out->distance->nverts != out->background->nverts) {
        if (naming == SM_JOB_NAME_PARTS || files->target_mesh_given)
            snprintf(bg, sizeof bg, "the target mesh");
        else
            snprintf(bg, sizeof bg, "the target mesh '%s'", files->target_mesh);
        return sm_error_set(err, SM_ERR_INVALID, "%s: has %ld values but %s has %ld vertices", sol,
                            (long)out->distance->nverts, bg, (long)out->background->nverts);
    }
    for (int32_t v = 0; v < out->distance->nverts; v++)
        if (!isfinite(out->distance->values[v]))
            return sm_error_set(err, SM_ERR_INVALID, "%s: value %ld is not finite", sol,
                                (long)v + 1);
    out->failed = SM_NPARTS;
    return SM_OK;
}

/* Mean edge length of the template's elements. */
static double mean_edge(const sm_mesh *m)
{
    int n = m->dim + 1;
    double sum = 0;
    int64_t count = 0;
    for (int32_t e = 0; e < m->nelems; e++)
        for (int a = 0; a < n; a++)
            for (int b = a + 1; b < n; b++) {
                const double *p = m->coords + (size_t)m->elems[(size_t)e * n + a] * m->dim;
                const double *q = m->coords + (size_t)m->elems[(size_t)e * n + b] * m->dim;
                double d2 = 0;
                for (int k = 0; k < m->dim; k++)
                    d2 += (p[k] - q[k]) * (p[k] - q[k]);
                sum += sqrt(d2);
                count++;
            }
    return count ? sum / (double)count : 0;
}

/* A generated background is held to the bounds of an uploaded one (the
 * daemon's --max-vertices, --max-elements): its size is the job's
 * choice, its distance computation and the run the daemon's cost. */
static sm_status check_background_limits(sm_read_limits *limits, const sm_mesh *bg, sm_error *err)
{
    if (!limits)
        return SM_OK;
    int verts = limits->max_vertices > 0 && bg->nverts > limits->max_vertices;
    if (!verts && !(limits->max_elements > 0 && bg->nelems > limits->max_elements))
        return SM_OK;
    limits->hit = verts ? SM_LIMIT_VERTICES : SM_LIMIT_ELEMENTS;
    return sm_error_set(err, SM_ERR_INVALID,
                        "the generated background has %ld %s, beyond the limit of %lld: give a "
                        "larger --background-size", verts ? (long)bg->nverts : (long)bg->nelems,
                        verts ? "vertices" : "elements",
                        verts ? (long long)limits->max_vertices : (long long)limits->max_elements);
}

/* The files' values a generated background needs, the files' own limits
 * and path borrowed. */
static sm_job_background_plan plan_of(const sm_job_files *files, sm_job_naming naming,
                                      const char *target_path)
{
    sm_job_background_plan p = {.naming = naming, .size = files->background_size,
                                .padding = files->background_padding, .limits = files->limits,
                                .target_path = target_path};
    return p;
}

/* The plan kept in out for a background built after the alignment: the
 * limits and the path copied (the files need not outlive the read). */
static sm_status defer_background(const sm_job_files *files, sm_job_naming naming,
                                  const char *target_path, sm_job_inputs *out, sm_error *err)
{
    out->plan = plan_of(files, naming, NULL);
    if (files->limits) {
        out->plan_limits = *files->limits;
        out->plan.limits = &out->plan_limits;
    }
    if (!(out->plan_path = strdup(target_path)))
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    out->plan.target_path = out->plan_path;
    out->target_deferred = 1;
    return SM_OK;
}

/* The padded box of template and surface, graded toward the surface,
 * near-surface cells of the smaller of the template's and the surface's
 * mean edge lengths (not below a quarter of the size that would give a
 * uniform grid of 250k vertices). */
static sm_status generate_background(const sm_job_background_plan *plan, const sm_mesh *tpl,
                                     sm_job_inputs *out, const sm_surface *s, const sm_sdf *d,
                                     const char *checked, sm_error *err)
{
    int dim = out->dim;
    double lo[3], hi[3], tlo[3], thi[3], diag = 0, cells = 1;
    sm_mesh_bbox(tpl, tpl->coords, tlo, thi);
    for (int k = 0; k < dim; k++) {
        lo[k] = fmin(tlo[k], out->health.lo[k]);
        hi[k] = fmax(thi[k], out->health.hi[k]);
        diag += (hi[k] - lo[k]) * (hi[k] - lo[k]);
    }
    diag = sqrt(diag);
    out->background_padding = plan->padding > 0 ? plan->padding : SM_BACKGROUND_PADDING_DEFAULT;
    double pad = out->background_padding * diag;
    for (int k = 0; k < dim; k++) {
        lo[k] -= pad;
        hi[k] += pad;
        cells *= hi[k] - lo[k];
    }
    double h = fmin(mean_edge(tpl), sm_surface_mean_edge(s));
    /* template and surface in units a power of ten apart (the criterion
     * of the "units" warning): a size from either would be one of the
     * wrong unit for the other (a target in millimetres and a template in
     * metres made a 1.57M-vertex background in 16 s), and a match between
     * them means nothing: refused before anything is built, unless the
     * user sized the background */
    sm_job_sizes sz = sm_job_compare_sizes(dim, tlo, thi, out->health.lo, out->health.hi);
    if (sz.units_differ && !(plan->size > 0)) {
        char text[256];
        sm_job_units_text(&sz, text, sizeof text);
        out->failed = SM_PART_TARGET_SURFACE;
        /* the part, then the field that would override the refusal */
        const char *what = plan->naming == SM_JOB_NAME_PARTS ? "" : plan->target_path;
        return sm_error_set(err, SM_ERR_INVALID,
                            "target_surface%s%s%s: %s A background generated for both would be "
                            "sized in the wrong unit for one of them: scale one onto the other's "
                            "unit (%s similarity does it first), or %s to generate it anyway",
                            what[0] ? " '" : "", what, what[0] ? "'" : "", text,
                            plan->naming == SM_JOB_NAME_PARTS ? "params align" : "--align",
                            plan->naming == SM_JOB_NAME_PARTS
                                ? "set params.background_size"
                                : "give --background-size");
    }
    double hmin = pow(cells / 250000.0, 1.0 / dim) / 4;
    if (!(h >= hmin))
        h = hmin;
    if (plan->size > 0)
        h = plan->size;
    out->background_generated = 1;
    out->background_size = h;
    /* checked: the same background, built by an earlier read (d NULL) */
    sm_status st = checked ? sm_mesh_read_limited(checked, plan->limits, &out->background, err)
                           : sm_background_graded_new(dim, lo, hi, h, d, &out->background, err);
    if (st == SM_OK)
        st = check_background_limits(plan->limits, out->background, err);
    if (st != SM_OK && st != SM_ERR_NOMEM && plan->naming == SM_JOB_NAME_PARTS) {
        /* the core's advice names the CLI's flag: name the param */
        out->failed = SM_PART_PARAMS;
        part_error(err, "params.background_size", "--background-size");
    }
    return st;
}

/* The target from a surface: background given or generated, then the
 * exact signed distance at its vertices. */
static sm_status read_surface_target(const sm_job_files *files, sm_job_naming naming,
                                     sm_job_inputs *out, sm_error *err)
{
    sm_surface *s = NULL;
    sm_sdf *d = NULL;
    /* with an alignment the surface and its distance are kept for it */
    const int align = out->params.align != SM_ALIGN_NONE;
    sm_status st = take_surface(files->target_surface, files->target_surface_given,
                                files->limits, &s, err);
    if (st == SM_OK)
        st = sm_surface_repair(s, &out->health, err);
    if (st != SM_OK) {
        file_error(err, naming, SM_PART_TARGET_SURFACE, files->target_surface, out);
        goto done;
    }
    out->has_surface = 1;
    if (s->dim != out->dim) {
        st = sm_error_set(err, SM_ERR_INVALID, "dimension mismatch: the template is %dD but the "
                          "target surface is %dD", out->dim, s->dim);
        goto done;
    }
    double t0 = sm_clock_seconds();
    /* the background and distance an earlier read built (the upload's
     * check): read, not built again, so no distance structure either */
    const int reuse = !files->target_mesh && !align && files->checked_background &&
                      files->checked_distance;
    if (!reuse && (st = sm_sdf_new(s, &d, err)) != SM_OK) {
        if (st != SM_ERR_NOMEM)
            file_error(err, naming, SM_PART_TARGET_SURFACE, files->target_surface, out);
        goto done;
    }
    if (files->target_mesh) {
        if ((st = take_mesh(files->target_mesh, files->target_mesh_given, files->limits, &out->background,
                                       err)) != SM_OK) {
            file_error(err, naming, SM_PART_TARGET_MESH, files->target_mesh, out);
            goto done;
        }
    } else if (align) {
        /* the background waits for the alignment (sm_job_inputs_finish_
         * target); the surface is checked now as its distance would check
         * it (n = 0: the enclosed volume only) */
        if ((st = sm_sdf_signed(d, 0, NULL, NULL, err)) != SM_OK) {
            file_error(err, naming, SM_PART_TARGET_SURFACE, files->target_surface, out);
            goto done;
        }
        st = defer_background(files, naming, files->target_surface, out, err);
        out->sdf_seconds = sm_clock_seconds() - t0;
        goto done;
    } else {
        sm_job_background_plan plan = plan_of(files, naming, files->target_surface);
        if ((st = generate_background(&plan, out->template_mesh, out, s, d,
                                      reuse ? files->checked_background : NULL, err)) != SM_OK)
            goto done;
    }
    if (out->background->dim != out->dim) {
        st = sm_error_set(err, SM_ERR_INVALID,
                          "dimension mismatch: the template is %dD but the target mesh is %dD",
                          out->dim, out->background->dim);
        goto done;
    }
    if (reuse) {
        st = sm_sol_read_limited(files->checked_distance, files->limits, &out->distance, err);
        if (st == SM_OK && (out->distance->nverts != out->background->nverts ||
                            out->distance->ncomp != 1))
            st = sm_error_set(err, SM_ERR_INVALID, "%s: %d values for the %d vertices of %s",
                              files->checked_distance, (int)out->distance->nverts,
                              (int)out->background->nverts, files->checked_background);
        out->checked_reused = st == SM_OK;
    } else if ((st = sm_sol_alloc(&out->distance, out->dim, out->background->nverts, 1, err)) ==
               SM_OK) {
        st = sm_sdf_signed(d, out->background->nverts, out->background->coords,
                           out->distance->values, err);
    }
    out->sdf_seconds = sm_clock_seconds() - t0;
    if (st != SM_OK && st != SM_ERR_NOMEM)
        file_error(err, naming, SM_PART_TARGET_SURFACE, files->target_surface, out);
done:
    if (st == SM_OK && align) { /* the alignment's exact target */
        out->target_surface = s;
        out->target_sdf = d;
        return st;
    }
    sm_sdf_free(d);
    if (st == SM_OK)
        out->surface = s; /* kept: the run's exact distances (sm_coverage.h) */
    else
        sm_surface_free(s);
    return st;
}

/* The image's bounds from the daemon's: its voxel bytes and inflated
 * size under --max-inflated (a refusal counts as that limit's), its voxel
 * count under SM_JOB_VOXELS_PER_VERTEX x --max-vertices (that limit's),
 * and one file only (an upload is one part: a detached header is
 * refused).  The voxel count is the cost of the check (inflating, the
 * distance transform, the level set: 32 s and 2 GiB for the 10^9 voxels
 * a 1 MB NRRD may declare), refused from the header before any of it. */
static sm_image_limits image_limits(const sm_job_files *files, sm_job_naming naming)
{
    sm_image_limits l = {0, 0, naming == SM_JOB_NAME_PARTS, 0};
    if (files->limits) {
        l.max_inflated = files->limits->max_inflated;
        if (files->limits->max_vertices > 0 &&
            files->limits->max_vertices <= INT64_MAX / SM_JOB_VOXELS_PER_VERTEX)
            l.max_voxels = files->limits->max_vertices * SM_JOB_VOXELS_PER_VERTEX;
    }
    return l;
}

/* The generated background of an image target: around its label's
 * surface and the template tpl. */
static sm_status image_background(const sm_job_background_plan *plan, const sm_mesh *tpl,
                                  sm_job_inputs *out, const sm_image_target *t, sm_error *err)
{
    double padding = plan->padding > 0 ? plan->padding : SM_BACKGROUND_PADDING_DEFAULT;
    sm_status st = sm_job_image_background(t, &out->image, tpl, plan->size, padding,
                                           &out->background, &out->background_size, err);
    if (st == SM_OK)
        st = check_background_limits(plan->limits, out->background, err);
    if (st != SM_OK) {
        if (st != SM_ERR_NOMEM && plan->naming == SM_JOB_NAME_PARTS) {
            out->failed = SM_PART_PARAMS;
            part_error(err, "params.background_size", "--background-size");
        }
        return st;
    }
    out->background_generated = 1;
    out->background_padding = padding;
    return SM_OK;
}

/* How the template as given fits the label's surface in the image space
 * it was read in and in the other one (LPS and RAS differ by x, y -> -x,
 * -y about the world origin): the RMS distance of its boundary vertices
 * to the surface, both ways, for the image-frame warning.  Left at 0
 * (no figure) when out of memory. */
static void image_frame_fit(sm_job_inputs *out, const sm_sdf *d)
{
    const sm_mesh *m = out->prepared;
    int64_t n = 0;
    uint8_t *on = calloc((size_t)m->nverts + 1, 1);
    double *p = malloc(((size_t)m->nverts + 1) * 3 * sizeof *p);
    double *dist = malloc(((size_t)m->nverts + 1) * sizeof *dist);
    out->frame_rms[0] = out->frame_rms[1] = 0;
    if (!on || !p || !dist || !d) {
        free(on), free(p), free(dist);
        return;
    }
    for (int64_t f = 0; f < (int64_t)m->nbfacets * 3; f++)
        on[m->bfacets[f]] = 1;
    for (int32_t v = 0; v < m->nverts; v++)
        if (on[v])
            memcpy(p + 3 * n++, m->coords + 3 * (size_t)v, 3 * sizeof *p);
    for (int frame = 0; frame < 2 && n > 0; frame++) {
        if (frame == 1)
            for (int64_t i = 0; i < n; i++)
                p[3 * i] = -p[3 * i], p[3 * i + 1] = -p[3 * i + 1];
        sm_sdf_distance(d, n, p, dist, NULL);
        double sum = 0;
        for (int64_t i = 0; i < n; i++)
            sum += dist[i] * dist[i];
        out->frame_rms[frame] = sqrt(sum / (double)n);
    }
    free(on);
    free(p);
    free(dist);
}

/* The target from a label-map image: its selection by the params (set
 * before the target is read), the level-set surface, a background given
 * or generated around it and the template, the distance at its
 * vertices. */
/* A 2D template's image target: the label's boundary as a closed curve
 * (sm_job_image_contour), then exactly the surface target's way, the
 * curve in memory in place of a surface file (its health report kept,
 * the summary's target is the image). */
static sm_status read_image_curve(const sm_job_files *files, sm_job_naming naming,
                                  sm_image_limits *lim, const sm_image_select *sel,
                                  sm_job_inputs *out, sm_error *err)
{
    sm_surface *curve = NULL;
    double t0 = sm_clock_seconds();
    sm_status st = sm_job_image_contour(files->target_image, lim, sel, out->params.image_space,
                                        out->params.smooth, &curve, &out->image, err);
    if (st != SM_OK) {
        if (files->limits && (lim->hit == SM_IMAGE_LIMIT_INFLATED || lim->hit == SM_IMAGE_LIMIT_VOXELS))
            files->limits->hit = SM_LIMIT_INFLATED;
        if (st != SM_ERR_NOMEM || lim->hit)
            file_error(err, naming, SM_PART_TARGET_IMAGE, files->target_image, out);
        return st;
    }
    sm_job_files as_surface = *files;
    as_surface.target_surface = files->target_image; /* names it in messages */
    as_surface.target_surface_given = curve;
    st = read_surface_target(&as_surface, naming, out, err);
    sm_surface_free(curve);
    out->has_surface = 0;
    if (out->failed == SM_PART_TARGET_SURFACE) {
        /* the part is the image: "target_surface: ..." is its message */
        size_t n = strlen(SM_PART_NAME_TARGET_SURFACE);
        out->failed = SM_PART_TARGET_IMAGE;
        if (strncmp(err->msg, SM_PART_NAME_TARGET_SURFACE, n) == 0) {
            char rest[SM_ERROR_MSG_LEN];
            snprintf(rest, sizeof rest, "%s", err->msg + n);
            sm_error_set(err, err->code, "%s%s", SM_PART_NAME_TARGET_IMAGE, rest);
        }
    }
    if (st == SM_OK)
        out->image.exact_vertices = out->background->nverts; /* the curve's exact distance */
    out->sdf_seconds = sm_clock_seconds() - t0; /* the contour and the distance */
    return st;
}

static sm_status read_image_target(const sm_job_files *files, sm_job_naming naming,
                                   sm_job_inputs *out, sm_error *err)
{
    sm_image_target *t = NULL;
    sm_sdf *d = NULL;
    sm_image_limits lim = image_limits(files, naming);
    sm_image_select sel = sm_job_image_select(&out->params);
    out->has_image = 1;
    if (out->dim == 2)
        return read_image_curve(files, naming, &lim, &sel, out, err);
    double padding = files->background_padding > 0 ? files->background_padding
                                                   : SM_BACKGROUND_PADDING_DEFAULT;
    double t0 = sm_clock_seconds();
    sm_status st = sm_job_image_target(files->target_image, &lim, &sel, out->params.image_space,
                                       out->params.smooth, padding, &t, &out->image, err);
    if (st != SM_OK) {
        if (files->limits && lim.hit == SM_IMAGE_LIMIT_INFLATED)
            files->limits->hit = SM_LIMIT_INFLATED;
        if (files->limits && lim.hit == SM_IMAGE_LIMIT_VOXELS)
            files->limits->hit = SM_LIMIT_VERTICES;
        if (st != SM_ERR_NOMEM || lim.hit)
            file_error(err, naming, SM_PART_TARGET_IMAGE, files->target_image, out);
        goto done;
    }
    /* the label's surface and its hierarchy: the frame's figures, and
     * with an alignment its exact target */
    sm_error local;
    if (sm_sdf_new(sm_image_target_surface(t), &d, &local) == SM_OK)
        image_frame_fit(out, d);
    if (files->target_mesh) {
        if ((st = take_mesh(files->target_mesh, files->target_mesh_given, files->limits, &out->background,
                                       err)) != SM_OK) {
            file_error(err, naming, SM_PART_TARGET_MESH, files->target_mesh, out);
            goto done;
        }
        if (out->background->dim != 3) {
            st = sm_error_set(err, SM_ERR_INVALID, "dimension mismatch: the template is 3D but "
                              "the target mesh is %dD", out->background->dim);
            goto done;
        }
    } else if (out->params.align != SM_ALIGN_NONE && d) {
        /* the background waits for the alignment, which aligns onto the
         * label's surface (sm_job_inputs_finish_target) */
        st = defer_background(files, naming, files->target_image, out, err);
        goto done;
    } else {
        sm_job_background_plan plan = plan_of(files, naming, files->target_image);
        if ((st = image_background(&plan, out->template_mesh, out, t, err)) != SM_OK)
            goto done;
    }
    st = sm_job_image_distance(t, out->background, &out->distance, &out->image, err);
done:
    out->sdf_seconds = sm_clock_seconds() - t0;
    if (st == SM_OK && out->params.align != SM_ALIGN_NONE && d) {
        out->image_target = t; /* the alignment's exact target */
        out->target_sdf = d;
        return st;
    }
    sm_sdf_free(d);
    sm_image_target_free(t);
    return st;
}

sm_status sm_job_files_check_background(const sm_job_files *files, sm_job_naming naming,
                                        sm_error *err)
{
    static const char *const names[2][4] = {
        [SM_JOB_NAME_PARTS] = {"background_size", "background_padding", "target_surface",
                               "target_mesh"},
        [SM_JOB_NAME_PATHS] = {"--background-size", "--background-padding",
                               "--target-surface", "--target-mesh"}};
    int size = files->background_size > 0, padding = files->background_padding > 0;
    if ((!size && !padding) ||
        ((files->target_surface || files->target_image) && !files->target_mesh))
        return SM_OK;
    const char *const *n = names[naming == SM_JOB_NAME_PATHS];
    char where[64] = "";
    if (naming == SM_JOB_NAME_PARTS) /* the params path first, as for every bad param */
        snprintf(where, sizeof where, "params.%s: ", size ? n[0] : n[1]);
    return sm_error_set(err, SM_ERR_INVALID,
                        "%s%s and %s are for a generated background (%s without %s): %s %s",
                        where, n[0], n[1], n[2], n[3], files->target_surface ? n[3] : n[2],
                        files->target_surface ? "is given" : "is not given");
}

/* A landmark file's message for the daemon: "PART: ..." with its path
 * replaced, without the local run's "landmarks (ROLE): " prefix. */
static void landmark_part_error(sm_error *err, const sm_job_files *files, sm_part part)
{
    const char *path = part == SM_PART_TEMPLATE_LANDMARKS ? files->landmarks_template
                                                          : files->landmarks_target;
    const char *colon = strncmp(err->msg, "landmarks (", 11) == 0 ? strstr(err->msg, "): ") : NULL;
    if (colon)
        memmove(err->msg, colon + 3, strlen(colon + 3) + 1);
    part_error(err, sm_part_name(part), path);
}

/* The template an earlier read meshed (files->checked_template, with its
 * figures): read as meshed, after the checks that it is that template. */
static sm_status reuse_template(const sm_job_files *files, sm_job_naming naming,
                                sm_job_inputs *out, sm_error *err)
{
    const sm_job_template_made *made = files->checked_template_made;
    sm_job_template_source kind = files->template_image ? SM_TEMPLATE_IMAGE : SM_TEMPLATE_SURFACE;
    sm_status st = take_mesh(files->checked_template, NULL, files->limits, &out->template_mesh, err);
    if (st == SM_OK && (made->source != kind || made->mesh.nverts != out->template_mesh->nverts ||
                        made->mesh.nelems != out->template_mesh->nelems))
        st = sm_error_set(err, SM_ERR_INVALID, "%s is not the template its figures describe",
                          files->checked_template);
    if (st != SM_OK) {
        sm_mesh_free(out->template_mesh);
        out->template_mesh = NULL;
        file_error(err, naming, SM_PART_TEMPLATE, files->checked_template, out);
        return st;
    }
    out->template_made = *made;
    out->template_reused = 1;
    return SM_OK;
}

/* The template: given (a volume mesh), or meshed from template_surface
 * or template_image (sm_job_template.h).  A meshing's message names its
 * part ("template_surface: open: ..."; the path too for a local run);
 * the daemon's part is then SM_PART_TEMPLATE, the file part it came in. */
static sm_status take_template(const sm_job_files *files, sm_job_naming naming,
                               sm_job_inputs *out, sm_error *err)
{
    const char *made_from = files->template_surface ? files->template_surface : files->template_image;
    if (!made_from) {
        sm_status st = take_mesh(files->template_mesh, files->template_given, files->limits,
                                 &out->template_mesh, err);
        if (st != SM_OK)
            file_error(err, naming, SM_PART_TEMPLATE, files->template_mesh, out);
        return st;
    }
    const char *part = files->template_surface ? SM_PART_NAME_TEMPLATE_SURFACE
                                               : SM_PART_NAME_TEMPLATE_IMAGE;
    if (files->template_mesh || (files->template_surface && files->template_image)) {
        out->failed = SM_PART_TEMPLATE;
        return sm_error_set(err, SM_ERR_INVALID,
                            "%s: give one template: a volume mesh (template), a closed surface "
                            "(template_surface) or a label map (template_image)",
                            part);
    }
    if (files->checked_template && files->checked_template_made)
        return reuse_template(files, naming, out, err);
    /* a label map is read as the target image is: its bounds, and a
     * refusal counted as --max-inflated's (413) */
    sm_image_limits lim = image_limits(files, naming);
    sm_status st = sm_job_template_mesh(made_from, files->template_surface_given,
                                        files->template_image != NULL, files->template_label,
                                        files->template_size, files->template_min_quality,
                                        files->limits, &lim, &out->template_mesh,
                                        &out->template_made, err);
    if (st != SM_OK) {
        if (files->limits && (lim.hit == SM_IMAGE_LIMIT_INFLATED || lim.hit == SM_IMAGE_LIMIT_VOXELS))
            files->limits->hit = SM_LIMIT_INFLATED;
        out->failed = SM_PART_TEMPLATE;
        if (naming == SM_JOB_NAME_PARTS)
            part_error(err, part, made_from);
        else if (strstr(err->msg, made_from))
            sm_error_prefix(err, "%s", part);
        else
            sm_error_prefix(err, "%s: %s", part, made_from);
    }
    return st;
}

sm_status sm_job_inputs_read_template(const sm_job_files *files, sm_job_naming naming,
                                      sm_job_inputs *out, sm_error *err)
{
    memset(out, 0, sizeof *out);
    sm_params_default(&out->params);
    out->failed = SM_NPARTS;
    out->read_started = sm_clock_seconds();
    sm_status st;
    if ((st = sm_job_files_check_background(files, naming, err)) != SM_OK) {
        out->failed = SM_PART_PARAMS;
        return st;
    }
    /* a label selects a label map's voxels: with any other template it
     * would be ignored, so it is refused */
    if (files->template_label != 0 && !files->template_image) {
        out->failed = SM_PART_PARAMS;
        return sm_error_set(err, SM_ERR_INVALID, "%s",
                            naming == SM_JOB_NAME_PARTS
                                ? "params.template_label: the label of a template_image, and "
                                  "the job has none"
                                : "template_label (--template-label) is the label of a template "
                                  "image (--template-image), and there is none");
    }
    out->background_asked.size = files->background_size > 0 ? files->background_size : 0;
    out->background_asked.padding = files->background_padding > 0 ? files->background_padding : 0;
    out->background_asked.template_size = files->template_size > 0 ? files->template_size : 0;
    out->background_asked.template_label =
        files->template_label > 0 && files->template_label <= INT_MAX ? (int)files->template_label : 0;
    if ((st = take_template(files, naming, out, err)) != SM_OK)
        goto fail;
    out->dim = out->template_mesh->dim;
    /* topology checks on a copy: building the boundary reorients
     * elements, and the outputs keep the input's connectivity as is; the
     * run works on this copy */
    if ((st = sm_mesh_clone(out->template_mesh, &out->prepared, err)) != SM_OK ||
        (st = sm_mesh_build_boundary(out->prepared, err)) != SM_OK ||
        (st = sm_mesh_check_manifold(out->prepared, err)) != SM_OK) {
        file_error(err, naming, SM_PART_TEMPLATE, files->template_mesh, out);
        goto fail;
    }
    if ((st = sm_job_read_landmarks(files, out, err)) != SM_OK) {
        if (naming == SM_JOB_NAME_PARTS && out->failed != SM_NPARTS)
            landmark_part_error(err, files, out->failed);
        goto fail;
    }
    return SM_OK;
fail:
    if (st == SM_ERR_NOMEM && !(files->limits && files->limits->hit))
        out->failed = SM_NPARTS;
    sm_job_inputs_free(out);
    return st;
}

/* The target: a surface (its distance on a given or generated
 * background) or a background mesh and its distance, then the field. */
static sm_status read_target(const sm_job_files *files, sm_job_naming naming, sm_job_inputs *out,
                             sm_error *err)
{
    sm_status st;
    if (files->target_image) {
        if (files->target_sol || files->target_surface) {
            out->failed = SM_PART_TARGET_IMAGE;
            return sm_error_set(err, SM_ERR_INVALID, "%s excludes %s: give one target",
                                SM_PART_NAME_TARGET_IMAGE,
                                sm_part_name(files->target_sol ? SM_PART_TARGET_SOL
                                                               : SM_PART_TARGET_SURFACE));
        }
        if ((st = read_image_target(files, naming, out, err)) != SM_OK)
            return st;
    } else if (files->target_surface) {
        if (files->target_sol) {
            out->failed = SM_PART_TARGET_SURFACE;
            return sm_error_set(err, SM_ERR_INVALID, "%s excludes %s: give one target",
                                SM_PART_NAME_TARGET_SURFACE, sm_part_name(SM_PART_TARGET_SOL));
        }
        if ((st = read_surface_target(files, naming, out, err)) != SM_OK)
            return st;
    } else {
        if ((st = take_mesh(files->target_mesh, files->target_mesh_given, files->limits, &out->background,
                                       err)) != SM_OK)
            return file_error(err, naming, SM_PART_TARGET_MESH, files->target_mesh, out);
        if (out->background->dim != out->dim)
            return sm_error_set(err, SM_ERR_INVALID,
                                "dimension mismatch: the template is %dD but the target mesh is %dD",
                                out->dim, out->background->dim);
        if ((st = take_sol(files->target_sol, files->target_sol_given, files->limits, &out->distance,
                           err)) !=
            SM_OK)
            return file_error(err, naming, SM_PART_TARGET_SOL, files->target_sol, out);
        if ((st = check_distance(files, naming, out, err)) != SM_OK)
            return st;
    }
    if (out->target_deferred)
        return SM_OK;
    double tf = sm_clock_seconds();
    st = sm_field_new(out->background, out->distance->values, &out->field, err);
    out->field_builds++;
    out->field_build_seconds = sm_clock_seconds() - tf;
    if (st != SM_OK)
        return file_error(err, naming, SM_PART_TARGET_MESH, files->target_mesh, out);
    return SM_OK;
}

sm_status sm_job_inputs_finish_target(sm_job_inputs *in, const sm_mesh *template_mesh,
                                      sm_error *err)
{
    if (!in->target_deferred)
        return SM_OK;
    const sm_job_background_plan *plan = &in->plan;
    sm_part part = in->image_target ? SM_PART_TARGET_IMAGE : SM_PART_TARGET_SURFACE;
    double t0 = sm_clock_seconds();
    sm_status st;
    if (in->image_target) {
        st = image_background(plan, template_mesh, in, in->image_target, err);
        if (st == SM_OK)
            st = sm_job_image_distance(in->image_target, in->background, &in->distance,
                                       &in->image, err);
    } else {
        st = generate_background(plan, template_mesh, in, in->target_surface, in->target_sdf,
                                 NULL, err);
        if (st == SM_OK &&
            (st = sm_sol_alloc(&in->distance, in->dim, in->background->nverts, 1, err)) == SM_OK)
            st = sm_sdf_signed(in->target_sdf, in->background->nverts, in->background->coords,
                               in->distance->values, err);
    }
    in->sdf_seconds += sm_clock_seconds() - t0;
    if (st == SM_OK) {
        double tf = sm_clock_seconds();
        st = sm_field_new(in->background, in->distance->values, &in->field, err);
        in->field_builds++;
        in->field_build_seconds = sm_clock_seconds() - tf;
    }
    if (st != SM_OK && st != SM_ERR_NOMEM && in->failed == SM_NPARTS)
        file_error(err, plan->naming, part, plan->target_path, in);
    in->target_deferred = 0;
    if (in->image_target) { /* the label's hierarchy borrows its surface */
        sm_sdf_free(in->target_sdf);
        in->target_sdf = NULL;
    }
    sm_image_target_free(in->image_target);
    in->image_target = NULL;
    in->plan.target_path = NULL;
    in->plan.limits = NULL;
    free(in->plan_path);
    in->plan_path = NULL;
    return st;
}

/* After read_target, on its thread: the run's measure when the run will
 * use the field as read (no alignment).  A failure leaves it NULL: the
 * run builds it again and reports. */
static void prepare_coverage(sm_job_inputs *in)
{
    if (in->params.align != SM_ALIGN_NONE || in->target_deferred || !in->field)
        return;
    const sm_surface *exact = in->surface ? in->surface
                              : in->has_surface ? in->target_surface
                                                : NULL;
    sm_error ignored;
    if (sm_coverage_new(in->field, exact, in->prepared, in->params.free_refs,
                        in->params.n_free_refs, &in->coverage, &ignored) != SM_OK)
        in->coverage = NULL;
}

/* The run's template side, set up beside read_target: only its own
 * members of *in are written (the other thread writes the target's). */
static void prepare_run(sm_job_inputs *in)
{
    double t0 = sm_clock_seconds();
    sm_error_clear(&in->match_error);
    if (in->params.align != SM_ALIGN_NONE)
        return; /* the template moves first: its side is set up on the
                 * moved copy (sm_job_run_exec) */
    sm_match_opts opts = {.template_mesh = in->template_mesh, .prepared = in->prepared,
                          .params = &in->params};
    int blas = in->template_mesh->nelems < SM_JOB_THREADS_MIN_ELEMENTS ? sm_job_blas_threads_set(1)
                                                                      : -1;
    in->match_status = sm_match_new(&opts, &in->match, &in->match_error);
    if (blas > 0)
        sm_job_blas_threads_set(blas);
    in->match_seconds = sm_clock_seconds() - t0;
}

sm_status sm_job_inputs_read_target(const sm_job_files *files, sm_job_naming naming, int prepare,
                                    sm_job_inputs *out, sm_error *err)
{
    sm_status st = SM_OK;
    if (prepare) {
        /* two coarse tasks, not a loop of small ones: worth a second
         * thread whatever the size (the run's thread policy is for the
         * descent's loops) */
#pragma omp parallel sections num_threads(omp_get_max_threads() > 1 ? 2 : 1)
        {
#pragma omp section
            if ((st = read_target(files, naming, out, err)) == SM_OK)
                prepare_coverage(out);
#pragma omp section
            prepare_run(out);
        }
    } else {
        st = read_target(files, naming, out, err);
    }
    if (st != SM_OK) {
        if (st == SM_ERR_NOMEM && !(files->limits && files->limits->hit))
            out->failed = SM_NPARTS;
        sm_job_inputs_free(out);
        return st;
    }
    out->read_seconds = sm_clock_seconds() - out->read_started;
    return SM_OK;
}

sm_status sm_job_inputs_read(const sm_job_files *files, sm_job_naming naming,
                             sm_job_inputs *out, sm_error *err)
{
    sm_status st = sm_job_inputs_read_template(files, naming, out, err);
    if (st == SM_OK)
        st = sm_job_inputs_read_target(files, naming, 0, out, err);
    return st;
}

sm_status sm_job_inputs_set_params(sm_job_inputs *in, const sm_params *params, sm_error *err)
{
    sm_status st;
    int32_t nclamped = 0;
    in->failed = SM_PART_PARAMS;
    /* no clamp given: the default ball, chosen on the template's own
     * boundary (the prepared copy has it) */
    sm_params p = *params;
    double inradius = 0;
    if ((st = sm_params_validate(&p, in->dim, err)) != SM_OK ||
        (st = sm_clamp_resolve(in->prepared, &p, &inradius, err)) != SM_OK ||
        (st = sm_clamp_check(in->template_mesh, &p, &nclamped, err)) != SM_OK ||
        (st = sm_clamp_check_parts(in->template_mesh, &p, err)) != SM_OK)
        return st;
    in->failed = SM_NPARTS;
    in->params = p;
    in->nclamped = nclamped;
    in->clamp_default = params->clamp == SM_CLAMP_AUTO;
    in->clamp_inradius = inradius;
    sm_job_landmarks_to_frame(in, params->image_space);
    /* a template side set up with other parameters is stale */
    sm_match_free(in->match);
    in->match = NULL;
    in->match_status = SM_OK;
    sm_coverage_free(in->coverage); /* its free boundary may change */
    in->coverage = NULL;
    return SM_OK;
}

sm_status sm_job_inputs_load(const sm_job_files *files, const char *params_text,
                             size_t params_len, sm_job_inputs *out, sm_error *err)
{
    json_t *root;
    /* cheap syntax check first: no mesh parsing for a garbled params */
    sm_status st = smp_load(params_text, params_len, SM_PARAMS_JSON_MAX_BYTES, "params", &root, err);
    if (st != SM_OK) {
        memset(out, 0, sizeof *out);
        out->failed = SM_PART_PARAMS;
        return st;
    }
    st = sm_job_inputs_load_json(files, root, out, err);
    json_decref(root);
    return st;
}

sm_status sm_job_inputs_load_json(const sm_job_files *files, const json_t *params_doc,
                                  sm_job_inputs *out, sm_error *err)
{
    sm_params params;
    sm_background_params bg;
    sm_status st;
    /* the values that do not need the template first: no mesh parsing
     * for a params object that is wrong anyway */
    if ((st = sm_job_params_from_jansson(params_doc, 0, "params", &params, &bg, err)) != SM_OK) {
        memset(out, 0, sizeof *out);
        out->failed = SM_PART_PARAMS;
        return st;
    }
    sm_job_files with_bg = *files;
    if (!(with_bg.background_size > 0))
        with_bg.background_size = bg.size;
    if (!(with_bg.background_padding > 0))
        with_bg.background_padding = bg.padding;
    if (!(with_bg.template_size > 0))
        with_bg.template_size = bg.template_size;
    if (with_bg.template_label == 0)
        with_bg.template_label = bg.template_label;
    if (!(with_bg.template_min_quality > 0))
        with_bg.template_min_quality = params.min_quality;
    /* the files, then the params' values (the upload's check: a file's
     * 413 before a param's 422); with prepare_run (the worker, on checked
     * inputs) the params come before the target, whose reading the run's
     * template side then overlaps */
    if ((st = sm_job_inputs_read_template(&with_bg, SM_JOB_NAME_PARTS, out, err)) != SM_OK)
        return st;
    /* an image target is selected by the params' label, level and
     * image_space: values the syntax check has decoded (they do not
     * depend on the dimension), in place before the target is read */
    out->params.label = params.label;
    out->params.level = params.level;
    out->params.smooth = params.smooth;
    out->params.image_space = params.image_space;
    /* and with an alignment a generated background waits for it (the
     * check builds none: the run builds it around the moved template) */
    out->params.align = params.align;
    if (!files->prepare_run &&
        (st = sm_job_inputs_read_target(&with_bg, SM_JOB_NAME_PARTS, 0, out, err)) != SM_OK)
        return st;
    if ((st = sm_job_params_from_jansson_for(params_doc, out->template_mesh, &params, NULL,
                                             err)) != SM_OK)
        goto fail;
    if ((st = sm_job_inputs_set_params(out, &params, err)) != SM_OK) {
        sm_error_prefix(err, "%s", params.clamp == SM_CLAMP_BALL ? "params.clamp" : "params.clamp.refs");
        goto fail;
    }
    /* landmarks are the alignment's start: without one they would be
     * ignored, so a job that gives them with align none is refused */
    if (out->nlandmarks > 0 && out->params.align == SM_ALIGN_NONE) {
        sm_job_inputs_free(out);
        out->failed = SM_PART_TEMPLATE_LANDMARKS;
        return sm_error_set(err, SM_ERR_INVALID,
                            "%s: landmarks need an alignment: params align is none; give align "
                            "rigid, similarity or affine, or leave out %s and %s",
                            sm_part_name(SM_PART_TEMPLATE_LANDMARKS),
                            sm_part_name(SM_PART_TEMPLATE_LANDMARKS),
                            sm_part_name(SM_PART_TARGET_LANDMARKS));
    }
    /* the landmark start itself (a few points: cheap), so that too few
     * pairs or collinear ones are refused with the upload, not by the run */
    sm_transform start;
    if (out->nlandmarks > 0 &&
        (st = sm_align_landmarks(out->dim, out->nlandmarks, out->landmarks[0], out->landmarks[1],
                                 out->params.align, &start, err)) != SM_OK) {
        sm_job_inputs_free(out);
        out->failed = SM_PART_TEMPLATE_LANDMARKS;
        sm_error_prefix(err, "%s", sm_part_name(SM_PART_TEMPLATE_LANDMARKS));
        return st;
    }
    if (files->prepare_run)
        return sm_job_inputs_read_target(&with_bg, SM_JOB_NAME_PARTS, 1, out, err);
    return SM_OK;
fail:
    sm_job_inputs_free(out);
    out->failed = SM_PART_PARAMS;
    return st;
}
