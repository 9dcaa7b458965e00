/* POST /v1/jobs/{id}/warp (see smd_warp.h). */
#include "api/smd_warp.h"

#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <limits.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <unistd.h>

#include "jobs/smd_check.h"
#include "jobs/smd_usecases.h"
#include "base/smd_body.h"
#include "job/sm_job_warp.h"
#include "sm_proto_vocab.h"
#include "store/spool/smd_store.h"
#include "worker/smd_worker.h"

/* The points are held in memory (parsed whole, then their images and
 * the answer): at most this much, whatever --max-upload allows multipart
 * uploads (as the OGC execute request, smd_ogc.c). */
#define WARP_BODY_MAX ((uint64_t)64 << 20)

#define CSV_MEDIA "text/csv"
#define JSON_MEDIA "application/json"
#define MESH_MEDIA "application/x-medit-mesh"
#define MESHB_MEDIA "application/x-medit-meshb"
#define SOL_MEDIA "application/x-medit-sol"
#define SOLB_MEDIA "application/x-medit-solb"

/* What the body holds, by its Content-Type. */
enum body_kind { BODY_CSV, BODY_JSON, BODY_MESH, BODY_FIELD };

/* Meshes and surfaces: the media types read (the content decides the
 * reader) and the format each is answered in unless format= says
 * otherwise; the same table names the answer's media type. */
static const struct mesh_media {
    const char *media, *ext;
} MESH_MEDIA_TABLE[] = {
    {MESH_MEDIA, "mesh"},           {MESHB_MEDIA, "mesh"},         {"model/stl", "stl"},
    {"model/obj", "obj"},           {"model/x-ply", "ply"},        {"model/x-off", "off"},
    {"application/x-vtk", "vtk"},   {"application/x-vtu", "vtu"},
};
#define NMESH_MEDIA (sizeof MESH_MEDIA_TABLE / sizeof MESH_MEDIA_TABLE[0])

struct smd_warp_body {
    int kind;            /* body_kind */
    int direction;       /* from the query; -1 not given */
    int strict;          /* from the query; -1 not given */
    int outside;         /* from the query (sm_job_warp_outside; points) */
    int normalize;       /* from the query (fields) */
    const char *ext;     /* meshes: the answer's format (MESH_MEDIA_TABLE) */
    smd_body body;       /* counted in --max-body-memory (base/smd_body.h) */
    int refused;         /* SMD_BODY_*: the rest is read and dropped */
    /* the warp, in a check child (jobs/smd_check.h): NONE -> RUNNING ->
     * DONE while the connection is suspended */
    struct MHD_Connection *conn;
    atomic_int state;
    smd_check_pool *checks; /* settled when the request goes */
    smd_check_result check;
    char results[PATH_MAX];  /* the job's results folder */
    char in[PATH_MAX];       /* the body as a file (meshes, fields) */
    char out[PATH_MAX];      /* the answer, written by the child */
    sm_read_limits limits;   /* the daemon's --max-inflated, --max-vertices, ... */
};

enum { WARP_NONE = 0, WARP_RUNNING, WARP_DONE };
/* smd_check_result.stage when the job's map could not be read (beyond
 * sm_job_warp_stage's steps) */
#define STAGE_MAP_OPEN 100

static uint64_t body_limit(const smd_server *srv)
{
    return srv->cfg.max_upload < WARP_BODY_MAX ? srv->cfg.max_upload : WARP_BODY_MAX;
}

void smd_warp_body_free(smd_warp_body *b)
{
    if (!b)
        return;
    smd_body_release(&b->body);
    if (b->in[0])
        unlink(b->in);
    if (b->out[0])
        unlink(b->out);
    smd_check_settled(b->checks);
    free(b);
}

/* ------------------------------------------------------------ request */

/* direction=forward|inverse, strict=true|false|1|0; -1 when absent;
 * -2 when malformed. */
