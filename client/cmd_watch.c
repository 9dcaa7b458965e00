/* `shapematch watch ID`: follows a job's events on the daemon
 * (GET /v1/jobs/{id}/events as Server-Sent Events) to the job's end.
 *
 * The stream is parsed as it arrives (sse.c, fed from libcurl's write
 * callback); progress events drive the same display as `run` (a bar on a
 * terminal, a plain line every few iterations otherwise), lifecycle
 * events print a line each, warning events print "shapematch: warning:
 * CODE: MESSAGE" (even with --quiet); with --json every event goes to stdout as
 * one JSON line.  The daemon ends a stream with a "status" event carrying
 * the job's final state, which decides the exit code.
 *
 * A stream that ends without that event (the daemon restarted, a proxy
 * cut the connection, the network failed) is resumed: reconnect with
 * Last-Event-ID = the last event id received, with a growing delay
 * between attempts, for up to --reconnect-timeout seconds without news.
 * Events at or below the last id are never shown twice, whatever the
 * server replays.  A job re-run by a restarted daemon shows its new
 * "started" event (attempt 2, ...) and its progress from the start. */
#include <errno.h>
#include <limits.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "shapematch/sm_clock.h"
#include "cli.h"
#include "progress.h"
#include "remote.h"
#include "sm_proto_events.h"
#include "sse.h"

#define BACKOFF_FIRST 0.25
#define BACKOFF_MAX 5.0

typedef struct watch_ctx {
    const char *id;
    const watch_options *opt;
    progress_display display;
    sse_parser sse;
    int64_t last_seq;              /* highest event id delivered, 0 none */
    unsigned long new_events;      /* events delivered on this connection */
    int outage;                    /* reconnecting: announce the recovery */
    int done;                      /* the final status event arrived */
    sm_job_state final_state;
    char final_message[SM_EVENT_MESSAGE_MAX];
    char end_message[SM_EVENT_MESSAGE_MAX]; /* of the failed/cancelled event */
    int have_result;
    sm_result result;
    int goal_max_iter;             /* the job's max_iter, 0 unknown */
    double goal_tol;               /* the job's tol_boundary, 0 none */
    int warned_unknown;
    int protocol_error;
    char error[256];
} watch_ctx;

static void sleep_seconds(double s)
{
    if (!(s > 0))
        return;
    struct timespec ts = {.tv_sec = (time_t)s, .tv_nsec = (long)((s - (double)(time_t)s) * 1e9)};
    while (nanosleep(&ts, &ts) != 0 && errno == EINTR)
        ;
}

/* An SSE id of ours: a decimal sequence number >= 1. */
static int parse_seq(const char *text, int64_t *out)
{
    if (!text[0] || strlen(text) > 18)
        return -1;
    int64_t v = 0;
    for (const char *p = text; *p; p++) {
        if (*p < '0' || *p > '9')
            return -1;
        v = v * 10 + (*p - '0');
    }
    if (v < 1)
        return -1;
    *out = v;
    return 0;
}

static int quiet(const watch_ctx *w)
{
    return w->opt->quiet;
}

static void handle_event(watch_ctx *w, const sm_event *ev)
{
    switch (ev->type) {
    case SM_EVENT_ACCEPTED:
        if (!quiet(w))
            progress_message(&w->display, "shapematch: job %s queued", w->id);
        break;
    case SM_EVENT_STARTED:
        /* a new run starts its iterations from 0: a fresh display */
        progress_finish(&w->display);
        progress_init(&w->display, stderr, w->opt->quiet);
        progress_set_goal(&w->display, w->goal_max_iter, w->goal_tol);
        if (quiet(w))
            break;
        if (ev->attempt > 1)
            progress_message(&w->display,
                             "shapematch: job %s started again (attempt %d, the daemon re-runs "
                             "an interrupted job from the start)",
                             w->id, ev->attempt);
        else
            progress_message(&w->display, "shapematch: job %s started", w->id);
        break;
    case SM_EVENT_PROGRESS:
        progress_update(&w->display, &ev->progress);
        break;
    case SM_EVENT_FINISHED:
        w->have_result = 1;
        w->result = ev->result;
        break;
    case SM_EVENT_FAILED:
    case SM_EVENT_CANCELLED:
        snprintf(w->end_message, sizeof w->end_message, "%s", ev->message);
        break;
    case SM_EVENT_WARNING:
        /* even with --quiet, as run prints them: they are about the result */
        progress_message(&w->display, "shapematch: warning: %s: %s", ev->code, ev->message);
        break;
    case SM_EVENT_STATUS:
        if (ev->state == SM_JOB_SUCCESSFUL || ev->state == SM_JOB_FAILED ||
            ev->state == SM_JOB_DISMISSED) {
            w->done = 1;
            w->final_state = ev->state;
            snprintf(w->final_message, sizeof w->final_message, "%s", ev->message);
        }
        break;
    }
}

