/* POST /v1/jobs/{id}/warp (see smd_warp.h). */
#include "api/smd_warp.h"

#include <errno.h>
#include <inttypes.h>
#include <limits.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <unistd.h>

#include "job/sm_job_map.h"
#include "shapematch/sm_io.h"
#include "shapematch/sm_surface.h"
#include "shapematch/sm_warp.h"
#include "sm_points_csv.h"
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
    int json;            /* BODY_JSON (kept for the points' answer) */
    int kind;            /* body_kind */
    int direction;       /* from the query; -1 not given */
    int strict;          /* from the query; -1 not given */
    int normalize;       /* from the query (fields) */
    const char *ext;     /* meshes: the answer's format (MESH_MEDIA_TABLE) */
    char *buf;
    size_t len, cap;
    int too_large;
};

static uint64_t body_limit(const smd_server *srv)
{
    return srv->cfg.max_upload < WARP_BODY_MAX ? srv->cfg.max_upload : WARP_BODY_MAX;
}

void smd_warp_body_free(smd_warp_body *b)
{
    if (!b)
        return;
    free(b->buf);
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
    pthread_mutex_lock(&srv->lock);
    smd_job *job = smd_store_get_visible(srv->store, req->id, req->who.tenant, req->who.admin);
    sm_job_state state = job ? job->state : SM_JOB_ACCEPTED;
    pthread_mutex_unlock(&srv->lock);
    if (!job)
        return smd_reply_problem(conn, req, 404, SMD_PROBLEM_NO_SUCH_JOB, "no job %s", req->id);
    if (state != SM_JOB_SUCCESSFUL) {
        const char *what = state == SM_JOB_ACCEPTED ? "is queued"
                           : state == SM_JOB_RUNNING ? "is running"
                           : state == SM_JOB_FAILED  ? "failed"
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
    if (direction == -2 || strict == -2 || normalize == -2)
        return smd_reply_problem(conn, req, 400, SMD_PROBLEM_BAD_REQUEST, "%s",
                                 direction == -2 ? "direction: expected forward or inverse"
                                 : strict == -2  ? "strict: expected true or false"
                                                 : "normalize: expected true or false");
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
    b->json = kind == BODY_JSON;
    b->kind = kind;
    b->normalize = normalize > 0;
    b->direction = direction;
    b->strict = strict;
    b->ext = ext;
    req->body_state = b;
    return MHD_YES;
}

/* ----------------------------------------------------------- JSON in */

/* The members of a JSON request into p, direction and strict.  0, or -1
 * with the 400's detail in msg. */
static int parse_json(const smd_warp_body *b, sm_points *p, int *direction, int *strict,
                      char *msg, size_t cap)
{
    json_error_t jerr;
    json_t *doc = json_loadb(b->buf, b->len, JSON_REJECT_DUPLICATES, &jerr);
    int rc = -1;
    if (!json_is_object(doc)) {
        snprintf(msg, cap, "the body is not a JSON object%s%s", doc ? "" : ": ",
                 doc ? "" : jerr.text);
        goto done;
    }
    json_t *d = json_object_get(doc, "direction"), *s = json_object_get(doc, "strict");
    json_t *pts = json_object_get(doc, "points");
    if (d && !(json_is_string(d) && (strcmp(json_string_value(d), "forward") == 0 ||
                                     strcmp(json_string_value(d), "inverse") == 0))) {
        snprintf(msg, cap, "direction: expected \"forward\" or \"inverse\"");
        goto done;
    }
    if (s && !json_is_boolean(s)) {
        snprintf(msg, cap, "strict: expected true or false");
        goto done;
    }
    if (d)
        *direction = strcmp(json_string_value(d), "inverse") == 0 ? SM_WARP_INVERSE
                                                                   : SM_WARP_FORWARD;
    if (s)
        *strict = json_is_true(s);
    size_t n = json_array_size(pts);
    if (!json_is_array(pts) || n == 0) {
        snprintf(msg, cap, "points: expected a non-empty array of [x, y] or [x, y, z]");
        goto done;
    }
    p->dim = (int)json_array_size(json_array_get(pts, 0));
    if (p->dim != 2 && p->dim != 3) {
        snprintf(msg, cap, "points[0]: expected 2 or 3 numbers");
        goto done;
    }
    if (!(p->xyz = malloc(n * (size_t)p->dim * sizeof *p->xyz))) {
        snprintf(msg, cap, "out of memory");
        goto done;
    }
    for (size_t i = 0; i < n; i++) {
        json_t *pt = json_array_get(pts, i);
        if (!json_is_array(pt) || json_array_size(pt) != (size_t)p->dim) {
            snprintf(msg, cap, "points[%zu]: expected %d numbers, as points[0]", i, p->dim);
            goto done;
        }
        for (int k = 0; k < p->dim; k++) {
            json_t *c = json_array_get(pt, (size_t)k);
            if (!json_is_number(c)) {
                snprintf(msg, cap, "points[%zu][%d]: not a number", i, k);
                goto done;
            }
            p->xyz[i * (size_t)p->dim + (size_t)k] = json_number_value(c);
        }
    }
    p->n = (int64_t)n;
    rc = 0;
done:
    json_decref(doc);
    return rc;
}

/* ---------------------------------------------------------------- map */

/* Reads the job's result map (job/sm_job_map.h): *m with the template
 * coordinates, and the deformed ones.  0, or -1 with msg; *gone when the
 * job was deleted since its state was read (its files are missing and
 * it is no longer there). */
static int load_map(smd_request *req, sm_mesh **m, double **deformed, int *gone, char *msg,
                    size_t cap)
{
    char dir[PATH_MAX];
    sm_error err;
    sm_error_clear(&err);
    *gone = 0;
    if (smd_store_path(req->srv->store, req->id, SMD_RESULTS_DIR, dir, sizeof dir) != 0) {
        snprintf(msg, cap, "path too long");
        return -1;
    }
    if (sm_job_map_read(dir, m, deformed, &err) == SM_OK)
        return 0;
    smd_server *srv = req->srv;
    pthread_mutex_lock(&srv->lock);
    *gone = err.code == SM_ERR_IO &&
            !smd_store_get_visible(srv->store, req->id, req->who.tenant, req->who.admin);
    pthread_mutex_unlock(&srv->lock);
    snprintf(msg, cap, "the results of job %s cannot be read: %s", req->id, err.msg);
    return -1;
}

/* ------------------------------------------------------------ answer */

static enum MHD_Result reply_points(struct MHD_Connection *conn, smd_request *req, int json,
                                    int direction, const sm_points *p, const double *out,
                                    const uint8_t *inside, int64_t noutside)
{
    char *body = NULL;
    size_t len = 0;
    if (json) {
        json_t *pts = json_array(), *in = json_array();
        for (int64_t i = 0; pts && in && i < p->n; i++) {
            const double *x = out + (size_t)i * (size_t)p->dim;
            json_array_append_new(pts, p->dim == 3 ? json_pack("[fff]", x[0], x[1], x[2])
                                                   : json_pack("[ff]", x[0], x[1]));
            json_array_append_new(in, json_integer(inside[i]));
        }
        json_t *doc = json_pack("{s:s,s:o*,s:o*,s:I}", "direction",
                                direction == SM_WARP_INVERSE ? "inverse" : "forward", "points",
                                pts, "inside", in, "outside", (json_int_t)noutside);
        body = doc ? json_dumps(doc, JSON_COMPACT | JSON_REAL_PRECISION(17)) : NULL;
        json_decref(doc);
        len = body ? strlen(body) : 0;
    } else {
        body = sm_points_csv_format(p, out, inside, &len);
    }
    if (!body)
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE, "out of memory");
    struct MHD_Response *resp =
        smd_buffer_response(conn, req, json ? JSON_MEDIA : CSV_MEDIA, body, len);
    if (!resp)
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE, "out of memory");
    return smd_reply(conn, req, 200, resp);
}

