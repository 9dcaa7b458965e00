/* GET /v1/jobs/{id}/results[/mesh|/displacement|/history|/snapshots[/{n}]].
 *
 * The worker writes every format once (results/, see smd_worker.h), so
 * serving is a matter of choosing a file: by ?format=, else by Accept,
 * else the first (default) format.  Files go out with sendfile, or
 * through a streaming gzip encoder when Accept-Encoding allows gzip, so a
 * large result never sits in memory.
 *
 * Snapshots (params.save_every = K > 0): the worker writes the mesh of the
 * first state (iteration 0), every K iterations and of the final state to
 * results/snapshots/iter-NNNNN.mesh; /results/snapshots
 * lists them (read from the folder, names parsed strictly), and
 * /results/snapshots/{n} serves one, its file name built from the number
 * parsed out of the path, never from the path itself.  They are results
 * like the others: served once the job is successful. */
#include <ctype.h>
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include "sm_payload.h"
#include "sm_proto_vocab.h"
#include "http/smd_negotiate.h"
#include "store/spool/smd_store.h"
#include "api/smd_results.h"
#include "jobs/smd_usecases.h"
#include "worker/smd_worker.h"

/* proto's table of result formats (sm_proto_vocab.h), by kind: the
 * default format of each kind first */
typedef sm_result_format result_format;
static const result_format *const mesh_formats = &sm_result_formats[0];
static const result_format *const displacement_formats = &sm_result_formats[4];
static const result_format *const history_formats = &sm_result_formats[6];
/* the file is per iteration (SM_SNAPSHOT_FORMAT) */
static const result_format snapshot_formats[] = {
    {SM_RESULT_MESH, "mesh", SM_SNAPSHOT_MEDIA, NULL},
};

/* Iterations in URLs: a decimal number without sign or leading zero, at
 * most this many digits (the core's iteration count is an int). */
#define SNAPSHOT_ITERATION_DIGITS 9

/* ---------------------------------------------------- streaming gzip */

typedef struct gz_stream {
    int fd;
    z_stream z;
    int eof, done;
    uint64_t *bytes_out;
    unsigned char in[65536];
} gz_stream;

static ssize_t gz_read(void *cls, uint64_t pos, char *buf, size_t max)
{
    gz_stream *g = cls;
    (void)pos;
    if (g->done)
        return MHD_CONTENT_READER_END_OF_STREAM;
    g->z.next_out = (Bytef *)buf;
    g->z.avail_out = (uInt)(max > (1u << 30) ? (1u << 30) : max);
    uInt avail = g->z.avail_out;
    while (g->z.avail_out > 0) {
        if (g->z.avail_in == 0 && !g->eof) {
            ssize_t n = read(g->fd, g->in, sizeof g->in);
            if (n < 0 && errno == EINTR)
                continue;
            if (n < 0)
                return MHD_CONTENT_READER_END_WITH_ERROR;
            if (n == 0)
                g->eof = 1;
            g->z.next_in = g->in;
            g->z.avail_in = (uInt)n;
        }
        int rc = deflate(&g->z, g->eof ? Z_FINISH : Z_NO_FLUSH);
        if (rc == Z_STREAM_END) {
            g->done = 1;
            break;
        }
        if (rc != Z_OK && rc != Z_BUF_ERROR)
            return MHD_CONTENT_READER_END_WITH_ERROR;
        if (g->z.avail_out < avail && g->z.avail_in == 0 && !g->eof)
            break; /* hand over what we have before reading more */
    }
    size_t produced = avail - g->z.avail_out;
    if (g->bytes_out)
        *g->bytes_out += produced;
    if (produced == 0 && g->done)
        return MHD_CONTENT_READER_END_OF_STREAM;
    return (ssize_t)produced;
}

static void gz_free(void *cls)
{
    gz_stream *g = cls;
    deflateEnd(&g->z);
    close(g->fd);
    free(g);
}

static struct MHD_Response *gzip_file_response(int fd, uint64_t *bytes_out)
{
    gz_stream *g = calloc(1, sizeof *g);
    if (!g)
        return NULL;
    if (deflateInit2(&g->z, 6, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY) != Z_OK) {
        free(g);
        return NULL;
    }
    g->fd = fd;
    g->bytes_out = bytes_out;
    struct MHD_Response *resp =
        MHD_create_response_from_callback(MHD_SIZE_UNKNOWN, 64 * 1024, gz_read, g, gz_free);
    if (!resp) {
        deflateEnd(&g->z);
        free(g);
    }
    return resp;
}

