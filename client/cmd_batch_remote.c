/* `shapematch batch --server URL`: the batch run by a daemon
 * (docs/api.md "Batches"): each target submitted as an ordinary job
 * (submit_job.h, as `shapematch submit` sends one), the jobs grouped by
 * POST /v1/batches, the batch followed to its end (its event stream,
 * GET /v1/batches/{id}/events: a line whenever its progress changes),
 * then every target's results
 * fetched into DIR/targets/NAME/ (as `shapematch fetch`) and the model's
 * files into DIR/model/; DIR/batch.json is the batch's final document.
 * The targets and the run options are the local batch's; what runs
 * where is the daemon's business (its workers, on any node).
 *
 * --template-from medoid|mean|FILE: the rounds of the local batch
 * (sm_job_batch_rounds, proto/job/sm_job_template_from.c: one choice of
 * the next template for both), each round a daemon's batch as above into
 * DIR/rounds/K/ (batch.json its summary), the batch request saying which
 * round of which mode and the batch before ("template_from"), so that
 * every round stays a durable job on the daemon and says where its
 * template came from. */
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "cli.h"
#include "daemon_ops.h"
#include "fsutil.h"
#include "job/sm_job_batch_list.h"
#include "job/sm_job_template_from.h"
#include "shapematch/sm_shape_model.h"
#include "remote.h"
#include "sse.h"
#include "sm_json.h"
#include "sm_proto_events.h"
#include "sm_proto_params.h"
#include "sm_proto_vocab.h"
#include "submit_job.h"

enum { RB_TEMPLATE, RB_SURFACE, RB_IMAGE, RB_MESH, RB_SOL, RB_TARGETS, RB_ALIGN, RB_OUTPUT,
       RB_FORMAT, RB_QUIET, RB_FROM, RB_ROUNDS, RB_TOLERANCE, RB_LOCAL_ONLY };

typedef struct remote_batch {
    sm_batch_list list;
    const char *template_path, *model_align, *outdir, *pending_mesh;
    unsigned formats;
    int quiet;
    job_options job;
    int listing;                    /* RB_SURFACE or RB_IMAGE: the words after
                                     * it are more of them (a shell glob) */
    char (*ids)[SM_JOB_ID_MAX + 1]; /* the targets' jobs, by list index */
    char batch_id[SM_JOB_ID_MAX + 1];
    /* --template-from, --rounds, --template-tolerance */
    const char *template_from;
    int rounds;
    double tolerance;
    sm_template_from from;
    /* the batch request's template_from (mode NULL: none) */
    const char *origin_mode;
    int origin_round;
    char origin_previous[SM_JOB_ID_MAX + 1];
} remote_batch;

static int rb_flag(void *user, int id, const char *flag, const char *value, char *msg, size_t cap)
{
    remote_batch *b = user;
    sm_error err;
    sm_error_clear(&err);
    sm_status st = SM_OK;
    if (id == CLI_ARG_POSITIONAL && b->listing)
        id = b->listing; /* --target-surface a.stl b.stl ... */
    b->listing = id == RB_SURFACE || id == RB_IMAGE ? id : 0;
    switch (id) {
    case CLI_ARG_POSITIONAL:
        snprintf(msg, cap, "unexpected argument '%.80s' (batch takes options only; several "
                           "targets follow one --target-surface or --target-image)", value);
        return -1;
    case CLI_ARG_JOB: return job_option_apply(&b->job, flag, value, msg, cap);
    case RB_TEMPLATE: b->template_path = value; return 0;
    case RB_SURFACE: st = sm_batch_list_add(&b->list, NULL, value, NULL, NULL, NULL, NULL, &err); break;
    case RB_IMAGE: st = sm_batch_list_add(&b->list, NULL, NULL, value, NULL, NULL, NULL, &err); break;
    case RB_MESH:
        if (b->pending_mesh) {
            snprintf(msg, cap, "--target-mesh %.200s has no --target-sol", b->pending_mesh);
            return -1;
        }
        b->pending_mesh = value;
        return 0;
    case RB_SOL:
        if (!b->pending_mesh) {
            snprintf(msg, cap, "--target-sol %.200s follows no --target-mesh", value);
            return -1;
        }
        st = sm_batch_list_add(&b->list, NULL, NULL, NULL, b->pending_mesh, value, NULL, &err);
        b->pending_mesh = NULL;
        break;
    case RB_TARGETS: return batch_read_list(&b->list, value, msg, cap);
    case RB_ALIGN: b->model_align = value; return 0;
    case RB_OUTPUT: b->outdir = value; return 0;
    case RB_FORMAT: return fetch_parse_formats(flag, value, &b->formats, msg, cap);
    case RB_QUIET: b->quiet = 1; return 0;
    case RB_FROM: b->template_from = value; return 0;
    case RB_ROUNDS: return batch_parse_rounds(value, &b->rounds, msg, cap);
    case RB_TOLERANCE: return batch_parse_tolerance(value, &b->tolerance, msg, cap);
    default:
        snprintf(msg, cap, "%s is for a local batch (without --server)", flag);
        return -1;
    }
    if (st != SM_OK)
        snprintf(msg, cap, "%s", err.msg);
    return st == SM_OK ? 0 : -1;
}