static int query_direction(struct MHD_Connection *conn)
{
    const char *v = MHD_lookup_connection_value(conn, MHD_GET_ARGUMENT_KIND, "direction");
    if (!v)
        return -1;
    return strcmp(v, "forward") == 0 ? SM_WARP_FORWARD
           : strcmp(v, "inverse") == 0 ? SM_WARP_INVERSE
                                       : -2;
}

static int query_bool(struct MHD_Connection *conn, const char *name)
{
    const char *v = MHD_lookup_connection_value(conn, MHD_GET_ARGUMENT_KIND, name);
    if (!v)
        return -1;
    return strcmp(v, "true") == 0 || strcmp(v, "1") == 0    ? 1
           : strcmp(v, "false") == 0 || strcmp(v, "0") == 0 ? 0
                                                            : -2;
}

/* The media type of the Content-Type header without its parameters
 * matches type (case-insensitive). */
static int media_is(const char *ctype, const char *type)
{
    size_t n = strlen(type);
    if (!ctype || strncasecmp(ctype, type, n) != 0)
        return 0;
    return ctype[n] == '\0' || ctype[n] == ';' || ctype[n] == ' ';
}

enum MHD_Result smd_route_warp(struct MHD_Connection *conn, smd_request *req)
{
    smd_server *srv = req->srv;
    if (atomic_load(&srv->draining)) { /* the check children are about to stop */
        req->retry_after = 5;
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE,
                                 "shutting down: no new warp is computed");
    }
    smd_job view;
    if (!smd_jobs_find(srv, req->id, req->who.tenant, req->who.admin, &view))
        return smd_reply_problem(conn, req, 404, SMD_PROBLEM_NO_SUCH_JOB, "no job %s", req->id);
    if (view.state != SM_JOB_SUCCESSFUL) {
        const char *what = view.state == SM_JOB_ACCEPTED ? "is queued"
                           : view.state == SM_JOB_RUNNING ? "is running"
                           : view.state == SM_JOB_FAILED  ? "failed"
                                                     : "was dismissed";
        return smd_reply_problem(conn, req, 409, SMD_PROBLEM_RESULT_NOT_READY,
                                 "job %s %s: it has no map to warp through (only a successful "
                                 "job has)", req->id, what);
    }
    const char *ctype =
        MHD_lookup_connection_value(conn, MHD_HEADER_KIND, MHD_HTTP_HEADER_CONTENT_TYPE);
    const char *ext = NULL;
    for (size_t i = 0; i < NMESH_MEDIA && !ext; i++)
        if (media_is(ctype, MESH_MEDIA_TABLE[i].media))
            ext = MESH_MEDIA_TABLE[i].ext;
    int kind = media_is(ctype, CSV_MEDIA)    ? BODY_CSV
               : media_is(ctype, JSON_MEDIA) ? BODY_JSON
               : ext                         ? BODY_MESH
               : media_is(ctype, SOL_MEDIA) || media_is(ctype, SOLB_MEDIA) ? BODY_FIELD
                                                                           : -1;
    if (kind < 0)
        return smd_reply_problem(conn, req, 415, SMD_PROBLEM_UNSUPPORTED_MEDIA,
                                 "the body is points (" CSV_MEDIA ", " JSON_MEDIA "), a mesh ("
                                 MESH_MEDIA ", " MESHB_MEDIA "), a surface (model/stl, "
                                 "model/obj, model/x-ply, model/x-off, application/x-vtk, "
                                 "application/x-vtu) or a field (" SOL_MEDIA ", " SOLB_MEDIA
                                 "); Content-Type '%.100s'", ctype ? ctype : "none");
    const char *format = MHD_lookup_connection_value(conn, MHD_GET_ARGUMENT_KIND, "format");
    if (format) {
        const char *asked = NULL;
        for (size_t i = 0; i < NMESH_MEDIA && !asked; i++)
            if (strcmp(format, MESH_MEDIA_TABLE[i].ext) == 0)
                asked = MESH_MEDIA_TABLE[i].ext;
        if (!asked || kind != BODY_MESH)
            return smd_reply_problem(conn, req, 400, SMD_PROBLEM_BAD_REQUEST,
                                     "format: %s", kind != BODY_MESH
                                         ? "only for a mesh or surface body"
                                         : "expected mesh, vtu, stl, obj, ply, off or vtk");
        ext = asked;
    }
    int direction = query_direction(conn), strict = query_bool(conn, "strict");
    int normalize = query_bool(conn, "normalize");
    const char *outside_name = MHD_lookup_connection_value(conn, MHD_GET_ARGUMENT_KIND,
                                                           "outside");
    int outside = outside_name ? sm_job_warp_outside_from_name(outside_name) : 0;
    if (direction == -2 || strict == -2 || normalize == -2 || outside < 0)
        return smd_reply_problem(conn, req, 400, SMD_PROBLEM_BAD_REQUEST, "%s",
                                 direction == -2 ? "direction: expected forward or inverse"
                                 : strict == -2  ? "strict: expected true or false"
                                 : outside < 0   ? "outside: expected " SM_JOB_WARP_OUTSIDE_NAMES
                                                 : "normalize: expected true or false");
    if (outside > 0 && kind != BODY_CSV && kind != BODY_JSON)
        return smd_reply_problem(conn, req, 400, SMD_PROBLEM_BAD_REQUEST, "outside: %s is for "
                                 "points (a mesh's vertices outside are extrapolated, or refused "
                                 "with strict)", outside_name);
    const char *length =
        MHD_lookup_connection_value(conn, MHD_HEADER_KIND, MHD_HTTP_HEADER_CONTENT_LENGTH);
    uint64_t n = 0;
    if (length && smd_parse_uint(length, 0, UINT64_MAX, &n) == SMD_NUM_OK &&
        n > body_limit(srv))
        return smd_reply_problem(conn, req, 413, SMD_PROBLEM_TOO_LARGE,
                                 "the points exceed the limit of %" PRIu64 " bytes (--max-upload, "
                                 "at most 64 MiB)", body_limit(srv));
    smd_warp_body *b = calloc(1, sizeof *b);
    if (!b)
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE, "out of memory");
    b->kind = kind;
    b->body.max = (size_t)body_limit(srv);
    b->body.budget = srv->cfg.max_body_memory;
    b->limits = (sm_read_limits){.max_inflated = srv->cfg.max_inflated < WARP_BODY_MAX * 4
                                                     ? srv->cfg.max_inflated
                                                     : WARP_BODY_MAX * 4,
                                 .max_vertices = (int64_t)srv->cfg.max_vertices,
                                 .max_elements = (int64_t)srv->cfg.max_elements};
    b->normalize = normalize > 0;
    b->direction = direction;
    b->strict = strict;
    b->outside = outside;
    b->ext = ext;
    req->body_state = b;
    return MHD_YES;
}

