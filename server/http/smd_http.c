/* libmicrohttpd setup and dispatch (see smd_http.h): every request is
 * matched against the route table (smd_http_app's route), authenticated,
 * and handed to its handler; replies go through smd_reply.h. */
#include "http/smd_http.h"

#include <arpa/inet.h>
#include <errno.h>
#include <netinet/in.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/socket.h>
#include <unistd.h>

#include "shapematch/sm_clock.h"
#include "sm_proto_text.h"
#include "http/smd_conns.h"
#include "http/smd_cors.h"
#include "http/smd_ratelimit.h"
#include "http/smd_reply.h"
#include "http/smd_tls.h"

/* ------------------------------------------------------------ strictness */

/* Headers that must appear at most once: a second Content-Length makes the
 * body's framing ambiguous (request smuggling behind a proxy that reads the
 * other one), a second Authorization makes it unclear which credential was
 * meant. */
typedef struct {
    unsigned content_length;
    unsigned authorization;
    unsigned host;
} header_counts;

static enum MHD_Result count_header(void *cls, enum MHD_ValueKind kind, const char *key,
                                    const char *value)
{
    header_counts *c = cls;
    (void)kind;
    (void)value;
    if (strcasecmp(key, MHD_HTTP_HEADER_CONTENT_LENGTH) == 0)
        c->content_length++;
    else if (strcasecmp(key, MHD_HTTP_HEADER_AUTHORIZATION) == 0)
        c->authorization++;
    else if (strcasecmp(key, MHD_HTTP_HEADER_HOST) == 0)
        c->host++;
    return MHD_YES;
}

/* The framing and credential rules libmicrohttpd leaves to us: NULL when
 * the request may go on, else the detail of its 400. */
static const char *request_strictness(struct MHD_Connection *conn, const char *version)
{
    header_counts c = {0, 0, 0};
    MHD_get_connection_values(conn, MHD_HEADER_KIND, count_header, &c);
    if (c.content_length > 1)
        return "Content-Length: given more than once (the body's length is ambiguous)";
    if (c.authorization > 1)
        return "Authorization: given more than once (send one credential)";
    if (c.host == 0 && version && strcmp(version, MHD_HTTP_VERSION_1_1) == 0)
        return "Host: an HTTP/1.1 request must carry a Host header (RFC 9112, 3.2)";
    if (c.host > 1)
        return "Host: given more than once";
    return NULL;
}

/* ---------------------------------------------------------------- routing */

static enum MHD_Result dispatch(struct MHD_Connection *conn, smd_request *req)
{
    if (req->allowed && req->bad_id)
        return smd_reply_problem(conn, req, 404, SMD_PROBLEM_NO_SUCH_JOB,
                                 "no job with this id (ids are 32 lowercase hex digits)");
    if (req->route)
        return req->srv->app->handle(conn, req);
    if (req->allowed) {
        char allow[64];
        smd_methods_format(req->allowed, allow, sizeof allow);
        return smd_reply_method_not_allowed(conn, req, allow);
    }
    return smd_reply_problem(conn, req, 404, SMD_PROBLEM_NOT_FOUND, "no such resource: %s (see /v1)",
                             req->path);
}

/* A CORS preflight (or any OPTIONS): 204 with the path's methods from the
 * route table, and the CORS headers for a listed Origin (smd_cors.h).
 * Preflights carry no credentials: answered before authentication. */
static enum MHD_Result preflight(struct MHD_Connection *conn, smd_request *req)
{
    if (!req->allowed)
        return smd_reply_problem(conn, req, 404, SMD_PROBLEM_NOT_FOUND,
                                 "no such resource: %s (see /v1)", req->path);
    char methods[64], allow[80];
    smd_methods_format(req->allowed, methods, sizeof methods);
    snprintf(allow, sizeof allow, "%s, OPTIONS", methods);
    struct MHD_Response *resp = MHD_create_response_from_buffer(0, NULL, MHD_RESPMEM_PERSISTENT);
    if (!resp)
        return MHD_NO;
    MHD_add_response_header(resp, MHD_HTTP_HEADER_ALLOW, allow);
    smd_cors_preflight(&req->srv->cfg, conn, resp, methods);
    return smd_reply(conn, req, 204, resp);
}