/* The rules beyond each flag's own; NULL when fine. */
static const char *rb_problem(remote_batch *b, char *msg, size_t cap)
{
    sm_error err;
    sm_error_clear(&err);
    if (b->pending_mesh)
        return "--target-mesh has no --target-sol";
    if (batch_resolve_template_from(b->template_from, &b->template_path, b->rounds, b->tolerance,
                                    0, &b->from, msg, cap) != 0)
        return msg;
    if (!b->template_path)
        return "--template is required";
    if (!b->outdir)
        return "-o DIR is required";
    if (b->list.n == 0)
        return "no target (--target-surface, --target-image, --target-mesh/--target-sol, --targets)";
    if (sm_batch_list_finish(&b->list, &err) != SM_OK) {
        snprintf(msg, cap, "%s", err.msg);
        return msg;
    }
    for (size_t i = 0; i < b->list.n; i++)
        if (b->list.t[i].landmarks)
            return "per-target landmarks are for a local batch (without --server)";
    const sm_batch_target *t = &b->list.t[0];
    const char *own = t->target_surface ? t->target_surface : t->target_image;
    if (job_options_finish(&b->job, msg, cap) != 0 ||
        job_options_check_background(&b->job, own, t->target_mesh, msg, cap) != 0)
        return msg;
    return NULL;
}

static void sleep_seconds(double s)
{
    struct timespec ts = {.tv_sec = (time_t)s, .tv_nsec = (long)((s - (double)(time_t)s) * 1e9)};
    nanosleep(&ts, NULL);
}

/* Cancels the jobs submitted so far (a later submission failed). */
static void withdraw(http_client *c, const remote_batch *b, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        char path[96];
        snprintf(path, sizeof path, "/v1/jobs/%s", b->ids[i]);
        http_request rq = {.method = "DELETE", .path = path, .accept = "application/json"};
        http_response rs;
        http_perform(c, &rq, &rs);
        http_response_free(&rs);
    }
}

/* Every target as a job. */
static int submit_targets(http_client *c, remote_batch *b, int token_given, const char *params)
{
    for (size_t i = 0; i < b->list.n; i++) {
        const sm_batch_target *t = &b->list.t[i];
        /* each job named after its target, when the name can be one */
        char why[96];
        int named = sm_job_name_check(t->name, strlen(t->name), why, sizeof why) == 0;
        submit_job j = {.template_path = b->template_path, .target_mesh = t->target_mesh,
                        .target_sol = t->target_sol, .target_surface = t->target_surface,
                        .target_image = t->target_image, .params_json = params,
                        .name = named ? t->name : NULL};
        http_response rs;
        int code = remote_submit_job(c, "batch", token_given, &j, &rs, b->ids[i], sizeof b->ids[i]);
        if (code != 0) {
            fprintf(stderr, "shapematch batch: target %s not submitted; the %zu submitted before "
                            "are cancelled\n", t->name, i);
            withdraw(c, b, i);
            return code;
        }
        http_response_free(&rs);
        if (!b->quiet)
            fprintf(stderr, "shapematch batch: target %zu/%zu %s: job %s\n", i + 1, b->list.n,
                    t->name, b->ids[i]);
    }
    return 0;
}

