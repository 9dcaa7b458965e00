/* GET /v1/batches/{id}/events (see smd_batch_events.h). */
#include "api/smd_batch_events.h"
#include "jobs/smd_usecases.h"

#include <stdlib.h>
#include <string.h>

#include "sm_json.h"
#include "api/smd_batches.h"
#include "api/smd_routes.h"
#include "api/smd_stream.h"
#include "store/spool/smd_store.h"

typedef struct batch_events {
    char model[SMD_ID_LEN + 1];
    json_t *batch;            /* the description: its members */
    char (*ids)[SMD_ID_LEN + 1]; /* the members' ids, sorted (follows) */
    size_t n;
    json_t *sent;             /* the "targets" last sent, NULL before the first */
    json_t *sent_summary;     /* status, progress and counts last sent */
    int64_t sent_version;
    int64_t resume;           /* the version the client has seen, -1 none */
} batch_events;

static int id_cmp(const void *a, const void *b)
{
    return strcmp(a, b);
}

static int batch_follows(const void *state, const char *id)
{
    const batch_events *b = state;
    return bsearch(id, b->ids, b->n, sizeof b->ids[0], id_cmp) != NULL;
}

static void batch_free(void *state)
{
    batch_events *b = state;
    json_decref(b->batch);
    json_decref(b->sent);
    json_decref(b->sent_summary);
    free(b->ids);
    free(b);
}

/* Lock held: the number of events of job id's log (0 when it is not in
 * this node's table or its log cannot be read). */
static int64_t job_events(smd_server *srv, const char *id)
{
    smd_job *job = smd_store_get(srv->store, id);
    sm_error err;
    if (!job || smd_store_load_events(srv->store, job, &err) != SM_OK)
        return 0;
    return job->nevents;
}

/* Appends one event: in SSE with id seq (none when < 1), in NDJSON as a
 * line.  -1 out of memory. */
static int emit(int sse, const char *type, json_t *o, int64_t seq, char **buf, size_t *len,
                size_t *cap)
{
    json_t *ev = json_pack("{s:s}", "type", type);
    if (!ev || json_object_update(ev, o) != 0) {
        json_decref(ev);
        return -1;
    }
    char *line = sm_json_dumps(ev, 0);
    json_decref(ev);
    if (!line)
        return -1;
    size_t n = strlen(line);
    int rc = sse ? smd_sse_format(buf, len, cap, seq, type, line, n)
                 : smd_buf_append(buf, len, cap, line, n) == 0 &&
                           smd_buf_append(buf, len, cap, "\n", 1) == 0
                       ? 0
                       : -1;
    free(line);
    return rc;
}

/* The members whose entries changed since the last call, then the batch
 * event when anything changed. */
static int emit_changes(batch_events *b, int sse, const json_t *doc, int64_t version,
                        char **buf, size_t *len, size_t *cap)
{
    json_t *targets = json_object_get(doc, "targets"), *t;
    size_t i;
    int changed = version != b->sent_version || !b->sent;
    json_array_foreach(targets, i, t) {
        if (b->sent && json_equal(t, json_array_get(b->sent, i)))
            continue;
        changed = 1;
        json_t *o = json_pack("{s:s}", "batchID", b->model);
        int rc = o && json_object_update(o, t) == 0 ? emit(sse, "target", o, 0, buf, len, cap) : -1;
        json_decref(o);
        if (rc != 0)
            return -1;
    }
    json_t *summary = json_pack("{s:O,s:O,s:O}", "status", json_object_get(doc, "status"),
                                "progress", json_object_get(doc, "progress"), "counts",
                                json_object_get(doc, "counts"));
    if (!summary)
        return -1;
    changed |= !b->sent_summary || !json_equal(summary, b->sent_summary);
    int rc = 0;
    if (changed) {
        json_t *o = json_pack("{s:s,s:I,s:O}", "batchID", b->model, "seq", (json_int_t)version,
                              "eta", json_object_get(doc, "eta"));
        rc = o && json_object_update(o, summary) == 0
                 ? emit(sse, "batch", o, version, buf, len, cap)
                 : -1;
        json_decref(o);
    }
    json_decref(b->sent);
    json_decref(b->sent_summary);
    b->sent = json_incref(targets);
    b->sent_summary = summary;
    b->sent_version = version;
    return rc;
}

