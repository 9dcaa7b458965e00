/* /v1/batches (see smd_batches.h). */
#include "api/smd_batches.h"

#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "sm_json.h"
#include "shapematch/sm_clock.h"
#include "api/smd_batch_request.h"
#include "api/smd_routes.h"
#include "jobs/smd_jobs.h"
#include "jobs/smd_usecases.h"
#include "base/smd_body.h"
#include "store/spool/smd_store.h"
#include "worker/smd_job_file.h"
#include "worker/smd_worker.h"

_Static_assert(SMD_JOB_MEMBERS_MAX == SMD_BATCH_MEMBERS_MAX, "one bound of a batch's members");

/* A request body is a list of ids and names: 1 MiB holds 1000 members
 * many times over. */
#define BATCH_BODY_MAX (1u << 20)

typedef struct batch_body {
    smd_body body; /* counted in --max-body-memory (base/smd_body.h) */
    int refused;   /* SMD_BODY_*: the rest is read and dropped */
} batch_body;

typedef smd_batch_member member;

static enum MHD_Result no_such_batch(struct MHD_Connection *conn, smd_request *req)
{
    return smd_reply_problem(conn, req, 404, SMD_PROBLEM_NOT_FOUND, "no batch %s", req->id);
}

/* ------------------------------------------------------ the document */

json_t *smd_batch_read(smd_server *srv, const char *id)
{
    char dir[PATH_MAX];
    if (smd_store_path(srv->store, id, "", dir, sizeof dir) != 0)
        return NULL;
    smd_job_file f;
    sm_error err;
    json_t *batch = NULL;
    if (smd_job_file_read(dir, &f, &err) == SM_OK && f.batch)
        batch = json_incref(f.batch);
    smd_job_file_free(&f);
    return batch;
}

typedef struct tally {
    int n[5];          /* by sm_job_state */
    int unknown;       /* not (or no longer) in this node's table */
    double progress;   /* sum of the members' progress, final ones 100 */
    double first_start; /* earliest start of a member, < 0 none */
} tally;

/* Lock held: one member's entry, counted into t. */
static json_t *member_entry(smd_server *srv, const char *id, const char *name, tally *t)
{
    const smd_job *job = smd_store_get(srv->store, id);
    char href[64];
    snprintf(href, sizeof href, "/v1/jobs/%s", id);
    if (!job) {
        t->unknown++;
        return json_pack("{s:s,s:s,s:s,s:s}", "name", name, "jobID", id, "status", "unknown",
                         "href", href);
    }
    t->n[job->state]++;
    int progress = smd_job_state_final(job->state) ? 100 : job->progress;
    t->progress += progress;
    if (job->started >= 0 && (t->first_start < 0 || job->started < t->first_start))
        t->first_start = job->started;
    json_t *e = json_pack("{s:s,s:s,s:s,s:i,s:s,s:s}", "name", name, "jobID", id, "status",
                          sm_job_state_name(job->state), "progress", progress, "message",
                          job->message, "href", href);
    if (job->state == SM_JOB_SUCCESSFUL)
        json_object_set_new(e, "converged", json_boolean(!job->not_converged));
    if (job->have_progress && job->state != SM_JOB_ACCEPTED)
        json_object_set_new(e, "iteration", json_integer(job->last_progress.iteration));
    return e;
}

/* The batch's status: the model job's once it runs or ended; before,
 * running while a member runs, else accepted. */
static const char *batch_status(const smd_job *model, const tally *t)
{
    if (model->state != SM_JOB_ACCEPTED)
        return sm_job_state_name(model->state);
    return t->n[SM_JOB_RUNNING] || t->n[SM_JOB_SUCCESSFUL] || t->n[SM_JOB_FAILED] ||
                   t->n[SM_JOB_DISMISSED]
               ? "running"
               : "accepted";
}

/* Progress counts each member and the model step alike; the ETA is the
 * time since the first member started, scaled by what is left (null
 * before any progress; 0 when final). */