/* -------------------------------------------------- in the check child */

/* The whole of buf into path; 0 or -1 (errno). */
static int write_all(const char *path, const char *buf, size_t len)
{
    int fd = open(path, O_WRONLY | O_TRUNC | O_CLOEXEC);
    if (fd < 0)
        return -1;
    size_t done = 0;
    while (done < len) {
        ssize_t k = write(fd, buf + done, len - done);
        if (k < 0 && errno == EINTR)
            continue;
        if (k <= 0)
            break;
        done += (size_t)k;
    }
    int saved = errno;
    if (close(fd) != 0 && done == len)
        return -1;
    errno = saved;
    return done == len ? 0 : -1;
}

/* The warp itself (job/sm_job_warp.h), in a child process of the check
 * pool (forked, --check-timeout, --memory-limit): the body parsed, the
 * job's map read, the answer written to b->out.  Only what the reply
 * needs crosses back in out. */
static void warp_in_child(void *arg, smd_check_result *out)
{
    smd_warp_body *b = arg;
    sm_error err;
    sm_error_clear(&err);
    sm_warp_direction dir = b->direction == SM_WARP_INVERSE ? SM_WARP_INVERSE : SM_WARP_FORWARD;
    sm_read_limits limits = b->limits;
    sm_job_warp_request rq = {.direction = dir, .strict = b->strict > 0,
                              .outside = (sm_job_warp_outside)b->outside,
                              .normalize = b->normalize, .limits = &limits,
                              .max_points = limits.max_vertices, .name = "the body"};
    sm_job_warp_report rep;
    memset(&rep, 0, sizeof rep);
    sm_job_map *map = NULL;
    char *answer = NULL;
    size_t len = 0;
    sm_status st;
    int points = b->kind == BODY_CSV || b->kind == BODY_JSON;
    if (!points && write_all(b->in, b->body.buf ? b->body.buf : "", b->body.len) != 0) {
        st = sm_error_set(&err, SM_ERR_IO, "cannot write a temporary file: %s", strerror(errno));
        rep.stage = STAGE_MAP_OPEN;
    } else if ((st = sm_job_map_open(b->results, b->kind == BODY_FIELD ? 0u : 1u << dir, &map,
                                     &err)) != SM_OK) {
        rep.stage = STAGE_MAP_OPEN;
    } else if (points) {
        rq.name = NULL;
        st = sm_job_warp_points_text(map, b->kind == BODY_JSON, b->body.buf ? b->body.buf : "",
                                     b->body.len, &rq, &answer, &len, &rep, &err);
        if (st == SM_OK && write_all(b->out, answer, len) != 0) {
            st = sm_error_set(&err, SM_ERR_IO, "cannot write the answer: %s", strerror(errno));
            rep.stage = SM_JOB_WARP_OUTPUT;
        }
    } else if (b->kind == BODY_FIELD) {
        st = sm_job_warp_field_file(map, b->in, b->out, &rq, NULL, &rep, &err);
    } else {
        st = sm_job_warp_mesh_file(map, b->in, b->out, &rq, NULL, &rep, &err);
    }
    free(answer);
    sm_job_map_free(map);
    out->status = st;
    out->stage = (int)rep.stage;
    out->limit_hit = limits.hit;
    if (points && rep.stage == SM_JOB_WARP_INPUT && st == SM_ERR_NOMEM)
        out->limit_hit = SM_LIMIT_VERTICES; /* more points than --max-vertices */
    if (st != SM_OK) {
        /* the body's temporary names are no one's business */
        const char *msg = err.msg;
        size_t n = strlen(b->out);
        if (strncmp(msg, b->out, n) == 0)
            msg += n;
        snprintf(out->msg, sizeof out->msg, "%s", msg);
    }
}