static int on_sse_event(void *user, const sse_event *e)
{
    watch_ctx *w = user;
    int64_t seq = 0;
    if (e->has_id) {
        if (parse_seq(e->id, &seq) != 0) {
            w->protocol_error = 1;
            snprintf(w->error, sizeof w->error, "event id '%.40s' is not a sequence number",
                     e->id);
            return -1;
        }
        if (seq <= w->last_seq)
            return 0; /* shown already: replayed after a reconnection */
        w->last_seq = seq;
    }
    w->new_events++;
    if (w->opt->json) {
        /* one event, one line: the data of several "data:" lines is
         * joined with newlines, which in JSON can only be whitespace
         * between tokens (a string cannot hold a raw newline) */
        for (size_t i = 0; i < e->data_len; i++)
            fputc(e->data[i] == '\n' || e->data[i] == '\r' ? ' ' : e->data[i], stdout);
        fputc('\n', stdout);
        fflush(stdout);
    }
    sm_event ev;
    sm_error err;
    sm_error_clear(&err);
    if (sm_event_from_json(e->data, e->data_len, &ev, &err) != SM_OK) {
        /* an event this client does not know (a newer daemon): --json
         * passed it on, the display skips it */
        if (!w->warned_unknown && !quiet(w))
            progress_message(&w->display, "shapematch: warning: skipped an event: %s", err.msg);
        w->warned_unknown = 1;
        return 0;
    }
    handle_event(w, &ev);
    /* the daemon closes the stream after the final status; no need to
     * wait for it */
    return w->done ? 1 : 0;
}

static int on_stream_data(void *user, const char *data, size_t len)
{
    watch_ctx *w = user;
    if (w->outage && !quiet(w)) {
        progress_message(&w->display, "shapematch: reconnected to the daemon; resuming after "
                                      "event %lld",
                         (long long)w->last_seq);
    }
    w->outage = 0;
    if (sse_feed(&w->sse, data, len) == 0)
        return 0;
    if (w->sse.stopped && w->done)
        return 1;
    if (!w->protocol_error) {
        w->protocol_error = 1;
        snprintf(w->error, sizeof w->error, "%s", w->sse.error[0] ? w->sse.error : "bad event");
    }
    return -1;
}

static int finish(watch_ctx *w, const char *cmd)
{
    progress_finish(&w->display);
    const char *why = w->end_message[0] ? w->end_message : w->final_message;
    switch (w->final_state) {
    case SM_JOB_SUCCESSFUL:
        if (!quiet(w)) {
            char line[512];
            if (w->have_result)
                remote_format_result(line, sizeof line, &w->result);
            else
                snprintf(line, sizeof line, "%s", w->final_message);
            fprintf(stderr, "shapematch: job %s successful%s%s\n", w->id, line[0] ? ": " : "",
                    line);
        }
        return CLI_EXIT_OK;
    case SM_JOB_FAILED:
        fprintf(stderr, "shapematch %s: job %s failed: %s\n", cmd, w->id,
                why[0] ? why : "no reason given");
        return CLI_EXIT_JOB_FAILED;
    default:
        fprintf(stderr, "shapematch %s: job %s was cancelled (dismissed)%s%s\n", cmd, w->id,
                why[0] ? ": " : "", why);
        return CLI_EXIT_CANCELLED;
    }
}

/* The bar's goals, as `run` has them: GET /v1/jobs/ID gives the job's
 * maxIter and tolBoundary.  Best effort: without them (an older daemon, a
 * failed request, which the events request then reports) the bar shows
 * the rate only. */
static void get_goal(http_client *c, watch_ctx *w)
{
    char path[128];
    snprintf(path, sizeof path, "/v1/jobs/%s", w->id);
    http_request rq = {.path = path, .accept = "application/json", .gzip = 1};
    http_response rs;
    http_outcome out = http_perform(c, &rq, &rs);
    json_t *doc = out == HTTP_DONE && rs.status == 200 ? remote_json_object(&rs) : NULL;
    http_response_free(&rs);
    json_t *max_iter = json_object_get(doc, "maxIter"), *tol = json_object_get(doc, "tolBoundary");
    if (json_is_integer(max_iter) && json_integer_value(max_iter) > 0 &&
        json_integer_value(max_iter) <= INT_MAX)
        w->goal_max_iter = (int)json_integer_value(max_iter);
    if (json_is_number(tol) && json_number_value(tol) > 0)
        w->goal_tol = json_number_value(tol);
    json_decref(doc);
    progress_set_goal(&w->display, w->goal_max_iter, w->goal_tol);
}