/* POST /v1/batches: the batch's id into b->batch_id. */
static int post_batch(http_client *c, remote_batch *b, int token_given)
{
    json_t *targets = json_array();
    for (size_t i = 0; targets && i < b->list.n; i++)
        json_array_append_new(targets, json_pack("{s:s,s:s}", "job", b->ids[i], "name",
                                                 b->list.t[i].name));
    json_t *doc = json_pack("{s:o,s:s}", "targets", targets, "model_align",
                            b->model_align ? b->model_align : "rigid");
    if (doc && b->origin_mode) {
        json_t *tf = json_pack("{s:s,s:i}", "mode", b->origin_mode, "round", b->origin_round);
        if (tf && b->origin_previous[0])
            json_object_set_new(tf, "previous", json_string(b->origin_previous));
        json_object_set_new(doc, "template_from", tf);
    }
    char *body = doc ? sm_json_dumps(doc, 0) : NULL;
    json_decref(doc);
    if (!body) {
        fprintf(stderr, "shapematch batch: error: out of memory\n");
        return CLI_EXIT_INPUT;
    }
    http_request rq = {.method = "POST", .path = "/v1/batches", .accept = "application/json",
                       .headers = {"Content-Type: application/json"}, .body = body,
                       .body_len = strlen(body)};
    http_response rs;
    http_outcome out = http_perform(c, &rq, &rs);
    free(body);
    int code = 0;
    if (out != HTTP_DONE || rs.status != 201) {
        code = remote_report("batch", c, token_given, out, &rs, "creating the batch");
        withdraw(c, b, b->list.n);
    } else {
        json_t *answer = remote_json_object(&rs);
        const char *id = answer ? json_string_value(json_object_get(answer, "batchID")) : NULL;
        char msg[128];
        if (id && remote_check_id(id, msg, sizeof msg) == 0) {
            snprintf(b->batch_id, sizeof b->batch_id, "%s", id);
        } else {
            fprintf(stderr, "shapematch batch: error: bad response from %s: no batchID\n", c->base);
            code = CLI_EXIT_SERVER;
        }
        json_decref(answer);
    }
    http_response_free(&rs);
    if (code == 0 && !b->quiet)
        fprintf(stderr, "shapematch batch: batch %s of %zu targets\n", b->batch_id, b->list.n);
    return code;
}

/* Following the batch: GET /v1/batches/{id}/events as Server-Sent
 * Events, a line whenever its "batch" event (status, progress, counts,
 * eta) changes, until the last "status" event carries the final batch
 * document.  A stream that ends or breaks off before it is resumed from
 * the last "batch" event's id (Last-Event-ID), a few times in a row at
 * most without news. */
#define BATCH_STREAM_RETRIES 5
#define BATCH_EVENT_MAX ((size_t)8 << 20) /* a status event: the whole document */

typedef struct batch_follow {
    const remote_batch *b;
    sse_parser sse;
    char last[160];       /* the progress line shown last */
    long long seq;        /* the last "batch" event's id */
    json_t *final;        /* the "status" event: the batch document */
    int news;             /* events on this connection */
    char error[200];
} batch_follow;

