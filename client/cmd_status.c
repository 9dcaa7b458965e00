/* `shapematch status ID`, `shapematch list`, `shapematch cancel ID`: the
 * job documents of the daemon (OGC API - Processes statusInfo), printed
 * for a human, or as the daemon's JSON with --json. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "remote.h"
#include "sm_proto_events.h"
#include "sm_proto_vocab.h"

#define LIST_PAGE 100
#define LIST_MAX_JOBS 1000000L

static const char *str_member(const json_t *doc, const char *key)
{
    const char *s = json_string_value(json_object_get(doc, key));
    return s ? s : "";
}

static double num_member(const json_t *doc, const char *key)
{
    const json_t *v = json_object_get(doc, key);
    return json_is_number(v) ? json_number_value(v) : NAN;
}

/* The job's name as sent by the daemon, "" when it is none a terminal
 * should print as it is (sm_job_name_check). */
static const char *printable_name(const json_t *doc)
{
    const json_t *v = json_object_get(doc, "name");
    char why[96];
    if (!json_is_string(v) ||
        sm_job_name_check(json_string_value(v), json_string_length(v), why, sizeof why) != 0)
        return "";
    return json_string_value(v);
}

/* The readable form of one statusInfo. */
static void print_status(const json_t *doc)
{
    const char *status = str_member(doc, "status");
    printf("job       %s\n", str_member(doc, "jobID"));
    if (str_member(doc, "name")[0])
        printf("name      %s\n", printable_name(doc));
    const json_t *progress = json_object_get(doc, "progress");
    if (json_is_integer(progress) && strcmp(status, "accepted") != 0)
        printf("status    %s (%lld%%)\n", status, (long long)json_integer_value(progress));
    else
        printf("status    %s\n", status);
    static const char *const fields[] = {"message", "created", "started", "finished", "updated"};
    for (size_t i = 0; i < sizeof fields / sizeof fields[0]; i++) {
        const char *v = str_member(doc, fields[i]);
        if (v[0])
            printf("%-9s %s\n", fields[i], v);
    }
    const json_t *last = json_object_get(doc, "lastProgress");
    if (json_is_object(last)) {
        /* the figures by the progress event's names, as watch shows them */
        const json_t *it = json_object_get(last, "iteration");
        const json_t *d = json_object_get(last, "distance");
        const json_t *rt = json_object_get(d, "result_to_target"),
                     *tr = json_object_get(d, "target_to_result");
        char figures[160];
        if (json_is_object(rt) && json_is_object(tr))
            snprintf(figures, sizeof figures,
                     "result->target rms %.3e  max %.3e  target->result rms %.3e  max %.3e  "
                     "p99 %.3e",
                     num_member(rt, "rms"), num_member(rt, "max"), num_member(tr, "rms"),
                     num_member(tr, "max"), num_member(tr, "p99"));
        else
            snprintf(figures, sizeof figures, "rms %.3e  max %.3e",
                     num_member(last, "boundary_rms"), num_member(last, "boundary_max"));
        printf("last      iter %lld  %s  L2 %.3e  J %.6e  step %.3e  qmin %.3f\n",
               json_is_integer(it) ? (long long)json_integer_value(it) : -1LL, figures,
               num_member(last, "boundary_l2"), num_member(last, "J"), num_member(last, "step"),
               num_member(last, "min_quality"));
    }
}

/* A finished job's result figures (its summary, GET .../results), by
 * their summary names as `run` and `watch` print them; nothing when the
 * summary cannot be had. */
static void print_result(http_client *c, const char *id)
{
    char path[128];
    snprintf(path, sizeof path, "/v1/jobs/%s/results", id);
    http_request rq = {.path = path, .accept = "application/json", .gzip = 1};
    http_response rs;
    http_outcome out = http_perform(c, &rq, &rs);
    json_t *doc = out == HTTP_DONE && rs.status == 200 ? remote_json_object(&rs) : NULL;
    http_response_free(&rs);
    sm_result r;
    sm_error err;
    if (doc && sm_result_from_jansson(doc, "summary", &r, &err) == SM_OK) {
        char line[512];
        remote_format_result(line, sizeof line, &r);
        printf("result    %s\n", line);
    }
    json_decref(doc);
}

/* ----------------------------------------------------------- commands */

enum { S_JSON, S_STATUS, S_LIMIT };

typedef struct status_args {
    const char *cmd;
    const char *id;
    int json;
    const char *status_filter;
    long limit;
    int takes_id;
} status_args;

