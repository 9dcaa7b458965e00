/* libmicrohttpd setup, routing, authentication, request bookkeeping and
 * reply helpers (see smd_http.h).  The route handlers live in
 * smd_routes.c (jobs, processes, health) and smd_results.c. */
#include "smd_http.h"

#include <arpa/inet.h>
#include <errno.h>
#include <netinet/in.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>
#include <zlib.h>

#include "smd_routes.h"
#include "smd_upload.h"

/* ---------------------------------------------------------------- replies */

enum MHD_Result smd_reply(struct MHD_Connection *conn, smd_request *req, unsigned status,
                          struct MHD_Response *resp)
{
    if (!resp)
        return MHD_NO;
    if (req->body_pending && !req->deferred) {
        req->deferred = resp;
        req->deferred_status = status;
        req->status = status;
        req->replied = 1;
        return MHD_YES;
    }
    enum MHD_Result r = MHD_queue_response(conn, status, resp);
    MHD_destroy_response(resp);
    if (r == MHD_YES) {
        req->status = status;
        req->replied = 1;
    }
    return r;
}

struct MHD_Response *smd_buffer_response(struct MHD_Connection *conn, smd_request *req,
                                         const char *content_type, char *body, size_t len)
{
    const char *ae = MHD_lookup_connection_value(conn, MHD_HEADER_KIND,
                                                 MHD_HTTP_HEADER_ACCEPT_ENCODING);
    int gzip = len > 0 && smd_accepts_gzip(ae);
    if (gzip) {
        char *z;
        size_t zlen;
        if (smd_gzip_buffer(body, len, &z, &zlen) == 0) {
            free(body);
            body = z;
            len = zlen;
        } else {
            gzip = 0; /* send it plain rather than not at all */
        }
    }
    struct MHD_Response *resp = MHD_create_response_from_buffer(len, body, MHD_RESPMEM_MUST_FREE);
    if (!resp) {
        free(body);
        return NULL;
    }
    MHD_add_response_header(resp, MHD_HTTP_HEADER_CONTENT_TYPE, content_type);
    MHD_add_response_header(resp, MHD_HTTP_HEADER_VARY, "Accept-Encoding");
    if (gzip)
        MHD_add_response_header(resp, MHD_HTTP_HEADER_CONTENT_ENCODING, "gzip");
    req->bytes_out += len;
    return resp;
}

enum MHD_Result smd_reply_json(struct MHD_Connection *conn, smd_request *req, unsigned status,
                               json_t *body)
{
    char *text = body ? json_dumps(body, JSON_INDENT(2) | JSON_PRESERVE_ORDER) : NULL;
    json_decref(body);
    if (!text)
        return MHD_NO;
    size_t len = strlen(text);
    char *nl = realloc(text, len + 2);
    if (nl) {
        text = nl;
        text[len++] = '\n';
        text[len] = '\0';
    }
    return smd_reply(conn, req, status, smd_buffer_response(conn, req, "application/json", text, len));
}

static const char *problem_title(unsigned status, const char *type)
{
    if (strcmp(type, SMD_PROBLEM_NO_SUCH_JOB) == 0)
        return "No such job";
    if (strcmp(type, SMD_PROBLEM_RESULT_NOT_READY) == 0)
        return "Result not ready";
    if (strcmp(type, SMD_PROBLEM_NO_SUCH_PROCESS) == 0)
        return "No such process";
    const char *r = MHD_get_reason_phrase_for(status);
    return (r && *r) ? r : "Error";
}

/* "template: line 3: ..." -> {name: template, reason: line 3: ...};
 * likewise target_mesh, target_sol and params paths.  NULL otherwise. */
static json_t *invalid_params(const char *detail)
{
    static const char *const parts[] = {"template", "target_mesh", "target_sol", "params"};
    const char *colon = strstr(detail, ": ");
    if (!colon)
        return NULL;
    size_t n = (size_t)(colon - detail);
    for (size_t i = 0; i < sizeof parts / sizeof parts[0]; i++) {
        size_t k = strlen(parts[i]);
        if (n >= k && strncmp(detail, parts[i], k) == 0 && (n == k || detail[k] == '.' || detail[k] == '[')) {
            char name[160];
            snprintf(name, sizeof name, "%.*s", (int)(n < sizeof name ? n : sizeof name - 1), detail);
            return json_pack("[{s:s,s:s}]", "name", name, "reason", colon + 2);
        }
    }
    return NULL;
}

