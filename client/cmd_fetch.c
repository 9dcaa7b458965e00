/* `shapematch fetch ID -o OUTDIR [--format LIST]`: downloads the results
 * of a successful job into OUTDIR (the engine, remote_fetch, is
 * daemon_ops.c's, shared with `submit --wait -o`). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "daemon_ops.h"
#include "remote.h"

/* ------------------------------------------------------------ command */

void cmd_fetch_help(void)
{
    printf("Usage: shapematch fetch [--format LIST] [--quiet] -o OUTDIR ID\n"
           "\n"
           "Downloads the results of the successful job ID into OUTDIR (created if\n"
           "missing), the same files as 'shapematch run' writes:\n"
           "  result.mesh, result.meshb, result.vtu, result.smmesh  (by --format)\n"
           "  displacement.sol, displacement.solb   cumulative displacement per vertex\n"
           "  history.csv        one row per iteration\n"
           "  summary.json       stop reason, figures, timings, parameters\n"
           "Transfers are compressed when the daemon allows it.  Files are written under\n"
           "temporary names and renamed; summary.json comes last.\n"
           "\n"
           "Options:\n"
           "  -o, --output DIR        output directory (required)\n"
           "  --format LIST           mesh formats, comma-separated: mesh (Medit ASCII),\n"
           "                          meshb (Medit binary), vtu (ParaView, with the fields\n"
           "                          displacement and distance), binary (the API payload,\n"
           "                          proto/PAYLOAD.md), sol, solb (displacement; sol\n"
           "                          when neither is named); default " FETCH_DEFAULT_FORMATS_TEXT "\n"
           "  -q, --quiet             print nothing on success\n"
           "  -h, --help              this help\n"
           "\n");
    remote_help_connection(stdout);
    printf("\n");
    remote_help_exit_codes(stdout);
}

enum { F_OUTPUT, F_FORMAT, F_QUIET };

typedef struct fetch_args {
    const char *id;
    fetch_options opt;
} fetch_args;

static int fetch_flag(void *user, int id, const char *flag, const char *value, char *msg,
                      size_t cap)
{
    fetch_args *a = user;
    switch (id) {
    case CLI_ARG_POSITIONAL:
        if (a->id) {
            snprintf(msg, cap, "unexpected argument '%.80s' (fetch takes one job id)", value);
            return -1;
        }
        a->id = value;
        return 0;
    case F_OUTPUT:
        if (!value[0]) {
            snprintf(msg, cap, "%s: empty path", flag);
            return -1;
        }
        a->opt.outdir = value;
        return 0;
    case F_FORMAT:
        return fetch_parse_formats(flag, value, &a->opt.formats, msg, cap);
    case F_QUIET:
        a->opt.quiet = 1;
        return 0;
    }
    return -1;
}

int cmd_fetch(int argc, char **argv)
{
    static const cli_flag flags[] = {
        {"--output", 1, F_OUTPUT},
        {"-o", 1, F_OUTPUT},
        {"--format", 1, F_FORMAT},
        {"--quiet", 0, F_QUIET},
        {"-q", 0, F_QUIET},
    };
    fetch_args a;
    memset(&a, 0, sizeof a);
    a.opt.formats = FETCH_DEFAULT_FORMATS;
    a.opt.show_result = 1;
    remote_options conn;
    char msg[ARGS_MSG_LEN];
    switch (remote_parse(argc, argv, flags, sizeof flags / sizeof flags[0], 0, &conn, fetch_flag,
                         &a, msg, sizeof msg)) {
    case ARGS_HELP:
        cmd_fetch_help();
        return CLI_EXIT_OK;
    case ARGS_ERROR:
        return remote_usage_error("fetch", msg);
    case ARGS_OK:
        break;
    }
    if (!a.id)
        return remote_usage_error("fetch", "missing the job id");
    if (!a.opt.outdir)
        return remote_usage_error("fetch", "missing required option -o/--output");
    if (remote_check_id(a.id, msg, sizeof msg) != 0)
        return remote_usage_error("fetch", msg);
    http_client c;
    int code = remote_open("fetch", &conn, &c);
    if (code != 0)
        return code;
    code = remote_fetch(&c, "fetch", conn.token != NULL, a.id, &a.opt);
    remote_close(&c);
    return code;
}
