/* The one job runner: checked inputs (sm_job_inputs.h) -> sm_match_run ->
 * the whole result set and its summary.  `shapematch run` and
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
 * The result set (file names: sm_proto_vocab.h), written into one folder,
 * each file atomically (sm_atomic.h), summary.json last after an older
 * one is removed, so its presence vouches for a complete set from one run:
 *   result.mesh, result.meshb   deformed template (same topology, refs)
 *   result.vtu                  with point fields displacement, distance
 *   result.smmesh               the binary payload (proto/PAYLOAD.md)
 *   displacement.sol, .solb     cumulative displacement x_k - x_0
 *   history.csv, history.json   one row per iteration
 *   summary.json                the summary document below
 * and, with params.save_every K > 0, iter-NNNNN.mesh after iterations K,
 * 2K, ... into the snapshot folder the caller names.
 *
 * summary.json: sm_result_to_jansson's members (stop_reason, iterations,
 * J_initial, J_final, boundary_l2, boundary_max, min_quality, accepted,
 * rejected, timings, parameters) plus shapematch_version, status,
 * exit_code, inverted_elements, field_builds, timings.read and
 * timings.field_build, inputs (the names the caller gives), template
 * (dimension and counts; physical_names [{dim, tag, name}] when the
 * template is a Gmsh .msh with $PhysicalNames), outputs (the file of each result format) and
 * warnings ([{code, message, figure}], sm_job_warnings.h; [] when none).
 * A distance whose sign is unambiguously inverted is refused before the
 * run (SM_ERR_INVALID, the message about target_sol).
 * The daemon serves it as GET /v1/jobs/{id}/results, adding jobID and
 * links. */
#ifndef SM_JOB_RUNNER_H
#define SM_JOB_RUNNER_H

#include <stddef.h>
#include <stdint.h>

#include <jansson.h>

#include "shapematch/sm_error.h"
#include "sm_job_inputs.h"
#include "sm_job_warnings.h"
#include "shapematch/sm_match.h"
#include "sm_proto_vocab.h"

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
 * "converged"): it did not stop as quality_blocked, and its final RMS
 * boundary error is at most SM_JOB_RESOLVED_FACTOR times the resolution,
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
    char message[512];           /* failed: why, for the user */
    sm_job_warnings warnings;    /* sm_job_warnings.h; in the summary */
} sm_job_run;

/* Runs the job on in (field and prepared template reused, nothing is
 * built again; the run's template side too when it was set up while
 * the target was read: in->match is consumed, and its failure is the
 * run's).  SM_OK: run->outcome says how it ended, run->coords and
 * run->result describe the state reached.  Errors: the core's (with its
 * message), SM_ERR_IO when a snapshot cannot be written, SM_ERR_NOMEM.
 * Free run with sm_job_run_free in every case. */
sm_status sm_job_run_exec(sm_job_inputs *in, const sm_job_hooks *hooks,
                          sm_job_run *run, sm_error *err);
void sm_job_run_free(sm_job_run *run);

/* Thread policy of a run: OpenMP and BLAS threads for a template of
 * `elements` elements when at most max_threads are allowed (the OpenMP
 * limit when the run starts: OMP_NUM_THREADS, which the daemon sets from
 * --worker-threads; else the cores) and idle_cores cores run no other
 * process's task right now (sm_job_idle_cores; -1: unknown).
 *   - From SM_JOB_THREADS_MIN_ELEMENTS on, max_threads: the parallel
 *     regions hold enough work to pay even on a busy machine.
 *   - From SM_JOB_THREADS_IDLE_MIN_ELEMENTS on, as many threads as cores
 *     are idle (at most max_threads): with another core free, the
 *     30k-tetrahedron 3D example runs in 0.53 s instead of 0.63 s, but
 *     with both cores busy two threads make it 1.35 s instead of 1.03
 *     (a thread the scheduler does not run makes every barrier wait for
 *     it), so a second thread is only taken where a core is free.
 *   - Below, one thread: a region holds a few microseconds of work (a
 *     778-triangle 2D run at 0.07 ms per iteration with one thread, 0.09
 *     with two even on an idle machine, 16 ms on a busy one).
 * sm_job_run_exec applies it for the run and restores the limit after.
 * The results do not depend on the thread count (the parallel loops
 * write per-item results, their sums and minima are taken in a fixed
 * order: the 3D example's result files are identical with one and two
 * threads), so the policy only changes the time. */
#define SM_JOB_THREADS_MIN_ELEMENTS 100000
#define SM_JOB_THREADS_IDLE_MIN_ELEMENTS 20000
int sm_job_threads_for(int64_t elements, int max_threads, int idle_cores);

/* Cores this process may run on (its affinity) that no task of another
 * process is running on now: from /proc/loadavg's count of running
 * tasks, less this process's own running threads (/proc/self/task).
 * An instant's view, taken when a run starts; -1 when unknown (no
 * /proc), which the policy reads as "none free". */
int sm_job_idle_cores(void);

/* The summary document (a new reference; NULL when out of memory).
 * names: what "inputs" reports for each file. */
json_t *sm_job_summary_to_jansson(const sm_job_inputs *in, const sm_job_run *run,
                                  const sm_job_files *names);

/* Writes the whole result set into dir (which exists).  flags:
 * SM_ATOMIC_FSYNC makes every file durable. */
sm_status sm_job_write_results(const sm_job_inputs *in, const sm_job_run *run,
                               const sm_job_files *names, const char *dir,
                               unsigned flags, sm_error *err);

/* A choice of outputs (`shapematch run --format`): bit i is the file of
 * sm_result_formats[i] (sm_proto_vocab.h); history.csv and summary.json
 * are always written (sm_job_outputs_fix adds history.csv).  With
 * SM_JOB_OUT_GZ the chosen mesh and displacement files are written
 * gzip-compressed as FILE.gz (the same bytes once decompressed).  The
 * daemon's worker writes everything: SM_JOB_OUT_ALL. */
#define SM_JOB_OUT_FORMAT(i) (1u << (i))
#define SM_JOB_OUT_ALL ((1u << SM_RESULT_FORMATS_N) - 1u)
#define SM_JOB_OUT_GZ (1u << SM_RESULT_FORMATS_N)
#define SM_JOB_OUT_NAMES "mesh, meshb, vtu, binary, sol, solb, gz"
unsigned sm_job_outputs_fix(unsigned outputs);
/* "mesh,vtu,sol,gz" -> *outputs: the mesh and displacement format names
 * of sm_result_formats plus gz.  0, or -1 with a message in msg (an
 * unknown name, or gz alone). */
int sm_job_outputs_parse(const char *text, unsigned *outputs, char *msg, size_t cap);
/* sm_job_write_results limited to outputs; the summary's "outputs" lists
 * exactly the files written. */
sm_status sm_job_write_selected(const sm_job_inputs *in, const sm_job_run *run,
                                const sm_job_files *names, const char *dir,
                                unsigned outputs, unsigned flags, sm_error *err);
/* The summary with "outputs" limited to outputs (sm_job_summary_to_jansson
 * lists all of them). */
json_t *sm_job_summary_outputs(const sm_job_inputs *in, const sm_job_run *run,
                               const sm_job_files *names, unsigned outputs);

#endif