/* The points parsed; the map read and applied; the answer. */
static enum MHD_Result warp_answer(struct MHD_Connection *conn, smd_request *req,
                                   const smd_warp_body *b)
{
    char msg[600];
    sm_points p = {0};
    int direction = b->direction >= 0 ? b->direction : SM_WARP_FORWARD;
    int strict = b->strict > 0;
    sm_error err;
    sm_error_clear(&err);
    if (b->json ? parse_json(b, &p, &direction, &strict, msg, sizeof msg) != 0
                : sm_points_csv_parse(b->buf, b->len, 0, &p, &err) != SM_OK) {
        sm_points_release(&p);
        return smd_reply_problem(conn, req, 400, SMD_PROBLEM_BAD_REQUEST, "%s",
                                 b->json ? msg : err.msg);
    }
    sm_points_to_frame(&p, SM_POINTS_FRAME_LPS); /* Slicer's RAS markups */
    sm_mesh *m = NULL;
    double *deformed = NULL, *out = NULL;
    uint8_t *inside = NULL;
    sm_warp *w = NULL;
    int gone = 0;
    int64_t noutside = 0;
    enum MHD_Result r;
    if (load_map(req, &m, &deformed, &gone, msg, sizeof msg) != 0) {
        r = gone ? smd_reply_problem(conn, req, 404, SMD_PROBLEM_NO_SUCH_JOB, "no job %s", req->id)
                 : smd_reply_problem(conn, req, 500, SMD_PROBLEM_INTERNAL, "%s", msg);
        goto done;
    }
    if (p.dim != m->dim) {
        r = smd_reply_problem(conn, req, 422, SMD_PROBLEM_INVALID_INPUT,
                              "points: %dD points, and the map of job %s is %dD", p.dim, req->id,
                              m->dim);
        goto done;
    }
    out = malloc((size_t)p.n * (size_t)p.dim * sizeof *out);
    inside = malloc((size_t)p.n);
    if (!out || !inside ||
        sm_warp_new(m, deformed, 1u << direction, &w, &err) != SM_OK) {
        r = smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE, "%s",
                              err.msg[0] ? err.msg : "out of memory");
        goto done;
    }
    if (sm_points_warp(w, (sm_warp_direction)direction, strict, &p, b->json ? NULL : b->buf,
                       b->len, out, inside, &noutside, &err) != SM_OK) {
        r = smd_reply_problem(conn, req, 422, SMD_PROBLEM_INVALID_INPUT, "points: %s", err.msg);
        goto done;
    }
    r = reply_points(conn, req, b->json, direction, &p, out, inside, noutside);