static int batch_refill(void *state, smd_server *srv, smd_job *model, int sse, int64_t *next_seq,
                        char **buf, size_t *len, size_t *cap)
{
    batch_events *b = state;
    int64_t version = job_events(srv, model->id);
    for (size_t i = 0; i < b->n; i++)
        version += job_events(srv, b->ids[i]);
    json_t *doc = smd_batch_document(srv, model, b->batch);
    if (!doc)
        return -1;
    /* the end: the model job's is on disk (as a job's stream: its last
     * event may still be coming) and no target is live any more (a cancel
     * ends the model job first, then its targets), or the batch is gone */
    json_t *counts = json_object_get(doc, "counts");
    int live = (int)json_integer_value(json_object_get(counts, "accepted")) +
               (int)json_integer_value(json_object_get(counts, "running"));
    int final = model->removed || (smd_job_state_final(model->state) && !model->worker_active &&
                                   !model->ending && live == 0);
    int rc = 0;
    if (!b->sent && b->resume >= 0 && b->resume == version) {
        /* resumed where it left: the client has this state already */
        b->sent = json_incref(json_object_get(doc, "targets"));
        b->sent_summary = json_pack("{s:O,s:O,s:O}", "status", json_object_get(doc, "status"),
                                    "progress", json_object_get(doc, "progress"), "counts",
                                    json_object_get(doc, "counts"));
        b->sent_version = version;
        rc = b->sent_summary ? 0 : -1;
    } else {
        rc = emit_changes(b, sse, doc, version, buf, len, cap);
    }
    *next_seq = version + 1;
    if (rc == 0 && final) {
        if (model->removed)
            json_object_set_new(doc, "message", json_string("deleted"));
        rc = emit(sse, "status", doc, 0, buf, len, cap) == 0 ? 1 : -1;
    }
    json_decref(doc);
    return rc;
}

static const smd_follow_source batch_source = {batch_refill, batch_follows, batch_free};

/* The stream's state for the batch described by batch (reference taken);
 * NULL out of memory. */
static batch_events *batch_events_new(const char *id, json_t *batch, int64_t resume)
{
    batch_events *b = calloc(1, sizeof *b);
    json_t *members = json_object_get(batch, "members"), *v;
    size_t n = json_array_size(members), i;
    if (!b || !(b->ids = calloc(n ? n : 1, sizeof *b->ids))) {
        free(b);
        return NULL;
    }
    json_array_foreach(members, i, v)
        snprintf(b->ids[b->n++], sizeof b->ids[0], "%s",
                 json_string_value(json_object_get(v, "job")) ? json_string_value(json_object_get(v, "job")) : "");
    qsort(b->ids, b->n, sizeof b->ids[0], id_cmp);
    snprintf(b->model, sizeof b->model, "%s", id);
    b->batch = json_incref(batch);
    b->sent_version = -1;
    b->resume = resume;
    return b;
}

enum MHD_Result smd_route_batch_events(struct MHD_Connection *conn, smd_request *req)
{
    smd_server *srv = req->srv;
    /* the request's own values first, as the job events route does: a
     * bad Last-Event-ID is a 400 whether or not the batch exists */
    smd_stream_request sr;
    enum MHD_Result r;
    if (!smd_stream_request_open(conn, req, &sr, &r))
        return r;
    smd_job seen;
    int found = smd_jobs_find(srv, req->id, req->who.tenant, req->who.admin, &seen) &&
                seen.batch_model;
    json_t *batch = found ? smd_batch_read(srv, req->id) : NULL;
    if (!batch)
        return smd_reply_problem(conn, req, 404, SMD_PROBLEM_NOT_FOUND, "no batch %s", req->id);
    batch_events *b = batch_events_new(req->id, batch, sr.resumed ? sr.after : -1);
    json_decref(batch);
    if (!b)
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE, "out of memory");
    char msg[256];
    smd_follow_request rq = {.id = req->id, .tenant = req->who.tenant, .admin = req->who.admin,
                             .sse = sr.sse, .after_seq = sr.after, .bytes_out = &req->bytes_out,
                             .cred = sr.cred, .src = &batch_source, .src_state = b};
    struct MHD_Response *resp = smd_stream_response(srv, conn, &rq, &found, msg, sizeof msg);
    if (!found) /* deleted meanwhile */
        return smd_reply_problem(conn, req, 404, SMD_PROBLEM_NOT_FOUND, "no batch %s", req->id);
    if (!resp)
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE, "%s", msg);
    return smd_reply(conn, req, 200, resp);
}