/* In a check thread: the warp is done; the handler answers next. */
static void warp_done(void *user)
{
    smd_warp_body *b = user;
    atomic_store(&b->state, WARP_DONE);
    MHD_resume_connection(b->conn);
}

/* The body is in: temporary names made, the connection suspended while a
 * check child warps. */
static enum MHD_Result start_warp(struct MHD_Connection *conn, smd_request *req,
                                  smd_warp_body *b)
{
    const char *tmp = smd_store_tmp_dir(req->srv->store);
    const char *ext = b->kind == BODY_FIELD ? "sol" : b->kind == BODY_MESH ? b->ext : "answer";
    if (smd_store_path(req->srv->store, req->id, SMD_RESULTS_DIR, b->results,
                       sizeof b->results) != 0 ||
        smd_pathf(b->in, sizeof b->in, "%s/warp-XXXXXX", tmp) != 0) {
        b->in[0] = '\0';
        return smd_reply_problem(conn, req, 500, SMD_PROBLEM_INTERNAL, "path too long");
    }
    int fd = mkstemp(b->in);
    if (fd < 0) {
        int saved = errno;
        b->in[0] = '\0';
        return smd_reply_problem(conn, req, 500, SMD_PROBLEM_STORAGE,
                                 "cannot create a temporary file: %s", strerror(saved));
    }
    close(fd);
    if (smd_pathf(b->out, sizeof b->out, "%s.out.%s", b->in, ext) != 0) {
        b->out[0] = '\0';
        return smd_reply_problem(conn, req, 500, SMD_PROBLEM_INTERNAL, "path too long");
    }
    fd = open(b->out, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600); /* for write_all */
    if (fd < 0) {
        int saved = errno;
        b->out[0] = '\0';
        return smd_reply_problem(conn, req, 500, SMD_PROBLEM_STORAGE,
                                 "cannot create a temporary file: %s", strerror(saved));
    }
    close(fd);
    b->conn = conn;
    atomic_store(&b->state, WARP_RUNNING);
    MHD_suspend_connection(conn);
    if (smd_check_submit(req->srv->checks, warp_in_child, b, &b->check, warp_done, b) == 0) {
        b->checks = req->srv->checks;
    } else {
        memset(&b->check, 0, sizeof b->check);
        b->check.status = SM_ERR_NOMEM;
        b->check.shutdown = 1;
        snprintf(b->check.msg, sizeof b->check.msg,
                 "%d uploads and warps are waiting for a check slot: retry in a few seconds",
                 SMD_CHECK_QUEUE_MAX);
        warp_done(b);
    }
    return MHD_YES;
}