done:
    sm_warp_free(w);
    free(out);
    free(inside);
    free(deformed);
    sm_mesh_free(m);
    sm_points_release(&p);
    return r;
}

/* ------------------------------------------------------ mesh, field */

/* A reader's message about the temporary file path, said of "the body". */
static const char *about_body(const char *msg, const char *path)
{
    size_t n = strlen(path);
    return strncmp(msg, path, n) == 0 ? msg + n : msg;
}

/* The body's vertices (n of them, dim coordinates) through the map
 * into a new *xyz; 0 or an HTTP status with msg. */
static unsigned warp_vertices(const smd_warp_body *b, int direction, const sm_mesh *m,
                              const double *deformed, int dim, int32_t n, const double *in,
                              double **xyz, char *msg, size_t cap)
{
    sm_warp *w = NULL;
    sm_error err;
    sm_error_clear(&err);
    unsigned status = 0;
    *xyz = NULL;
    if (dim != m->dim) {
        snprintf(msg, cap, "a %dD mesh, and the map is %dD", dim, m->dim);
        return 422;
    }
    if (!(*xyz = malloc(((size_t)n * (size_t)dim + 1) * sizeof **xyz)) ||
        sm_warp_new(m, deformed, 1u << direction, &w, &err) != SM_OK) {
        snprintf(msg, cap, "%s", err.msg[0] ? err.msg : "out of memory");
        status = 503;
    } else if (sm_warp_points(w, (sm_warp_direction)direction, b->strict > 0, n, in, *xyz, NULL,
                              NULL, &err) != SM_OK) {
        snprintf(msg, cap, "vertices: %s", err.msg);
        status = 422;
    }
    sm_warp_free(w);
    if (status) {
        free(*xyz);
        *xyz = NULL;
    }
    return status;
}

/* A mesh or surface body (the file in) warped into out (b->ext's
 * format): a volume mesh first (sm_mesh_read: Medit, Gmsh, VTK), a
 * surface when that fails (sm_surface_read: STL, OBJ, PLY, OFF, VTK,
 * Medit, Gmsh), as `shapematch warp --mesh` reads them.  0, or an HTTP
 * status with the detail in msg. */