enum MHD_Result smd_reply_problem(struct MHD_Connection *conn, smd_request *req, unsigned status,
                                  const char *type, const char *detail_fmt, ...)
{
    char detail[1024];
    va_list ap;
    va_start(ap, detail_fmt);
    vsnprintf(detail, sizeof detail, detail_fmt, ap);
    va_end(ap);
    /* detail may quote client input: keep valid UTF-8 / JSON */
    for (char *c = detail; *c; c++)
        if ((unsigned char)*c < 0x20 || (unsigned char)*c >= 0x7f)
            *c = '?';
    json_t *body = json_object();
    json_object_set_new(body, "type", json_string(type));
    json_object_set_new(body, "title", json_string(problem_title(status, type)));
    json_object_set_new(body, "status", json_integer(status));
    json_object_set_new(body, "detail", json_string(detail));
    char instance[300];
    snprintf(instance, sizeof instance, "%s", req->path);
    for (char *c = instance; *c; c++)
        if ((unsigned char)*c < 0x21 || (unsigned char)*c >= 0x7f)
            *c = '?';
    json_object_set_new(body, "instance", json_string(instance));
    if (status == 400 || status == 422) {
        json_t *ip = invalid_params(detail);
        if (ip)
            json_object_set_new(body, "invalid-params", ip);
    }
    char *text = json_dumps(body, JSON_INDENT(2) | JSON_PRESERVE_ORDER);
    json_decref(body);
    if (!text)
        return MHD_NO;
    struct MHD_Response *resp =
        smd_buffer_response(conn, req, "application/problem+json", text, strlen(text));
    if (!resp)
        return MHD_NO;
    if (status == 401) {
        const char *auth = MHD_lookup_connection_value(conn, MHD_HEADER_KIND,
                                                       MHD_HTTP_HEADER_AUTHORIZATION);
        MHD_add_response_header(resp, MHD_HTTP_HEADER_WWW_AUTHENTICATE,
                                auth ? "Bearer realm=\"shapematch\", error=\"invalid_token\""
                                     : "Bearer realm=\"shapematch\"");
    }
    if (status == 503)
        MHD_add_response_header(resp, MHD_HTTP_HEADER_RETRY_AFTER, "5");
    if (status == 405) {
        const char *allow = strstr(detail, "(allowed: ");
        if (allow) {
            char list[64];
            snprintf(list, sizeof list, "%s", allow + 10);
            char *close = strchr(list, ')');
            if (close)
                *close = '\0';
            MHD_add_response_header(resp, MHD_HTTP_HEADER_ALLOW, list);
        }
    }
    return smd_reply(conn, req, status, resp);
}

json_t *smd_status_document(const smd_job *job)
{
    json_t *doc = smd_job_status_fields(job);
    if (!doc)
        return NULL;
    char self[64], events[80], results[80];
    snprintf(self, sizeof self, "/v1/jobs/%s", job->id);
    snprintf(events, sizeof events, "/v1/jobs/%s/events", job->id);
    snprintf(results, sizeof results, "/v1/jobs/%s/results", job->id);
    json_t *links = json_array();
    json_array_append_new(links, json_pack("{s:s,s:s,s:s,s:s}", "href", self, "rel", "self", "type",
                                           "application/json", "title", "this job"));
    json_array_append_new(links, json_pack("{s:s,s:s,s:s,s:s}", "href", events, "rel", "monitor",
                                           "type", "text/event-stream", "title",
                                           "progress events (SSE, or NDJSON)"));
    if (job->state == SM_JOB_SUCCESSFUL)
        json_array_append_new(links, json_pack("{s:s,s:s,s:s,s:s}", "href", results, "rel",
                                               "http://www.opengis.net/def/rel/ogc/1.0/results",
                                               "type", "application/json", "title", "results"));
    json_object_set_new(doc, "links", links);
    return doc;
}

/* ---------------------------------------------------------------- routing */