/* -------------------------------------------------------------- files */

/* Sends results/<file>.  A missing file is a 500 (the worker wrote them
 * all), or 404 with missing_detail when one may legitimately be absent. */
static enum MHD_Result send_file(struct MHD_Connection *conn, smd_request *req,
                                 const result_format *f, const char *file,
                                 const char *disposition_name, const char *missing_detail)
{
    smd_server *srv = req->srv;
    char path[PATH_MAX], name[128];
    if (smd_pathf(name, sizeof name, SMD_RESULTS_DIR "/%s", file) != 0 ||
        smd_store_path(srv->store, req->id, name, path, sizeof path) != 0)
        return smd_reply_problem(conn, req, 500, SMD_PROBLEM_INTERNAL, "path too long");
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    struct stat st;
    if (fd < 0 || fstat(fd, &st) != 0) {
        int missing = errno == ENOENT;
        if (fd >= 0)
            close(fd);
        int exists = smd_jobs_find(srv, req->id, req->who.tenant, req->who.admin, NULL);
        if (missing && !exists) /* deleted since its state was read */
            return smd_reply_problem(conn, req, 404, SMD_PROBLEM_NO_SUCH_JOB, "no job %s", req->id);
        if (missing && missing_detail)
            return smd_reply_problem(conn, req, 404, SMD_PROBLEM_NOT_FOUND, "%s", missing_detail);
        return smd_reply_problem(conn, req, 500, SMD_PROBLEM_INTERNAL,
                                 "the result file %s of job %s is missing", file, req->id);
    }
    const char *ae =
        MHD_lookup_connection_value(conn, MHD_HEADER_KIND, MHD_HTTP_HEADER_ACCEPT_ENCODING);
    int gzip = smd_accepts_gzip(ae);
    struct MHD_Response *resp;
    if (gzip) {
        resp = gzip_file_response(fd, &req->bytes_out);
    } else {
        resp = MHD_create_response_from_fd((uint64_t)st.st_size, fd);
        if (resp)
            req->bytes_out += (uint64_t)st.st_size;
    }
    if (!resp) {
        close(fd);
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE, "out of memory");
    }
    char disposition[128];
    snprintf(disposition, sizeof disposition, "attachment; filename=\"%s\"", disposition_name);
    MHD_add_response_header(resp, MHD_HTTP_HEADER_CONTENT_TYPE, f->media);
    MHD_add_response_header(resp, MHD_HTTP_HEADER_CONTENT_DISPOSITION, disposition);
    MHD_add_response_header(resp, MHD_HTTP_HEADER_VARY, "Accept, Accept-Encoding");
    if (gzip)
        MHD_add_response_header(resp, MHD_HTTP_HEADER_CONTENT_ENCODING, "gzip");
    return smd_reply(conn, req, 200, resp);
}

/* Picks the format: ?format=, else Accept, else the first.  Returns its
 * index, or -1 after replying 400 / 406. */
static int choose_format(struct MHD_Connection *conn, smd_request *req,
                         const result_format *formats, int n, enum MHD_Result *replied)
{
    const char *format = MHD_lookup_connection_value(conn, MHD_GET_ARGUMENT_KIND, "format");
    int choice = -1;
    char names[96] = "";
    for (int i = 0; i < n; i++) {
        strncat(names, i ? (i + 1 == n ? " or " : ", ") : "", sizeof names - strlen(names) - 1);
        strncat(names, formats[i].name, sizeof names - strlen(names) - 1);
    }
    if (format) {
        for (int i = 0; i < n; i++)
            if (strcmp(format, formats[i].name) == 0)
                choice = i;
        if (choice < 0)
            *replied = smd_reply_problem(conn, req, 400, SMD_PROBLEM_BAD_REQUEST,
                                         "format: expected %s", names);
    } else {
        const char *offered[8];
        for (int i = 0; i < n; i++)
            offered[i] = formats[i].media;
        const char *accept = MHD_lookup_connection_value(conn, MHD_HEADER_KIND, MHD_HTTP_HEADER_ACCEPT);
        choice = smd_accept_choose(accept, offered, n);
        if (choice < 0)
            *replied = smd_reply_problem(conn, req, 406, SMD_PROBLEM_NOT_ACCEPTABLE,
                                         "Accept allows none of the formats offered (%s; or use "
                                         "?format=%s)",
                                         names, names);
    }
    return choice;
}