static void show_progress(batch_follow *f, const json_t *doc)
{
    const char *status = json_string_value(json_object_get(doc, "status"));
    json_t *counts = json_object_get(doc, "counts"), *eta = json_object_get(doc, "eta");
    char line[160];
    snprintf(line, sizeof line, "%s, %d%%: %d of %d targets ended, %d running",
             status ? status : "?", (int)json_integer_value(json_object_get(doc, "progress")),
             (int)(json_integer_value(json_object_get(counts, "successful")) +
                   json_integer_value(json_object_get(counts, "failed")) +
                   json_integer_value(json_object_get(counts, "dismissed"))),
             (int)json_integer_value(json_object_get(counts, "total")),
             (int)json_integer_value(json_object_get(counts, "running")));
    if (f->b->quiet || strcmp(line, f->last) == 0)
        return;
    fprintf(stderr, "shapematch batch: %s", line);
    if (json_is_number(eta) && json_number_value(eta) > 0)
        fprintf(stderr, ", about %.0f s left", json_number_value(eta));
    fprintf(stderr, "\n");
    snprintf(f->last, sizeof f->last, "%s", line);
}

static int on_batch_event(void *user, const sse_event *e)
{
    batch_follow *f = user;
    json_error_t je;
    json_t *ev = json_loadb(e->data, e->data_len, 0, &je);
    if (!json_is_object(ev)) {
        json_decref(ev);
        snprintf(f->error, sizeof f->error, "a '%.40s' event is not a JSON object (%.100s)",
                 e->type, je.text);
        return -1;
    }
    f->news++;
    if (e->has_id) {
        char *end;
        long long seq = strtoll(e->id, &end, 10);
        if (*end || seq < 0) {
            json_decref(ev);
            snprintf(f->error, sizeof f->error, "event id '%.40s' is not a version", e->id);
            return -1;
        }
        f->seq = seq;
    }
    if (strcmp(e->type, "batch") == 0) {
        show_progress(f, ev);
    } else if (strcmp(e->type, "status") == 0) {
        const char *status = json_string_value(json_object_get(ev, "status"));
        if (!status || !json_is_array(json_object_get(ev, "targets"))) {
            json_decref(ev);
            snprintf(f->error, sizeof f->error, "the final status event has no batch document");
            return -1;
        }
        show_progress(f, ev);
        f->final = ev;
        return 1; /* the daemon closes the stream after it */
    }
    json_decref(ev); /* "target": one target's entry, not shown */
    return 0;
}

static int on_batch_data(void *user, const char *data, size_t len)
{
    batch_follow *f = user;
    return sse_feed(&f->sse, data, len) == 0 ? 0 : 1;
}

/* The batch followed to its end; the final document into *final. */
static int follow(http_client *c, const remote_batch *b, int token_given, json_t **final)
{
    batch_follow f;
    memset(&f, 0, sizeof f);
    f.b = b;
    sse_init(&f.sse, BATCH_EVENT_MAX, on_batch_event, &f);
    char path[128], last_header[64];
    snprintf(path, sizeof path, "/v1/batches/%s/events", b->batch_id);
    int code = 0, quiet_tries = 0;
    for (;;) {
        http_request rq = {.path = path, .accept = "text/event-stream", .stream = 1,
                           .sink = on_batch_data, .sink_user = &f};
        if (f.seq > 0) {
            snprintf(last_header, sizeof last_header, "Last-Event-ID: %lld", f.seq);
            rq.headers[0] = last_header;
        }
        sse_restart(&f.sse);
        f.news = 0;
        http_response rs;
        http_outcome out = http_perform(c, &rq, &rs);
        if (f.final) {
            http_response_free(&rs);
            *final = f.final;
            break;
        }
        if (f.error[0] || (f.sse.error[0] && !f.sse.stopped)) {
            fprintf(stderr, "shapematch batch: error: bad event stream from %s: %s\n", c->base,
                    f.error[0] ? f.error : f.sse.error);
            http_response_free(&rs);
            code = CLI_EXIT_SERVER;
            break;
        }
        /* a stream that ended or broke off before the end: resumed */
        if (!(out == HTTP_DONE && rs.status == 200) && out != HTTP_DROPPED) {
            code = remote_report("batch", c, token_given, out, &rs, "following the batch");
            http_response_free(&rs);
            break;
        }
        http_response_free(&rs);
        quiet_tries = f.news ? 0 : quiet_tries + 1;
        if (quiet_tries > BATCH_STREAM_RETRIES) {
            fprintf(stderr, "shapematch batch: error: the batch's event stream at %s ended %d "
                            "times in a row without news; 'shapematch status %s' shows the "
                            "batch\n", c->base, quiet_tries, b->batch_id);
            code = CLI_EXIT_CONNECT;
            break;
        }
        sleep_seconds(0.25 * quiet_tries);
    }
    sse_free(&f.sse);
    return code;
}