/* Splits the path into the route and the job (or process) id. */
static smd_route classify(const char *url, char id[SMD_ID_LEN + 1], int *bad_id, char *pid,
                          size_t pid_cap)
{
    id[0] = '\0';
    *bad_id = 0;
    if (strcmp(url, "/") == 0 || strcmp(url, "/v1") == 0 || strcmp(url, "/v1/") == 0)
        return SMD_ROUTE_ROOT;
    if (strcmp(url, "/healthz") == 0)
        return SMD_ROUTE_HEALTHZ;
    if (strcmp(url, "/readyz") == 0)
        return SMD_ROUTE_READYZ;
    if (strcmp(url, "/metrics") == 0)
        return SMD_ROUTE_METRICS;
    if (strcmp(url, "/v1/openapi.yaml") == 0)
        return SMD_ROUTE_OPENAPI;
    if (strcmp(url, "/v1/processes") == 0)
        return SMD_ROUTE_PROCESSES;
    if (strncmp(url, "/v1/processes/", 14) == 0 && url[14] && !strchr(url + 14, '/')) {
        snprintf(pid, pid_cap, "%s", url + 14);
        return SMD_ROUTE_PROCESS;
    }
    if (strcmp(url, "/v1/jobs") == 0)
        return SMD_ROUTE_JOBS;
    if (strncmp(url, "/v1/jobs/", 9) != 0)
        return SMD_ROUTE_OTHER;
    const char *rest = url + 9;
    const char *slash = strchr(rest, '/');
    size_t idlen = slash ? (size_t)(slash - rest) : strlen(rest);
    if (idlen == SMD_ID_LEN) {
        memcpy(id, rest, SMD_ID_LEN);
        id[SMD_ID_LEN] = '\0';
    }
    if (!smd_id_valid(id)) {
        id[0] = '\0';
        *bad_id = 1; /* answered as an unknown job: nothing reaches the disk */
    }
    if (!slash)
        return SMD_ROUTE_JOB;
    if (strcmp(slash, "/events") == 0)
        return SMD_ROUTE_EVENTS;
    if (strcmp(slash, "/results") == 0)
        return SMD_ROUTE_RESULTS;
    if (strcmp(slash, "/results/mesh") == 0)
        return SMD_ROUTE_RESULT_MESH;
    if (strcmp(slash, "/results/displacement") == 0)
        return SMD_ROUTE_RESULT_DISPLACEMENT;
    if (strcmp(slash, "/results/history") == 0)
        return SMD_ROUTE_RESULT_HISTORY;
    /* /results/snapshots[/{iteration}]: counted under /results (the metrics
     * have no label of their own for them); smd_results.c tells them apart
     * by the path, parses the iteration as a number and answers 404 for
     * anything else.  A segment longer than any iteration is not a route
     * (so req->path, which truncates, always holds it whole). */
    if (strcmp(slash, "/results/snapshots") == 0)
        return SMD_ROUTE_RESULTS;
    if (strncmp(slash, "/results/snapshots/", 19) == 0 && slash[19] && !strchr(slash + 19, '/') &&
        strlen(slash + 19) <= 16)
        return SMD_ROUTE_RESULTS;
    *bad_id = 0;
    id[0] = '\0';
    return SMD_ROUTE_OTHER;
}

static enum MHD_Result method_not_allowed(struct MHD_Connection *conn, smd_request *req,
                                          const char *allow)
{
    enum MHD_Result r = smd_reply_problem(conn, req, 405, SMD_PROBLEM_METHOD,
                                          "%s is not allowed on %s (allowed: %s)", req->method,
                                          req->path, allow);
    return r;
}

static int is_get(const char *method)
{
    return strcmp(method, "GET") == 0 || strcmp(method, "HEAD") == 0;
}

