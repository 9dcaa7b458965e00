/* Streaming multipart uploads of POST /v1/jobs (see smd_upload.h). */
#include "api/smd_upload.h"
#include "store/spool/smd_store.h"

#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <limits.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include "job/sm_job_inputs.h"
#include "sm_json.h"
#include "sm_proto_params.h"
#include "sm_proto_vocab.h"
#include "sm_proto_text.h"
#include "jobs/smd_jobs.h"
#include "shapematch/sm_clock.h"
#include "jobs/smd_check.h"
#include "http/smd_conns.h"
#include "worker/smd_job_file.h"
#include "api/smd_parts.h"
#include "jobs/smd_usecases.h"
#include "http/smd_ratelimit.h"
#include "api/smd_routes.h"
#include "worker/smd_worker.h"



enum { CHECK_NONE = 0, CHECK_RUNNING, CHECK_DONE };

struct smd_upload {
    struct MHD_PostProcessor *pp;
    char dir[PATH_MAX];            /* SPOOL/tmp/up-XXXXXX */
    int committed;                 /* dir became a job: do not remove */
    uint64_t received;
    smd_parts parts;               /* names, files, params, hashes, first error */
    char idempotency_key[SMD_IDEMPOTENCY_KEY_MAX + 1];
    char limit_key[SMD_RATELIMIT_KEY_MAX + 1]; /* tenant or address (smd_ratelimit.h) */
    sm_read_limits limits;         /* of the daemon's flags */
    /* the acceptance check (smd_check.h), run while the connection is
     * suspended: check_state goes NONE -> RUNNING -> DONE */
    atomic_int check_state;
    struct MHD_Connection *conn;
    smd_check_result check;
    smd_check_pool *checks;        /* set when a check was submitted: settled at free */
    const smd_upload_decoder *dec; /* a body other than multipart, NULL none */
    void *dec_cls;
    int dec_ended;                 /* dec->end called (once, at the body's end) */
    char created_header[2][64];    /* an extra header of the 201, "" none */
};

int smd_idempotency_key_valid(const char *key)
{
    size_t n = key ? strlen(key) : 0;
    if (n == 0 || n > SMD_IDEMPOTENCY_KEY_MAX)
        return 0;
    for (size_t i = 0; i < n; i++)
        if ((unsigned char)key[i] < 0x21 || (unsigned char)key[i] > 0x7e)
            return 0;
    return 1;
}

void smd_upload_fail(smd_upload *u, unsigned status, const char *type, const char *fmt, ...)
{
    char detail[sizeof u->parts.err_detail];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(detail, sizeof detail, fmt, ap);
    va_end(ap);
    smd_parts_fail(&u->parts, status, type, "%s", detail);
}

void smd_upload_created_header(smd_upload *u, const char *name, const char *value)
{
    snprintf(u->created_header[0], sizeof u->created_header[0], "%s", name);
    snprintf(u->created_header[1], sizeof u->created_header[1], "%s", value);
}

void smd_upload_part(smd_upload *u, const char *name, const void *data, size_t n)
{
    smd_parts_on_part(&u->parts, MHD_POSTDATA_KIND, name, NULL, NULL, NULL, data, 0, n);
}

static enum MHD_Result reply_existing(struct MHD_Connection *conn, smd_request *req,
                                      smd_job *job);

/* A job found by its Idempotency-Key: the same request is replayed, a
 * different one refused (the IETF httpapi idempotency draft's 422). */
static enum MHD_Result reply_keyed(struct MHD_Connection *conn, smd_request *req, smd_job *job,
                                   uint64_t hash)
{
    if (job->request_hash && job->request_hash != hash)
        return smd_reply_problem(conn, req, 422, SMD_PROBLEM_IDEMPOTENCY_MISMATCH,
                                 "Idempotency-Key \"%s\" was used for job %s with a different "
                                 "request; use a new key for a new request",
                                 job->idempotency_key, job->id);
    return reply_existing(conn, req, job);
}

static enum MHD_Result reply_error(struct MHD_Connection *conn, smd_request *req, smd_upload *u)
{
    return smd_reply_problem(conn, req, u->parts.err_status, u->parts.err_type, "%s", u->parts.err_detail);
}

