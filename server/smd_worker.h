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
 * JOB_DIR/job.json (written by the daemon after validation):
 *   {"template": "inputs/template.mesh", "target_mesh": "inputs/...",
 *    "target_sol": "inputs/...", "params": {<sm_params_to_json>}}
 * (paths relative to JOB_DIR).  The worker writes its outputs into
 * JOB_DIR/results.tmp/ and renames it to JOB_DIR/results/ when every file
 * is complete, then emits "finished" with the summary and exits 0. */
#ifndef SMD_WORKER_H
#define SMD_WORKER_H

#define SMD_WORKER_EVENT_FD 3

#define SMD_JOB_FILE "job.json"
#define SMD_RESULTS_DIR "results"
#define SMD_RESULTS_TMP_DIR "results.tmp"
#define SMD_WORKER_LOG "worker.log"

/* Files of JOB_DIR/results/. */
#define SMD_RESULT_MESH "result.mesh"
#define SMD_RESULT_MESHB "result.meshb"
#define SMD_RESULT_VTU "result.vtu"
#define SMD_RESULT_PAYLOAD "result.smmesh"
#define SMD_RESULT_DISPLACEMENT "displacement.sol"
#define SMD_RESULT_DISPLACEMENT_B "displacement.solb"
#define SMD_RESULT_HISTORY_CSV "history.csv"
#define SMD_RESULT_HISTORY_JSON "history.json"
#define SMD_RESULT_SUMMARY "summary.json"
/* Snapshots (params.save_every K): results/snapshots/iter-NNNNN.mesh after
 * iterations K, 2K, ..., the names `shapematch run --save-every` uses. */
#define SMD_SNAPSHOTS_DIR "snapshots"
#define SMD_SNAPSHOT_FORMAT "iter-%05d.mesh"

/* Exit codes of shapematch-worker. */
enum smd_worker_exit {
    SMD_WORKER_EXIT_OK = 0,
    SMD_WORKER_EXIT_USAGE = 1,     /* bad arguments or job folder */
    SMD_WORKER_EXIT_INPUT = 2,     /* inputs unreadable or inconsistent */
    SMD_WORKER_EXIT_NUMERIC = 3,   /* the core failed (factorization, ...) */
    SMD_WORKER_EXIT_OUTPUT = 4,    /* cannot write the results */
    SMD_WORKER_EXIT_CANCELLED = 5, /* SIGTERM */
    SMD_WORKER_EXIT_NOMEM = 6,     /* out of memory (memory limit) */
    SMD_WORKER_EXIT_EXEC = 127     /* the program could not be executed */
};

#endif