static enum MHD_Result dispatch(struct MHD_Connection *conn, smd_request *req, const char *pid,
                                int bad_id)
{
    const char *m = req->method;
    if (bad_id)
        return smd_reply_problem(conn, req, 404, SMD_PROBLEM_NO_SUCH_JOB,
                                 "no job with this id (ids are 32 lowercase hex digits)");
    switch (req->route) {
    case SMD_ROUTE_ROOT:
        return is_get(m) ? smd_route_landing(conn, req) : method_not_allowed(conn, req, "GET, HEAD");
    case SMD_ROUTE_OPENAPI:
        return is_get(m) ? smd_route_openapi(conn, req) : method_not_allowed(conn, req, "GET, HEAD");
    case SMD_ROUTE_HEALTHZ:
        return is_get(m) ? smd_route_healthz(conn, req) : method_not_allowed(conn, req, "GET, HEAD");
    case SMD_ROUTE_READYZ:
        return is_get(m) ? smd_route_readyz(conn, req) : method_not_allowed(conn, req, "GET, HEAD");
    case SMD_ROUTE_METRICS:
        return is_get(m) ? smd_route_metrics(conn, req) : method_not_allowed(conn, req, "GET, HEAD");
    case SMD_ROUTE_PROCESSES:
        return is_get(m) ? smd_route_processes(conn, req) : method_not_allowed(conn, req, "GET, HEAD");
    case SMD_ROUTE_PROCESS:
        return is_get(m) ? smd_route_process(conn, req, pid) : method_not_allowed(conn, req, "GET, HEAD");
    case SMD_ROUTE_JOBS:
        if (is_get(m))
            return smd_route_jobs_list(conn, req);
        if (strcmp(m, "POST") == 0)
            return smd_upload_begin(conn, req);
        return method_not_allowed(conn, req, "GET, HEAD, POST");
    case SMD_ROUTE_JOB:
        if (is_get(m))
            return smd_route_job_get(conn, req);
        if (strcmp(m, "DELETE") == 0)
            return smd_route_job_delete(conn, req);
        return method_not_allowed(conn, req, "GET, HEAD, DELETE");
    case SMD_ROUTE_EVENTS:
        return is_get(m) ? smd_route_events(conn, req) : method_not_allowed(conn, req, "GET, HEAD");
    case SMD_ROUTE_RESULTS:
    case SMD_ROUTE_RESULT_MESH:
    case SMD_ROUTE_RESULT_DISPLACEMENT:
    case SMD_ROUTE_RESULT_HISTORY:
        return is_get(m) ? smd_route_results(conn, req) : method_not_allowed(conn, req, "GET, HEAD");
    case SMD_ROUTE_OTHER:
    case SMD_ROUTE_COUNT:
        break;
    }
    return smd_reply_problem(conn, req, 404, SMD_PROBLEM_NOT_FOUND, "no such resource: %s (see /v1)",
                             req->path);
}

/* Authentication, then the route's handler. */
static enum MHD_Result handle(struct MHD_Connection *conn, smd_request *req)
{
    smd_server *srv = req->srv;
    req->dispatched = 1;
    if (srv->tokens && req->route != SMD_ROUTE_HEALTHZ && req->route != SMD_ROUTE_READYZ) {
        const char *auth = MHD_lookup_connection_value(conn, MHD_HEADER_KIND,
                                                       MHD_HTTP_HEADER_AUTHORIZATION);
        smd_auth_result a = smd_tokens_check(srv->tokens, auth);
        if (a != SMD_AUTH_OK)
            return smd_reply_problem(conn, req, 401, SMD_PROBLEM_UNAUTHORIZED,
                                     a == SMD_AUTH_MISSING
                                         ? "this daemon requires a bearer token "
                                           "(Authorization: Bearer <token>)"
                                         : "the bearer token is not valid");
    }
    enum MHD_Result r = dispatch(conn, req, req->pid, req->bad_id);
    if (r == MHD_YES && !req->replied && !req->upload)
        return smd_reply_problem(conn, req, 500, SMD_PROBLEM_INTERNAL, "no response produced");
    if (req->upload && req->deferred) {
        /* an upload cannot have a reply waiting as well */
        smd_upload_free(req->upload);
        req->upload = NULL;
    }
    return r;
}