/* Every successful target's results, the model's files, batch.json. */
static int fetch_all(http_client *c, const remote_batch *b, int token_given, const json_t *doc)
{
    int code = 0;
    json_t *t;
    size_t i;
    json_array_foreach(json_object_get(doc, "targets"), i, t) {
        const char *status = json_string_value(json_object_get(t, "status"));
        if (code != 0 || i >= b->list.n || !status || strcmp(status, "successful") != 0)
            continue;
        char dir[PATH_MAX];
        snprintf(dir, sizeof dir, "%s/targets/%s", b->outdir, b->list.t[i].name);
        fetch_options fo = {.outdir = dir, .formats = b->formats, .quiet = 1};
        code = remote_fetch(c, "batch", token_given, b->ids[i], &fo);
    }
    if (code == 0 && !strcmp(json_string_value(json_object_get(doc, "status")), "successful")) {
        static const struct { const char *name, *media; } files[] = {
            {"mean.mesh", "application/x-medit-mesh"}, {"mean.vtu", "application/vnd.vtk.vtu+xml"},
            {"modes.vtu", "application/vnd.vtk.vtu+xml"}, {"scores.csv", "text/csv"},
            {"summary.json", "application/json"}};
        char dir[PATH_MAX], msg[256];
        snprintf(dir, sizeof dir, "%s/model", b->outdir);
        if (fs_output_dir(dir, msg, sizeof msg) != 0) {
            fprintf(stderr, "shapematch batch: error: %s\n", msg);
            return CLI_EXIT_OUTPUT;
        }
        for (size_t k = 0; code == 0 && k < sizeof files / sizeof files[0]; k++) {
            char path[160];
            snprintf(path, sizeof path, "/v1/batches/%s/model/%s", b->batch_id, files[k].name);
            code = remote_download(c, "batch", token_given, path, dir, files[k].name, files[k].media);
        }
    }
    return code == 0 ? remote_write_json("batch", b->outdir, "batch.json", doc) : code;
}

/* The exit code of the batch's end: 0 every target and the model, 5
 * cancelled, 11 a target failed or no model. */
static int outcome(const remote_batch *b, const json_t *doc)
{
    const char *status = json_string_value(json_object_get(doc, "status"));
    json_t *counts = json_object_get(doc, "counts");
    long ok = (long)json_integer_value(json_object_get(counts, "successful"));
    if (!b->quiet || strcmp(status, "successful") != 0)
        fprintf(stderr, "shapematch batch: batch %s %s: %ld of %zu targets matched%s; results "
                        "in %s\n", b->batch_id, status, ok, b->list.n,
                !strcmp(status, "successful") ? ", model built" : "", b->outdir);
    if (!strcmp(status, "dismissed"))
        return CLI_EXIT_CANCELLED;
    return !strcmp(status, "successful") && ok == (long)b->list.n ? CLI_EXIT_OK
                                                                   : CLI_EXIT_BATCH_PARTIAL;
}

/* One batch on the daemon, b->template_path and b->outdir set: its exit
 * code (outcome's, or the failed request's); its final document into
 * *doc. */
static int one_batch(http_client *c, remote_batch *b, int token, const char *params,
                     json_t **doc)
{
    int code = submit_targets(c, b, token, params);
    if (code == 0)
        code = post_batch(c, b, token);
    if (code == 0)
        code = follow(c, b, token, doc);
    if (code == 0)
        code = fetch_all(c, b, token, *doc);
    if (code == 0)
        code = outcome(b, *doc);
    return code;
}

typedef struct remote_rounds {
    remote_batch *b;
    http_client *c;
    int token;
    const char *params;
    int code;        /* the last round's exit code */
} remote_rounds;

