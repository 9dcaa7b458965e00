/* Warnings of a job: what a run that "succeeded" should still tell its
 * user, each with a stable code, a sentence and one figure.  The job
 * runner computes them (sm_job_run.warnings); summary.json lists them as
 * warnings: [{code, message, figure}], `shapematch run` prints them on
 * stderr and the daemon's worker streams each as a "warning" event.  Codes:
 *   outside-background  part of the final boundary lies outside the
 *                       background mesh, where d is only extrapolated
 *                       (figure: fraction of boundary sample points)
 *   sign-inverted       the distance looks positive inside: negative at
 *                       every extreme vertex of the background (figure:
 *                       the fraction of template vertices with d > 0); an
 *                       unambiguous case is refused before the run
 *   misaligned          the template is off the target: the centre of its
 *                       box lies outside the target's box with fewer than
 *                       SM_JOB_INSIDE_MIN_CENTRE of its vertices inside,
 *                       or fewer than
 *                       SM_JOB_INSIDE_MIN of its vertices lie inside the
 *                       target and the boxes of both overlap by less than
 *                       SM_JOB_OVERLAP_MIN of the smaller; names --align
 *                       (after an alignment: that it missed) (figure:
 *                       fraction of vertices outside)
 *   clamp-outside       d > 0 at every clamped vertex (figure: the
 *                       smallest d there)
 *   units               the boxes' diagonals of target and template differ
 *                       by SM_JOB_SIZE_RATIO_UNITS or more (figure:
 *                       target / template)
 *   surface-open        the target surface has open edges (figure: their
 *                       number)
 *   surface-components  the target surface has several components
 *                       (figure: their number)
 *   above-resolution    the final RMS boundary error is above the local
 *                       size of the background elements, the resolution
 *                       d is given at (figure: their ratio)
 *   target-not-reached  the match does not cover the target (see
 *                       sm_job_check_coverage): says how much of the
 *                       target is farther than SM_JOB_COVERED_FACTOR times
 *                       the resolution, how far at most, its centre and
 *                       box (or the same of the result's part that is off
 *                       the target, a sheet across a hole), and a topology
 *                       mismatch (genus, pieces) when the surfaces tell
 *                       one (figure: the fraction of that part)
 *   surface-holes       with above-resolution, when the target surface has
 *                       open edges: its sign may be wrong near the holes;
 *                       says to check it with shapematch sdf (figure: the
 *                       number of open edges)
 *   label-touches-border  the image target's label reaches the image's
 *                       border (figure: the label's voxels)
 *   label-components    the label has several 26-connected components
 *                       (figure: their number)
 *   image-params-unused label, level, smooth or image_space given for a target
 *                       that is not an image (figure: how many)
 *   image-frame         the template as given fits an image target's label
 *                       far better in the other image space (LPS against
 *                       RAS: x, y mirrored): its boundary's RMS distance
 *                       there under SM_JOB_FRAME_RATIO times the one in the
 *                       space read, and under SM_JOB_FRAME_FIT of its box
 *                       diagonal; names --image-space (figure: the ratio
 *                       of the two RMS, read over other)
 *   alpha-small         no clamp and alpha far below the scale E / L^2
 *                       where the descent converges (figure: alpha L^2/E)
 *   clamp-default       no clamp given: the default ball chosen, named so
 *                       that the choice is on record (figure: its radius) */
#ifndef SM_JOB_WARNINGS_H
#define SM_JOB_WARNINGS_H

#include "shapematch/sm_error.h"
#include "shapematch/sm_match.h"
#include <stddef.h>

#include "job/sm_job_inputs.h"
#include "sm_proto_events.h"

#define SM_JOB_WARNINGS_MAX 12

/* misaligned: a template that has under 5% of its vertices inside
 * the target and a box overlapping the target's by under half (a target
 * shrunk x0.5 inside a Gmsh unit ball holds 12% of its vertices, and the
 * boxes overlap fully) */
#define SM_JOB_INSIDE_MIN 0.05
/* image-frame: the other image space fits by this factor better, and
 * within this fraction of the template's box diagonal */
