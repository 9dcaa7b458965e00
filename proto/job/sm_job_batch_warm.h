/* A batch's warm starts (params warm_start, sm_job_batch.h): each target
 * of a batch starts its descent from the final map of the finished
 * target nearest to it, instead of from the template.
 *
 * A target that ends with a result leaves a record in the batch's warm
 * folder (DIR/.warm/NAME.start, written atomically, removed when the
 * batch ends): its final displacement from the template its run worked
 * on, and the linear part of its alignment (the identity without one).
 * A target about to descend reads the records there, carries each map to
 * its own frame (the displacement d_i of target i becomes L_j L_i^-1 d_i
 * at target j: pulled back to the template's frame by i's alignment,
 * pushed forward by j's), and measures how far each moved template is
 * from its own target: the RMS of the target's distance d at the loaded
 * boundary's vertices (the run's boundary error, one side; both sides'
 * exact measure, sm_coverage_measure, costs seconds on the 3D example,
 * this a few milliseconds).  The nearest start wins if it is nearer than
 * the template itself and keeps every element above the quality floor;
 * else the target starts cold.  A record's vertices in the target's clamp
 * set stay at 0.
 *
 * Which records exist when a target starts depends on which targets
 * finished first: with --jobs 1 a batch is deterministic, with more
 * children the starts (so the final maps, within the descent's
 * tolerance) can differ between two runs of the same batch. */
#ifndef SM_JOB_BATCH_WARM_H
#define SM_JOB_BATCH_WARM_H

#include "job/sm_job_runner.h"

/* A child's choice, for the summary. */
typedef struct sm_job_warm {
    const char *dir;          /* the warm folder */
    const char *name;         /* this target (its own record is skipped) */
    char source[256];         /* the target started from; "" = the template */
    int candidates;           /* records measured */
    double score_template;    /* RMS of d at the template's boundary vertices */
    double score_start;       /* the same at the start taken */
    double seconds;           /* reading and measuring the records */
} sm_job_warm;

/* The runner's start hook (sm_job_hooks.start) with user an sm_job_warm:
 * the start as described above. */
int sm_job_warm_choose(const sm_mesh *run_mesh, const sm_params *params, const sm_field *target,
                       const sm_job_alignment *a, double *start, void *user);

/* After a run with a result: its record DIR/NAME.start, and its choice
 * DIR/NAME.used ("SOURCE\nCANDIDATES SCORE_TEMPLATE SCORE_START SECONDS\n",
 * SOURCE empty for the template) for the parent's summary. */
sm_status sm_job_warm_record(const sm_job_warm *w, const sm_job_inputs *in,
                             const sm_job_run *run, sm_error *err);

/* The choice of a target whose process ended (its .used file); 0 when
 * there is none (the target failed before its run). */
int sm_job_warm_read_used(const char *dir, const char *name, sm_job_warm *w);

/* The warm folder emptied and removed (at the start of a batch, a stale
 * one; at its end, its own). */
void sm_job_warm_clear(const char *dir);

#endif