json_t *smd_batch_document(smd_server *srv, const smd_job *model, const json_t *batch)
{
    tally t = {.first_start = -1};
    json_t *targets = json_array();
    json_t *members = json_object_get(batch, "members"), *v;
    size_t i, n = json_array_size(members);
    json_array_foreach(members, i, v)
        json_array_append_new(targets, member_entry(srv, json_string_value(json_object_get(v, "job")),
                                                    json_string_value(json_object_get(v, "name")),
                                                    &t));
    double model_progress = smd_job_state_final(model->state) ? 100 : model->progress;
    double progress = (t.progress + model_progress) / (double)(n + 1);
    json_t *eta = json_null();
    if (smd_job_state_final(model->state))
        eta = json_real(0);
    else if (progress > 0 && t.first_start >= 0)
        eta = json_real((sm_time_now() - t.first_start) * (100 - progress) / progress);
    char self[64], model_href[80];
    snprintf(self, sizeof self, "/v1/batches/%s", model->id);
    snprintf(model_href, sizeof model_href, "/v1/batches/%s/model", model->id);
    json_t *counts = json_pack("{s:i,s:i,s:i,s:i,s:i,s:i,s:i}", "total", (int)n, "accepted",
                               t.n[SM_JOB_ACCEPTED], "running", t.n[SM_JOB_RUNNING], "successful",
                               t.n[SM_JOB_SUCCESSFUL], "failed", t.n[SM_JOB_FAILED], "dismissed",
                               t.n[SM_JOB_DISMISSED], "unknown", t.unknown);
    json_t *links = json_array();
    json_array_append_new(links, json_pack("{s:s,s:s,s:s}", "href", self, "rel", "self", "type",
                                           "application/json"));
    if (model->state == SM_JOB_SUCCESSFUL)
        json_array_append_new(links, json_pack("{s:s,s:s,s:s}", "href", model_href, "rel",
                                               "http://www.opengis.net/def/rel/ogc/1.0/results",
                                               "type", "application/json"));
    json_t *doc = json_pack("{s:s,s:s,s:s,s:i,s:o,s:O,s:o,s:o,s:o,s:o}", "batchID", model->id,
                            "status", batch_status(model, &t), "message", model->message,
                            "progress", (int)(progress + 0.5), "eta", eta, "modelAlign",
                            json_object_get(batch, "align"), "counts", counts, "targets", targets,
                            "model", smd_status_document(model), "links", links);
    /* round K of a client's --template-from (smd_batch_request.h) */
    json_t *tf = json_object_get(batch, "template_from");
    if (doc && tf)
        json_object_set(doc, "templateFrom", tf);
    return doc;
}

/* The model job of batch req->id, visible to the requester, and its
 * description: 1, or 0 with the 404 answered into *r. */
static int find_batch(struct MHD_Connection *conn, smd_request *req, json_t **batch,
                      enum MHD_Result *r)
{
    smd_job model;
    int found = smd_jobs_find(req->srv, req->id, req->who.tenant, req->who.admin, &model) &&
                model.batch_model;
    *batch = found ? smd_batch_read(req->srv, req->id) : NULL;
    if (!*batch)
        *r = no_such_batch(conn, req);
    return *batch != NULL;
}

/* The batch document as it is now (its members' records are read under
 * the lock), or NULL when the model job is gone (or out of memory:
 * *gone 0). */
typedef struct document_ask {
    const json_t *batch;
    json_t *doc;
} document_ask;

static void document_of(smd_server *srv, const smd_job *model, void *ctx)
{
    document_ask *a = ctx;
    a->doc = smd_batch_document(srv, model, a->batch);
}

static json_t *document_now(smd_request *req, const json_t *batch, int *gone)
{
    document_ask a = {batch, NULL};
    *gone = !smd_jobs_inspect(req->srv, req->id, req->who.tenant, req->who.admin, document_of, &a);
    return a.doc;
}

enum MHD_Result smd_route_batch_get(struct MHD_Connection *conn, smd_request *req)
{
    json_t *batch;
    enum MHD_Result r;
    if (!find_batch(conn, req, &batch, &r))
        return r;
    int gone;
    json_t *doc = document_now(req, batch, &gone);
    json_decref(batch);
    if (gone)
        return no_such_batch(conn, req);
    return doc ? smd_reply_json(conn, req, 200, doc)
               : smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE, "out of memory");
}

/* ----------------------------------------------------------- create */

