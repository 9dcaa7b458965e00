/* HTTP front of shapematchd on libmicrohttpd: daemon setup, routing,
 * authentication, per-request bookkeeping (log line, metrics) and the
 * reply helpers shared by the route handlers (JSON bodies and RFC 9457
 * problem details).
 *
 * libmicrohttpd runs with its internal polling threads (epoll, a pool of
 * --http-threads), suspend/resume enabled for event streams, and these
 * limits: --max-connections in total, --max-connections-per-ip,
 * --connection-timeout of inactivity (slow or stalled requests are
 * closed; suspended event streams are exempt and get keepalives instead),
 * --connection-memory per connection (request line + headers + send
 * buffer; larger headers get 431/413 from libmicrohttpd). */
#ifndef SMD_HTTP_H
#define SMD_HTTP_H

#include <microhttpd.h>
#include <stdint.h>

#include <jansson.h>

#include "smd_metrics.h"
#include "smd_server.h"

/* Problem types (RFC 9457 "type"): the OGC API - Processes exception
 * types where one applies, otherwise about:blank (the title is then the
 * HTTP status phrase and the detail says what is wrong), as documented in
 * proto/openapi.yaml.  The names below only say why each reply is sent. */
#define SMD_PROBLEM_NO_SUCH_JOB "http://www.opengis.net/def/exceptions/ogcapi-processes-1/1.0/no-such-job"
#define SMD_PROBLEM_RESULT_NOT_READY "http://www.opengis.net/def/exceptions/ogcapi-processes-1/1.0/result-not-ready"
#define SMD_PROBLEM_NO_SUCH_PROCESS "http://www.opengis.net/def/exceptions/ogcapi-processes-1/1.0/no-such-process"
#define SMD_PROBLEM_INVALID_INPUT "about:blank"
#define SMD_PROBLEM_BAD_REQUEST "about:blank"
#define SMD_PROBLEM_BAD_MULTIPART "about:blank"
#define SMD_PROBLEM_TOO_LARGE "about:blank"
#define SMD_PROBLEM_UNSUPPORTED_MEDIA "about:blank"
#define SMD_PROBLEM_NOT_ACCEPTABLE "about:blank"
#define SMD_PROBLEM_UNAUTHORIZED "about:blank"
#define SMD_PROBLEM_NOT_FOUND "about:blank"
#define SMD_PROBLEM_METHOD "about:blank"
#define SMD_PROBLEM_UNAVAILABLE "about:blank"
#define SMD_PROBLEM_INTERNAL "about:blank"
#define SMD_PROBLEM_STORAGE "about:blank"

struct smd_upload;

/* One request (libmicrohttpd's per-request pointer). */
typedef struct smd_request {
    smd_server *srv;
    double t0;                   /* monotonic */
    smd_route route;
    char method[8];
    char path[256];              /* for the log, truncated */
    char id[SMD_ID_LEN + 1];     /* job id in the path, "" if none */
    unsigned status;             /* what was queued */
    uint64_t bytes_in, bytes_out;
    struct smd_upload *upload;   /* POST /v1/jobs in progress */
    int replied;
    /* A request with a body still to come: a reply made before its end
     * (an error, an idempotent replay) waits here while the body is read
     * and dropped, then goes out.  Replying first and closing would make
     * the client's send fail before it reads the reply (clients without
     * "Expect: 100-continue", e.g. browsers, would see a reset). */
    int body_pending;
    struct MHD_Response *deferred;
    unsigned deferred_status;
    /* Requests without a body are answered on libmicrohttpd's second call,
     * once the whole request has been read: a response queued on the first
     * call counts as an early reply and costs the connection its
     * keep-alive. */
    int dispatched;
    char pid[64];                /* process id in the path */
    int bad_id;                  /* the path's job id is malformed */
} smd_request;

sm_status smd_http_start(smd_server *srv, sm_error *err);
/* Stops accepting connections (the listening socket is closed). */
void smd_http_quiesce(smd_server *srv);
/* Closes every connection and stops the threads.  Every event stream
 * must have been resumed (smd_stream_collect_all) before. */
void smd_http_stop(smd_server *srv);

/* ---- replies (queue the response and record the status) ---- */

enum MHD_Result smd_reply(struct MHD_Connection *conn, smd_request *req, unsigned status,
                          struct MHD_Response *resp);
/* A response for body (malloc'd, taken over), gzip-compressed when the
 * request's Accept-Encoding allows it; counts the bytes sent.  The caller
 * adds its headers and calls smd_reply.  NULL when out of memory. */
struct MHD_Response *smd_buffer_response(struct MHD_Connection *conn, smd_request *req,
                                         const char *content_type, char *body, size_t len);
/* body is stolen; pretty-printed JSON, Content-Type application/json. */
enum MHD_Result smd_reply_json(struct MHD_Connection *conn, smd_request *req, unsigned status,
                               json_t *body);
/* application/problem+json {type, title, status, detail, instance}, and
 * for 400/422 "invalid-params" naming the part or parameter at fault when
 * the detail starts with one ("params.clamp.radius: ..."). */
enum MHD_Result smd_reply_problem(struct MHD_Connection *conn, smd_request *req,
                                  unsigned status, const char *type, const char *detail_fmt, ...)
    __attribute__((format(printf, 5, 6)));

/* Status document of a job (OGC statusInfo with links).  Lock held. */
json_t *smd_status_document(const smd_job *job);

/* ---- content negotiation ---- */

/* Picks among offered media types (first = default) the one the Accept
 * header prefers (q-values, type/ and star wildcards).  Returns the
 * index, 0 when accept is NULL or empty, -1 when none is acceptable. */
int smd_accept_choose(const char *accept, const char *const *offered, int n);
/* 1 when the Accept-Encoding header value allows gzip. */
int smd_accepts_gzip(const char *accept_encoding);

/* gzip (RFC 1952) of len bytes into a new malloc'd buffer.  0 or -1. */
int smd_gzip_buffer(const void *data, size_t len, char **out, size_t *out_len);

#endif