/* The answer to a submission: the job's status document (doc, taken
 * over; NULL out of memory), its Location, and one more header when
 * header is not NULL or "" (201 for a new job, 200 for a replay). */
static enum MHD_Result reply_status(struct MHD_Connection *conn, smd_request *req, unsigned status,
                                    const char *id, json_t *doc, const char *header,
                                    const char *value)
{
    char location[64];
    snprintf(location, sizeof location, "/v1/jobs/%s", id);
    snprintf(req->id, sizeof req->id, "%s", id);
    char *text = doc ? sm_json_dumps(doc, 2) : NULL;
    json_decref(doc);
    if (!text)
        return MHD_NO;
    struct MHD_Response *resp = smd_buffer_response(conn, req, "application/json", text, strlen(text));
    if (!resp)
        return MHD_NO;
    MHD_add_response_header(resp, MHD_HTTP_HEADER_LOCATION, location);
    if (header && header[0])
        MHD_add_response_header(resp, header, value);
    return smd_reply(conn, req, status, resp);
}

static enum MHD_Result reply_existing(struct MHD_Connection *conn, smd_request *req, smd_job *job)
{
    /* job: a copy (smd_job_view) */
    return reply_status(conn, req, MHD_HTTP_OK, job->id, smd_status_document(job),
                        "Idempotent-Replayed", "true");
}

/* ------------------------------------------------------------ limits */

/* The key of the submitter's limits: its tenant, or its client address
 * when the daemon has no tokens. */
static void limit_key(struct MHD_Connection *conn, const smd_request *req, char *key, size_t cap)
{
    if (req->srv->tokens) {
        snprintf(key, cap, "t:%s", req->who.tenant);
        return;
    }
    char addr[64];
    smd_conn_address(conn, addr, sizeof addr);
    smd_ratelimit_address_key(addr, req->srv->cfg.submit_ipv4_prefix, key, cap);
}

/* The limiter's tracked jobs of a key, counted by live() (smd_jobs_unfinished). */
typedef struct tracked {
    smd_ratelimit *rl;
    const char *key;
} tracked;

static size_t count_tracked(void *ctx, int (*live)(const char *id, void *arg), void *arg)
{
    tracked *t = ctx;
    return smd_ratelimit_live(t->rl, t->key, live, arg);
}

/* Unfinished jobs of the key: by owner with tokens, else the jobs the
 * limiter saw the address submit. */
static size_t unfinished_jobs(smd_server *srv, const smd_request *req, const char *key)
{
    tracked t = {srv->ratelimit, key};
    return smd_jobs_unfinished(srv, srv->tokens ? req->who.tenant : NULL, count_tracked, &t);
}

static const char *limit_subject(const smd_server *srv)
{
    return srv->tokens ? "tenant" : "client address";
}

/* 429 when the key holds --max-queued unfinished jobs. */
static enum MHD_Result queued_refusal(struct MHD_Connection *conn, smd_request *req,
                                      const char *key, int *refused)
{
    smd_server *srv = req->srv;
    size_t n = srv->cfg.max_queued ? unfinished_jobs(srv, req, key) : 0;
    *refused = srv->cfg.max_queued && n >= srv->cfg.max_queued;
    if (!*refused)
        return MHD_YES;
    req->retry_after = 5;
    return smd_reply_problem(conn, req, 429, SMD_PROBLEM_TOO_MANY,
                             "this %s has %zu unfinished jobs, the limit is %u (the daemon's "
                             "--max-queued): retry when one of them ends",
                             limit_subject(srv), n, srv->cfg.max_queued);
}

/* The two submission limits at the start of a request: 429 before the
 * body is read.  *refused says whether a reply was made. */
static enum MHD_Result limits_refusal(struct MHD_Connection *conn, smd_request *req,
                                      const char *key, int *refused)
{
    smd_server *srv = req->srv;
    enum MHD_Result r = queued_refusal(conn, req, key, refused);
    if (*refused)
        return r;
    unsigned wait = smd_ratelimit_take(srv->ratelimit, key, sm_clock_seconds());
    *refused = wait > 0;
    if (!wait)
        return MHD_YES;
    req->retry_after = wait;
    return smd_reply_problem(conn, req, 429, SMD_PROBLEM_TOO_MANY,
                             "this %s submitted %u jobs in the last %g s, the limit (the daemon's "
                             "--submit-rate and --submit-window): retry in %u s",
                             limit_subject(srv), srv->cfg.submit_rate, srv->cfg.submit_window, wait);
}

