/* The job runner's alignment step (see sm_job_align.h). */
#include "job/sm_job_align.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "shapematch/sm_clamp.h"
#include "sm_points_csv.h"
#include "shapematch/sm_clock.h"
#include "sm_proto_json.h"
#include "sm_proto_vocab.h"

sm_status sm_job_read_landmarks(const sm_job_files *files, sm_job_inputs *in, sm_error *err)
{
    const char *paths[2] = {files->landmarks_template, files->landmarks_target};
    static const char *const roles[2] = {"template", "target"};
    if (!paths[0] && !paths[1])
        return SM_OK;
    if (!paths[0] || !paths[1])
        return sm_error_set(err, SM_ERR_INVALID,
                            "landmarks: give both files, the template's and the target's");
    int32_t n[2] = {0, 0};
    /* Slicer's markups state their frame: kept as read, put in the
     * template's by sm_job_landmarks_to_frame once the params say it */
    for (int k = 0; k < 2; k++) {
        sm_points p;
        sm_status st = sm_points_read_file(paths[k], (size_t)16 << 20,
                                           SM_LANDMARKS_MAX, &p, err);
        if (st == SM_OK && p.dim != in->dim)
            st = sm_error_set(err, SM_ERR_FORMAT, "%s: %dD points (x,y%s), the template is %dD",
                              paths[k], p.dim, p.dim == 3 ? ",z" : "", in->dim);
        if (st == SM_OK) {
            in->landmarks_frame[k] = (int)p.frame;
            in->landmarks[k] = p.xyz;
            n[k] = (int32_t)p.n;
            p.xyz = NULL;
        }
        sm_points_release(&p);
        if (st != SM_OK) {
            in->failed = k ? SM_PART_TARGET_LANDMARKS : SM_PART_TEMPLATE_LANDMARKS;
            sm_error_prefix(err, "landmarks (%s)", roles[k]);
            return st;
        }
    }
    in->failed = SM_PART_TARGET_LANDMARKS; /* the second file disagrees with the first */
    if (n[0] != n[1])
        return sm_error_set(err, SM_ERR_INVALID,
                            "landmarks: %ld template point(s) and %ld target point(s): the rows "
                            "must match one to one",
                            (long)n[0], (long)n[1]);
    in->failed = SM_NPARTS;
    in->nlandmarks = n[0];
    return SM_OK;
}

void sm_job_landmarks_to_frame(sm_job_inputs *in, sm_image_space space)
{
    int want = space == SM_IMAGE_SPACE_RAS ? SM_POINTS_FRAME_RAS : SM_POINTS_FRAME_LPS;
    for (int k = 0; k < 2 && in->dim == 3; k++) {
        if (!in->landmarks[k] || in->landmarks_frame[k] == SM_POINTS_FRAME_UNSTATED ||
            in->landmarks_frame[k] == want)
            continue;
        for (int32_t i = 0; i < in->nlandmarks; i++) { /* LPS <-> RAS: x and y negated */
            in->landmarks[k][3 * i] = -in->landmarks[k][3 * i];
            in->landmarks[k][3 * i + 1] = -in->landmarks[k][3 * i + 1];
        }
        in->landmarks_frame[k] = want;
    }
}

void sm_job_alignment_free(sm_job_alignment *a)
{
    if (!a)
        return;
    sm_mesh_free(a->template_mesh);
    sm_mesh_free(a->prepared);
    a->template_mesh = a->prepared = NULL;
}

/* The moved copy of m (coordinates through t; det > 0 keeps every
 * element's orientation and the boundary's). */
static sm_status moved_copy(const sm_mesh *m, const sm_transform *t, sm_mesh **out,
                            sm_error *err)
{
    sm_status st = sm_mesh_clone(m, out, err);
    if (st == SM_OK)
        sm_transform_apply(t, (*out)->nverts, (*out)->coords, (*out)->coords);
    return st;
}

/* The target the alignment sees: the exact surface when the inputs kept
 * one (a surface target's, an image's level set), else the field. */
static void target_of(const sm_job_inputs *in, sm_align_opts *o)
{
    o->surface = in->target_sdf;
    if (!o->surface) {
        o->target = in->field;
        o->background = in->background;
        o->distance = in->distance ? in->distance->values : NULL;
    }
}

/* A background deferred by the inputs, built around the template where
 * the match starts (moved, or as read when nothing moved). */
static sm_status finish_target(sm_job_inputs *in, sm_job_alignment *a, const sm_mesh *where,
                               sm_error *err)
{
    if (!in->target_deferred)
        return SM_OK;
    double t0 = sm_clock_seconds();
    sm_status st = sm_job_inputs_finish_target(in, where, err);
    a->background_after = st == SM_OK;
    a->background_seconds = sm_clock_seconds() - t0;
    return st;
}