static enum MHD_Result on_request(void *cls, struct MHD_Connection *conn, const char *url,
                                  const char *method, const char *version, const char *upload_data,
                                  size_t *upload_data_size, void **req_cls)
{
    smd_server *srv = cls;
    (void)version;
    smd_request *req = *req_cls;
    if (req) {
        if (!req->dispatched) {
            if (*upload_data_size > 0) { /* an unexpected body: read and dropped */
                req->bytes_in += *upload_data_size;
                *upload_data_size = 0;
                return MHD_YES;
            }
            return handle(conn, req);
        }
        if (*upload_data_size == 0)
            req->body_pending = 0; /* the body is complete: replies go out now */
        if (req->deferred) {
            if (*upload_data_size > 0) {
                /* drop the body, within reason */
                req->bytes_in += *upload_data_size;
                *upload_data_size = 0;
                return req->bytes_in > 4 * srv->cfg.max_upload + (16u << 20) ? MHD_NO : MHD_YES;
            }
            struct MHD_Response *resp = req->deferred;
            req->deferred = NULL;
            enum MHD_Result r = MHD_queue_response(conn, req->deferred_status, resp);
            MHD_destroy_response(resp);
            return r;
        }
        if (req->upload && !req->replied)
            return smd_upload_continue(conn, req, upload_data, upload_data_size);
        req->bytes_in += *upload_data_size;
        *upload_data_size = 0;
        return MHD_YES;
    }
    req = calloc(1, sizeof *req);
    if (!req)
        return MHD_NO;
    *req_cls = req;
    req->srv = srv;
    req->t0 = smd_monotonic();
    snprintf(req->method, sizeof req->method, "%s", method);
    snprintf(req->path, sizeof req->path, "%s", url);
    req->route = classify(url, req->id, &req->bad_id, req->pid, sizeof req->pid);
    /* a body is coming (and not one refused outright for its size) */
    const char *length = MHD_lookup_connection_value(conn, MHD_HEADER_KIND,
                                                     MHD_HTTP_HEADER_CONTENT_LENGTH);
    const char *chunked = MHD_lookup_connection_value(conn, MHD_HEADER_KIND,
                                                      MHD_HTTP_HEADER_TRANSFER_ENCODING);
    /* a malformed or huge length is no body worth waiting for (libmicrohttpd
     * refuses malformed ones itself; the upload route answers 413) */
    uint64_t body = 0;
    if (length && smd_parse_uint(length, 0, UINT64_MAX, &body) != SMD_NUM_OK)
        body = 0;
    req->body_pending = (body > 0 && body <= srv->cfg.max_upload) || (!length && chunked);
    /* no body: answer on the next call (keeps the connection alive) */
    if (!req->body_pending && !length && !chunked && strcmp(method, MHD_HTTP_METHOD_POST) != 0)
        return MHD_YES;
    return handle(conn, req);
}

static void on_completed(void *cls, struct MHD_Connection *conn, void **req_cls,
                         enum MHD_RequestTerminationCode toe)
{
    smd_server *srv = cls;
    smd_request *req = *req_cls;
    if (!req)
        return;
    *req_cls = NULL;
    double seconds = smd_monotonic() - req->t0;
    unsigned status = req->replied ? req->status : 499; /* client went away before a reply */
    smd_metrics_request(&srv->metrics, req->route, req->method, status, seconds, req->bytes_in,
                        req->bytes_out);
    if (smd_log_enabled(&srv->log, SMD_LOG_INFO)) {
        char remote[INET6_ADDRSTRLEN] = "?";
        const union MHD_ConnectionInfo *ci =
            MHD_get_connection_info(conn, MHD_CONNECTION_INFO_CLIENT_ADDRESS);
        if (ci && ci->client_addr) {
            const struct sockaddr *sa = ci->client_addr;
            if (sa->sa_family == AF_INET)
                inet_ntop(AF_INET, &((const struct sockaddr_in *)sa)->sin_addr, remote, sizeof remote);
            else if (sa->sa_family == AF_INET6)
                inet_ntop(AF_INET6, &((const struct sockaddr_in6 *)sa)->sin6_addr, remote,
                          sizeof remote);
        }
        char path[sizeof req->path];
        snprintf(path, sizeof path, "%s", req->path);
        for (char *c = path; *c; c++)
            if ((unsigned char)*c < 0x20 || (unsigned char)*c >= 0x7f)
                *c = '?';
        json_t *f = json_pack("{s:s,s:s,s:s,s:i,s:f,s:I,s:I,s:s}", "method", req->method, "path",
                              path, "route", smd_route_label(req->route), "status", (int)status,
                              "ms", seconds * 1000.0, "bytes_in", (json_int_t)req->bytes_in,
                              "bytes_out", (json_int_t)req->bytes_out, "remote", remote);
        if (f && req->id[0])
            json_object_set_new(f, "job", json_string(req->id));
        if (f && toe != MHD_REQUEST_TERMINATED_COMPLETED_OK) {
            static const char *const why[] = {"completed", "error", "timeout", "shutdown",
                                              "read error", "client abort"};
            json_object_set_new(f, "ended", json_string((unsigned)toe < 6 ? why[toe] : "other"));
        }
        smd_log(&srv->log, SMD_LOG_INFO, "request", f);
    }
    smd_upload_free(req->upload);
    if (req->deferred)
        MHD_destroy_response(req->deferred);
    free(req);
}

static void mhd_logger(void *cls, const char *fmt, va_list ap)
{
    smd_server *srv = cls;
    char msg[512];
    vsnprintf(msg, sizeof msg, fmt, ap);
    size_t n = strlen(msg);
    while (n > 0 && (msg[n - 1] == '\n' || msg[n - 1] == '\r'))
        msg[--n] = '\0';
    smd_logf(&srv->log, SMD_LOG_WARN, "httpd", "%s", msg);
}