/* ---------------------------------------------------------- requests */

/* The upload's checks and folder, then its body decoder: multipart
 * (dec NULL), or dec for a body of content type ctype_prefix (415 with
 * ctype_detail otherwise). */
static enum MHD_Result begin(struct MHD_Connection *conn, smd_request *req, const char *ctype_prefix,
                             const char *ctype_detail, const smd_upload_decoder *dec, void *dec_cls)
{
    smd_server *srv = req->srv;
    if (atomic_load(&srv->draining))
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE,
                                 "the daemon is shutting down and accepts no new job");
    if (atomic_load(&srv->unwritable))
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE,
                                 "a job record could not be written (disk full?): no new job "
                                 "until the spool takes writes again (see /readyz)");
    const char *length = MHD_lookup_connection_value(conn, MHD_HEADER_KIND, MHD_HTTP_HEADER_CONTENT_LENGTH);
    uint64_t n;
    int lrc = length ? smd_parse_uint(length, 0, srv->cfg.max_upload, &n) : SMD_NUM_OK;
    if (lrc == SMD_NUM_RANGE)
        return smd_reply_problem(conn, req, 413, SMD_PROBLEM_TOO_LARGE,
                                 "the request body (%.40s bytes) exceeds the limit of %" PRIu64
                                 " bytes (--max-upload)",
                                 length, srv->cfg.max_upload);
    const char *ctype = MHD_lookup_connection_value(conn, MHD_HEADER_KIND, MHD_HTTP_HEADER_CONTENT_TYPE);
    if (!ctype || strncasecmp(ctype, ctype_prefix, strlen(ctype_prefix)) != 0)
        return smd_reply_problem(conn, req, 415, SMD_PROBLEM_UNSUPPORTED_MEDIA, "%s", ctype_detail);
    const char *key = MHD_lookup_connection_value(conn, MHD_HEADER_KIND, "Idempotency-Key");
    if (key && !smd_idempotency_key_valid(key))
        return smd_reply_problem(conn, req, 400, SMD_PROBLEM_BAD_REQUEST,
                                 "Idempotency-Key must be 1 to %d visible ASCII characters",
                                 SMD_IDEMPOTENCY_KEY_MAX);
    char lkey[SMD_RATELIMIT_KEY_MAX + 1];
    limit_key(conn, req, lkey, sizeof lkey);
    int refused;
    enum MHD_Result lr = limits_refusal(conn, req, lkey, &refused);
    if (refused)
        return lr;
    /* a known key is answered after the body (same request or not) */
    smd_upload *u = calloc(1, sizeof *u);
    if (!u)
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE, "out of memory");
    smd_parts_init(&u->parts, u->dir);
    memcpy(u->limit_key, lkey, sizeof u->limit_key);
    u->limits = (sm_read_limits){.max_inflated = srv->cfg.max_inflated,
                                 .max_vertices = (int64_t)srv->cfg.max_vertices,
                                 .max_elements = (int64_t)srv->cfg.max_elements};
    if (key)
        snprintf(u->idempotency_key, sizeof u->idempotency_key, "%s", key);
    char inputs[PATH_MAX];
    if (smd_pathf(u->dir, sizeof u->dir, "%s/up-XXXXXX", smd_store_tmp_dir(srv->store)) != 0 ||
        !mkdtemp(u->dir)) {
        u->dir[0] = '\0';
        smd_upload_free(u);
        return smd_reply_problem(conn, req, 507, SMD_PROBLEM_STORAGE,
                                 "cannot create an upload folder in the spool: %s", strerror(errno));
    }
    if (smd_pathf(inputs, sizeof inputs, "%s/inputs", u->dir) != 0 || mkdir(inputs, 0750) != 0) {
        smd_upload_free(u);
        return smd_reply_problem(conn, req, 507, SMD_PROBLEM_STORAGE,
                                 "cannot create an upload folder in the spool: %s", strerror(errno));
    }
    u->dec = dec;
    u->dec_cls = dec_cls;
    if (!dec)
        u->pp = MHD_create_post_processor(conn, 65536, smd_parts_on_part, &u->parts);
    if (!dec && !u->pp) {
        smd_upload_free(u);
        return smd_reply_problem(conn, req, 400, SMD_PROBLEM_BAD_MULTIPART,
                                 "malformed multipart/form-data Content-Type (missing boundary?)");
    }
    req->upload = u;
    return MHD_YES;
}

