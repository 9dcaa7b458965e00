/* What the daemon commands of the client (submit, watch, fetch, status,
 * list, cancel) share: option parsing with the connection options
 * (--server / SHAPEMATCH_SERVER, --token / SHAPEMATCH_TOKEN), opening the
 * HTTP client, turning a failed or refused request into a message and an
 * exit code (cli.h).  The watch and fetch engines that `submit --wait`
 * chains are daemon_ops.h's. */
#ifndef CLI_REMOTE_H
#define CLI_REMOTE_H

#include <stdio.h>

#include <jansson.h>

#include "args.h"
#include "http.h"

#define REMOTE_DEFAULT_SERVER "http://127.0.0.1:8080"
#define REMOTE_RECONNECT_DEFAULT 30.0
#define REMOTE_RECONNECT_MAX (7.0 * 24 * 3600)

/* ---- option parsing ---- */

/* ids given to the callback besides a table's own */
enum {
    CLI_ARG_POSITIONAL = -1,   /* flag NULL, value = the argument */
    CLI_ARG_JOB = -2           /* a job option (args.h), flag and value */
};

typedef struct cli_flag {
    const char *name;          /* "--wait", "-o" */
    int takes_value;
    int id;                    /* >= 0, passed to the callback */
} cli_flag;

typedef int (*cli_flag_fn)(void *user, int id, const char *flag, const char *value,
                           char *msg, size_t cap);

typedef struct remote_options {
    const char *server;        /* --server, else $SHAPEMATCH_SERVER, else the default */
    const char *token;         /* --token, else $SHAPEMATCH_TOKEN, else none */
    const char *cacert;        /* --cacert, else $SHAPEMATCH_CACERT, else the system CAs */
} remote_options;

/* Parses argv[1..] GNU-style ("--name value", "--name=value"; "--" ends
 * the options): -h/--help gives ARGS_HELP; --server and --token fill conn
 * (whose defaults come from the environment); the table's flags, the job
 * options of args.h when allow_job, and positional arguments go to fn.
 * Returns ARGS_ERROR with msg filled on an unknown option, a missing
 * value or an error from fn. */
args_result remote_parse(int argc, char **argv, const cli_flag *flags, size_t nflags,
                         int allow_job, remote_options *conn, cli_flag_fn fn, void *user,
                         char *msg, size_t cap);

/* Help lines of --server and --token. */
void remote_help_connection(FILE *out);
/* Help lines of the exit codes of the daemon commands. */
void remote_help_exit_codes(FILE *out);

/* A usage error: prints "shapematch CMD: MSG" and the hint, returns 1. */
int remote_usage_error(const char *cmd, const char *msg);

/* Opens the HTTP client.  Returns 0, or an exit code with the message
 * printed. */
int remote_open(const char *cmd, const remote_options *conn, http_client *c);
void remote_close(http_client *c);

/* Reports a request that did not succeed on stderr ("shapematch CMD:
 * error: WHAT: ...", WHAT naming the request, e.g. "submitting the job")
 * and returns its exit code: cannot connect or
 * connection lost 6, HTTP 4xx 7 (problem detail shown; 401 names the
 * token options), 5xx or an unintelligible response 9, a local failure 4. */
int remote_report(const char *cmd, const http_client *c, int token_given, http_outcome o,
                  const http_response *rs, const char *what);

/* A job id is 1..64 characters of [0-9A-Za-z_-] (shapematchd's are 32
 * lowercase hex digits); anything else could not be put in a URL path. */
int remote_check_id(const char *id, char *msg, size_t cap);

/* The response body as a JSON object (NULL when it is not one). */
json_t *remote_json_object(const http_response *rs);

/* Prints body (as received) on stdout with a final newline. */
void remote_print_body(const http_response *rs);

/* "max_iterations after 20 iterations: result->target RMS 2.3e-04 (max
 * 7.9e-04), target->result RMS ... (max ..., p99 ...); L2 of d on the
 * boundary 1.1e-04, min quality 0.504, J -1.2e-02 -> -1.3e-02": the
 * figures of progress_format_figures first, the L2 norm by its name */
void remote_format_result(char *buf, size_t cap, const sm_result *r);

#endif