enum MHD_Result smd_route_batch_create(struct MHD_Connection *conn, smd_request *req)
{
    smd_server *srv = req->srv;
    if (atomic_load(&srv->draining) || atomic_load(&srv->unwritable))
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE,
                                 "the daemon takes no new job now (shutting down, or the spool "
                                 "cannot be written: see /readyz)");
    const char *ctype = MHD_lookup_connection_value(conn, MHD_HEADER_KIND, MHD_HTTP_HEADER_CONTENT_TYPE);
    if (!ctype || strncasecmp(ctype, "application/json", 16) != 0)
        return smd_reply_problem(conn, req, 415, SMD_PROBLEM_UNSUPPORTED_MEDIA,
                                 "POST /v1/batches takes application/json: {\"targets\": "
                                 "[{\"job\": ID, \"name\": NAME}, ...], \"model_align\": "
                                 "\"rigid\"}");
    const char *length = MHD_lookup_connection_value(conn, MHD_HEADER_KIND, MHD_HTTP_HEADER_CONTENT_LENGTH);
    uint64_t n;
    if (length && smd_parse_uint(length, 0, BATCH_BODY_MAX, &n) == SMD_NUM_RANGE)
        return smd_reply_problem(conn, req, 413, SMD_PROBLEM_TOO_LARGE,
                                 "the batch description exceeds %u bytes", BATCH_BODY_MAX);
    batch_body *b = calloc(1, sizeof *b);
    if (!b)
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE, "out of memory");
    b->body.max = BATCH_BODY_MAX;
    b->body.budget = req->srv->cfg.max_body_memory;
    req->body_state = b;
    return MHD_YES;
}

void smd_batches_body_free(void *body)
{
    batch_body *b = body;
    if (b)
        smd_body_release(&b->body);
    free(b);
}

/* Every member is a job of the requester's, not a batch, and
 * all of one dimension (*dim: the model job's, kept in its record). */
static unsigned check_members(smd_server *srv, const smd_request *req, const member *m, size_t n,
                              int *dim, char *msg, size_t cap)
{
    smd_job job;
    for (size_t i = 0; i < n; i++) {
        if (!smd_jobs_find(srv, m[i].id, req->who.tenant, req->who.admin, &job) ||
            job.batch_model || (job.owner[0] && strcmp(job.owner, req->who.tenant) != 0)) {
            snprintf(msg, cap, "targets[%zu].job: no job %s of yours (on this node) to put in a "
                     "batch", i, m[i].id);
            return 422;
        }
        if (i == 0)
            *dim = job.dim;
        else if (job.dim != *dim) {
            snprintf(msg, cap, "targets[%zu].job: job %s is %dD and targets[0] is %dD: a batch's "
                     "targets share the template", i, m[i].id, job.dim, *dim);
            return 422;
        }
    }
    return 0;
}

/* The model job's folder: job.json (its batch) and an empty inputs/. */
static int write_model_folder(const char *dir, const member *m, size_t n, const char *align,
                              const smd_batch_origin *origin)
{
    char inputs[PATH_MAX];
    if (smd_pathf(inputs, sizeof inputs, "%s/inputs", dir) != 0 || mkdir(inputs, 0750) != 0)
        return -1;
    smd_job_file *f = calloc(1, sizeof *f);
    json_t *list = json_array();
    for (size_t i = 0; list && i < n; i++)
        json_array_append_new(list, json_pack("{s:s,s:s}", "job", m[i].id, "name", m[i].name));
    if (f) {
        f->params = json_object();
        f->batch = json_pack("{s:s,s:o}", "align", align, "members", list);
        list = NULL;
        if (f->batch && origin->has)
            json_object_set_new(f->batch, "template_from", smd_batch_origin_json(origin));
    }
    int rc = f && f->params && f->batch ? smd_job_file_write(dir, f) : (errno = ENOMEM, -1);
    int saved = errno;
    json_decref(list);
    if (f)
        smd_job_file_free(f);
    free(f);
    errno = saved;
    return rc;
}

