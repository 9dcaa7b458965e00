/* The reply layer of shapematchd, below every route handler (the shape of
 * systemd journal-remote's microhttpd-util.c): the per-request record,
 * the problem types, JSON / problem+json / buffer replies, gzip of
 * buffered bodies and content negotiation.
 *
 * It knows libmicrohttpd, jansson and the daemon's shared state, and
 * nothing of the routes: the handlers (api/: smd_routes.c, smd_results.c,
 * smd_upload.c) include it, the route table (api/smd_route_table.c)
 * includes the handlers, and main hands the table to the dispatcher
 * (smd_http.c: smd_http_app), which includes no handler. */
#ifndef SMD_REPLY_H
#define SMD_REPLY_H

#include <microhttpd.h>
#include <stdint.h>

#include <jansson.h>

#include "base/smd_server.h"
#include "http/smd_auth.h"
#include "base/smd_util.h"
#include "http/smd_auth.h"

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
#define SMD_PROBLEM_FORBIDDEN "about:blank"
#define SMD_PROBLEM_MISDIRECTED "about:blank"
#define SMD_PROBLEM_NOT_FOUND "about:blank"
#define SMD_PROBLEM_METHOD "about:blank"
#define SMD_PROBLEM_UNAVAILABLE "about:blank"
#define SMD_PROBLEM_INTERNAL "about:blank"
#define SMD_PROBLEM_STORAGE "about:blank"
#define SMD_PROBLEM_TOO_MANY "about:blank"
/* an Idempotency-Key reused with a different request (IETF httpapi draft) */
#define SMD_PROBLEM_IDEMPOTENCY_MISMATCH "https://shapematch.invalid/problems/idempotency-key-mismatch"

struct smd_upload;
struct smd_route; /* the row of the route table that matched (smd_route_table.h) */

/* One request (libmicrohttpd's per-request pointer). */
typedef struct smd_request {
    smd_server *srv;
    double t0;                   /* monotonic */
    const struct smd_route *route; /* the row for this path and method, or NULL */
    unsigned allowed;            /* methods of the path (0: no route has it) */
    int public_path;             /* answered without a bearer token */
    smd_identity who;            /* tenant of the token (admin without tokens) */
    const char *route_label;     /* metrics label of the path ("other" if none) */
    char method[8];
    char path[256];              /* for the log, truncated */
    char id[SMD_ID_LEN + 1];     /* job id in the path, "" if none */
    int bad_id;                  /* the path's job id is malformed */
    char pid[64];                /* process id in the path ({pid}) */
    char arg[24];                /* last variable segment, e.g. {iteration} */
    unsigned status;             /* what was queued */
    unsigned retry_after;        /* seconds for the Retry-After of a 429 or 503 (503: 5 when 0) */
    uint64_t bytes_in, bytes_out;
    struct smd_upload *upload;   /* POST /v1/jobs in progress */
    /* Another route's body reader (api/: POST /v1/jobs/{id}/warp), when
     * the body is not an upload: the app's body and body_free take it. */
    void *body_state;
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
} smd_request;

/* How much of a body the daemon reads and drops after it has decided to
 * refuse it (a deferred reply, an upload over --max-upload): a client
 * that sends no "Expect: 100-continue" must be allowed to finish sending
 * to see the answer, but one that goes on far past the limit is cut off
 * by closing the connection.  Four times the limit, plus 16 MiB so that
 * a small limit does not cut ordinary clients short. */
uint64_t smd_drain_limit(uint64_t max_upload);

/* Method set bits (the route table's rows, a 405's Allow list). */
#define SMD_METHOD_GET (1u << 0)
#define SMD_METHOD_HEAD (1u << 1)
#define SMD_METHOD_POST (1u << 2)
#define SMD_METHOD_DELETE (1u << 3)
#define SMD_METHOD_READ (SMD_METHOD_GET | SMD_METHOD_HEAD)

/* Bit of a method name ("GET" -> SMD_METHOD_GET); 0 for any other. */
unsigned smd_method_bit(const char *method);

/* "GET, HEAD, POST" for a method set, into buf (cap bytes). */
void smd_methods_format(unsigned methods, char *buf, size_t cap);

/* ---- replies (queue the response and record the status) ---- */

/* The browser security headers every reply gets (smd_reply adds them):
 * X-Content-Type-Options: nosniff, X-Frame-Options: DENY,
 * Content-Security-Policy: frame-ancestors 'none', Referrer-Policy:
 * no-referrer. */
void smd_reply_security_headers(struct MHD_Response *resp);

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
 * the detail starts with one ("params.clamp.radius: ...").  401 adds
 * WWW-Authenticate, 503 Retry-After, 429 Retry-After of req->retry_after. */
enum MHD_Result smd_reply_problem(struct MHD_Connection *conn, smd_request *req,
                                  unsigned status, const char *type, const char *detail_fmt, ...)
    __attribute__((format(printf, 5, 6)));
/* 405 problem with the Allow header set to allow ("GET, HEAD"). */
enum MHD_Result smd_reply_method_not_allowed(struct MHD_Connection *conn, smd_request *req,
                                             const char *allow);

/* gzip (RFC 1952) of len bytes into a new malloc'd buffer.  0 or -1. */
int smd_gzip_buffer(const void *data, size_t len, char **out, size_t *out_len);

#endif