/* --------------------------------------------------------------- daemon */

sm_status smd_http_start(smd_server *srv, sm_error *err)
{
    const smd_config *cfg = &srv->cfg;
    struct sockaddr_storage ss;
    memset(&ss, 0, sizeof ss);
    unsigned flags = MHD_USE_INTERNAL_POLLING_THREAD | MHD_USE_EPOLL | MHD_ALLOW_SUSPEND_RESUME |
                     MHD_USE_ERROR_LOG;
    struct sockaddr_in *in4 = (struct sockaddr_in *)&ss;
    struct sockaddr_in6 *in6 = (struct sockaddr_in6 *)&ss;
    if (inet_pton(AF_INET, cfg->listen_host, &in4->sin_addr) == 1) {
        in4->sin_family = AF_INET;
        in4->sin_port = htons((uint16_t)cfg->listen_port);
    } else if (inet_pton(AF_INET6, cfg->listen_host, &in6->sin6_addr) == 1) {
        in6->sin6_family = AF_INET6;
        in6->sin6_port = htons((uint16_t)cfg->listen_port);
        flags |= MHD_USE_IPv6;
    } else if (strcmp(cfg->listen_host, "localhost") == 0) {
        in4->sin_family = AF_INET;
        in4->sin_addr.s_addr = htonl(INADDR_LOOPBACK);
        in4->sin_port = htons((uint16_t)cfg->listen_port);
    } else {
        return sm_error_set(err, SM_ERR_INVALID,
                            "--listen: '%s' is not a numeric IPv4/IPv6 address (or localhost)",
                            cfg->listen_host);
    }
    /* Per-connection buffers come from the connection's pool, and the
     * pool must hold the request headers plus a send buffer. */
    srv->httpd = MHD_start_daemon(
        flags, (uint16_t)cfg->listen_port, NULL, NULL, on_request, srv, MHD_OPTION_EXTERNAL_LOGGER,
        mhd_logger, srv, MHD_OPTION_SOCK_ADDR,
        (struct sockaddr *)&ss, MHD_OPTION_THREAD_POOL_SIZE, (unsigned)cfg->http_threads,
        MHD_OPTION_CONNECTION_LIMIT, cfg->max_connections, MHD_OPTION_PER_IP_CONNECTION_LIMIT,
        cfg->max_connections_per_ip, MHD_OPTION_CONNECTION_TIMEOUT, cfg->connection_timeout,
        MHD_OPTION_CONNECTION_MEMORY_LIMIT, (size_t)cfg->connection_memory,
        MHD_OPTION_NOTIFY_COMPLETED, on_completed, srv, MHD_OPTION_END);
    if (!srv->httpd)
        return sm_error_set(err, SM_ERR_IO, "cannot listen on %s:%u (address in use, or not local?)",
                            cfg->listen_host, cfg->listen_port);
    const union MHD_DaemonInfo *di = MHD_get_daemon_info(srv->httpd, MHD_DAEMON_INFO_BIND_PORT);
    srv->port = di ? di->port : cfg->listen_port;
    return SM_OK;
}

void smd_http_quiesce(smd_server *srv)
{
    if (!srv->httpd)
        return;
    MHD_socket fd = MHD_quiesce_daemon(srv->httpd);
    if (fd != MHD_INVALID_SOCKET)
        close(fd);
}

void smd_http_stop(smd_server *srv)
{
    if (srv->httpd) {
        MHD_stop_daemon(srv->httpd);
        srv->httpd = NULL;
    }
}

int smd_gzip_buffer(const void *data, size_t len, char **out, size_t *out_len)
{
    z_stream z;
    memset(&z, 0, sizeof z);
    if (deflateInit2(&z, 6, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY) != Z_OK)
        return -1;
    size_t cap = deflateBound(&z, (uLong)len) + 32;
    char *buf = malloc(cap);
    if (!buf) {
        deflateEnd(&z);
        return -1;
    }
    z.next_in = (Bytef *)data;
    z.avail_in = (uInt)len;
    z.next_out = (Bytef *)buf;
    z.avail_out = (uInt)cap;
    int rc = deflate(&z, Z_FINISH);
    size_t produced = cap - z.avail_out;
    deflateEnd(&z);
    if (rc != Z_STREAM_END) {
        free(buf);
        return -1;
    }
    *out = buf;
    *out_len = produced;
    return 0;
}