static int status_flag(void *user, int id, const char *flag, const char *value, char *msg,
                       size_t cap)
{
    status_args *a = user;
    switch (id) {
    case CLI_ARG_POSITIONAL:
        if (!a->takes_id || a->id) {
            snprintf(msg, cap, "unexpected argument '%.80s' (%s)", value,
                     a->takes_id ? "give one job id" : "list takes options only");
            return -1;
        }
        a->id = value;
        return 0;
    case S_JSON:
        a->json = 1;
        return 0;
    case S_STATUS: {
        /* checked here: the value goes into the query string */
        char buf[128];
        if (!value[0] || strlen(value) >= sizeof buf) {
            snprintf(msg, cap, "%s: expected states separated by commas", flag);
            return -1;
        }
        snprintf(buf, sizeof buf, "%s", value);
        char *save = NULL;
        for (char *tok = strtok_r(buf, ",", &save); tok; tok = strtok_r(NULL, ",", &save)) {
            sm_job_state st;
            if (sm_job_state_from_name(tok, &st) != 0) {
                snprintf(msg, cap,
                         "%s: '%.40s' is not a job state (accepted, running, successful, "
                         "failed, dismissed)",
                         flag, tok);
                return -1;
            }
        }
        if (value[0] == ',' || value[strlen(value) - 1] == ',' || strstr(value, ",,")) {
            snprintf(msg, cap, "%s: empty item in '%s'", flag, value);
            return -1;
        }
        a->status_filter = value;
        return 0;
    }
    case S_LIMIT:
        return args_parse_int(flag, value, 1, LIST_MAX_JOBS, &a->limit, msg, cap);
    }
    return -1;
}

static int parse_common(int argc, char **argv, status_args *a, int list, remote_options *conn,
                        void (*help)(void), int *done)
{
    static const cli_flag one_flags[] = {{"--json", 0, S_JSON}};
    static const cli_flag list_flags[] = {
        {"--json", 0, S_JSON},
        {"--status", 1, S_STATUS},
        {"--limit", 1, S_LIMIT},
    };
    char msg[ARGS_MSG_LEN];
    *done = 1;
    switch (remote_parse(argc, argv, list ? list_flags : one_flags,
                         list ? sizeof list_flags / sizeof list_flags[0] : 1, 0, conn, status_flag,
                         a, msg, sizeof msg)) {
    case ARGS_HELP:
        help();
        return CLI_EXIT_OK;
    case ARGS_ERROR:
        return remote_usage_error(a->cmd, msg);
    case ARGS_OK:
        break;
    }
    if (a->takes_id) {
        if (!a->id)
            return remote_usage_error(a->cmd, "missing the job id");
        if (remote_check_id(a->id, msg, sizeof msg) != 0)
            return remote_usage_error(a->cmd, msg);
    }
    *done = 0;
    return 0;
}

static void help_tail(void)
{
    printf("\n");
    remote_help_connection(stdout);
    printf("\n");
    remote_help_exit_codes(stdout);
}

void cmd_status_help(void)
{
    printf("Usage: shapematch status [--json] ID\n"
           "\n"
           "Shows the state of the job ID on the daemon: status (accepted, running,\n"
           "successful, failed, dismissed), message, times, progress and the figures of\n"
           "its latest iteration.\n"
           "\n"
           "Options:\n"
           "  --json                  the daemon's status document (OGC statusInfo) as is\n"
           "  -h, --help              this help\n");
    help_tail();
}

void cmd_list_help(void)
{
    printf("Usage: shapematch list [--status STATES] [--limit N] [--json]\n"
           "\n"
           "Lists the daemon's jobs, oldest first, one line each.\n"
           "\n"
           "Options:\n"
           "  --status STATES         only jobs in these states, comma-separated (accepted,\n"
           "                          running, successful, failed, dismissed)\n"
           "  --limit N               at most N jobs (default: all)\n"
           "  --json                  {\"jobs\": [statusInfo...], \"numberMatched\": N}\n"
           "  -h, --help              this help\n");
    help_tail();
}

void cmd_cancel_help(void)
{
    printf("Usage: shapematch cancel [--json] ID\n"
           "\n"
           "Cancels the job ID when it is queued or running (it becomes dismissed; a\n"
           "running worker is stopped), or deletes it with its files when it has ended.\n"
           "\n"
           "Options:\n"
           "  --json                  the daemon's answer (the job's status document)\n"
           "  -h, --help              this help\n");
    help_tail();
}

/* GET or DELETE /v1/jobs/{id}, shown. */
static int one_job(int argc, char **argv, const char *cmd, const char *method, void (*help)(void))
{
    status_args a = {.cmd = cmd, .takes_id = 1};
    remote_options conn;
    int done;
    int code = parse_common(argc, argv, &a, 0, &conn, help, &done);
    if (done)
        return code;
    http_client c;
    if ((code = remote_open(cmd, &conn, &c)) != 0)
        return code;
    char path[128];
    snprintf(path, sizeof path, "/v1/jobs/%s", a.id);
    int cancel = strcmp(method, "DELETE") == 0;
    http_request rq = {.method = method, .path = path, .accept = "application/json", .gzip = 1};
    http_response rs;
    http_outcome out = http_perform(&c, &rq, &rs);
    if (out != HTTP_DONE || rs.status != 200) {
        code = remote_report(cmd, &c, conn.token != NULL, out, &rs,
                             cancel ? "cancelling the job" : "asking for the job's status");
    } else if (a.json) {
        remote_print_body(&rs);
    } else {
        json_t *doc = remote_json_object(&rs);
        if (!doc) {
            fprintf(stderr, "shapematch %s: error: bad response from %s: not a JSON object\n",
                    cmd, c.base);
            code = CLI_EXIT_SERVER;
        } else if (!cancel) {
            print_status(doc);
            if (strcmp(str_member(doc, "status"), "successful") == 0)
                print_result(&c, a.id);
        } else if (strcmp(str_member(doc, "message"), "deleted") == 0) {
            printf("job %s deleted with its files (it was %s)\n", a.id, str_member(doc, "status"));
        } else {
            printf("job %s cancelled: %s (%s)\n", a.id, str_member(doc, "status"),
                   str_member(doc, "message"));
        }
        json_decref(doc);
    }
    http_response_free(&rs);
    remote_close(&c);
    return code;
}

