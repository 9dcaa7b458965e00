/* The contract between shapematchd and shapematch-worker.
 *
 * The daemon runs `shapematch-worker JOB_DIR` with
 *   fd 0  /dev/null
 *   fd 1, 2  JOB_DIR/worker.log (appended)
 *   fd 3  the event pipe: one JSON event per line (sm_proto_events.h,
 *         seq 0); the daemon numbers them and appends them to the log
 *   its own process group, PR_SET_PDEATHSIG = SIGKILL (a worker never
 *   outlives its daemon), RLIMIT_CPU / RLIMIT_AS / RLIMIT_CORE = 0.
 * SIGTERM asks the worker to stop at the next iteration.
 *
 * JOB_DIR/job.json (written by the daemon after validation; both sides
 * through smd_job_file.h):
 *   {"template": "inputs/template.mesh", "target_mesh": "inputs/...",
 *    "target_sol": "inputs/...", "params": {<sm_job_params_to_json>}}
 * (paths relative to JOB_DIR); a surface target has "target_surface"
 * instead of "target_sol", and "target_mesh" only when one was sent.  The worker writes its outputs into
 * JOB_DIR/results.tmp/ and renames it to JOB_DIR/results/ when every file
 * is complete, then emits "finished" with the summary and exits 0. */
#ifndef SMD_WORKER_H
#define SMD_WORKER_H

#include "job/sm_job_runner.h"

#define SMD_WORKER_EVENT_FD 3

#define SMD_JOB_FILE "job.json"
#define SMD_RESULTS_DIR "results"
#define SMD_RESULTS_TMP_DIR "results.tmp"
#define SMD_WORKER_LOG "worker.log"
/* The live mesh while a job runs (the worker replaces both atomically,
 * the Medit file first; served by GET /v1/jobs/{id}/mesh/latest), and
 * the longest time between two publications. */
#define SMD_LIVE_PAYLOAD "live.smmesh"
#define SMD_LIVE_MESH "live.mesh"
#define SMD_LIVE_PERIOD 0.5

/* JOB_DIR/results/ holds the job runner's result set (file names:
 * proto/sm_proto_vocab.h, sm_result_formats and SM_RESULT_SUMMARY_FILE),
 * snapshots in results/snapshots/ (SM_SNAPSHOTS_DIR, SM_SNAPSHOT_FORMAT). */

/* Exit codes of shapematch-worker. */
enum smd_worker_exit {
    SMD_WORKER_EXIT_OK = SM_JOB_EXIT_OK,
    SMD_WORKER_EXIT_USAGE = SM_JOB_EXIT_USAGE,         /* bad arguments or job folder */
    SMD_WORKER_EXIT_INPUT = SM_JOB_EXIT_INPUT,         /* inputs unreadable or inconsistent */
    SMD_WORKER_EXIT_NUMERIC = SM_JOB_EXIT_NUMERIC,     /* the core failed (factorization,
                                                        * ...) or no step was possible */
    SMD_WORKER_EXIT_OUTPUT = SM_JOB_EXIT_OUTPUT,       /* cannot write the results */
    SMD_WORKER_EXIT_CANCELLED = SM_JOB_EXIT_CANCELLED, /* SIGTERM */
    SMD_WORKER_EXIT_NOMEM = 6,     /* out of memory (memory limit) */
    SMD_WORKER_EXIT_EXEC = 127     /* the program could not be executed */
};

#endif