enum MHD_Result smd_upload_begin(struct MHD_Connection *conn, smd_request *req)
{
    return begin(conn, req, "multipart/form-data",
                 "POST /v1/jobs takes multipart/form-data with the parts " SMD_UPLOAD_PARTS
                 " (e.g. curl -F)",
                 NULL, NULL);
}

enum MHD_Result smd_upload_begin_decoded(struct MHD_Connection *conn, smd_request *req,
                                         const char *ctype, const char *ctype_detail,
                                         const smd_upload_decoder *dec, void *dec_cls)
{
    enum MHD_Result r = begin(conn, req, ctype, ctype_detail, dec, dec_cls);
    if (!req->upload)
        dec->free(dec_cls); /* refused: the decoder was not taken */
    return r;
}

/* What the check built, kept under inputs/checked/ beside the uploads so
 * that it travels with the job (PostgreSQL stores inputs/ whole) and
 * named in job.json with the key of what it was built from: the
 * generated background and distance (a surface target without
 * target_mesh and without alignment: the worker would build the same),
 * and the template meshed from template_surface or template_image with
 * its figures (nglib's meshing, seconds for a few thousand vertices).
 * Nothing kept of what cannot be written (the worker builds it): the
 * check's verdict does not depend on it. */
static void keep_checked(smd_upload *u, const sm_job_inputs *in, smd_job_file *f)
{
    const int bg_kept = in->background_generated && in->has_surface && in->background &&
                        in->distance && !in->target_deferred;
    const int tmpl_kept = in->template_made.source != SM_TEMPLATE_GIVEN && in->template_mesh;
    if (!bg_kept && !tmpl_kept)
        return;
    static const char bg_rel[] = "inputs/checked/background.meshb";
    static const char d_rel[] = "inputs/checked/distance.solb";
    static const char t_rel[] = "inputs/checked/template.meshb";
    char dir[PATH_MAX], bg[PATH_MAX], d[PATH_MAX], t[PATH_MAX];
    sm_error err;
    if (smd_pathf(dir, sizeof dir, "%s/inputs/checked", u->dir) != 0 ||
        smd_pathf(bg, sizeof bg, "%s/%s", u->dir, bg_rel) != 0 ||
        smd_pathf(d, sizeof d, "%s/%s", u->dir, d_rel) != 0 ||
        smd_pathf(t, sizeof t, "%s/%s", u->dir, t_rel) != 0 ||
        (mkdir(dir, 0750) != 0 && errno != EEXIST) ||
        smd_job_file_inputs_key(u->dir, f, f->checked_key) != 0) {
        f->checked_key[0] = '\0';
        return;
    }
    if (bg_kept && sm_mesh_write(bg, in->background, &err) == SM_OK &&
        sm_sol_write(d, in->distance, &err) == SM_OK) {
        snprintf(f->checked_background, sizeof f->checked_background, "%s", bg_rel);
        snprintf(f->checked_distance, sizeof f->checked_distance, "%s", d_rel);
    }
    if (tmpl_kept && (f->checked_template_made = sm_job_template_made_to_json(&in->template_made)) &&
        sm_mesh_write(t, in->template_mesh, &err) == SM_OK)
        snprintf(f->checked_template, sizeof f->checked_template, "%s", t_rel);
    if (!f->checked_background[0] && !f->checked_template[0])
        f->checked_key[0] = '\0';
}

/* Writes job.json: inputs and canonical params (with the background
 * members the job gave, for the worker's sm_job_inputs_load).  0, or -1
 * with errno set. */