static void on_round_done(int round, const char *template_path, double movement,
                          const char *next_template, void *user)
{
    const remote_batch *b = user;
    if (b->quiet)
        return;
    fprintf(stderr, "shapematch batch: round %d (batch %s) on %s done", round, b->batch_id,
            template_path);
    if (movement == movement) /* not NAN */
        fprintf(stderr, "; the mean moved by %.3g of its size", movement);
    if (next_template)
        fprintf(stderr, "; next template %s", next_template);
    fputc('\n', stderr);
}

/* sm_rounds_opts.run: round k as a daemon's batch into dir (batch.json
 * its summary), the request naming the round and the batch before. */
static sm_status remote_round(const sm_batch_list *list, const sm_batch_opts *opts, int k,
                              const char *dir, sm_batch_outcome *out, void *user, sm_error *err)
{
    (void)list; /* b->list, submitted by name */
    remote_rounds *rr = user;
    remote_batch *b = rr->b;
    memset(out, 0, sizeof *out);
    b->template_path = opts->template_mesh;
    b->outdir = dir;
    b->origin_mode = sm_template_from_name(b->from);
    b->origin_round = k;
    snprintf(b->origin_previous, sizeof b->origin_previous, "%s", k > 1 ? b->batch_id : "");
    json_t *doc = NULL;
    rr->code = one_batch(rr->c, b, rr->token, rr->params, &doc);
    if (rr->code != 0 && rr->code != CLI_EXIT_BATCH_PARTIAL && rr->code != CLI_EXIT_CANCELLED) {
        json_decref(doc);
        return sm_error_set(err, SM_ERR_IO, "round %d: the daemon's batch did not end (see "
                            "above)", k);
    }
    const char *status = json_string_value(json_object_get(doc, "status"));
    json_t *counts = json_object_get(doc, "counts");
    out->nok = (size_t)json_integer_value(json_object_get(counts, "successful"));
    out->nfailed = b->list.n > out->nok ? b->list.n - out->nok : 0;
    out->model_built = status && strcmp(status, "successful") == 0;
    out->cancelled = status && strcmp(status, "dismissed") == 0;
    const char *message = json_string_value(json_object_get(doc, "message"));
    if (!out->model_built)
        snprintf(out->model_error, sizeof out->model_error, "batch %s %s: %.300s", b->batch_id,
                 status ? status : "?", message ? message : "");
    json_decref(doc);
    return SM_OK;
}

/* The rounds of --template-from, each a daemon's batch. */
static int run_rounds(http_client *c, remote_batch *b, int token, const char *params)
{
    remote_rounds rr = {.b = b, .c = c, .token = token, .params = params};
    const char *outdir = b->outdir;
    sm_shape_align align = SM_SHAPE_ALIGN_RIGID;
    if (b->model_align && sm_shape_align_parse(b->model_align, &align) != 0)
        return remote_usage_error("batch", "--model-align: expected none, rigid or similarity");
    /* the rounds read each target's result mesh */
    b->formats |= FETCH_MESH;
    sm_batch_opts o = {.template_mesh = b->template_path, .build_model = 1,
                       .model = {.align = align}, .user = b};
    sm_rounds_opts r = {.from = b->from, .rounds = b->rounds, .tolerance = b->tolerance,
                        .round_done = on_round_done, .run = remote_round, .run_user = &rr,
                        .summary_file = "batch.json"};
    sm_batch_outcome out;
    sm_rounds_outcome ends;
    sm_error err;
    sm_error_clear(&err);
    sm_status st = sm_job_batch_rounds(&b->list, &o, &r, outdir, &out, &ends, &err);
    b->outdir = outdir;
    if (st != SM_OK) {
        fprintf(stderr, "shapematch batch: error: %s\n", err.msg);
        return rr.code ? rr.code : st == SM_ERR_IO ? CLI_EXIT_OUTPUT : CLI_EXIT_INPUT;
    }
    if (ends.message[0])
        fprintf(stderr, "shapematch batch: %s\n", ends.message);
    if (!b->quiet)
        fprintf(stderr, "shapematch batch: template from the %s: %d round%s (%s%s%s); the last "
                "round's template in %s/template.mesh, its batch in %s/batch.json\n",
                sm_template_from_name(b->from), ends.rounds, ends.rounds == 1 ? "" : "s",
                ends.stop, ends.medoid[0] ? ": " : "", ends.medoid, outdir, outdir);
    return rr.code;
}