/* ------------------------------------------------------------ answer */

/* The limit that refused the body, named as the upload check names it. */
static enum MHD_Result limit_refused(struct MHD_Connection *conn, smd_request *req, int hit,
                                     const char *msg)
{
    const char *flag = hit == SM_LIMIT_INFLATED   ? "--max-inflated"
                       : hit == SM_LIMIT_VERTICES ? "--max-vertices"
                                                  : "--max-elements";
    return smd_reply_problem(conn, req, 413, SMD_PROBLEM_TOO_LARGE,
                             "%s (the daemon's %s; its operator can raise it)", msg, flag);
}

/* The child's verdict when it refused or failed. */
static enum MHD_Result warp_refused(struct MHD_Connection *conn, smd_request *req,
                                    const smd_check_result *r)
{
    smd_server *srv = req->srv;
    if (r->timed_out)
        return smd_reply_problem(conn, req, 422, SMD_PROBLEM_INVALID_INPUT,
                                 "the warp took longer than %g s (the daemon's --check-timeout; "
                                 "its operator can raise it)", srv->cfg.check_timeout);
    if (r->crashed)
        return smd_reply_problem(conn, req, 500, SMD_PROBLEM_INTERNAL,
                                 "the warp stopped (signal %d)", r->signal);
    if (r->shutdown) {
        req->retry_after = 5;
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE, "%s", r->msg);
    }
    if (r->stage == STAGE_MAP_OPEN) {
        int gone = r->status == SM_ERR_IO &&
                   !smd_jobs_find(srv, req->id, req->who.tenant, req->who.admin, NULL);
        if (gone)
            return smd_reply_problem(conn, req, 404, SMD_PROBLEM_NO_SUCH_JOB, "no job %s", req->id);
        return smd_reply_problem(conn, req, 500, SMD_PROBLEM_INTERNAL,
                                 "the results of job %s cannot be read: %s", req->id, r->msg);
    }
    if (r->limit_hit)
        return limit_refused(conn, req, r->limit_hit, r->msg);
    switch (r->stage) {
    case SM_JOB_WARP_INPUT:
        if (r->status == SM_ERR_NOMEM) /* what the body declares is out of bounds */
            return smd_reply_problem(conn, req, 413, SMD_PROBLEM_TOO_LARGE, "%s", r->msg);
        return smd_reply_problem(conn, req, r->status == SM_ERR_IO ? 500 : 400,
                                 r->status == SM_ERR_IO ? SMD_PROBLEM_INTERNAL
                                                        : SMD_PROBLEM_BAD_REQUEST,
                                 "%s", r->msg);
    case SM_JOB_WARP_FORMAT:
        return smd_reply_problem(conn, req, 422, SMD_PROBLEM_INVALID_INPUT, "%s", r->msg);
    case SM_JOB_WARP_MAP:
        if (r->status == SM_ERR_NOMEM) {
            req->retry_after = 5;
            return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE, "%s", r->msg);
        }
        return smd_reply_problem(conn, req, 422, SMD_PROBLEM_INVALID_INPUT, "%s", r->msg);
    default:
        return smd_reply_problem(conn, req, r->status == SM_ERR_INVALID ? 422 : 500,
                                 r->status == SM_ERR_INVALID ? SMD_PROBLEM_INVALID_INPUT
                                                             : SMD_PROBLEM_INTERNAL,
                                 "%s", r->msg);
    }
}