static int write_job_file(smd_upload *u, const sm_job_inputs *in)
{
    smd_job_file *f = calloc(1, sizeof *f); /* 16 KiB of paths */
    /* no clamp asked: the worker chooses the same default ball again,
     * and says so in the job's warnings */
    sm_params asked = in->params;
    if (in->clamp_default)
        asked.clamp = SM_CLAMP_AUTO;
    if (!f || !(f->params = sm_job_params_to_jansson(&asked, &in->background_asked, in->dim))) {
        free(f);
        errno = ENOMEM;
        return -1;
    }
    size_t prefix = strlen(u->dir) + 1; /* paths relative to the job folder */
    for (int i = 0; i < SM_PART_PARAMS; i++)
        if (u->parts.seen[i])
            snprintf(f->part[i], sizeof f->part[i], "%s", u->parts.path[i] + prefix);
    keep_checked(u, in, f);
    int rc = smd_job_file_write(u->dir, f);
    int saved = errno;
    smd_job_file_free(f);
    free(f);
    errno = saved;
    return rc;
}

/* An input beyond one of the configured bounds: 413 naming the flag. */
static enum MHD_Result limit_refused(struct MHD_Connection *conn, smd_request *req, int hit,
                                     const char *msg)
{
    const char *flag = hit == SM_LIMIT_INFLATED   ? "--max-inflated"
                       : hit == SM_LIMIT_VERTICES ? "--max-vertices"
                                                  : "--max-elements";
    return smd_reply_problem(conn, req, 413, SMD_PROBLEM_TOO_LARGE,
                             "%s (the daemon's %s; its operator can raise it%s)", msg, flag,
                             hit == SM_LIMIT_INFLATED ? "" : ", or --memory-limit");
}

/* The stored file of a part, NULL when the request has none. */
static const char *file_of(const smd_upload *u, sm_part id)
{
    return u->parts.seen[id] ? u->parts.path[id] : NULL;
}

/* ------------------------------------------------------ the check */

/* In the check's child process (smd_check.h): reads and checks every
 * input within the limits, writes job.json, sends back the summary. */
static void check_in_child(void *arg, smd_check_result *out)
{
    smd_upload *u = arg;
    sm_job_inputs in;
    sm_error err;
    sm_error_clear(&err);
    sm_read_limits limits = u->limits;
    sm_job_files files = {.template_mesh = file_of(u, SM_PART_TEMPLATE),
                          .template_surface = file_of(u, SM_PART_TEMPLATE_SURFACE),
                          .template_image = file_of(u, SM_PART_TEMPLATE_IMAGE),
                          .target_mesh = file_of(u, SM_PART_TARGET_MESH),
                          .target_sol = file_of(u, SM_PART_TARGET_SOL),
                          .target_surface = file_of(u, SM_PART_TARGET_SURFACE),
                          .target_image = file_of(u, SM_PART_TARGET_IMAGE),
                          .landmarks_template = file_of(u, SM_PART_TEMPLATE_LANDMARKS),
                          .landmarks_target = file_of(u, SM_PART_TARGET_LANDMARKS),
                          .limits = &limits};
    out->status = sm_job_inputs_load(&files, u->parts.params ? u->parts.params : "", u->parts.params_len, &in, &err);
    if (out->status != SM_OK) {
        out->limit_hit = limits.hit;
        snprintf(out->msg, sizeof out->msg, "%s", err.msg);
        return;
    }
    out->dim = in.dim;
    out->max_iter = in.params.max_iter;
    out->tol_boundary = in.params.tol_boundary;
    out->nverts = in.template_mesh->nverts;
    out->nelems = in.template_mesh->nelems;
    if (write_job_file(u, &in) != 0) {
        out->status = SM_ERR_IO;
        out->storage = 1;
        snprintf(out->msg, sizeof out->msg, "cannot write job.json: %s", strerror(errno));
    }
    sm_job_inputs_free(&in);
}

/* In a check thread: the result is in; the handler answers next. */
static void check_done(void *user)
{
    smd_upload *u = user;
    atomic_store(&u->check_state, CHECK_DONE);
    MHD_resume_connection(u->conn);
}

/* The body is complete and its parts are known: the connection waits,
 * suspended, while a check thread checks the inputs. */