static enum MHD_Result serve(struct MHD_Connection *conn, smd_request *req,
                             const result_format *formats, int n)
{
    enum MHD_Result replied = MHD_YES;
    int choice = choose_format(conn, req, formats, n, &replied);
    if (choice < 0)
        return replied;
    const result_format *f = &formats[choice];
    const char *dot = strrchr(f->file, '.');
    char disposition[64];
    if (formats == mesh_formats)
        snprintf(disposition, sizeof disposition, "result%s", dot ? dot : "");
    else
        snprintf(disposition, sizeof disposition, "%s", f->file);
    return send_file(conn, req, f, f->file, disposition, NULL);
}

/* ---------------------------------------------------------- snapshots */

typedef struct snapshot {
    int iteration;
    uint64_t bytes;
} snapshot;

/* The iteration of a worker's snapshot name "iter-<digits>.mesh" (at
 * least 5 digits, as SM_SNAPSHOT_FORMAT writes them), or -1 for any other
 * name (temporary files, strays). */
static int snapshot_name_iteration(const char *name)
{
    if (strncmp(name, "iter-", 5) != 0)
        return -1;
    const char *p = name + 5;
    long v = 0;
    int digits = 0;
    for (; isdigit((unsigned char)*p); p++, digits++) {
        if (digits >= SNAPSHOT_ITERATION_DIGITS)
            return -1;
        v = v * 10 + (*p - '0');
    }
    if (digits < 5 || strcmp(p, ".mesh") != 0)
        return -1;
    return (int)v;
}

/* The {iteration} segment of the path: canonical decimal, 0 (the first
 * state) or more. */
static int parse_iteration(const char *seg)
{
    uint64_t v;
    if (strlen(seg) > SNAPSHOT_ITERATION_DIGITS || (seg[0] == '0' && seg[1] != '\0') ||
        smd_parse_uint(seg, 0, INT_MAX, &v) != SMD_NUM_OK)
        return -1;
    return (int)v;
}

static int by_iteration(const void *a, const void *b)
{
    int x = ((const snapshot *)a)->iteration, y = ((const snapshot *)b)->iteration;
    return (x > y) - (x < y);
}

static enum MHD_Result snapshot_list(struct MHD_Connection *conn, smd_request *req)
{
    char dir[PATH_MAX];
    if (smd_store_path(req->srv->store, req->id, SMD_RESULTS_DIR "/" SM_SNAPSHOTS_DIR, dir,
                       sizeof dir) != 0)
        return smd_reply_problem(conn, req, 500, SMD_PROBLEM_INTERNAL, "path too long");
    snapshot *list = NULL;
    size_t count = 0, cap = 0;
    DIR *d = opendir(dir);
    if (!d && errno != ENOENT) /* no folder: the job asked for none */
        return smd_reply_problem(conn, req, 500, SMD_PROBLEM_INTERNAL,
                                 "cannot read the snapshots of job %s: %s", req->id, strerror(errno));
    for (struct dirent *e; d && (e = readdir(d)) != NULL;) {
        int iteration = snapshot_name_iteration(e->d_name);
        struct stat st;
        if (iteration < 0 || fstatat(dirfd(d), e->d_name, &st, AT_SYMLINK_NOFOLLOW) != 0 ||
            !S_ISREG(st.st_mode))
            continue;
        if (count == cap) {
            size_t ncap = cap ? 2 * cap : 64;
            snapshot *grown = realloc(list, ncap * sizeof *grown);
            if (!grown) {
                free(list);
                closedir(d);
                return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE, "out of memory");
            }
            list = grown;
            cap = ncap;
        }
        list[count++] = (snapshot){iteration, (uint64_t)st.st_size};
    }
    if (d)
        closedir(d);
    if (count > 1)
        qsort(list, count, sizeof *list, by_iteration);
    json_t *items = json_array();
    for (size_t i = 0; items && i < count; i++) {
        char href[128];
        snprintf(href, sizeof href, "/v1/jobs/%s/results/snapshots/%d", req->id, list[i].iteration);
        json_array_append_new(items, json_pack("{s:i,s:s,s:I,s:s}", "iteration", list[i].iteration,
                                               "href", href, "bytes", (json_int_t)list[i].bytes,
                                               "type", snapshot_formats[0].media));
    }
    free(list);
    char self[96], up[96];
    snprintf(self, sizeof self, "/v1/jobs/%s/results/snapshots", req->id);
    snprintf(up, sizeof up, "/v1/jobs/%s/results", req->id);
    json_t *links = json_pack("[{s:s,s:s,s:s},{s:s,s:s,s:s}]", "href", self, "rel", "self", "type",
                              "application/json", "href", up, "rel", "up", "type",
                              "application/json");
    json_t *doc = json_pack("{s:s,s:o*,s:o*}", "jobID", req->id, "snapshots", items, "links", links);
    if (!doc)
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE, "out of memory");
    return smd_reply_json(conn, req, 200, doc);
}

