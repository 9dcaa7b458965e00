/* Shared declarations of the shapematch command-line client: exit codes
 * and the subcommand entry points dispatched by main.c.
 *
 * Exit codes (also printed by `shapematch --help`; scripts rely on them,
 * so they never change meaning):
 *   0  the run finished and converged (summary.json "converged": true,
 *      whatever its stop reason)
 *   1  usage error (unknown option, missing or malformed argument, ...)
 *   2  bad input file (cannot read, parse error, dimension mismatch,
 *      sizes that do not agree)
 *   3  numerical failure (factorization failed, no valid step at the
 *      start, out of memory during the run)
 *   4  cannot write the outputs
 *   5  cancelled (SIGINT/SIGTERM); the outputs of the state reached are
 *      still written.  Daemon commands (watch, submit --wait): the job was
 *      cancelled (dismissed) on the daemon
 *
 * The daemon commands (submit, watch, fetch, status, list, cancel) add:
 *   6  cannot connect to the daemon (refused, unknown host, 10 s connect
 *      timeout), or the connection was lost during a request (watch: and
 *      not re-established within --reconnect-timeout)
 *   7  the daemon refused the request: HTTP 4xx, with the problem+json
 *      "detail" printed (401: no or wrong token, 404: unknown job or no
 *      results yet, 422: the job's inputs or parameters are invalid)
 *   8  the job failed on the daemon (the reason is printed)
 *   9  daemon error: HTTP 5xx, or a response the client cannot understand
 *  10  run, watch, submit --wait: finished but not converged
 *      (quality_blocked, the result's boundary ends off the target by more
 *      than the background resolves: SM_JOB_RESOLVED_FACTOR in
 *      proto/job/sm_job_runner.h, or the target is not covered:
 *      SM_JOB_COVERED_FACTOR in proto/job/sm_job_warnings.h, warning
 *      target-not-reached); every output is written (a daemon's job
 *      is successful with "converged": false; submit --wait -o still
 *      downloads its results) (after 6-9 so that no code changes meaning)
 * Interrupting watch (Ctrl-C) leaves the job running on the daemon.
 */
#ifndef CLI_H
#define CLI_H

#include "shapematch/sm_io.h" /* sm_mesh, sm_sol */
#include "sm_proto_vocab.h" /* sm_template_from */

enum cli_exit_code {
    CLI_EXIT_OK = 0,
    CLI_EXIT_USAGE = 1,
    CLI_EXIT_INPUT = 2,
    CLI_EXIT_NUMERIC = 3,
    CLI_EXIT_OUTPUT = 4,
    CLI_EXIT_CANCELLED = 5,
    CLI_EXIT_CONNECT = 6,
    CLI_EXIT_REFUSED = 7,
    CLI_EXIT_JOB_FAILED = 8,
    CLI_EXIT_SERVER = 9,
    CLI_EXIT_NOT_CONVERGED = 10,
    /* batch: some targets failed or the model could not be built */
    CLI_EXIT_BATCH_PARTIAL = 11
};

#ifndef SM_VERSION
#define SM_VERSION "unknown"
#endif

/* The text block describing the exit codes, shared by the help pages. */
extern const char cli_exit_codes_help[];
/* The codes `run` and `sdf` can return, for their help pages. */
extern const char cli_exit_codes_run_help[];
extern const char cli_exit_codes_sdf_help[];

/* A subcommand: argv[0] is the command name, options follow.  Returns
 * the process exit code. */
typedef int (*cli_command_fn)(int argc, char **argv);

int cmd_run(int argc, char **argv);
int cmd_batch(int argc, char **argv);
/* `shapematch batch --server URL ...` (cmd_batch_remote.c) */
int cmd_batch_remote(int argc, char **argv);
/* A batch's LIST.csv (sm_job_batch_list.h) appended to *l, paths
 * relative to its folder (cmd_batch.c).  0, or -1 with msg. */
struct sm_batch_list;
int batch_read_list(struct sm_batch_list *l, const char *path, char *msg, size_t cap);
/* The options of a batch's own template (cmd_batch.c; local and
 * --server alike): --rounds K and --template-tolerance T parsed (0, or
 * -1 with msg); --template-from V checked against the rest and resolved
 * into *from (a FILE becomes *template_path; V NULL: none, and no rounds
 * or tolerance allowed). */
int batch_parse_rounds(const char *v, int *rounds, char *msg, size_t cap);
int batch_parse_tolerance(const char *v, double *tolerance, char *msg, size_t cap);
int batch_resolve_template_from(const char *v, const char **template_path, int rounds,
                                double tolerance, int no_model, sm_template_from *from, char *msg,
                                size_t cap);
/* `shapematch sdf`: signed distance to a surface on a background mesh. */
int cmd_sdf(int argc, char **argv);
void cmd_sdf_help(void);
/* DIR/background.mesh and DIR/background.sol (DIR made if needed); an
 * exit code, the message printed. */
int cmd_sdf_write_dir(const char *dir, const sm_mesh *bg, const sm_sol *sol);
/* `sdf --image` (cmd_sdf_image.c): a label map's boundary. */
int cmd_sdf_image(int argc, char **argv);
/* Writes the help page of `shapematch run` to stdout. */
void cmd_run_help(void);
void cmd_batch_help(void);

/* Daemon commands (HTTP client of shapematchd). */
int cmd_submit(int argc, char **argv);
void cmd_submit_help(void);
int cmd_watch(int argc, char **argv);
void cmd_watch_help(void);
int cmd_fetch(int argc, char **argv);
void cmd_fetch_help(void);
int cmd_status(int argc, char **argv);
void cmd_status_help(void);
int cmd_list(int argc, char **argv);
void cmd_list_help(void);
int cmd_cancel(int argc, char **argv);
void cmd_cancel_help(void);
/* `shapematch warp`: points, meshes and fields through a result's map
 * (a result folder, or a daemon job's results downloaded). */
int cmd_warp(int argc, char **argv);
void cmd_warp_help(void);

#endif
