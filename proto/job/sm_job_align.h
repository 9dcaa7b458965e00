/* The job runner's alignment step (params "align", sm_align.h): before
 * the descent the template is moved onto the target, and with it the
 * clamp ball (given in template coordinates).  The run then works on the
 * moved copies; the inputs keep the template as read, so the result set's
 * displacement (final positions minus the template as read) is the whole
 * map, alignment and elastic together, and result.* are in the target's
 * coordinates.
 *
 * Landmarks (files landmarks_template and landmarks_target, CSV rows of
 * dim numbers, sm_landmarks_parse) give the refinement its start
 * (Kabsch for rigid, Umeyama otherwise); they need an alignment. */
#ifndef SM_JOB_ALIGN_H
#define SM_JOB_ALIGN_H

#include <jansson.h>

#include "job/sm_job_inputs.h"
#include "shapematch/sm_align.h"
#include "sm_proto_events.h"

typedef struct sm_job_alignment {
    int done;                 /* 1: the template was moved */
    int cancelled;            /* 1: the cancel flag stopped the alignment
                               * (done 0: nothing moved) */
    sm_align_mode mode;
    sm_align_result result;
    int32_t landmarks;        /* pairs that gave the start (0: moments) */
    sm_mesh *template_mesh;   /* the moved copies (owned) */
    sm_mesh *prepared;
    sm_params params;         /* the job's, the clamp ball moved */
    int exact;                /* 1: aligned onto the target's exact surface
                               * (a surface or an image's level set), 0:
                               * onto its sampled field */
    int background_after;     /* 1: the background was generated after the
                               * alignment, around the moved template */
    double background_seconds; /* building it, its distance and field */
} sm_job_alignment;

/* Reads the landmark files of files (both or none; SM_ERR_INVALID for
 * one) into in->landmarks for the template's dimension; equal counts.
 * Messages start with the file's role ("landmarks (template): ..."); on
 * failure in->failed is the landmark part the message is about. */
sm_status sm_job_read_landmarks(const sm_job_files *files, sm_job_inputs *in, sm_error *err);
/* The landmark sets whose files stated a frame (Slicer's markups) put in
 * the template's, params image_space (x and y negated between LPS and
 * RAS); sm_job_inputs_set_params calls it. */
void sm_job_landmarks_to_frame(sm_job_inputs *in, sm_image_space space);

/* Aligns when in->params.align is not none (a->done 0 otherwise, or
 * SM_ERR_INVALID when landmarks were given without an alignment), onto
 * the target's exact surface when the inputs kept one, else onto its
 * field.  Then a background the inputs deferred is built
 * (sm_job_inputs_finish_target) around the moved template, or the
 * template as read when nothing moved (no alignment, a cancel): every
 * run leaves here with its target's field.  The
 * clamp ball's centre moves by the transform and its radius scales by
 * its scale (exact for rigid and similarity; affine: the mean scale
 * |det A|^(1/d), an ellipsoid's ball of equal volume); the moved clamp
 * must still hold vertices as the input's did (sm_clamp_check).  cancel
 * (may be NULL) is the run's flag, polled by the alignment as by the
 * descent: set, the alignment stops within one pass over its points and
 * a->cancelled is set (SM_OK). */
sm_status sm_job_align(sm_job_inputs *in, const volatile int *cancel, sm_job_alignment *a,
                       sm_error *err);
void sm_job_alignment_free(sm_job_alignment *a);

/* summary.json's "alignment": {mode, matrix (row-major (d+1)x(d+1),
 * homogeneous, template -> target), scale, rms_before, rms_after,
 * target_rms_after (the target's surface to the moved template), exact,
 * iterations, candidates, landmarks, seconds}; NULL when out of memory. */
json_t *sm_job_alignment_json(const sm_job_alignment *a, int dim);

/* The alignment as an "alignment" event (sm_proto_events.h; no seq, no
 * time): what the worker streams before the descent. */
void sm_job_alignment_event(const sm_job_alignment *a, sm_event *ev);

/* The inputs as the run sees them: in with the moved template, prepared
 * and params when a->done (a shallow copy: nothing to free). */
void sm_job_aligned_view(const sm_job_inputs *in, const sm_job_alignment *a, sm_job_inputs *view);

#endif