/* The description is valid: the model job is written and submitted. */
static enum MHD_Result create_batch(struct MHD_Connection *conn, smd_request *req, member *m,
                                    size_t n, const char *align,
                                    const smd_batch_origin *origin)
{
    smd_server *srv = req->srv;
    char msg[256], dir[PATH_MAX], id[SMD_ID_LEN + 1];
    int dim = 0;
    unsigned status = check_members(srv, req, m, n, &dim, msg, sizeof msg);
    /* the round before is a batch the requester sees (here, as the members) */
    smd_job prev;
    if (!status && origin->previous[0] &&
        !(smd_jobs_find(srv, origin->previous, req->who.tenant, req->who.admin, &prev) &&
          prev.batch_model)) {
        snprintf(msg, sizeof msg, "template_from.previous: no batch %s of yours (on this node)",
                 origin->previous);
        status = 422;
    }
    if (status)
        return smd_reply_problem(conn, req, status, SMD_PROBLEM_INVALID_INPUT, "%s", msg);
    if (smd_random_id(id) != 0)
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE,
                                 "no random source for the batch id: %s", strerror(errno));
    if (smd_pathf(dir, sizeof dir, "%s/up-XXXXXX", smd_store_tmp_dir(srv->store)) != 0 ||
        !mkdtemp(dir))
        return smd_reply_problem(conn, req, 507, SMD_PROBLEM_STORAGE,
                                 "cannot create a folder in the spool: %s", strerror(errno));
    char (*ids)[SMD_ID_LEN + 1] = calloc(n, sizeof *ids);
    for (size_t i = 0; ids && i < n; i++)
        memcpy(ids[i], m[i].id, sizeof ids[i]);
    if (!ids || write_model_folder(dir, m, n, align, origin) != 0) {
        int why = ids ? errno : ENOMEM;
        free(ids);
        smd_rmtree(dir);
        return smd_reply_problem(conn, req, 507, SMD_PROBLEM_STORAGE,
                                 "cannot write the batch's model job: %s", strerror(why));
    }
    smd_submission sub = {.dir = dir, .id = id, .owner = req->who.tenant, .dim = dim, .max_iter = 1,
                          .batch_model = 1,
                          .members = (const char (*)[SMD_ID_LEN + 1])ids, .nmembers = n};
    sm_error err;
    sm_error_clear(&err);
    smd_job model;
    int created = 0;
    sm_status st = smd_jobs_create(srv, &sub, &model, &created, &err);
    free(ids);
    json_t *batch = NULL, *doc = NULL;
    if (st == SM_OK) {
        batch = json_pack("{s:s,s:[]}", "align", align, "members");
        if (batch && origin->has)
            json_object_set_new(batch, "template_from", smd_batch_origin_json(origin));
        for (size_t i = 0; batch && i < n; i++)
            json_array_append_new(json_object_get(batch, "members"),
                                  json_pack("{s:s,s:s}", "job", m[i].id, "name", m[i].name));
        snprintf(req->id, sizeof req->id, "%s", model.id);
        int gone;
        doc = batch ? document_now(req, batch, &gone) : NULL;
    }
    json_decref(batch);
    if (st != SM_OK) {
        smd_rmtree(dir);
        smd_logf(&srv->log, SMD_LOG_ERROR, "store_error", "%s", err.msg);
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE,
                                 "cannot store the batch: %s; nothing was stored, retry later",
                                 err.msg);
    }
    smd_logf(&srv->log, SMD_LOG_INFO, "batch_created", "batch %s: %zu targets, align %s", id, n,
             align);
    if (!doc)
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE, "out of memory");
    char location[64];
    snprintf(location, sizeof location, "/v1/batches/%s", id);
    snprintf(req->id, sizeof req->id, "%s", id);
    char *text = sm_json_dumps(doc, 2);
    json_decref(doc);
    struct MHD_Response *resp =
        text ? smd_buffer_response(conn, req, "application/json", text, strlen(text)) : NULL;
    if (!resp)
        return MHD_NO;
    MHD_add_response_header(resp, MHD_HTTP_HEADER_LOCATION, location);
    return smd_reply(conn, req, 201, resp);
}

enum MHD_Result smd_batches_continue(struct MHD_Connection *conn, smd_request *req,
                                     const char *data, size_t *size)
{
    batch_body *b = req->body_state;
    if (*size == 0) {
        if (b->refused == SMD_BODY_TOO_LARGE)
            return smd_reply_problem(conn, req, 413, SMD_PROBLEM_TOO_LARGE,
                                     "the batch description exceeds %u bytes", BATCH_BODY_MAX);
        if (b->refused) {
            req->retry_after = 5;
            return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE, "%s",
                                     b->refused == SMD_BODY_BUSY
                                         ? "the daemon holds its --max-body-memory of request "
                                           "bodies already: try again shortly"
                                         : "out of memory");
        }
        member *m = NULL;
        size_t n = 0;
        char align[16], msg[512];
        smd_batch_origin origin;
        unsigned status = smd_batch_request_parse(b->body.buf ? b->body.buf : "", b->body.len,
                                                  req->srv->cfg.max_batch_targets, &m, &n, align,
                                                  &origin, msg, sizeof msg);
        smd_body_release(&b->body);
        if (status)
            return smd_reply_problem(conn, req, status,
                                     status == 413   ? SMD_PROBLEM_TOO_LARGE
                                     : status == 400 ? SMD_PROBLEM_BAD_REQUEST
                                     : status == 503 ? SMD_PROBLEM_UNAVAILABLE
                                                     : SMD_PROBLEM_INVALID_INPUT,
                                     "%s", msg);
        enum MHD_Result r = create_batch(conn, req, m, n, align, &origin);
        free(m);
        return r;
    }
    size_t n = *size;
    *size = 0;
    req->bytes_in += n;
    if (!b->refused)
        b->refused = smd_body_append(&b->body, data, n);
    if (b->refused) /* read and dropped; answered at the end */
        return req->bytes_in > smd_drain_limit(BATCH_BODY_MAX) ? MHD_NO : MHD_YES;
    return MHD_YES;
}