int remote_watch(http_client *c, const char *cmd, int token_given, const char *id,
                 const watch_options *o)
{
    watch_ctx w;
    memset(&w, 0, sizeof w);
    w.id = id;
    w.opt = o;
    progress_init(&w.display, stderr, o->quiet);
    if (w.display.mode == PROGRESS_TTY && !o->json)
        get_goal(c, &w);
    sse_init(&w.sse, SM_EVENT_LINE_MAX + 64, on_sse_event, &w);

    char path[128], last_header[64];
    snprintf(path, sizeof path, "/v1/jobs/%s/events", id);
    int connected_once = 0;
    double deadline = -1.0, backoff = BACKOFF_FIRST;
    int code;
    for (;;) {
        http_request rq = {
            .path = path,
            .accept = "text/event-stream",
            .stream = 1,
            .sink = on_stream_data,
            .sink_user = &w,
        };
        if (w.last_seq > 0) {
            snprintf(last_header, sizeof last_header, "Last-Event-ID: %lld",
                     (long long)w.last_seq);
            rq.headers[0] = last_header;
        }
        if (deadline >= 0) {
            /* a reconnection attempt must not outlive the deadline */
            double left = deadline - sm_clock_seconds();
            long ms = (long)(left * 1000.0);
            rq.connect_timeout_ms = ms < 200 ? 200 : ms > HTTP_CONNECT_TIMEOUT_MS
                                                         ? HTTP_CONNECT_TIMEOUT_MS
                                                         : ms;
        }
        sse_restart(&w.sse);
        w.new_events = 0;
        unsigned long comments_before = w.sse.comments;
        http_response rs;
        http_outcome out = http_perform(c, &rq, &rs);
        if (w.done) {
            http_response_free(&rs);
            code = finish(&w, cmd);
            break;
        }
        if (w.protocol_error) {
            progress_finish(&w.display);
            fprintf(stderr, "shapematch %s: error: bad event stream from %s: %s\n", cmd, c->base,
                    w.error);
            http_response_free(&rs);
            code = CLI_EXIT_SERVER;
            break;
        }
        if (rs.status == 200)
            connected_once = 1;
        /* what may be retried: a stream that ended or broke off before
         * the final status, a daemon that is away (once it was there) or
         * briefly unavailable */
        int retry = 0;
        if (out == HTTP_DONE && rs.status == 200)
            retry = 1;
        else if (out == HTTP_DROPPED)
            retry = 1;
        else if (out == HTTP_CONNECT_FAILED && connected_once)
            retry = 1;
        else if (out == HTTP_DONE && connected_once && (rs.status == 502 || rs.status == 503 ||
                                                        rs.status == 504))
            retry = 1;
        if (!retry) {
            progress_finish(&w.display);
            code = remote_report(cmd, c, token_given, out, &rs, "following the job's events");
            http_response_free(&rs);
            break;
        }
        double now = sm_clock_seconds();
        if (w.new_events > 0 || w.sse.comments > comments_before || deadline < 0) {
            /* news since the last attempt: a fresh reconnection window */
            deadline = now + o->reconnect_timeout;
            backoff = BACKOFF_FIRST;
        }
        char why[HTTP_MSG_LEN + 32];
        if (out == HTTP_DONE && rs.status == 200)
            snprintf(why, sizeof why, "the stream ended before the job did");
        else if (out == HTTP_DONE)
            snprintf(why, sizeof why, "HTTP %ld", rs.status);
        else
            snprintf(why, sizeof why, "%s", rs.error);
        http_response_free(&rs);
        if (!w.outage && !quiet(&w))
            progress_message(&w.display,
                             "shapematch: connection to the daemon lost (%s); reconnecting for up "
                             "to %g s",
                             why, o->reconnect_timeout);
        w.outage = 1;
        if (now >= deadline) {
            progress_finish(&w.display);
            fprintf(stderr,
                    "shapematch %s: error: lost the connection to %s and could not resume the "
                    "event stream within %g s (%s); the job may still be running: 'shapematch "
                    "watch %s' resumes\n",
                    cmd, c->base, o->reconnect_timeout, why, id);
            code = CLI_EXIT_CONNECT;
            break;
        }
        double wait = backoff < deadline - now ? backoff : deadline - now;
        sleep_seconds(wait);
        backoff = backoff * 2 > BACKOFF_MAX ? BACKOFF_MAX : backoff * 2;
    }
    sse_free(&w.sse);
    return code;
}

/* ------------------------------------------------------------ command */

void cmd_watch_help(void)
{
    printf("Usage: shapematch watch [--json] [--quiet] [--reconnect-timeout S] ID\n"
           "\n"
           "Follows the job ID on the daemon to its end: its past events are replayed,\n"
           "then new ones are shown as they come (on a terminal the bar of 'run': progress\n"
           "toward the job's tol_boundary or max_iter, rate, ETA, then iteration, J,\n"
           "boundary error, step; a plain line every %d iterations otherwise).\n"
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

int watch_parse_reconnect(const char *flag, const char *value, double *out, char *msg,
                          size_t cap)
{
    double v;
    if (args_parse_real(flag, value, &v, msg, cap) != 0)
        return -1;
    if (v < 0 || v > REMOTE_RECONNECT_MAX) {
        snprintf(msg, cap, "%s: %s is out of range (0 to %g seconds)", flag, value,
                 REMOTE_RECONNECT_MAX);
        return -1;
    }
    *out = v;
    return 0;
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
