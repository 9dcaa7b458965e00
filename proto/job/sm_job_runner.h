/* The one job runner: checked inputs (sm_job_inputs.h) -> sm_match_run ->
 * the whole result set and its summary (sm_job_results.h), under the
 * thread policy of sm_job_threads.h.  `shapematch run` and
 * `shapematch-worker` both run jobs through it, so a job has one outcome
 * and one summary.json whichever way it is run; each program only adds
 * its own I/O framing (the CLI: progress line, NDJSON, exit codes; the
 * worker: events on its pipe, the results folder it publishes).
 *
 * Outcome of a run that returned SM_OK:
 *   finished   the descent ended by its rules (stop reason);
 *   cancelled  the cancel flag, or the progress hook, asked to stop;
 *   failed     not even the first step could be taken (stop
 *              step_tolerance after 0 iterations): nothing moved, which
 *              for a user is a failure, not a result.
 *
 * A distance whose sign is unambiguously inverted is refused before the
 * run (SM_ERR_INVALID, the message about target_sol). */
#ifndef SM_JOB_RUNNER_H
#define SM_JOB_RUNNER_H

#include <stddef.h>
#include <stdint.h>

#include "job/sm_job_align.h"
#include "job/sm_job_inputs.h"
#include "job/sm_job_warnings.h"
#include "shapematch/sm_error.h"
#include "shapematch/sm_match.h"

/* Exit codes shared by `shapematch run` and `shapematch-worker` (the
 * programs add their own above these). */
enum sm_job_exit {
    SM_JOB_EXIT_OK = 0,
    SM_JOB_EXIT_USAGE = 1,
    SM_JOB_EXIT_INPUT = 2,
    SM_JOB_EXIT_NUMERIC = 3,
    SM_JOB_EXIT_OUTPUT = 4,
    SM_JOB_EXIT_CANCELLED = 5,
    /* finished, every output written, but not converged (the result's
     * converged is false, see below): after 6-9 of the CLI's daemon
     * commands */
    SM_JOB_EXIT_NOT_CONVERGED = 10
};

/* When a finished run has converged (sm_result.converged, summary.json
 * "converged"): it did not stop as quality_blocked, it covers the target
 * (sm_job_check_coverage, sm_job_warnings.h), and its final RMS distance
 * to the target (distance.result_to_target.rms, exact: sm_coverage.h) is
 * at most SM_JOB_RESOLVED_FACTOR times the resolution,
 * the mean size of the background elements at the final boundary
 * (summary.json "resolution"): d is known to P1 accuracy on that grid,
 * so a boundary that still lies half an element away from the zero level
 * set has not reached the target.  Measured (bench/robust.sh, Gmsh unit
 * ball onto ellipsoids, x2, x0.5, a peanut: ratio 0.01-0.05 at the end
 * of a match; onto a torus, a shape of another topology: 2.0-2.1; the
 * paper-like examples: 0.018 in 2D, 0.002 in 3D). */
#define SM_JOB_RESOLVED_FACTOR 0.5

typedef enum sm_job_outcome {
    SM_JOB_OUTCOME_FINISHED = 0,
    SM_JOB_OUTCOME_CANCELLED = 1,
    SM_JOB_OUTCOME_FAILED = 2
} sm_job_outcome;
/* "finished", "cancelled", "failed". */
const char *sm_job_outcome_name(sm_job_outcome outcome);

typedef struct sm_job_hooks {
    /* After each iteration (and the initial state), once the runner has
     * recorded it and written its snapshot.  Nonzero stops the run
     * (outcome cancelled).  May be NULL. */
    int (*progress)(const sm_progress *p, void *user);
    /* Before progress, with the current vertex positions (nverts*dim),
     * for callers that show the shape as it moves (the worker's live
     * mesh); nonzero stops the run like progress.  May be NULL. */
    int (*shape)(const sm_progress *p, const double *coords, void *user);
    /* Each warning as the runner raises it (the sign check before the
     * run, the result checks after it), for callers that stream them
     * (the worker's warning events).  May be NULL. */
    void (*warning)(const sm_job_warning *w, void *user);
    /* Once the template has been aligned (params align not none), before
     * the descent: the CLI's line, the worker's alignment event.  May be
     * NULL. */
    void (*alignment)(const sm_job_alignment *a, void *user);
    /* Before the descent: a warm start (a batch's, sm_job_batch_warm.h).
     * It may write the displacement the descent starts from into start
     * (nverts*dim, from run_mesh: the template the run works on, with its
     * boundary built; the moved copy with an alignment, whose transform a
     * holds; params the run's, its clamp resolved and moved) and return
     * 1; 0 starts from run_mesh itself.  target is the target's field.
     * The core checks the start (sm_match_set_start): one it refuses
     * fails the run with its message.  May be NULL. */
    int (*start)(const sm_mesh *run_mesh, const sm_params *params, const sm_field *target,
                 const sm_job_alignment *a, double *start, void *user);
    void *user;
    const volatile int *cancel;  /* polled between iterations; may be NULL */
    const char *snapshot_dir;    /* iter-NNNNN.mesh go here (NULL: none) */
    unsigned write_flags;        /* SM_ATOMIC_FSYNC: snapshots durable */
} sm_job_hooks;

typedef struct sm_job_run {
    sm_result result;
    double *coords;              /* final vertex positions (nverts*dim) */
    sm_progress *history;        /* one row per iteration, 0 first */
    size_t nhistory, history_cap;
    sm_job_outcome outcome;
    int exit_code;               /* SM_JOB_EXIT_OK, _NUMERIC or _CANCELLED */
    int32_t inverted;            /* elements with volume <= 0 at the end */
    double resolution;           /* background element size at the final
                                  * boundary (sm_job_check_result) */
    char message[512];           /* failed: why, for the user (also set when a
                                  * cancel came during the alignment) */
    sm_job_warnings warnings;    /* sm_job_warnings.h; in the summary */
    sm_job_alignment alignment;  /* params align: the transform and the
                                  * moved template the run worked on */
} sm_job_run;

/* Runs the job on in (field and prepared template reused, nothing is
 * built again; with params align, the template is first moved onto the
 * target, sm_job_align.h, and the run starts from the moved copy; the run's template side too when it was set up while
 * the target was read: in->match is consumed, and its failure is the
 * run's).  SM_OK: run->outcome says how it ended, run->coords and
 * run->result describe the state reached.  Errors: the core's (with its
 * message), SM_ERR_IO when a snapshot cannot be written, SM_ERR_NOMEM.
 * Free run with sm_job_run_free in every case. */
sm_status sm_job_run_exec(sm_job_inputs *in, const sm_job_hooks *hooks,
                          sm_job_run *run, sm_error *err);
void sm_job_run_free(sm_job_run *run);

#endif