smd_auth_result smd_http_identify(smd_server *srv, const char *authorization, const char *token,
                                  smd_identity *who)
{
    pthread_mutex_lock(&srv->tokens_lock);
    smd_auth_result a = !srv->tokens ? SMD_AUTH_OK
                        : token      ? smd_tokens_identify_token(srv->tokens, token, who)
                                     : smd_tokens_identify(srv->tokens, authorization, who);
    pthread_mutex_unlock(&srv->tokens_lock);
    return a;
}

/* The request's tenant from its credentials: the Authorization header,
 * or on GET and HEAD the access_token query parameter (RFC 6750 2.3: what
 * EventSource and download links can send).  MHD hands the handlers the
 * path without its query, so the token reaches no log line nor label.
 * The tokens may be replaced by SIGHUP meanwhile. */
static smd_auth_result authenticate(struct MHD_Connection *conn, smd_request *req)
{
    smd_server *srv = req->srv;
    const char *auth = MHD_lookup_connection_value(conn, MHD_HEADER_KIND,
                                                   MHD_HTTP_HEADER_AUTHORIZATION);
    const char *token = NULL;
    if (!auth && (smd_method_bit(req->method) & SMD_METHOD_READ))
        token = MHD_lookup_connection_value(conn, MHD_GET_ARGUMENT_KIND, "access_token");
    return smd_http_identify(srv, auth, token, &req->who);
}

/* DNS rebinding: a page of a name the attacker controls, resolved to this
 * daemon's address, reads with the victim's browser.  Every route but the
 * public ones (health checks, the web app's static page: no job data)
 * answers only a Host that names this daemon (smd_cors_trusted_host).  A
 * request without Host (HTTP/1.0; browsers always send one) is no browser's. */
static int foreign_host(struct MHD_Connection *conn, const smd_request *req)
{
    const char *host = MHD_lookup_connection_value(conn, MHD_HEADER_KIND, MHD_HTTP_HEADER_HOST);
    return host && !req->public_path && !smd_cors_trusted_host(&req->srv->cfg, host);
}

/* Cross-site safety, authentication, then the route's handler. */
static enum MHD_Result handle(struct MHD_Connection *conn, smd_request *req)
{
    smd_server *srv = req->srv;
    req->dispatched = 1;
    if (strcmp(req->method, MHD_HTTP_METHOD_OPTIONS) == 0)
        return preflight(conn, req);
    if (foreign_host(conn, req)) {
        char shown[64];
        snprintf(shown, sizeof shown, "%s",
                 MHD_lookup_connection_value(conn, MHD_HEADER_KIND, MHD_HTTP_HEADER_HOST));
        sm_text_make_printable(shown, NULL);
        return smd_reply_problem(conn, req, 421, SMD_PROBLEM_MISDIRECTED,
                                 "Host %s is not a name of this daemon (list it with "
                                 "--allowed-host, or --public-url behind a proxy)", shown);
    }
    unsigned m = smd_method_bit(req->method);
    if (smd_cors_cross_site(&srv->cfg, conn, (m & (SMD_METHOD_POST | SMD_METHOD_DELETE)) != 0))
        return smd_reply_problem(conn, req, 403, SMD_PROBLEM_FORBIDDEN,
                                 "cross-site request refused: its Origin is neither this "
                                 "daemon's nor one listed with --cors-origin");
    req->who.admin = 1; /* no tokens: one tenant that sees everything */
    if (srv->tokens && !req->public_path) {
        smd_auth_result a = authenticate(conn, req);
        if (a != SMD_AUTH_OK)
            return smd_reply_problem(conn, req, 401, SMD_PROBLEM_UNAUTHORIZED,
                                     a == SMD_AUTH_MISSING
                                         ? "this daemon requires a bearer token "
                                           "(Authorization: Bearer <token>)"
                                         : "the bearer token is not valid");
    }
    enum MHD_Result r = dispatch(conn, req);
    if (r == MHD_YES && !req->replied && !req->upload && !req->body_state)
        return smd_reply_problem(conn, req, 500, SMD_PROBLEM_INTERNAL, "no response produced");
    if (req->upload && req->deferred) {
        /* an upload cannot have a reply waiting as well */
        req->srv->app->body_free(req);
    }
    return r;
}