static enum MHD_Result start_check(struct MHD_Connection *conn, smd_request *req, smd_upload *u)
{
    u->conn = conn;
    atomic_store(&u->check_state, CHECK_RUNNING);
    MHD_suspend_connection(conn);
    int rc = smd_check_submit_from(req->srv->checks, u->limit_key, check_in_child, u, &u->check,
                                   check_done, u);
    if (rc == 0) {
        u->checks = req->srv->checks;
    } else {
        memset(&u->check, 0, sizeof u->check);
        u->check.status = SM_ERR_NOMEM;
        u->check.busy = 1;
        if (rc == -2)
            snprintf(u->check.msg, sizeof u->check.msg, "%d uploads of this client are waiting "
                     "for their acceptance check: retry when they are answered",
                     SMD_CHECK_WAITING_PER_CLIENT);
        else
            snprintf(u->check.msg, sizeof u->check.msg, "%d uploads are waiting for their "
                     "acceptance check: retry in a few seconds", SMD_CHECK_QUEUE_MAX);
        check_done(u);
    }
    return MHD_YES;
}

/* The check's verdict when it refused the upload. */
static enum MHD_Result check_refused(struct MHD_Connection *conn, smd_request *req,
                                     const smd_check_result *r)
{
    const smd_config *cfg = &req->srv->cfg;
    if (r->timed_out)
        return smd_reply_problem(conn, req, 422, SMD_PROBLEM_INVALID_INPUT,
                                 "the acceptance check of this upload took longer than %g s (the "
                                 "daemon's --check-timeout; its operator can raise it)",
                                 cfg->check_timeout);
    if (r->crashed)
        return smd_reply_problem(conn, req, 500, SMD_PROBLEM_INTERNAL,
                                 "the acceptance check of this upload stopped (signal %d)",
                                 r->signal);
    if (r->busy) {
        /* a slot frees within one --check-timeout at most */
        double wait = cfg->check_timeout < 1    ? 1
                      : cfg->check_timeout > 60 ? 60
                                                : cfg->check_timeout;
        req->retry_after = (unsigned)wait;
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE, "%s", r->msg);
    }
    if (r->shutdown)
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE, "%s", r->msg);
    if (r->storage)
        return smd_reply_problem(conn, req, 507, SMD_PROBLEM_STORAGE, "%s", r->msg);
    if (r->limit_hit)
        return limit_refused(conn, req, r->limit_hit, r->msg);
    if (r->status == SM_ERR_IO)
        return smd_reply_problem(conn, req, 500, SMD_PROBLEM_INTERNAL, "%s", r->msg);
    return smd_reply_problem(conn, req, 422, SMD_PROBLEM_INVALID_INPUT, "%s", r->msg);
}

/* The check accepted the inputs (job.json written): the job is submitted
 * and 201 answered. */
static enum MHD_Result submit_checked(struct MHD_Connection *conn, smd_request *req, smd_upload *u)
{
    smd_server *srv = req->srv;
    const smd_check_result *r = &u->check;
    uint64_t hash = smd_parts_hash(&u->parts);
    sm_error err;
    sm_error_clear(&err);
    char id[SMD_ID_LEN + 1];
    if (smd_random_id(id) != 0)
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE,
                                 "no random source for the job id: %s", strerror(errno));
    smd_submission sub = {.dir = u->dir, .id = id, .idempotency_key = u->idempotency_key,
                          .owner = req->who.tenant, .name = u->parts.name, .request_hash = hash,
                          .dim = r->dim, .max_iter = r->max_iter, .tol_boundary = r->tol_boundary,
                          .nverts = r->nverts, .nelems = r->nelems, .bytes = u->received};
    smd_job view;
    int created;
    int refused;
    enum MHD_Result qr = queued_refusal(conn, req, u->limit_key, &refused);
    const char *key = sub.idempotency_key && sub.idempotency_key[0] ? sub.idempotency_key : NULL;
    int known = !refused && key && smd_jobs_find_key(srv, sub.owner, key, &view);
    if (refused) /* concurrent uploads of the same key got there first */
        return qr;
    if (known)
        return reply_keyed(conn, req, &view, hash); /* a retry */
    sm_status st = smd_jobs_create(srv, &sub, &view, &created, &err);
    if (st == SM_OK && !created) /* a concurrent retry with the same key won the race */
        return reply_keyed(conn, req, &view, hash);
    if (st != SM_OK) {
        smd_logf(&srv->log, SMD_LOG_ERROR, "store_error", "%s", err.msg);
        char why[256];
        if (!smd_backend_ready(srv->backend, why, sizeof why)) {
            /* the backend is down (a database), not full: the client may retry */
            req->retry_after = 5;
            return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE,
                                     "%s: nothing was stored, retry later (see /readyz)", why);
        }
        return smd_reply_problem(conn, req, 507, SMD_PROBLEM_STORAGE, "cannot store the job: %s",
                                 err.msg);
    }
    u->committed = 1;
    if (!srv->tokens)
        smd_ratelimit_track(srv->ratelimit, u->limit_key, view.id);
    memcpy(req->id, view.id, sizeof req->id);
    return reply_status(conn, req, MHD_HTTP_CREATED, id, smd_status_document(&view),
                        u->created_header[0], u->created_header[1]);
}