static unsigned warp_mesh_body(smd_request *req, const smd_warp_body *b, int direction,
                               const sm_mesh *m, const double *deformed, const char *in,
                               const char *out, char *msg, size_t cap)
{
    sm_read_limits limits = {.max_inflated = WARP_BODY_MAX * 4};
    sm_mesh *body = NULL;
    sm_surface *surf = NULL;
    double *xyz = NULL;
    sm_error merr, serr;
    sm_error_clear(&merr);
    sm_error_clear(&serr);
    unsigned status = 0;
    int volume = sm_mesh_read_limited(in, &limits, &body, &merr) == SM_OK;
    if (!volume && !limits.hit && sm_surface_read_limited(in, &limits, &surf, &serr) != SM_OK) {
        snprintf(msg, cap, "the body is neither a mesh (%.250s) nor a surface (%.250s)",
                 about_body(merr.msg, in), about_body(serr.msg, in));
        return limits.hit ? 413 : 400;
    }
    if (limits.hit) {
        snprintf(msg, cap, "the body%s", about_body(merr.msg, in));
        return 413;
    }
    if (volume && strcmp(b->ext, "mesh") != 0 && strcmp(b->ext, "vtu") != 0) {
        snprintf(msg, cap, "the body is a volume mesh: answered as format=mesh or vtu, not %s",
                 b->ext);
        status = 422;
    } else if (volume) {
        status = warp_vertices(b, direction, m, deformed, body->dim, body->nverts, body->coords,
                               &xyz, msg, cap);
    } else {
        status = warp_vertices(b, direction, m, deformed, surf->dim, surf->nverts, surf->coords,
                               &xyz, msg, cap);
    }
    if (!status) {
        sm_error err;
        sm_error_clear(&err);
        sm_status st = !volume                       ? sm_surface_write(out, surf, xyz, &err)
                       : strcmp(b->ext, "vtu") == 0 ? sm_vtu_write(out, body, xyz, NULL, NULL, &err)
                                                     : sm_mesh_write_coords(out, body, xyz, &err);
        if (st != SM_OK) {
            snprintf(msg, cap, "%s", about_body(err.msg, out));
            status = st == SM_ERR_INVALID ? 422 : 500;
        }
    }
    (void)req;
    free(xyz);
    sm_mesh_free(body);
    sm_surface_free(surf);
    return status;
}

/* The mesh or field of the body (the file in), warped into the file
 * out; 0, or an HTTP status with the detail in msg. */
static unsigned warp_file(smd_request *req, const smd_warp_body *b, int direction,
                          const char *in, const char *out, char *msg, size_t cap)
{
    sm_mesh *m = NULL;
    sm_sol *sol = NULL;
    double *deformed = NULL;
    sm_warp *w = NULL;
    sm_error err;
    sm_error_clear(&err);
    int gone = 0;
    unsigned status = 0;
    if (load_map(req, &m, &deformed, &gone, msg, cap) != 0) {
        status = gone ? 404 : 500;
        goto done;
    }
    if (b->kind == BODY_FIELD) {
        if (sm_sol_read(in, &sol, &err) != SM_OK) {
            snprintf(msg, cap, "the body%s", about_body(err.msg, in));
            status = 400;
        } else if (sol->nverts != m->nverts || sol->dim != m->dim) {
            snprintf(msg, cap, "the field is %dD on %ld vertices; the map of job %s is %dD on %ld",
                     sol->dim, (long)sol->nverts, req->id, m->dim, (long)m->nverts);
            status = 422;
        } else if (sm_warp_new(m, deformed, 0, &w, &err) != SM_OK ||
                   sm_warp_field(w, (sm_warp_direction)direction, sol->ncomp, b->normalize,
                                 sol->values, &err) != SM_OK ||
                   sm_sol_write(out, sol, &err) != SM_OK) {
            snprintf(msg, cap, "%s", err.msg);
            status = 500;
        }
        goto done;
    }
    status = warp_mesh_body(req, b, direction, m, deformed, in, out, msg, cap);
done:
    sm_warp_free(w);
    sm_sol_free(sol);
    free(deformed);
    sm_mesh_free(m);
    return status;
}

