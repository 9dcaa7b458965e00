/* The two daemon operations that several commands chain (daemon_ops.h):
 * following a job's events (`watch`, `submit --wait`) and downloading its
 * results (`fetch`, `submit --wait -o`).  The commands' own files parse
 * their options and call these.
 *
 * ---- watch: follows a job's events on the daemon
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
 * "started" event (attempt 2, ...) and its progress from the start.
 *
 * ---- fetch: downloads the results of
 * a successful job into OUTDIR, the same set of files `shapematch run`
 * writes:
 *   result.mesh / result.meshb / result.vtu / result.smmesh
 *                      GET /v1/jobs/{id}/results/mesh?format=...
 *   displacement.sol   GET .../results/displacement?format=sol
 *   history.csv        GET .../results/history?format=csv
 *   template.mesh      GET .../results/template (a template meshed from a
 *                      template_surface or template_image only)
 *   summary.json       GET .../results (the summary document)
 * Transfers ask for compression (libcurl decodes it).  Every file is
 * written under a temporary name and renamed into place; summary.json
 * comes last (an older one is removed first), so its presence means the
 * set is complete and from one job. */
#include "daemon_ops.h"

#include <errno.h>
#include <limits.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "cli.h"
#include "fsutil.h"
#include "progress.h"
#include "shapematch/sm_atomic.h"
#include "shapematch/sm_clock.h"
#include "shapematch/sm_path.h"
#include "sm_json.h"
#include "sm_proto_events.h"
#include "sm_proto_vocab.h"
#include "sse.h"

/* ================================================================ watch */

#define BACKOFF_FIRST 0.25
#define BACKOFF_MAX 5.0

typedef struct watch_ctx {
    const char *id;
    char label[SM_JOB_ID_MAX + SM_JOB_NAME_MAX + 8]; /* "ID (name)", or "ID" */
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
    int not_converged;             /* the final status or finished said
                                    * "converged": false */
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
            progress_message(&w->display, "shapematch: job %s queued", w->label);
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
                             w->label, ev->attempt);
        else
            progress_message(&w->display, "shapematch: job %s started", w->label);
        break;
    case SM_EVENT_PROGRESS:
        progress_update(&w->display, &ev->progress);
        break;
    case SM_EVENT_FINISHED:
        w->have_result = 1;
        w->result = ev->result;
        w->not_converged |= !ev->result.converged;
        break;
    case SM_EVENT_FAILED:
    case SM_EVENT_CANCELLED:
        snprintf(w->end_message, sizeof w->end_message, "%s", ev->message);
        break;
    case SM_EVENT_ALIGNMENT: /* run's line */
        progress_message(&w->display,
                         "shapematch: aligned (%s): scale %.6g, boundary RMS %.3e -> %.3e, %d "
                         "iterations, %.2f s",
                         ev->alignment.mode, ev->alignment.scale, ev->alignment.rms_before,
                         ev->alignment.rms_after, ev->alignment.iterations, ev->alignment.seconds);
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
            /* what the status says wins: the finished event may have been
             * seen before a reconnection, or not at all */
            if (ev->converged >= 0)
                w->not_converged = ev->state == SM_JOB_SUCCESSFUL && !ev->converged;
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
            if (!w->not_converged)
                fprintf(stderr, "shapematch: job %s successful%s%s\n", w->label,
                        line[0] ? ": " : "", line);
        }
        if (w->not_converged) {
            /* as `run`: said even with --quiet, and its own exit code; the
             * warnings of the message were printed as they came */
            const char *cut = strstr(w->final_message, "; warning: ");
            int len = cut ? (int)(cut - w->final_message) : (int)strlen(w->final_message);
            fprintf(stderr, "shapematch %s: job %s successful but NOT CONVERGED: %.*s\n", cmd,
                    w->label, len ? len : 15, len ? w->final_message : "see its summary");
            return CLI_EXIT_NOT_CONVERGED;
        }
        return CLI_EXIT_OK;
    case SM_JOB_FAILED:
        fprintf(stderr, "shapematch %s: job %s failed: %s\n", cmd, w->label,
                why[0] ? why : "no reason given");
        return CLI_EXIT_JOB_FAILED;
    default:
        fprintf(stderr, "shapematch %s: job %s was cancelled (dismissed)%s%s\n", cmd, w->label,
                why[0] ? ": " : "", why);
        return CLI_EXIT_CANCELLED;
    }
}