int cmd_status(int argc, char **argv)
{
    return one_job(argc, argv, "status", "GET", cmd_status_help);
}

int cmd_cancel(int argc, char **argv)
{
    return one_job(argc, argv, "cancel", "DELETE", cmd_cancel_help);
}

static void print_list_row(const json_t *job)
{
    const json_t *progress = json_object_get(job, "progress");
    char pct[16] = "-";
    if (json_is_integer(progress))
        snprintf(pct, sizeof pct, "%lld%%", (long long)json_integer_value(progress));
    printf("%-32s  %-10s  %4s  %-24s  %-16s  %s\n", str_member(job, "jobID"),
           str_member(job, "status"), pct, str_member(job, "created"), printable_name(job),
           str_member(job, "message"));
}

int cmd_list(int argc, char **argv)
{
    status_args a = {.cmd = "list", .limit = LIST_MAX_JOBS};
    remote_options conn;
    int done;
    int code = parse_common(argc, argv, &a, 1, &conn, cmd_list_help, &done);
    if (done)
        return code;
    http_client c;
    if ((code = remote_open("list", &conn, &c)) != 0)
        return code;
    json_t *all = json_array();
    long long matched = -1;
    long offset = 0;
    while (all && (long)json_array_size(all) < a.limit) {
        long want = a.limit - (long)json_array_size(all);
        char path[256];
        snprintf(path, sizeof path, "/v1/jobs?limit=%ld&offset=%ld%s%s",
                 want < LIST_PAGE ? want : LIST_PAGE, offset,
                 a.status_filter ? "&status=" : "", a.status_filter ? a.status_filter : "");
        http_request rq = {.path = path, .accept = "application/json", .gzip = 1};
        http_response rs;
        http_outcome out = http_perform(&c, &rq, &rs);
        if (out != HTTP_DONE || rs.status != 200) {
            code = remote_report("list", &c, conn.token != NULL, out, &rs, "listing the jobs");
            http_response_free(&rs);
            break;
        }
        json_t *doc = remote_json_object(&rs);
        http_response_free(&rs);
        json_t *jobs = doc ? json_object_get(doc, "jobs") : NULL;
        if (!json_is_array(jobs)) {
            fprintf(stderr, "shapematch list: error: bad response from %s: no \"jobs\" array\n",
                    c.base);
            json_decref(doc);
            code = CLI_EXIT_SERVER;
            break;
        }
        const json_t *nm = json_object_get(doc, "numberMatched");
        if (json_is_integer(nm))
            matched = json_integer_value(nm);
        size_t n = json_array_size(jobs);
        for (size_t i = 0; i < n && (long)json_array_size(all) < a.limit; i++)
            json_array_append(all, json_array_get(jobs, i));
        json_decref(doc);
        offset += (long)n;
        /* the end: an empty or short page, or all matched jobs seen */
        if (n == 0 || n < (size_t)(want < LIST_PAGE ? want : LIST_PAGE) ||
            (matched >= 0 && offset >= matched))
            break;
    }
    if (code == 0 && !all) {
        fprintf(stderr, "shapematch list: error: out of memory\n");
        code = CLI_EXIT_SERVER;
    }
    if (code == 0) {
        if (a.json) {
            json_t *doc = json_pack("{s:O,s:I}", "jobs", all, "numberMatched",
                                    (json_int_t)(matched >= 0 ? matched
                                                              : (long long)json_array_size(all)));
            char *text = doc ? sm_json_dumps(doc, 2) : NULL;
            if (text)
                printf("%s\n", text);
            free(text);
            json_decref(doc);
        } else if (json_array_size(all) == 0) {
            printf("no jobs%s%s\n", a.status_filter ? " with status " : "",
                   a.status_filter ? a.status_filter : "");
        } else {
            printf("%-32s  %-10s  %4s  %-24s  %-16s  %s\n", "JOB", "STATUS", "DONE", "CREATED",
                   "NAME", "MESSAGE");
            for (size_t i = 0; i < json_array_size(all); i++)
                print_list_row(json_array_get(all, i));
            if (matched > (long long)json_array_size(all))
                printf("(%zu of %lld jobs shown)\n", json_array_size(all), matched);
        }
        fflush(stdout);
    }
    json_decref(all);
    remote_close(&c);
    return code;
}