/* The answer the child wrote, sent back: the points in the request's
 * type, a field as Medit ASCII .sol, a mesh or surface in b->ext's
 * format. */
static enum MHD_Result warp_answer(struct MHD_Connection *conn, smd_request *req,
                                   const smd_warp_body *b)
{
    if (b->check.status != SM_OK)
        return warp_refused(conn, req, &b->check);
    char *body = NULL;
    size_t len = 0;
    if (smd_read_file(b->out, SIZE_MAX / 2, &body, &len) != 0)
        return smd_reply_problem(conn, req, 500, SMD_PROBLEM_INTERNAL,
                                 "cannot read the warped answer back: %s", strerror(errno));
    const char *media = b->kind == BODY_CSV    ? CSV_MEDIA
                        : b->kind == BODY_JSON ? JSON_MEDIA
                                               : SOL_MEDIA;
    for (size_t i = 0; b->kind == BODY_MESH && i < NMESH_MEDIA; i++)
        if (strcmp(MESH_MEDIA_TABLE[i].ext, b->ext) == 0) {
            media = MESH_MEDIA_TABLE[i].media; /* the first: .mesh is Medit ASCII */
            break;
        }
    struct MHD_Response *resp = smd_buffer_response(conn, req, media, body, len);
    if (!resp)
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE, "out of memory");
    return smd_reply(conn, req, 200, resp);
}

enum MHD_Result smd_warp_continue(struct MHD_Connection *conn, smd_request *req, const char *data,
                                  size_t *size)
{
    smd_warp_body *b = req->body_state;
    uint64_t limit = body_limit(req->srv);
    if (*size == 0) {
        int state = atomic_load(&b->state);
        if (state == WARP_DONE)
            return warp_answer(conn, req, b);
        if (state == WARP_RUNNING)
            return MHD_YES; /* not called while suspended; kept for safety */
        if (b->refused == SMD_BODY_TOO_LARGE)
            return smd_reply_problem(conn, req, 413, SMD_PROBLEM_TOO_LARGE,
                                     "the points exceed the limit of %" PRIu64
                                     " bytes (--max-upload, at most 64 MiB)", limit);
        if (b->refused) {
            req->retry_after = 5;
            return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE,
                                     "the daemon holds %" PRIu64 " bytes of request bodies "
                                     "already (its --max-body-memory): try again shortly",
                                     b->body.budget);
        }
        return start_warp(conn, req, b);
    }
    size_t n = *size;
    *size = 0;
    req->bytes_in += n;
    if (!b->refused)
        b->refused = smd_body_append(&b->body, data, n);
    /* a refused body is read without keeping it and answered at the end
     * (a body far past the limit is cut by closing the connection) */
    if (b->refused)
        return req->bytes_in > smd_drain_limit(req->srv->cfg.max_upload) ? MHD_NO : MHD_YES;
    return MHD_YES;
}
