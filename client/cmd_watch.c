/* `shapematch watch ID`: follows a job's events on the daemon to its end
 * (the engine, remote_watch, is daemon_ops.c's, shared with
 * `submit --wait`). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "daemon_ops.h"
#include "progress.h"
#include "remote.h"

/* ------------------------------------------------------------ command */

void cmd_watch_help(void)
{
    printf("Usage: shapematch watch [--json] [--quiet] [--reconnect-timeout S] ID\n"
           "\n"
           "Follows the job ID on the daemon to its end: its past events are replayed,\n"
           "then new ones are shown as they come (on a terminal the line of 'run', cut to\n"
           "the terminal's width: progress toward the job's tol_boundary or max_iter,\n"
           "iteration, the RMS and max of d on the boundary, the L2 norm, ETA, rate;\n"
           "a plain line every %d iterations otherwise).\n"
           "If the connection drops (the daemon restarts, the network fails), watch\n"
           "reconnects and resumes after the last event received; no event is shown\n"
           "twice.  Interrupting watch (Ctrl-C) leaves the job running.\n"
           "\n"
           "Options:\n"
           "  --json                  every event on stdout as one JSON line (NDJSON,\n"
           "                          proto/events.schema.json), the last of type \"status\"\n"
           "  -q, --quiet             no progress display (errors are still printed)\n"
           "  --reconnect-timeout S   keep trying to reconnect for S seconds without news\n"
           "                          (default %g; 0: give up at the first drop)\n"
           "  -h, --help              this help\n"
           "\n",
           PROGRESS_LINE_EVERY, REMOTE_RECONNECT_DEFAULT);
    remote_help_connection(stdout);
    printf("\n");
    remote_help_exit_codes(stdout);
}

enum { W_JSON, W_QUIET, W_RECONNECT };

typedef struct watch_args {
    const char *id;
    watch_options opt;
} watch_args;

static int watch_flag(void *user, int id, const char *flag, const char *value, char *msg,
                      size_t cap)
{
    watch_args *a = user;
    switch (id) {
    case CLI_ARG_POSITIONAL:
        if (a->id) {
            snprintf(msg, cap, "unexpected argument '%.80s' (watch takes one job id)", value);
            return -1;
        }
        a->id = value;
        return 0;
    case W_JSON:
        a->opt.json = 1;
        return 0;
    case W_QUIET:
        a->opt.quiet = 1;
        return 0;
    case W_RECONNECT:
        return watch_parse_reconnect(flag, value, &a->opt.reconnect_timeout, msg, cap);
    }
    return -1;
}

int cmd_watch(int argc, char **argv)
{
    static const cli_flag flags[] = {
        {"--json", 0, W_JSON},
        {"--quiet", 0, W_QUIET},
        {"-q", 0, W_QUIET},
        {"--reconnect-timeout", 1, W_RECONNECT},
    };
    watch_args a;
    memset(&a, 0, sizeof a);
    a.opt.reconnect_timeout = REMOTE_RECONNECT_DEFAULT;
    remote_options conn;
    char msg[ARGS_MSG_LEN];
    switch (remote_parse(argc, argv, flags, sizeof flags / sizeof flags[0], 0, &conn, watch_flag,
                         &a, msg, sizeof msg)) {
    case ARGS_HELP:
        cmd_watch_help();
        return CLI_EXIT_OK;
    case ARGS_ERROR:
        return remote_usage_error("watch", msg);
    case ARGS_OK:
        break;
    }
    if (!a.id)
        return remote_usage_error("watch", "missing the job id");
    if (remote_check_id(a.id, msg, sizeof msg) != 0)
        return remote_usage_error("watch", msg);
    http_client c;
    int code = remote_open("watch", &conn, &c);
    if (code != 0)
        return code;
    code = remote_watch(&c, "watch", conn.token != NULL, a.id, &a.opt);
    remote_close(&c);
    return code;
}
