/* The client's HTTP layer over libcurl: one easy handle per client (so
 * that consecutive requests reuse the connection), the daemon's base URL,
 * the bearer token, and requests whose outcome is classified the way the
 * commands report it:
 *   - no connection could be made (refused, unknown host, connect timeout);
 *   - the connection broke off during the exchange;
 *   - a complete response (any status; error bodies are kept in memory so
 *     that the problem+json "detail" can be shown);
 *   - a response that cannot be understood;
 *   - a local failure (out of memory, the body sink refused the data).
 *
 * Timeouts: 10 s to connect.  Ordinary requests are abandoned when no
 * byte moves for HTTP_STALL_SECONDS; event streams (request.stream) have
 * no time limit at all and rely on TCP keepalive to notice a dead peer. */
#ifndef CLI_HTTP_H
#define CLI_HTTP_H

#include <stddef.h>

#include <curl/curl.h>

#define HTTP_CONNECT_TIMEOUT_MS 10000L
#define HTTP_STALL_SECONDS 300L
/* Error bodies (problem+json) kept in memory, at most. */
#define HTTP_ERROR_BODY_MAX (64 * 1024)
/* Default bound of a 2xx body kept in memory (JSON documents). */
#define HTTP_BODY_MAX (16 * 1024 * 1024)
#define HTTP_MSG_LEN 512

typedef struct http_client {
    CURL *curl;
    char *base;            /* "http://host:port[/prefix]", no trailing '/' */
    char *auth_header;     /* "Authorization: Bearer ...", or NULL */
    long connect_timeout_ms;
    const char *cacert;    /* PEM CA file for https (borrowed), NULL: the system's */
} http_client;

/* Loads libcurl (curl_api.h) and calls curl_global_init; and
 * curl_global_cleanup.  Once per process. */
int http_global_init(char *msg, size_t cap);
void http_global_cleanup(void);

/* server: "http://127.0.0.1:8080" and the like (http or https, no query
 * or fragment; a path prefix is kept).  token may be NULL or "" (no
 * Authorization header); it must be printable ASCII without spaces.
 * Returns 0, or -1 with a message (a usage error). */
int http_client_init(http_client *c, const char *server, const char *token,
                     char *msg, size_t cap);
void http_client_free(http_client *c);

typedef enum http_outcome {
    HTTP_DONE = 0,          /* a complete response; see status */
    HTTP_CONNECT_FAILED,    /* no connection to the daemon */
    HTTP_DROPPED,           /* connected, then the exchange broke off */
    HTTP_BAD_RESPONSE,      /* not HTTP we understand, bad encoding */
    HTTP_STOPPED,           /* the sink asked to stop (not an error) */
    HTTP_LOCAL_ERROR        /* out of memory, the sink failed */
} http_outcome;

/* Receives the (decoded) body of a 2xx response.  Returns 0 to go on,
 * 1 to stop the transfer normally (HTTP_STOPPED), -1 on failure
 * (HTTP_LOCAL_ERROR; the sink keeps its own message). */
typedef int (*http_sink_fn)(void *user, const char *data, size_t len);

typedef struct http_request {
    const char *method;          /* "GET" (NULL), "POST", "DELETE" */
    const char *path;            /* "/v1/jobs?status=running" */
    const char *accept;          /* Accept header, or NULL */
    const char *headers[4];      /* extra "Name: value" lines, NULL ends */
    curl_mime *mime;             /* multipart POST body, or NULL */
    const char *body;            /* else a POST body of body_len bytes (its
                                  * Content-Type among headers), or NULL */
    size_t body_len;
    int gzip;                    /* advertise compression, decode it */
    int stream;                  /* an event stream: no time limit */
    long connect_timeout_ms;     /* 0: the client's */
    http_sink_fn sink;           /* 2xx bodies; NULL: kept in memory */
    void *sink_user;
    size_t max_body;             /* in-memory 2xx body bound (0: HTTP_BODY_MAX) */
} http_request;

typedef struct http_response {
    long status;                 /* 0 when no response arrived */
    char content_type[128];
    char *body;                  /* NUL-terminated; 2xx without a sink, or any error status */
    size_t len;
    int truncated;               /* the body went past its bound */
    size_t received;             /* body bytes delivered (memory or sink) */
    char error[HTTP_MSG_LEN];    /* transport error text (not HTTP_DONE) */
} http_response;


/* Performs the request.  rs is filled (free it with
 * http_response_free) whatever the outcome. */
http_outcome http_perform(http_client *c, const http_request *rq,
                          http_response *rs);
void http_response_free(http_response *rs);

/* Whether the response's media type (parameters ignored) is `type`. */
int http_content_type_is(const http_response *rs, const char *type);

/* Human-readable part of a problem+json (RFC 9457) body: "detail", else
 * "title", else the start of the body; the reason phrase of the status
 * when there is no body.  Also names the problem type when it is one of
 * the OGC exceptions ("no-such-job", ...), in type_out (may be NULL). */
void http_problem_text(const http_response *rs, char *buf, size_t cap,
                       char *type_out, size_t type_cap);

/* Reason phrase of a status ("Not Found"), "" when unknown. */
const char *http_reason(long status);

#endif