static int rb_run(remote_batch *b, const remote_options *conn)
{
    {
        /* physical names: the daemon takes numbers, the template has the names */
        char msg[ARGS_MSG_LEN];
        int named = job_options_resolve_names_at(&b->job, b->template_path, msg, sizeof msg);
        if (named == CLI_EXIT_INPUT)
            fprintf(stderr, "shapematch batch: %s\n", msg);
        if (named)
            return named == CLI_EXIT_INPUT ? named : remote_usage_error("batch", msg);
    }
    int dim = b->job.params.clamp == SM_CLAMP_BALL ? b->job.clamp_ball_dim : 0;
    char *params = sm_job_params_to_json(&b->job.params, &b->job.background, dim);
    char msg[256];
    if (!params)
        return remote_usage_error("batch", "the parameters cannot be encoded as JSON");
    if (fs_output_dir(b->outdir, msg, sizeof msg) != 0) {
        free(params);
        fprintf(stderr, "shapematch batch: output directory: %s\n", msg);
        return CLI_EXIT_OUTPUT;
    }
    http_client c;
    int code = remote_open("batch", conn, &c);
    if (code != 0) {
        free(params);
        return code;
    }
    int token = conn->token != NULL;
    json_t *doc = NULL;
    code = b->template_from ? run_rounds(&c, b, token, params)
                            : one_batch(&c, b, token, params, &doc);
    free(params);
    json_decref(doc);
    remote_close(&c);
    return code;
}

int cmd_batch_remote(int argc, char **argv)
{
    static const cli_flag flags[] = {
        {"--template", 1, RB_TEMPLATE}, {"--target-surface", 1, RB_SURFACE},
        {"--target-image", 1, RB_IMAGE}, {"--target-mesh", 1, RB_MESH},
        {"--target-sol", 1, RB_SOL}, {"--targets", 1, RB_TARGETS},
        {"--model-align", 1, RB_ALIGN}, {"-o", 1, RB_OUTPUT}, {"--output", 1, RB_OUTPUT},
        {"--format", 1, RB_FORMAT}, {"-q", 0, RB_QUIET}, {"--quiet", 0, RB_QUIET},
        {"--jobs", 1, RB_LOCAL_ONLY}, {"--no-model", 0, RB_LOCAL_ONLY},
        {"--model-from", 1, RB_LOCAL_ONLY}, {"--model-modes", 1, RB_LOCAL_ONLY},
        {"--template-landmarks", 1, RB_LOCAL_ONLY}, {"--template-from", 1, RB_FROM},
        {"--rounds", 1, RB_ROUNDS}, {"--template-tolerance", 1, RB_TOLERANCE}};
    remote_batch b;
    memset(&b, 0, sizeof b);
    job_options_init(&b.job);
    b.formats = FETCH_DEFAULT_FORMATS;
    remote_options conn;
    char msg[ARGS_MSG_LEN];
    int code = 0;
    switch (remote_parse(argc, argv, flags, sizeof flags / sizeof flags[0], 1, &conn, rb_flag, &b,
                         msg, sizeof msg)) {
    case ARGS_HELP:
        cmd_batch_help();
        goto done;
    case ARGS_ERROR:
        code = remote_usage_error("batch", msg);
        goto done;
    case ARGS_OK:
        break;
    }
    const char *problem = rb_problem(&b, msg, sizeof msg);
    if (problem) {
        code = remote_usage_error("batch", problem);
        goto done;
    }
    if (!(b.ids = calloc(b.list.n, sizeof *b.ids))) {
        code = remote_usage_error("batch", "out of memory");
        goto done;
    }
    code = rb_run(&b, &conn);
done:
    free(b.ids);
    sm_batch_list_free(&b.list);
    return code;
}