static enum MHD_Result snapshot_item(struct MHD_Connection *conn, smd_request *req, const char *seg)
{
    int iteration = parse_iteration(seg);
    if (iteration < 0)
        return smd_reply_problem(conn, req, 404, SMD_PROBLEM_NOT_FOUND,
                                 "no such snapshot: the last segment is an iteration, a decimal "
                                 "number 1, 2, ... (see /v1/jobs/%s/results/snapshots)",
                                 req->id);
    enum MHD_Result replied = MHD_YES;
    if (choose_format(conn, req, snapshot_formats, 1, &replied) < 0)
        return replied;
    char file[64], disposition[48], missing[160];
    snprintf(file, sizeof file, SM_SNAPSHOTS_DIR "/" SM_SNAPSHOT_FORMAT, iteration);
    snprintf(disposition, sizeof disposition, SM_SNAPSHOT_FORMAT, iteration);
    snprintf(missing, sizeof missing,
             "job %s has no snapshot at iteration %d (see /v1/jobs/%s/results/snapshots)", req->id,
             iteration, req->id);
    return send_file(conn, req, &snapshot_formats[0], file, disposition, missing);
}

/* ------------------------------------------------------------ summary */

static json_t *item(const char *id, const char *what, const result_format *f, const char *title)
{
    char href[160];
    snprintf(href, sizeof href, "/v1/jobs/%s/results/%s?format=%s", id, what, f->name);
    return json_pack("{s:s,s:s,s:s,s:s}", "href", href, "rel", "item", "type", f->media, "title",
                     title);
}

static enum MHD_Result summary(struct MHD_Connection *conn, smd_request *req)
{
    char path[PATH_MAX];
    if (smd_store_path(req->srv->store, req->id, SMD_RESULTS_DIR "/" SM_RESULT_SUMMARY_FILE, path,
                       sizeof path) != 0)
        return smd_reply_problem(conn, req, 500, SMD_PROBLEM_INTERNAL, "path too long");
    char *text;
    size_t len;
    if (smd_read_file(path, 1 << 20, &text, &len) != 0) {
        int saved = errno;
        int exists = smd_jobs_find(req->srv, req->id, req->who.tenant, req->who.admin, NULL);
        if (saved == ENOENT && !exists) /* deleted since its state was read */
            return smd_reply_problem(conn, req, 404, SMD_PROBLEM_NO_SUCH_JOB, "no job %s", req->id);
        return smd_reply_problem(conn, req, 500, SMD_PROBLEM_INTERNAL,
                                 "the summary of job %s is missing: %s", req->id, strerror(saved));
    }
    json_t *doc = json_loadb(text, len, 0, NULL);
    free(text);
    if (!json_is_object(doc)) {
        json_decref(doc);
        return smd_reply_problem(conn, req, 500, SMD_PROBLEM_INTERNAL,
                                 "the summary of job %s is unreadable", req->id);
    }
    json_object_set_new(doc, "jobID", json_string(req->id));
    json_t *links = json_array();
    char self[96], up[64];
    snprintf(self, sizeof self, "/v1/jobs/%s/results", req->id);
    snprintf(up, sizeof up, "/v1/jobs/%s", req->id);
    json_array_append_new(links, json_pack("{s:s,s:s,s:s,s:s}", "href", self, "rel", "self", "type",
                                           "application/json", "title", "this summary"));
    json_array_append_new(links, json_pack("{s:s,s:s,s:s,s:s}", "href", up, "rel", "up", "type",
                                           "application/json", "title", "the job"));
    static const char *const mesh_titles[] = {"deformed mesh (Medit ASCII)",
                                              "deformed mesh (Medit binary)",
                                              "deformed mesh with displacement and distance (VTK)",
                                              "deformed mesh (binary payload)"};
    for (int i = 0; i < 4; i++)
        json_array_append_new(links, item(req->id, "mesh", &mesh_formats[i], mesh_titles[i]));
    json_array_append_new(links, item(req->id, "displacement", &displacement_formats[0],
                                      "displacement (Medit .sol)"));
    json_array_append_new(links, item(req->id, "displacement", &displacement_formats[1],
                                      "displacement (Medit .solb)"));
    json_array_append_new(links, item(req->id, "history", &history_formats[0], "history (CSV)"));
    json_array_append_new(links, item(req->id, "history", &history_formats[1], "history (JSON)"));
    char snapshots[96];
    snprintf(snapshots, sizeof snapshots, "/v1/jobs/%s/results/snapshots", req->id);
    json_array_append_new(links, json_pack("{s:s,s:s,s:s,s:s}", "href", snapshots, "rel", "related",
                                           "type", "application/json", "title",
                                           "mesh snapshots every save_every iterations"));
    json_object_set_new(doc, "links", links);
    return smd_reply_json(conn, req, 200, doc);
}