/* The job's name and the bar's goals, as `run` has them: GET /v1/jobs/ID
 * gives its name, maxIter and tolBoundary.  Best effort: without them (an
 * older daemon, a failed request, which the events request then reports)
 * the lines name the id alone and the bar shows the rate only. */
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
    json_t *name = json_object_get(doc, "name");
    char why[96];
    if (json_is_string(name) && sm_job_name_check(json_string_value(name), json_string_length(name),
                                                  why, sizeof why) == 0)
        snprintf(w->label, sizeof w->label, "%s (%s)", w->id, json_string_value(name));
    json_decref(doc);
    progress_set_goal(&w->display, w->goal_max_iter, w->goal_tol);
}

int remote_watch(http_client *c, const char *cmd, int token_given, const char *id,
                 const watch_options *o)
{
    watch_ctx w;
    memset(&w, 0, sizeof w);
    w.id = id;
    snprintf(w.label, sizeof w.label, "%s", id);
    w.opt = o;
    progress_init(&w.display, stderr, o->quiet);
    if (!o->json && !o->quiet)
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

/* ================================================================ fetch */

/* --format bits of proto's mesh formats (sm_proto_vocab.h: file names and
 * media types) */
typedef struct mesh_format {
    unsigned bit;
    const char *name;      /* ?format= and --format value */
} mesh_format;

static const mesh_format mesh_formats[] = {
    {FETCH_MESH, "mesh"},
    {FETCH_MESHB, "meshb"},
    {FETCH_VTU, "vtu"},
    {FETCH_BINARY, "binary"},
    {FETCH_SOL, "sol"},
    {FETCH_SOLB, "solb"},
};
#define N_MESH_ONLY 4 /* the first ones are mesh formats, then displacement */
#define N_MESH_FORMATS (sizeof mesh_formats / sizeof mesh_formats[0])

int fetch_parse_formats(const char *flag, const char *text, unsigned *out, char *msg,
                        size_t cap)
{
    unsigned set = 0;
    const char *p = text;
    for (;;) {
        const char *comma = strchr(p, ',');
        size_t len = comma ? (size_t)(comma - p) : strlen(p);
        size_t k;
        for (k = 0; k < N_MESH_FORMATS; k++)
            if (strlen(mesh_formats[k].name) == len && strncmp(mesh_formats[k].name, p, len) == 0)
                break;
        if (k == N_MESH_FORMATS) {
            snprintf(msg, cap, "%s: '%.*s' is not a result format (expected a comma-separated "
                               "list of mesh, meshb, vtu, binary, sol, solb)",
                     flag, (int)(len > 40 ? 40 : len), p);
            return -1;
        }
        set |= mesh_formats[k].bit;
        if (!comma)
            break;
        p = comma + 1;
    }
    *out = set;
    return 0;
}

/* ---------------------------------------------------------- downloads */

typedef struct file_sink {
    FILE *f;
    int err;
} file_sink;

static int write_to_file(void *user, const char *data, size_t len)
{
    file_sink *s = user;
    if (fwrite(data, 1, len, s->f) != len) {
        s->err = errno ? errno : EIO;
        return -1;
    }
    return 0;
}

/* GET /v1/jobs/ID/results/KIND?format=F into outdir/FILE (atomically),
 * checking the media type. */
static int download(http_client *c, const char *cmd, int token_given, const char *outdir,
                    const char *id, const sm_result_format *f)
{
    char path[192];
    snprintf(path, sizeof path, "/v1/jobs/%s/results/%s?format=%s", id,
             sm_result_kind_name(f->kind), f->name);
    return remote_download(c, cmd, token_given, path, outdir, f->file, f->media);
}

int remote_download(http_client *c, const char *cmd, int token_given, const char *path,
                    const char *outdir, const char *name, const char *media)
{
    char what[160];
    snprintf(what, sizeof what, "downloading %s", name);
    char *final = sm_path_join(outdir, name);
    if (!final) {
        fprintf(stderr, "shapematch %s: error: out of memory\n", cmd);
        return CLI_EXIT_OUTPUT;
    }
    sm_atomic a;
    sm_error err;
    if (sm_atomic_open(&a, final, &err) != SM_OK) {
        fprintf(stderr, "shapematch %s: error: %s\n", cmd, err.msg);
        free(final);
        return CLI_EXIT_OUTPUT;
    }
    file_sink sink = {.f = a.f};
    http_request rq = {.path = path, .gzip = 1, .sink = write_to_file, .sink_user = &sink};
    http_response rs;
    http_outcome out = http_perform(c, &rq, &rs);
    int code = 0;
    if (out == HTTP_LOCAL_ERROR && sink.err) {
        fprintf(stderr, "shapematch %s: error: cannot write '%s': %s\n", cmd, final,
                strerror(sink.err));
        code = CLI_EXIT_OUTPUT;
    } else if (out != HTTP_DONE || rs.status != 200) {
        code = remote_report(cmd, c, token_given, out, &rs, what);
    } else if (!http_content_type_is(&rs, media)) {
        fprintf(stderr, "shapematch %s: error: bad response from %s while %s: content type '%s', "
                        "expected %s\n",
                cmd, c->base, what, rs.content_type, media);
        code = CLI_EXIT_SERVER;
    }
    http_response_free(&rs);
    if (code != 0) {
        sm_atomic_abort(&a);
    } else if (sm_atomic_commit(&a, SM_ATOMIC_FSYNC, &err) != SM_OK) {
        fprintf(stderr, "shapematch %s: error: %s\n", cmd, err.msg);
        code = CLI_EXIT_OUTPUT;
    }
    free(final);
    return code;
}

/* The job's state decides whether there is anything to fetch. */
static int check_job_state(http_client *c, const char *cmd, int token_given, const char *id)
{
    char path[128];
    snprintf(path, sizeof path, "/v1/jobs/%s", id);
    http_request rq = {.path = path, .accept = "application/json", .gzip = 1};
    http_response rs;
    http_outcome out = http_perform(c, &rq, &rs);
    if (out != HTTP_DONE || rs.status != 200) {
        int code = remote_report(cmd, c, token_given, out, &rs, "asking for the job's status");
        http_response_free(&rs);
        return code;
    }
    json_t *doc = remote_json_object(&rs);
    http_response_free(&rs);
    const char *status = doc ? json_string_value(json_object_get(doc, "status")) : NULL;
    const char *message = doc ? json_string_value(json_object_get(doc, "message")) : NULL;
    sm_job_state state;
    int code = 0;
    if (!status || sm_job_state_from_name(status, &state) != 0) {
        fprintf(stderr, "shapematch %s: error: bad response from %s: the job's status document "
                        "has no valid \"status\"\n",
                cmd, c->base);
        code = CLI_EXIT_SERVER;
    } else if (state == SM_JOB_FAILED) {
        fprintf(stderr, "shapematch %s: job %s failed%s%s: it has no results\n", cmd, id,
                message && message[0] ? ": " : "", message ? message : "");
        code = CLI_EXIT_JOB_FAILED;
    } else if (state == SM_JOB_DISMISSED) {
        fprintf(stderr, "shapematch %s: job %s was cancelled (dismissed): it has no results\n",
                cmd, id);
        code = CLI_EXIT_CANCELLED;
    } else if (state != SM_JOB_SUCCESSFUL) {
        fprintf(stderr,
                "shapematch %s: error: job %s is %s: no results yet ('shapematch watch %s' "
                "waits for its end)\n",
                cmd, id, state == SM_JOB_ACCEPTED ? "queued" : "running", id);
        code = CLI_EXIT_REFUSED;
    }
    json_decref(doc);
    return code;
}

/* GET .../results: the summary document, checked. */
static int get_summary(http_client *c, const char *cmd, int token_given, const char *id,
                       json_t **doc_out, sm_result *result)
{
    char path[128];
    snprintf(path, sizeof path, "/v1/jobs/%s/results", id);
    http_request rq = {.path = path, .accept = "application/json", .gzip = 1};
    http_response rs;
    http_outcome out = http_perform(c, &rq, &rs);
    if (out != HTTP_DONE || rs.status != 200) {
        int code = remote_report(cmd, c, token_given, out, &rs, "downloading the result summary");
        http_response_free(&rs);
        return code;
    }
    json_t *doc = remote_json_object(&rs);
    http_response_free(&rs);
    sm_error err;
    sm_error_clear(&err);
    if (!doc || sm_result_from_jansson(doc, "results", result, &err) != SM_OK) {
        fprintf(stderr, "shapematch %s: error: bad response from %s: the result summary %s\n",
                cmd, c->base, doc ? err.msg : "is not a JSON object");
        json_decref(doc);
        return CLI_EXIT_SERVER;
    }
    *doc_out = doc;
    return 0;
}

static int write_summary(const char *cmd, const char *outdir, const json_t *doc)
{
    return remote_write_json(cmd, outdir, SM_RESULT_SUMMARY_FILE, doc);
}

int remote_write_json(const char *cmd, const char *outdir, const char *name, const json_t *doc)
{
    char *text = sm_json_dumps(doc, 2);
    char *path = sm_path_join(outdir, name);
    int code = 0;
    sm_error err;
    if (!text || !path) {
        fprintf(stderr, "shapematch %s: error: out of memory\n", cmd);
        code = CLI_EXIT_OUTPUT;
    } else {
        size_t n = strlen(text);
        text[n] = '\n'; /* replaces the NUL: written with its length */
        if (sm_atomic_write_file(path, text, n + 1, SM_ATOMIC_FSYNC, &err) != SM_OK) {
            fprintf(stderr, "shapematch %s: error: %s\n", cmd, err.msg);
            code = CLI_EXIT_OUTPUT;
        }
    }
    free(text);
    free(path);
    return code;
}

int remote_fetch(http_client *c, const char *cmd, int token_given, const char *id,
                 const fetch_options *o)
{
    char msg[ARGS_MSG_LEN];
    int code = check_job_state(c, cmd, token_given, id);
    if (code != 0)
        return code;
    if (fs_output_dir(o->outdir, msg, sizeof msg) != 0) {
        fprintf(stderr, "shapematch %s: error: output directory: %s\n", cmd, msg);
        return CLI_EXIT_OUTPUT;
    }
    /* an older summary.json must not vouch for files only partly replaced */
    char *old_summary = sm_path_join(o->outdir, SM_RESULT_SUMMARY_FILE);
    if (!old_summary) {
        fprintf(stderr, "shapematch %s: error: out of memory\n", cmd);
        return CLI_EXIT_OUTPUT;
    }
    if (unlink(old_summary) != 0 && errno != ENOENT) {
        fprintf(stderr, "shapematch %s: error: cannot remove the previous '%s': %s\n", cmd,
                old_summary, strerror(errno));
        free(old_summary);
        return CLI_EXIT_OUTPUT;
    }
    free(old_summary);

    json_t *summary = NULL;
    sm_result result;
    memset(&result, 0, sizeof result);
    code = get_summary(c, cmd, token_given, id, &summary, &result);
    if (code != 0)
        return code;
    char files[256] = "";
    unsigned formats = o->formats;
    if (!(formats & (FETCH_SOL | FETCH_SOLB)))
        formats |= FETCH_SOL; /* the displacement always comes */
    for (size_t k = 0; k < N_MESH_FORMATS && code == 0; k++) {
        if (!(formats & mesh_formats[k].bit))
            continue;
        const sm_result_format *f = sm_result_format_find(
            k < N_MESH_ONLY ? SM_RESULT_MESH : SM_RESULT_DISPLACEMENT, mesh_formats[k].name);
        code = download(c, cmd, token_given, o->outdir, id, f);
        strncat(files, f->file, sizeof files - strlen(files) - 1);
        strncat(files, ", ", sizeof files - strlen(files) - 1);
    }
    const sm_result_format *history = sm_result_format_find(SM_RESULT_HISTORY, "csv");
    if (code == 0)
        code = download(c, cmd, token_given, o->outdir, id, history);
    /* a template the daemon meshed (template_surface, template_image): its mesh too, so
     * that the set repeats the job as `run` writes it */
    if (code == 0 && json_object_get(json_object_get(summary, "template"), "meshed")) {
        char path[128];
        snprintf(path, sizeof path, "/v1/jobs/%s/results/template", id);
        code = remote_download(c, cmd, token_given, path, o->outdir, SM_RESULT_TEMPLATE_FILE,
                               "application/x-medit-mesh");
        strncat(files, SM_RESULT_TEMPLATE_FILE ", ", sizeof files - strlen(files) - 1);
    }
    if (code == 0)
        code = write_summary(cmd, o->outdir, summary);
    json_decref(summary);
    if (code == 0 && !o->quiet) {
        if (o->show_result) {
            char line[512];
            remote_format_result(line, sizeof line, &result);
            fprintf(stderr, "shapematch: job %s: %s\n", id, line);
        }
        fprintf(stderr, "shapematch: results in %s: %s%s, %s\n", o->outdir, files,
                history->file, SM_RESULT_SUMMARY_FILE);
    }
    return code;
}