/* First call of a request: the record, and the route of its path. */
static smd_request *request_new(smd_server *srv, const char *url, const char *method)
{
    smd_request *req = calloc(1, sizeof *req);
    if (!req)
        return NULL;
    req->srv = srv;
    req->t0 = sm_clock_seconds();
    snprintf(req->method, sizeof req->method, "%s", method);
    snprintf(req->path, sizeof req->path, "%s", url);
    srv->app->route(req, url, smd_method_bit(method));
    return req;
}

static enum MHD_Result on_request(void *cls, struct MHD_Connection *conn, const char *url,
                                  const char *method, const char *version, const char *upload_data,
                                  size_t *upload_data_size, void **req_cls)
{
    smd_server *srv = cls;
    smd_request *req = *req_cls;
    if (req) {
        if (*upload_data_size > 0)
            smd_conns_body(conn, req->bytes_in + *upload_data_size);
        else
            smd_conns_body_done(conn);
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
                return req->bytes_in > smd_drain_limit(srv->cfg.max_upload) ? MHD_NO : MHD_YES;
            }
            struct MHD_Response *resp = req->deferred;
            req->deferred = NULL;
            enum MHD_Result r = MHD_queue_response(conn, req->deferred_status, resp);
            MHD_destroy_response(resp);
            return r;
        }
        if ((req->upload || req->body_state) && !req->replied)
            return srv->app->body(conn, req, upload_data, upload_data_size);
        req->bytes_in += *upload_data_size;
        *upload_data_size = 0;
        return MHD_YES;
    }
    req = request_new(srv, url, method);
    if (!req)
        return MHD_NO;
    *req_cls = req;
    const char *strict = request_strictness(conn, version);
    if (strict) {
        /* answered at once; the body (if any) is not read: the connection
         * closes after the reply */
        req->dispatched = 1;
        smd_conns_request(conn, 0);
        return smd_reply_problem(conn, req, 400, SMD_PROBLEM_BAD_REQUEST, "%s", strict);
    }
    /* a transfer coding other than plain chunked: libmicrohttpd would
     * wait for a body it never hands over (no answer at all) */
    const char *te = MHD_lookup_connection_value(conn, MHD_HEADER_KIND,
                                                 MHD_HTTP_HEADER_TRANSFER_ENCODING);
    if (te && strcasecmp(te, "chunked") != 0) {
        char shown[64];
        snprintf(shown, sizeof shown, "%s", te);
        sm_text_make_printable(shown, NULL);
        req->dispatched = 1;
        smd_conns_request(conn, 0);
        return smd_reply_problem(conn, req, 501, SMD_PROBLEM_BAD_REQUEST,
                                 "Transfer-Encoding: %s is not supported (only chunked)", shown);
    }
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
    if (smd_conns_request(conn, req->body_pending) != 0) {
        /* answered at once, the body not read (the connection closes) */
        req->body_pending = 0;
        req->dispatched = 1;
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE,
                                 "too many request bodies and event streams in progress (from "
                                 "your address: --max-streams-per-ip; in all: --max-connections "
                                 "minus --reserved-connections): try again shortly");
    }
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
    smd_conns_idle(conn);
    double seconds = sm_clock_seconds() - req->t0;
    unsigned status = req->replied ? req->status : 499; /* client went away before a reply */
    smd_metrics_request(&srv->metrics, req->route_label, req->method, status, seconds, req->bytes_in,
                        req->bytes_out);
    if (smd_log_enabled(&srv->log, SMD_LOG_INFO)) {
        char remote[INET6_ADDRSTRLEN];
        smd_conn_address(conn, remote, sizeof remote);
        char path[sizeof req->path];
        snprintf(path, sizeof path, "%s", req->path);
        sm_text_make_printable(path, NULL);
        json_t *f = json_pack("{s:s,s:s,s:s,s:i,s:f,s:I,s:I,s:s}", "method", req->method, "path",
                              path, "route", req->route_label, "status", (int)status,
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
    srv->app->body_free(req);
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
    /* the daemon's own cuts of slow connections (smd_conns.h) would
     * otherwise flood the log during an attack: counted in /metrics */
    int cut = strstr(msg, "closed by remote side") != NULL;
    smd_logf(&srv->log, cut ? SMD_LOG_DEBUG : SMD_LOG_WARN, "httpd", "%s", msg);
}

/* --------------------------------------------------------------- daemon */

sm_status smd_http_start(smd_server *srv, const smd_http_app *app, sm_error *err)
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
    /* TLS: the certificate comes from smd_tls at each handshake */
    struct MHD_OptionItem tls[] = {
        {MHD_OPTION_HTTPS_CERT_CALLBACK, 0, smd_tls_callback()},
        {MHD_OPTION_HTTPS_PRIORITIES, 0, (void *)SMD_TLS_PRIORITIES},
        {MHD_OPTION_END, 0, NULL}};
    if (cfg->tls_cert[0])
        flags |= MHD_USE_TLS;
    else
        tls[0].option = MHD_OPTION_END;
    srv->ratelimit = smd_ratelimit_new(cfg->submit_rate, cfg->submit_window);
    smd_conns_limits climits = {.header_timeout = cfg->header_timeout,
                                .min_upload_rate = cfg->min_upload_rate,
                                .body_stall = cfg->body_stall_timeout,
                                .max_long_per_ip = cfg->max_streams_per_ip,
                                .max_connections = cfg->max_connections,
                                .reserved = cfg->reserved_connections,
                                .ipv4_prefix = cfg->submit_ipv4_prefix};
    if (!srv->ratelimit)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    srv->conns = smd_conns_new(&climits, err);
    if (!srv->conns)
        return SM_ERR_IO;
    srv->app = app;
    if (app->open(srv, err) != SM_OK)
        return SM_ERR_IO;
    /* Per-connection buffers come from the connection's pool, and the
     * pool must hold the request headers plus a send buffer. */
    srv->httpd = MHD_start_daemon(
        flags, (uint16_t)cfg->listen_port, NULL, NULL, on_request, srv, MHD_OPTION_EXTERNAL_LOGGER,
        mhd_logger, srv, MHD_OPTION_SOCK_ADDR,
        (struct sockaddr *)&ss, MHD_OPTION_THREAD_POOL_SIZE, (unsigned)cfg->http_threads,
        MHD_OPTION_CONNECTION_LIMIT, cfg->max_connections, MHD_OPTION_PER_IP_CONNECTION_LIMIT,
        cfg->max_connections_per_ip, MHD_OPTION_CONNECTION_TIMEOUT, cfg->connection_timeout,
        MHD_OPTION_CONNECTION_MEMORY_LIMIT, (size_t)cfg->connection_memory,
        MHD_OPTION_NOTIFY_COMPLETED, on_completed, srv, MHD_OPTION_NOTIFY_CONNECTION,
        smd_conns_notify, srv->conns, MHD_OPTION_ARRAY, tls, MHD_OPTION_END);
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
    /* the app's suspended requests (upload checks) answered before the
     * daemon stops (it must not stop with suspended connections) */
    if (srv->app)
        srv->app->quiesce(srv);
    if (srv->httpd) {
        MHD_stop_daemon(srv->httpd);
        srv->httpd = NULL;
    }
    if (srv->app)
        srv->app->close(srv); /* after the last upload is freed */
    smd_conns_free(srv->conns);
    srv->conns = NULL;
    smd_ratelimit_free(srv->ratelimit);
    srv->ratelimit = NULL;
    smd_tls_shutdown();
}