/* ----------------------------------------------------------- delete */

/* DELETE: a live batch is cancelled: the model job first (so that the
 * members' ends do not start it), then its live members; a final batch
 * is deleted: the model job, then the members it dismissed.  A member
 * another batch also groups, and one that ran to its end (successful or
 * failed), stays unless ?members=all (then every member is cancelled or
 * deleted with the batch).  The reply is the batch document after the
 * cancel, or the last one before the deletion. */
enum MHD_Result smd_route_batch_delete(struct MHD_Connection *conn, smd_request *req)
{
    smd_server *srv = req->srv;
    const char *which = MHD_lookup_connection_value(conn, MHD_GET_ARGUMENT_KIND, "members");
    if (which && strcmp(which, "all") != 0)
        return smd_reply_problem(conn, req, 400, SMD_PROBLEM_BAD_REQUEST,
                                 "members: expected \"all\" (every member goes with the batch) "
                                 "or nothing (only those it owns alone and that did not finish)");
    int all = which != NULL;
    json_t *batch;
    enum MHD_Result r;
    if (!find_batch(conn, req, &batch, &r))
        return r;
    smd_job model;
    int gone;
    int remove = smd_jobs_find(srv, req->id, req->who.tenant, req->who.admin, &model) &&
                 smd_job_state_final(model.state);
    json_t *doc = remove ? document_now(req, batch, &gone) : NULL;
    sm_error err;
    unsigned what = remove ? SMD_WITHDRAW_DELETE : SMD_WITHDRAW_CANCEL;
    smd_withdrawn w = smd_jobs_withdraw(srv, req->who.tenant, req->who.admin, req->id, what, NULL, &err);
    int failed = w == SMD_WITHDRAWN_REFUSED || w == SMD_WITHDRAWN_UNWRITABLE;
    json_t *v;
    size_t i;
    json_array_foreach(json_object_get(batch, "members"), i, v) {
        const char *id = json_string_value(json_object_get(v, "job"));
        if (!all && smd_jobs_shared(srv, req->id, id))
            continue;
        unsigned member_what = all ? what : remove ? SMD_WITHDRAW_DELETE | SMD_WITHDRAW_DISMISSED
                                                   : SMD_WITHDRAW_CANCEL;
        w = smd_jobs_withdraw(srv, req->who.tenant, req->who.admin, id, member_what, NULL, &err);
        failed |= w == SMD_WITHDRAWN_REFUSED || w == SMD_WITHDRAWN_UNWRITABLE;
    }
    if (!remove)
        doc = document_now(req, batch, &gone);
    json_decref(batch);
    if (failed) {
        json_decref(doc);
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE,
                                 "batch %s: some of its jobs could not be %s now (%s); try again",
                                 req->id, remove ? "deleted" : "cancelled", err.msg);
    }
    if (!doc)
        return no_such_batch(conn, req);
    if (remove)
        json_object_set_new(doc, "message", json_string("deleted"));
    return smd_reply_json(conn, req, 200, doc);
}

/* ------------------------------------------------------------ model */

/* The files of a model (proto/job/sm_job_model.h): 1 when name is one. */
static int model_file_name(const char *name, const char **media)
{
    static const struct { const char *name, *media; } fixed[] = {
        {"mean.mesh", "application/x-medit-mesh"}, {"mean.vtu", "application/vnd.vtk.vtu+xml"},
        {"modes.vtu", "application/vnd.vtk.vtu+xml"}, {"scores.csv", "text/csv"},
        {"summary.json", "application/json"}};
    for (size_t i = 0; i < sizeof fixed / sizeof fixed[0]; i++)
        if (strcmp(name, fixed[i].name) == 0) {
            *media = fixed[i].media;
            return 1;
        }
    /* mode_K.sol, K = 1..9999 without a leading zero */
    size_t n = strlen(name);
    if (n < 10 || n > 13 || strncmp(name, "mode_", 5) != 0 || strcmp(name + n - 4, ".sol") != 0 ||
        name[5] == '0')
        return 0;
    for (size_t i = 5; i < n - 4; i++)
        if (name[i] < '0' || name[i] > '9')
            return 0;
    *media = "application/x-medit-sol";
    return 1;
}