/* 1 when the job is successful; otherwise the 404 (no such job, or
 * result-not-ready with its state and message) is sent and *r set. */
static int results_ready(struct MHD_Connection *conn, smd_request *req, enum MHD_Result *r)
{
    smd_job job;
    if (!smd_jobs_find(req->srv, req->id, req->who.tenant, req->who.admin, &job)) {
        *r = smd_reply_problem(conn, req, 404, SMD_PROBLEM_NO_SUCH_JOB, "no job %s", req->id);
        return 0;
    }
    if (job.state != SM_JOB_SUCCESSFUL) {
        const char *what = job.state == SM_JOB_ACCEPTED ? "is queued"
                           : job.state == SM_JOB_RUNNING ? "is running"
                           : job.state == SM_JOB_FAILED  ? "failed"
                                                     : "was dismissed";
        *r = smd_reply_problem(conn, req, 404, SMD_PROBLEM_RESULT_NOT_READY,
                               "job %s %s%s%s%s: it has no results", req->id, what,
                               job.message[0] ? " (" : "", job.message, job.message[0] ? ")" : "");
        return 0;
    }
    return 1;
}

enum MHD_Result smd_route_results(struct MHD_Connection *conn, smd_request *req)
{
    enum MHD_Result r;
    return results_ready(conn, req, &r) ? summary(conn, req) : r;
}

enum MHD_Result smd_route_result_mesh(struct MHD_Connection *conn, smd_request *req)
{
    enum MHD_Result r;
    return results_ready(conn, req, &r) ? serve(conn, req, mesh_formats, 4) : r;
}

enum MHD_Result smd_route_result_displacement(struct MHD_Connection *conn, smd_request *req)
{
    enum MHD_Result r;
    return results_ready(conn, req, &r) ? serve(conn, req, displacement_formats, 2) : r;
}

enum MHD_Result smd_route_result_history(struct MHD_Connection *conn, smd_request *req)
{
    enum MHD_Result r;
    return results_ready(conn, req, &r) ? serve(conn, req, history_formats, 2) : r;
}

/* The template a job meshed from its template_surface or template_image
 * (sm_job_template.h):
 * 404 for a job whose template was given as a mesh. */
enum MHD_Result smd_route_result_template(struct MHD_Connection *conn, smd_request *req)
{
    static const result_format f = {SM_RESULT_MESH, "mesh", "application/x-medit-mesh",
                                    SM_RESULT_TEMPLATE_FILE};
    enum MHD_Result r;
    if (!results_ready(conn, req, &r))
        return r;
    return send_file(conn, req, &f, f.file, f.file,
                     "this job's template was given as a mesh (template), not meshed from a "
                     "template_surface or a template_image");
}

enum MHD_Result smd_route_snapshots(struct MHD_Connection *conn, smd_request *req)
{
    enum MHD_Result r;
    return results_ready(conn, req, &r) ? snapshot_list(conn, req) : r;
}

enum MHD_Result smd_route_snapshot(struct MHD_Connection *conn, smd_request *req)
{
    enum MHD_Result r;
    return results_ready(conn, req, &r) ? snapshot_item(conn, req, req->arg) : r;
}
