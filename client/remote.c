/* Shared parts of the daemon commands (see remote.h). */
#include "remote.h"
#include "msg.h"

#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "progress.h"


/* ------------------------------------------------------------ parsing */

enum { FLAG_SERVER = -10, FLAG_TOKEN = -11, FLAG_CACERT = -12 };

static const cli_flag connection_flags[] = {
    {"--server", 1, FLAG_SERVER},
    {"--token", 1, FLAG_TOKEN},
    {"--cacert", 1, FLAG_CACERT},
};

static const cli_flag *find_flag(const cli_flag *flags, size_t n, const char *name)
{
    for (size_t i = 0; i < n; i++)
        if (strcmp(flags[i].name, name) == 0)
            return &flags[i];
    return NULL;
}

args_result remote_parse(int argc, char **argv, const cli_flag *flags, size_t nflags,
                         int allow_job, remote_options *conn, cli_flag_fn fn, void *user,
                         char *msg, size_t cap)
{
    const char *env_server = getenv("SHAPEMATCH_SERVER");
    const char *env_token = getenv("SHAPEMATCH_TOKEN");
    conn->server = env_server && env_server[0] ? env_server : REMOTE_DEFAULT_SERVER;
    conn->token = env_token && env_token[0] ? env_token : NULL;
    const char *env_cacert = getenv("SHAPEMATCH_CACERT");
    conn->cacert = env_cacert && env_cacert[0] ? env_cacert : NULL;
    int only_positional = 0;
    for (int i = 1; i < argc; i++) {
        const char *arg = argv[i];
        if (only_positional || arg[0] != '-' || arg[1] == '\0') {
            if (fn(user, CLI_ARG_POSITIONAL, NULL, arg, msg, cap) != 0)
                return ARGS_ERROR;
            continue;
        }
        if (strcmp(arg, "--") == 0) {
            only_positional = 1;
            continue;
        }
        if (strcmp(arg, "-h") == 0 || strcmp(arg, "--help") == 0)
            return ARGS_HELP;
        char flag[40];
        const char *inline_value;
        if (args_split_flag(arg, flag, sizeof flag, &inline_value) != 0) {
            cli_fail(msg, cap, "unknown option '%.40s...'", arg);
            return ARGS_ERROR;
        }
        const cli_flag *f = find_flag(flags, nflags, flag);
        if (!f)
            f = find_flag(connection_flags, sizeof connection_flags / sizeof connection_flags[0],
                          flag);
        int takes_value, id;
        if (f) {
            takes_value = f->takes_value;
            id = f->id;
        } else if (allow_job && (takes_value = job_option_lookup(flag)) >= 0) {
            id = CLI_ARG_JOB;
        } else {
            cli_fail(msg, cap, "unknown option '%s'", flag);
            return ARGS_ERROR;
        }
        const char *value = NULL;
        if (args_take_value(argc, argv, &i, flag, inline_value, takes_value, &value, msg, cap) != 0)
            return ARGS_ERROR;
        if (id == FLAG_SERVER) {
            if (!value[0]) {
                cli_fail(msg, cap, "--server: empty URL");
                return ARGS_ERROR;
            }
            conn->server = value;
        } else if (id == FLAG_TOKEN) {
            conn->token = value[0] ? value : NULL;
        } else if (id == FLAG_CACERT) {
            conn->cacert = value[0] ? value : NULL;
        } else if (fn(user, id, flag, value, msg, cap) != 0) {
            return ARGS_ERROR;
        }
    }
    return ARGS_OK;
}

void remote_help_connection(FILE *out)
{
    fputs("Daemon connection:\n"
          "  --server URL            the daemon's base URL (default: $SHAPEMATCH_SERVER,\n"
          "                          else " REMOTE_DEFAULT_SERVER ")\n"
          "  --token TOKEN           bearer token, sent as 'Authorization: Bearer TOKEN'\n"
          "                          (default: $SHAPEMATCH_TOKEN; prefer the variable: a\n"
          "                          command line is visible to other users)\n"
          "  --cacert FILE           trust the CA certificates (PEM) of FILE for an https://\n"
          "                          daemon, e.g. a self-signed one (default:\n"
          "                          $SHAPEMATCH_CACERT, else the system's CAs)\n",
          out);
}

void remote_help_exit_codes(FILE *out)
{
    fputs("Exit codes:\n"
          "  0  success (watch, submit --wait: the job ended successful)\n"
          "  1  usage error\n"
          "  2  an input file cannot be read (submit)\n"
          "  4  cannot write the outputs (fetch)\n"
          "  5  the job was cancelled (dismissed) on the daemon\n"
          "  6  cannot connect to the daemon, or the connection was lost (watch: and\n"
          "     not recovered within --reconnect-timeout)\n"
          "  7  the daemon refused the request (HTTP 4xx; its detail is printed): 401 no\n"
          "     or wrong token, 404 unknown job or no results yet, 422 invalid job, ...\n"
          "  8  the job failed on the daemon (the reason is printed)\n"
          "  9  daemon error (HTTP 5xx) or a response the client cannot understand\n"
          "  10 watch, submit --wait: the job finished but did not converge (status\n"
          "     successful with \"converged\": false; submit --wait -o still downloads)\n",
          out);
}