/* The body to a temporary file, warped into another, sent back (a field
 * as Medit ASCII .sol, a mesh or surface in b->ext's format). */
static enum MHD_Result warp_file_answer(struct MHD_Connection *conn, smd_request *req,
                                        const smd_warp_body *b)
{
    char in[PATH_MAX], out[PATH_MAX], msg[700];
    int direction = b->direction >= 0 ? b->direction : SM_WARP_FORWARD;
    const char *ext = b->kind == BODY_FIELD ? "sol" : b->ext;
    if (smd_pathf(in, sizeof in, "%s/warp-XXXXXX", smd_store_tmp_dir(req->srv->store)) != 0 ||
        smd_pathf(out, sizeof out, "%s.out.%s", in, ext) != 0)
        return smd_reply_problem(conn, req, 500, SMD_PROBLEM_INTERNAL, "path too long");
    int fd = mkstemp(in);
    if (fd < 0)
        return smd_reply_problem(conn, req, 500, SMD_PROBLEM_STORAGE,
                                 "cannot create a temporary file: %s", strerror(errno));
    size_t done = 0;
    while (done < b->len) {
        ssize_t k = write(fd, b->buf + done, b->len - done);
        if (k < 0 && errno == EINTR)
            continue;
        if (k <= 0)
            break;
        done += (size_t)k;
    }
    close(fd);
    memcpy(out, in, strlen(in)); /* the same folder and random part as in */
    unsigned status = done < b->len ? 500 : 0;
    if (status)
        snprintf(msg, sizeof msg, "cannot write a temporary file: %s", strerror(errno));
    else
        status = warp_file(req, b, direction, in, out, msg, sizeof msg);
    char *body = NULL;
    size_t len = 0;
    if (!status && smd_read_file(out, SIZE_MAX / 2, &body, &len) != 0) {
        status = 500;
        snprintf(msg, sizeof msg, "cannot read the warped %s back", ext);
    }
    unlink(in);
    unlink(out);
    if (status == 404)
        return smd_reply_problem(conn, req, 404, SMD_PROBLEM_NO_SUCH_JOB, "no job %s", req->id);
    if (status)
        return smd_reply_problem(conn, req, status,
                                 status == 400   ? SMD_PROBLEM_BAD_REQUEST
                                 : status == 413 ? SMD_PROBLEM_TOO_LARGE
                                 : status == 422 ? SMD_PROBLEM_INVALID_INPUT
                                 : status == 503 ? SMD_PROBLEM_UNAVAILABLE
                                                 : SMD_PROBLEM_INTERNAL,
                                 "%s", msg);
    const char *media = SOL_MEDIA;
    for (size_t i = 0; b->kind != BODY_FIELD && i < NMESH_MEDIA; i++)
        if (strcmp(MESH_MEDIA_TABLE[i].ext, ext) == 0) {
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
        if (b->too_large)
            return smd_reply_problem(conn, req, 413, SMD_PROBLEM_TOO_LARGE,
                                     "the points exceed the limit of %" PRIu64
                                     " bytes (--max-upload, at most 64 MiB)", limit);
        return b->kind == BODY_MESH || b->kind == BODY_FIELD ? warp_file_answer(conn, req, b)
                                                            : warp_answer(conn, req, b);
    }
    size_t n = *size;
    *size = 0;
    req->bytes_in += n;
    if (b->too_large || b->len + n > limit) {
        /* read the rest without keeping it, answer at the end (a body far
         * past the limit is cut by closing the connection) */
        b->too_large = 1;
        free(b->buf);
        b->buf = NULL;
        b->len = b->cap = 0;
        return req->bytes_in > smd_drain_limit(req->srv->cfg.max_upload) ? MHD_NO : MHD_YES;
    }
    if (b->len + n > b->cap) {
        size_t ncap = b->cap ? b->cap : 65536;
        while (ncap < b->len + n)
            ncap *= 2;
        char *grown = realloc(b->buf, ncap);
        if (!grown) {
            b->too_large = 1; /* answered 413: the daemon cannot hold it */
            return MHD_YES;
        }
        b->buf = grown;
        b->cap = ncap;
    }
    memcpy(b->buf + b->len, data, n);
    b->len += n;
    return MHD_YES;
}