static enum MHD_Result finish_upload(struct MHD_Connection *conn, smd_request *req, smd_upload *u)
{
    smd_server *srv = req->srv;
    int state = atomic_load(&u->check_state);
    if (state == CHECK_DONE)
        return u->check.status == SM_OK ? submit_checked(conn, req, u)
                                        : check_refused(conn, req, &u->check);
    if (state == CHECK_RUNNING)
        return MHD_YES; /* not called while suspended; kept for safety */
    smd_parts_close(&u->parts);
    if (u->pp) {
        enum MHD_Result clean = MHD_destroy_post_processor(u->pp);
        u->pp = NULL;
        if (clean != MHD_YES)
            smd_parts_fail(&u->parts, 400, SMD_PROBLEM_BAD_MULTIPART,
                 "malformed or truncated multipart/form-data body (no closing boundary)");
    }
    if (u->parts.err_status)
        return reply_error(conn, req, u);
    if (smd_parts_check(&u->parts) != 0)
        return reply_error(conn, req, u);
    if (smd_parts_name_files(&u->parts) != 0)
        return reply_error(conn, req, u);

    uint64_t hash = smd_parts_hash(&u->parts);
    smd_job known;
    if (u->idempotency_key[0] &&
        smd_jobs_find_key(srv, req->who.tenant, u->idempotency_key, &known))
        return reply_keyed(conn, req, &known, hash);
    return start_check(conn, req, u);
}

enum MHD_Result smd_upload_continue(struct MHD_Connection *conn, smd_request *req,
                                    const char *data, size_t *size)
{
    smd_upload *u = req->upload;
    if (*size == 0 && u->dec && !u->dec_ended && !u->parts.err_status) {
        u->dec_ended = 1;
        u->dec->end(u->dec_cls, u);
    }
    if (*size == 0)
        return finish_upload(conn, req, u);
    size_t n = *size;
    *size = 0;
    req->bytes_in += n;
    u->received += n;
    uint64_t limit = req->srv->cfg.max_upload;
    if (u->received > limit && !u->parts.err_status) {
        smd_parts_fail(&u->parts, 413, SMD_PROBLEM_TOO_LARGE,
             "the request body exceeds the limit of %" PRIu64 " bytes (--max-upload)", limit);
        smd_parts_close(&u->parts);
    }
    if (u->parts.err_status) {
        /* libmicrohttpd only lets a reply be queued before the body or
         * after all of it: read the rest without keeping it, and answer at
         * the end.  A body that goes on far past the limit is cut by
         * closing the connection instead (the client sees no reply). */
        if (u->received > smd_drain_limit(limit))
            return MHD_NO;
        return MHD_YES;
    }
    if (u->dec)
        u->dec->piece(u->dec_cls, u, data, n);
    else if (MHD_post_process(u->pp, data, n) != MHD_YES)
        smd_parts_fail(&u->parts, 400, SMD_PROBLEM_BAD_MULTIPART, "malformed multipart/form-data body");
    if (u->parts.err_status)
        smd_parts_close(&u->parts);
    return MHD_YES;
}

void smd_upload_free(smd_upload *u)
{
    if (!u)
        return;
    if (u->pp)
        MHD_destroy_post_processor(u->pp);
    smd_parts_release(&u->parts);
    if (!u->committed && u->dir[0])
        smd_rmtree(u->dir);
    smd_check_settled(u->checks);
    if (u->dec)
        u->dec->free(u->dec_cls);
    free(u);
}