int remote_usage_error(const char *cmd, const char *msg)
{
    fprintf(stderr, "shapematch %s: %s\nTry 'shapematch %s --help' for more information.\n", cmd,
            msg, cmd);
    return CLI_EXIT_USAGE;
}

/* ------------------------------------------------------------ client */

int remote_open(const char *cmd, const remote_options *conn, http_client *c)
{
    char msg[HTTP_MSG_LEN];
    if (http_global_init(msg, sizeof msg) != 0) {
        fprintf(stderr, "shapematch %s: error: %s\n", cmd, msg);
        return CLI_EXIT_SERVER;
    }
    if (http_client_init(c, conn->server, conn->token, msg, sizeof msg) != 0) {
        http_global_cleanup();
        return remote_usage_error(cmd, msg);
    }
    c->cacert = conn->cacert; /* borrowed: argv or the environment */
    return 0;
}

void remote_close(http_client *c)
{
    http_client_free(c);
    http_global_cleanup();
}

int remote_report(const char *cmd, const http_client *c, int token_given, http_outcome o,
                  const http_response *rs, const char *what)
{
    char detail[1024], type[64];
    switch (o) {
    case HTTP_CONNECT_FAILED:
        fprintf(stderr,
                "shapematch %s: error: cannot connect to the daemon at %s: %s\n"
                "  (is shapematchd running there? give its address with --server or "
                "SHAPEMATCH_SERVER)\n",
                cmd, c->base, rs->error);
        return CLI_EXIT_CONNECT;
    case HTTP_DROPPED:
        fprintf(stderr, "shapematch %s: error: %s: the connection to %s was lost: %s\n", cmd,
                what, c->base, rs->error);
        return CLI_EXIT_CONNECT;
    case HTTP_BAD_RESPONSE:
        fprintf(stderr, "shapematch %s: error: %s: bad response from %s: %s\n", cmd, what,
                c->base, rs->error);
        return CLI_EXIT_SERVER;
    case HTTP_LOCAL_ERROR:
    case HTTP_STOPPED:
        fprintf(stderr, "shapematch %s: error: %s: %s\n", cmd, what,
                rs->error[0] ? rs->error : "the transfer was stopped");
        return CLI_EXIT_OUTPUT;
    case HTTP_DONE:
        break;
    }
    http_problem_text(rs, detail, sizeof detail, type, sizeof type);
    if (rs->status == 401) {
        fprintf(stderr,
                "shapematch %s: error: %s: the daemon answered 401 Unauthorized: %s\n"
                "  %s\n",
                cmd, what, detail,
                token_given ? "the token given (--token or SHAPEMATCH_TOKEN) is not one the "
                              "daemon accepts"
                            : "this daemon needs a token: give it with --token or "
                              "SHAPEMATCH_TOKEN");
        return CLI_EXIT_REFUSED;
    }
    if (rs->status >= 400 && rs->status < 600) {
        int server_error = rs->status >= 500;
        fprintf(stderr, "shapematch %s: error: %s: %s %ld %s%s%s%s: %s\n", cmd, what,
                server_error ? "daemon error," : "the daemon answered", rs->status,
                http_reason(rs->status), type[0] ? " (" : "", type, type[0] ? ")" : "", detail);
        return server_error ? CLI_EXIT_SERVER : CLI_EXIT_REFUSED;
    }
    fprintf(stderr, "shapematch %s: error: %s: unexpected response from %s: HTTP %ld\n", cmd,
            what, c->base, rs->status);
    return CLI_EXIT_SERVER;
}

int remote_check_id(const char *id, char *msg, size_t cap)
{
    size_t n = strlen(id);
    int good = n >= 1 && n <= 64;
    for (size_t i = 0; i < n && good; i++) {
        char ch = id[i];
        good = (ch >= '0' && ch <= '9') || (ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') ||
               ch == '_' || ch == '-';
    }
    if (!good)
        return cli_fail(msg, cap, "'%.80s' is not a job id (the daemon's ids are 32 hex digits)",
                    id);
    return 0;
}

json_t *remote_json_object(const http_response *rs)
{
    if (!rs->body || rs->len == 0)
        return NULL;
    json_t *doc = json_loadb(rs->body, rs->len, 0, NULL);
    if (!json_is_object(doc)) {
        json_decref(doc);
        return NULL;
    }
    return doc;
}

void remote_print_body(const http_response *rs)
{
    if (rs->body && rs->len) {
        fwrite(rs->body, 1, rs->len, stdout);
        if (rs->body[rs->len - 1] != '\n')
            fputc('\n', stdout);
    }
    fflush(stdout);
}

void remote_format_result(char *buf, size_t cap, const sm_result *r)
{
    char figures[256];
    progress_format_figures(figures, sizeof figures, &r->distance, r->boundary_rms,
                            r->boundary_max, r->boundary_l2);
    snprintf(buf, cap,
             "%s after %d iteration%s: %s, min quality %.3f, J %.6e -> %.6e",
             sm_stop_reason_name(r->stop), r->iterations, r->iterations == 1 ? "" : "s", figures,
             r->min_quality, r->J_initial, r->J);
}
