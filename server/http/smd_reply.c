/* Replies of shapematchd (see smd_reply.h). */
#include "http/smd_reply.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

#include "sm_json.h"
#include "sm_proto_text.h"
#include "sm_proto_vocab.h"
#include "http/smd_cors.h"
#include "http/smd_negotiate.h"

uint64_t smd_drain_limit(uint64_t max_upload)
{
    /* --max-upload is bounded by the configuration (smd_config.c), far
     * below UINT64_MAX / 4: the sum does not overflow */
    return 4 * max_upload + (16u << 20);
}

void smd_reply_security_headers(struct MHD_Response *resp)
{
    /* a download is never sniffed into HTML or a script; no page may
     * frame ours (clickjacking); no URL leaves in a Referer (an
     * access_token query parameter would) */
    MHD_add_response_header(resp, "X-Content-Type-Options", "nosniff");
    MHD_add_response_header(resp, "X-Frame-Options", "DENY");
    MHD_add_response_header(resp, "Content-Security-Policy", "frame-ancestors 'none'");
    MHD_add_response_header(resp, "Referrer-Policy", "no-referrer");
}

enum MHD_Result smd_reply(struct MHD_Connection *conn, smd_request *req, unsigned status,
                          struct MHD_Response *resp)
{
    if (!resp)
        return MHD_NO;
    smd_cors_decorate(&req->srv->cfg, conn, resp);
    smd_reply_security_headers(resp);
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
    char *text = body ? sm_json_dumps(body, 2) : NULL;
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
    if (strcmp(type, SMD_PROBLEM_IDEMPOTENCY_MISMATCH) == 0)
        return "Idempotency-Key reused with a different request";
    const char *r = MHD_get_reason_phrase_for(status);
    return (r && *r) ? r : "Error";
}

/* "template: line 3: ..." -> {name: template, reason: line 3: ...};
 * likewise target_mesh, target_sol and params paths.  NULL otherwise. */
static json_t *invalid_params(const char *detail)
{
    const char *const *parts = sm_part_names;
    const char *colon = strstr(detail, ": ");
    if (!colon)
        return NULL;
    size_t n = (size_t)(colon - detail);
    for (size_t i = 0; i < SM_NPARTS; i++) {
        size_t k = strlen(parts[i]);
        if (n >= k && strncmp(detail, parts[i], k) == 0 && (n == k || detail[k] == '.' || detail[k] == '[')) {
            char name[160];
            snprintf(name, sizeof name, "%.*s", (int)(n < sizeof name ? n : sizeof name - 1), detail);
            return json_pack("[{s:s,s:s}]", "name", name, "reason", colon + 2);
        }
    }
    return NULL;
}

/* The problem+json response (not yet queued); NULL when out of memory. */
static struct MHD_Response *problem_response(struct MHD_Connection *conn, smd_request *req,
                                             unsigned status, const char *type,
                                             const char *detail)
{
    json_t *body = json_object();
    json_object_set_new(body, "type", json_string(type));
    json_object_set_new(body, "title", json_string(problem_title(status, type)));
    json_object_set_new(body, "status", json_integer(status));
    json_object_set_new(body, "detail", json_string(detail));
    char instance[300];
    snprintf(instance, sizeof instance, "%s", req->path);
    sm_text_make_printable(instance, " ");
    json_object_set_new(body, "instance", json_string(instance));
    if (status == 400 || status == 422) {
        json_t *ip = invalid_params(detail);
        if (ip)
            json_object_set_new(body, "invalid-params", ip);
    }
    char *text = sm_json_dumps(body, 2);
    json_decref(body);
    if (!text)
        return NULL;
    return smd_buffer_response(conn, req, "application/problem+json", text, strlen(text));
}

enum MHD_Result smd_reply_problem(struct MHD_Connection *conn, smd_request *req, unsigned status,
                                  const char *type, const char *detail_fmt, ...)
{
    char detail[1024];
    va_list ap;
    va_start(ap, detail_fmt);
    vsnprintf(detail, sizeof detail, detail_fmt, ap);
    va_end(ap);
    sm_text_make_printable(detail, NULL); /* it may quote client input: valid UTF-8 / JSON */
    if (req && req->srv)
        smd_unroot(detail, req->srv->cfg.spool); /* a file is named, never where the spool is */
    struct MHD_Response *resp = problem_response(conn, req, status, type, detail);
    if (!resp)
        return MHD_NO;
    if (status == 401) {
        const char *auth = MHD_lookup_connection_value(conn, MHD_HEADER_KIND,
                                                       MHD_HTTP_HEADER_AUTHORIZATION);
        MHD_add_response_header(resp, MHD_HTTP_HEADER_WWW_AUTHENTICATE,
                                auth ? "Bearer realm=\"shapematch\", error=\"invalid_token\""
                                     : "Bearer realm=\"shapematch\"");
    }
    if (status == 503 || status == 429) {
        char wait[16];
        unsigned seconds = req->retry_after ? req->retry_after : status == 503 ? 5 : 1;
        snprintf(wait, sizeof wait, "%u", seconds);
        MHD_add_response_header(resp, MHD_HTTP_HEADER_RETRY_AFTER, wait);
    }
    return smd_reply(conn, req, status, resp);
}

enum MHD_Result smd_reply_method_not_allowed(struct MHD_Connection *conn, smd_request *req,
                                             const char *allow)
{
    char detail[1024];
    snprintf(detail, sizeof detail, "%s is not allowed on %s (allowed: %s)", req->method, req->path,
             allow);
    sm_text_make_printable(detail, NULL);
    struct MHD_Response *resp = problem_response(conn, req, 405, SMD_PROBLEM_METHOD, detail);
    if (!resp)
        return MHD_NO;
    MHD_add_response_header(resp, MHD_HTTP_HEADER_ALLOW, allow);
    return smd_reply(conn, req, 405, resp);
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

/* ------------------------------------------------------------ methods */

static const char *const method_names[] = {"GET", "HEAD", "POST", "DELETE"};

unsigned smd_method_bit(const char *method)
{
    for (unsigned i = 0; i < sizeof method_names / sizeof method_names[0]; i++)
        if (strcmp(method, method_names[i]) == 0)
            return 1u << i;
    return 0;
}

void smd_methods_format(unsigned methods, char *buf, size_t cap)
{
    size_t len = 0;
    buf[0] = '\0';
    for (unsigned i = 0; i < sizeof method_names / sizeof method_names[0]; i++) {
        if (!(methods & (1u << i)))
            continue;
        int n = snprintf(buf + len, cap - len, "%s%s", len ? ", " : "", method_names[i]);
        if (n < 0 || (size_t)n >= cap - len)
            return;
        len += (size_t)n;
    }
}
