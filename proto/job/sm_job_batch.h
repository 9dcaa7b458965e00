/* A batch: one template matched onto many targets in one process group,
 * the template side built once, then the shape model of the results
 * (sm_job_model.h).  `shapematch batch` runs it (client/cmd_batch.c).
 *
 * Reuse: the parent reads and checks the template, applies the
 * parameters and sets up the run's template side (sm_match_new: the
 * topology, the clamp set, the elastic operator and its first
 * factorization or AMG hierarchy) once; each target then runs in a child
 * process forked from it, which inherits all of that copy-on-write
 * (shared read-only until the run moves its own copy; what it overwrites
 * whole it takes fresh: the parent trims its heap before forking, the
 * first refactorization gives the shared values back, sm_elasticity.c),
 * reads its target,
 * runs sm_job_run_exec and writes the result set of `shapematch run`
 * into DIR/targets/NAME/.  The computation is the one of `shapematch
 * run` (the same template side, built by the same call on the same
 * inputs), so the result files are identical bit for bit.  With
 * params.align the template moves before the run, and its side is set up
 * on the moved copy in the child, as `run` does.
 *
 * Thread policy: the cores this process may run on are counted when the
 * batch starts (its affinity); children run side by side, at most
 * min(jobs, targets, cores) at a time, and each child's OpenMP and BLAS
 * limit is cores / children (at most the host's OpenMP limit: the
 * daemon's --worker-threads, OMP_NUM_THREADS), under which the thread
 * policy of sm_job_threads.h applies: children x threads <= cores,
 * never oversubscribed.  The parent sets its own OpenMP and BLAS
 * threads to 1 before forking (a forked child cannot use a parent's
 * OpenMP pool) and puts the host's back for the model.
 *
 * Shared reads: a background (target_mesh) that several targets name is
 * read once by the parent and copied by each child (sm_job_files'
 * target_mesh_given) instead of parsed again; each target's own files
 * (its distance, surface or image) are its own.
 *
 * Warm starts (params warm_start, default 0): each target's descent
 * starts from the nearest finished target's map when that is nearer
 * than the template (sm_job_batch_warm.h); with warm_start 0 the results
 * are the separate runs' bit for bit (at the same thread count).
 *
 * A target that fails (unreadable, no valid step, crash) is reported
 * and left out of the model; it does not stop the others. */
#ifndef SM_JOB_BATCH_H
#define SM_JOB_BATCH_H

#include <stddef.h>

#include "job/sm_job_batch_list.h"
#include "job/sm_job_inputs.h"
#include "job/sm_job_model.h"
#include "shapematch/sm_error.h"

typedef struct sm_batch_opts {
    const char *template_mesh;
    const char *template_landmarks;  /* with per-target landmarks */
    double background_size, background_padding;
    const sm_params *params;         /* checked by the caller */
    unsigned outputs;                /* SM_RESULT_OUT_* of each target */
    int jobs;                        /* children at a time (>= 1) */
    int single_thread;               /* one thread per child even alone (a
                                      * host whose OpenMP pool a forked
                                      * child cannot use) */
    int build_model;                 /* 0: targets only */
    sm_model_opts model;
    /* set (by the caller's signal handler) to stop: no new target starts,
     * the running ones get SIGINT and stop as a cancelled run (the state
     * reached written, status "cancelled"), no model is built.  Each
     * child stops on SIGINT/SIGTERM by its own handler.  May be NULL. */
    const volatile int *cancel;
    /* after each target ends (in the parent; may be NULL) */
    void (*target_done)(size_t index, const char *name, const char *status, int exit_code,
                        double seconds, void *user);
    void *user;
} sm_batch_opts;

typedef struct sm_batch_outcome {
    size_t nok, nfailed;
    double template_seconds;  /* the template side, once */
    int template_setups;      /* sm_match_new calls in the parent (1, or 0
                               * with align: per target, as `run`) */
    double targets_seconds, model_seconds, total_seconds;
    int model_built;
    int cancelled;            /* opts->cancel was set */
    int cores;                /* counted when the batch started */
    int jobs;                 /* children at a time: opts->jobs, at most
                               * the targets and the cores */
    int threads;              /* each child's OpenMP/BLAS limit */
    int warm_start;           /* params warm_start */
    int shared_backgrounds;   /* target meshes read once for several targets */
    char model_error[SM_ERROR_MSG_LEN];
} sm_batch_outcome;

/* Runs the batch into out_dir (targets/, model/, summary.json).  Errors
 * are the template's or the parameters' (nothing run), or writing
 * out_dir; a failed target or model is in the outcome and summary. */
sm_status sm_job_batch_run(const sm_batch_list *list, const sm_batch_opts *opts,
                           const char *out_dir, sm_batch_outcome *out, sm_error *err);

/* Builds BATCH_DIR/model again from the targets BATCH_DIR/summary.json
 * lists as finished or not_converged (their folders under
 * BATCH_DIR/targets/), with opts (another alignment, more modes, ...):
 * `shapematch batch --model-from DIR`.  *members: the targets used. */
sm_status sm_job_batch_remodel(const char *batch_dir, const sm_model_opts *opts, size_t *members,
                               sm_error *err);

#endif