#define SM_JOB_FRAME_RATIO 0.25
#define SM_JOB_FRAME_FIT 0.1
#define SM_JOB_OVERLAP_MIN 0.5
/* misaligned also when the template's box centre lies outside the
 * target's box and under this fraction of its vertices inside the target
 * (a template half over a target, 33% inside, with its clamp outside
 * (tests/cli/warnings.sh) is a clamp problem, not an alignment one) */
#define SM_JOB_INSIDE_MIN_CENTRE 0.25
/* units: sizes 10^0.75 = 5.6 times apart or more (the Gmsh cases of
 * bench/robust.sh grow and shrink the template by 2.6 at most) */
#define SM_JOB_SIZE_RATIO_UNITS 5.6234

/* The sizes of template and target compared: one criterion for the units
 * warning and for the generated background, which a size of the wrong
 * unit would make millions of cells fine (sm_job_inputs.c refuses to
 * generate it then, unless background_size is given). */
typedef struct sm_job_sizes {
    double template_diag, target_diag; /* box diagonals */
    double ratio;                      /* target / template; 0 when either
                                        * box is empty */
    int units_differ;                  /* ratio >= SM_JOB_SIZE_RATIO_UNITS
                                        * or <= its inverse */
} sm_job_sizes;
sm_job_sizes sm_job_compare_sizes(int dim, const double template_lo[3],
                                  const double template_hi[3], const double target_lo[3],
                                  const double target_hi[3]);
/* "the target is 1000 times larger than the template (box diagonals ...),
 * about 1000 times: are they in different units (e.g. the target in
 * millimetres, the template in metres)?" for sizes whose units differ. */
void sm_job_units_text(const sm_job_sizes *s, char *buf, size_t cap);

typedef struct sm_job_warning {
    const char *code;           /* static string, one of the codes above */
    char message[320];
    double figure;
} sm_job_warning;

typedef struct sm_job_warnings {
    sm_job_warning w[SM_JOB_WARNINGS_MAX];
    int n;
} sm_job_warnings;

/* Before the run: the sign of d, the template's placement and size
 * against the target, the clamp set, the target surface's health.
 * SM_ERR_INVALID (message for the user, about target_sol) when the sign
 * is unambiguously inverted: negative at every extreme vertex of the
 * background (the far field, outside any target that does not touch the
 * background's hull) and positive at most of the template's vertices;
 * the warnings above otherwise. */
sm_status sm_job_check_sign(const sm_job_inputs *in, sm_job_warnings *out, sm_error *err);

/* After the run, on the final vertex positions: outside-background,
 * above-resolution and surface-holes (finished runs only), alpha-small.
 * *resolution receives the mean size of the background elements at the
 * final boundary's facet centres (0 when none lies inside the background). */
void sm_job_check_result(const sm_job_inputs *in, const double *coords, const sm_result *r,
                         int finished, sm_job_warnings *out, double *resolution);

/* Converged means covered: both sides of the final distance
 * (r->distance) have their 99th percentile within SM_JOB_COVERED_FACTOR
 * times the resolution (the target side catches a missed protrusion or
 * handle; the result side a sheet spanning a hole the target has), and
 * the target's surface and the template's boundary have the same
 * topology when both are closed (genus, pieces: a deformation keeps
 * them, so a match across a mismatch cannot be exact).  Returns 1 when
 * so (or when it cannot be told: no coverage, no resolution), 0
 * otherwise, and then for a finished run adds target-not-reached from
 * cov's last measure. */
#define SM_JOB_COVERED_FACTOR 2.0
int sm_job_check_coverage(const sm_job_inputs *in, const sm_coverage *cov, const sm_result *r,
                          double resolution, int finished, sm_job_warnings *out);

/* "warning: CODE: MESSAGE; warning: ..." into buf (cap bytes, truncated),
 * "" when there is none: the message of the finished event, which the
 * daemon adds to the job's status message. */
void sm_job_warnings_text(const sm_job_warnings *ws, char *buf, size_t cap);

/* One warning as a "warning" event (sm_proto_events.h; no seq, no
 * time): what the worker streams when the runner raises it. */
void sm_job_warning_event(const sm_job_warning *w, sm_event *ev);

#endif