sm_status sm_job_align(sm_job_inputs *in, const volatile int *cancel, sm_job_alignment *a,
                       sm_error *err)
{
    memset(a, 0, sizeof *a);
    a->mode = in->params.align;
    a->params = in->params;
    if (a->mode == SM_ALIGN_NONE) {
        if (in->nlandmarks > 0)
            return sm_error_set(err, SM_ERR_INVALID,
                                "landmarks need an alignment: give --align (params align) rigid, "
                                "similarity or affine");
        return finish_target(in, a, in->template_mesh, err);
    }
    sm_transform start;
    sm_status st = SM_OK;
    if (in->nlandmarks > 0 &&
        (st = sm_align_landmarks(in->dim, in->nlandmarks, in->landmarks[0], in->landmarks[1],
                                 a->mode, &start, err)) != SM_OK)
        return st;
    a->landmarks = in->nlandmarks;
    sm_align_opts o = {.mode = a->mode, .template_mesh = in->prepared,
                       .start = in->nlandmarks > 0 ? &start : NULL, .cancel = cancel};
    target_of(in, &o);
    a->exact = o.surface != NULL;
    if ((st = sm_align_run(&o, &a->result, err)) != SM_OK)
        return st;
    if (a->result.cancelled) {
        a->cancelled = 1;
        /* the result set of a cancelled run needs its target too */
        return finish_target(in, a, in->template_mesh, err);
    }
    const sm_transform *t = &a->result.transform;
    if ((st = moved_copy(in->template_mesh, t, &a->template_mesh, err)) != SM_OK ||
        (st = moved_copy(in->prepared, t, &a->prepared, err)) != SM_OK ||
        (st = finish_target(in, a, a->template_mesh, err)) != SM_OK) {
        sm_job_alignment_free(a);
        return st;
    }
    if (a->params.clamp == SM_CLAMP_BALL) {
        double c[3] = {0, 0, 0};
        sm_transform_apply(t, 1, in->params.clamp_center, c);
        memcpy(a->params.clamp_center, c, sizeof c);
        a->params.clamp_radius *= a->result.scale;
        if ((st = sm_clamp_check(a->prepared, &a->params, NULL, err)) != SM_OK) {
            sm_error_prefix(err, "the clamp ball moved with the template (affine: radius times "
                                 "the mean scale %.4g)",
                            a->result.scale);
            sm_job_alignment_free(a);
            return st;
        }
    }
    a->done = 1;
    return SM_OK;
}

void sm_job_aligned_view(const sm_job_inputs *in, const sm_job_alignment *a, sm_job_inputs *view)
{
    *view = *in;
    if (!a->done)
        return;
    view->template_mesh = a->template_mesh;
    view->prepared = a->prepared;
    view->params = a->params;
    view->match = NULL;
}

json_t *sm_job_alignment_json(const sm_job_alignment *a, int dim)
{
    json_t *o = json_object(), *matrix = json_array();
    int bad = !o || !matrix;
    double h[16];
    sm_transform_homogeneous(&a->result.transform, h);
    for (int i = 0; !bad && i < (dim + 1) * (dim + 1); i++)
        bad = json_array_append_new(matrix, json_real(h[i])) != 0;
    bad = bad || smp_set(o, "mode", json_string(sm_align_mode_name(a->mode))) ||
          smp_set(o, "matrix", json_incref(matrix)) ||
          smp_set(o, "scale", smp_real_or_null(a->result.scale)) ||
          smp_set(o, "rms_before", smp_real_or_null(a->result.rms_before)) ||
          smp_set(o, "rms_after", smp_real_or_null(a->result.rms_after)) ||
          smp_set(o, "target_rms_after", smp_real_or_null(a->result.target_rms_after)) ||
          smp_set(o, "exact", json_boolean(a->exact)) ||
          smp_set(o, "iterations", json_integer(a->result.iterations)) ||
          smp_set(o, "candidates", json_integer(a->result.candidates)) ||
          smp_set(o, "landmarks", json_integer(a->landmarks)) ||
          smp_set(o, "seconds", smp_real_or_null(a->result.seconds));
    json_decref(matrix);
    if (bad) {
        json_decref(o);
        return NULL;
    }
    return o;
}

void sm_job_alignment_event(const sm_job_alignment *a, sm_event *ev)
{
    sm_event_init(ev, SM_EVENT_ALIGNMENT);
    snprintf(ev->alignment.mode, sizeof ev->alignment.mode, "%s", sm_align_mode_name(a->mode));
    ev->alignment.scale = a->result.scale;
    ev->alignment.rms_before = a->result.rms_before;
    ev->alignment.rms_after = a->result.rms_after;
    ev->alignment.seconds = a->result.seconds;
    ev->alignment.iterations = a->result.iterations;
}