/* The model's results folder file: 1 and an open fd, or 0 with the reply
 * made (404 no batch, 409 not built). */
static int open_model_file(struct MHD_Connection *conn, smd_request *req, const char *name,
                           int *fd, enum MHD_Result *r)
{
    json_t *batch;
    if (!find_batch(conn, req, &batch, r))
        return 0;
    json_decref(batch);
    smd_job model;
    if (!smd_jobs_open_result(req->srv, req->id, req->who.tenant, req->who.admin, name, &model,
                              fd)) {
        *r = no_such_batch(conn, req);
        return 0;
    }
    if (model.state != SM_JOB_SUCCESSFUL) {
        *r = smd_reply_problem(conn, req, 409, SMD_PROBLEM_RESULT_NOT_READY,
                               "batch %s has no model (its model job is %s)", req->id,
                               sm_job_state_name(model.state));
        return 0;
    }
    if (*fd < 0) {
        *r = smd_reply_problem(conn, req, 404, SMD_PROBLEM_NOT_FOUND,
                               "batch %s's model has no %s", req->id, name);
        return 0;
    }
    return 1;
}

enum MHD_Result smd_route_batch_model(struct MHD_Connection *conn, smd_request *req)
{
    int fd;
    enum MHD_Result r;
    if (!open_model_file(conn, req, "summary.json", &fd, &r))
        return r;
    json_error_t jerr;
    FILE *f = fdopen(fd, "r");
    json_t *summary = f ? json_loadf(f, 0, &jerr) : NULL;
    if (f)
        fclose(f);
    else
        close(fd);
    if (!json_is_object(summary)) {
        json_decref(summary);
        return smd_reply_problem(conn, req, 500, SMD_PROBLEM_INTERNAL,
                                 "batch %s: the model's summary.json cannot be read", req->id);
    }
    /* links to every file of the model: the fixed ones and one per mode */
    json_t *files = json_array();
    static const char *const fixed[] = {"mean.mesh", "mean.vtu", "modes.vtu", "scores.csv",
                                        "summary.json"};
    char href[128];
    for (size_t i = 0; i < sizeof fixed / sizeof fixed[0]; i++) {
        snprintf(href, sizeof href, "/v1/batches/%s/model/%s", req->id, fixed[i]);
        json_array_append_new(files, json_pack("{s:s,s:s}", "name", fixed[i], "href", href));
    }
    size_t modes = json_array_size(json_object_get(summary, "variance_explained"));
    for (size_t k = 1; k <= modes && k <= 9999; k++) {
        char name[24];
        snprintf(name, sizeof name, "mode_%zu.sol", k);
        snprintf(href, sizeof href, "/v1/batches/%s/model/%s", req->id, name);
        json_array_append_new(files, json_pack("{s:s,s:s}", "name", name, "href", href));
    }
    return smd_reply_json(conn, req, 200, json_pack("{s:s,s:o,s:o}", "batchID", req->id,
                                                    "summary", summary, "files", files));
}

enum MHD_Result smd_route_batch_model_file(struct MHD_Connection *conn, smd_request *req)
{
    const char *media;
    if (!model_file_name(req->arg, &media))
        return smd_reply_problem(conn, req, 404, SMD_PROBLEM_NOT_FOUND,
                                 "no such model file: mean.mesh, mean.vtu, modes.vtu, "
                                 "mode_K.sol, scores.csv or summary.json");
    char name[24];
    snprintf(name, sizeof name, "%s", req->arg);
    int fd;
    enum MHD_Result r;
    if (!open_model_file(conn, req, name, &fd, &r))
        return r;
    struct stat st;
    struct MHD_Response *resp =
        fstat(fd, &st) == 0 ? MHD_create_response_from_fd((uint64_t)st.st_size, fd) : NULL;
    if (!resp) {
        close(fd);
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE, "out of memory");
    }
    req->bytes_out += (uint64_t)st.st_size;
    char disposition[96];
    snprintf(disposition, sizeof disposition, "attachment; filename=\"%s\"", name);
    MHD_add_response_header(resp, MHD_HTTP_HEADER_CONTENT_TYPE, media);
    MHD_add_response_header(resp, MHD_HTTP_HEADER_CONTENT_DISPOSITION, disposition);
    return smd_reply(conn, req, 200, resp);
}
