/* The client's HTTP layer over libcurl (see http.h). */
#include "http.h"
#include "curl_api.h"
#include "msg.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include <jansson.h>

#ifndef SM_VERSION
#define SM_VERSION "unknown"
#endif


int http_global_init(char *msg, size_t cap)
{
    if (curl_api_load(msg, cap) != 0)
        return -1;
    CURLcode rc = curl_api.global_init(CURL_GLOBAL_DEFAULT);
    if (rc != CURLE_OK)
        return cli_fail(msg, cap, "cannot initialise libcurl: %s", curl_api.easy_strerror(rc));
    return 0;
}

void http_global_cleanup(void)
{
    curl_api.global_cleanup();
}

/* ------------------------------------------------------------ client */

static int token_ok(const char *t)
{
    size_t n = strlen(t);
    if (n == 0 || n > 4096)
        return 0;
    for (size_t i = 0; i < n; i++)
        if ((unsigned char)t[i] < 0x21 || (unsigned char)t[i] > 0x7e)
            return 0;
    return 1;
}

int http_client_init(http_client *c, const char *server, const char *token,
                     char *msg, size_t cap)
{
    memset(c, 0, sizeof *c);
    c->connect_timeout_ms = HTTP_CONNECT_TIMEOUT_MS;
    if (!server || !server[0])
        return cli_fail(msg, cap, "--server: empty URL");
    /* "host:port" alone means http://host:port (not curl's https) */
    char *with_scheme = NULL;
    if (!strstr(server, "://")) {
        size_t n = strlen(server) + 8;
        with_scheme = malloc(n);
        if (!with_scheme)
            return cli_fail(msg, cap, "out of memory");
        snprintf(with_scheme, n, "http://%s", server);
    }
    const char *text = with_scheme ? with_scheme : server;
    CURLU *u = curl_api.url();
    char *scheme = NULL, *query = NULL, *fragment = NULL, *full = NULL;
    int rc = -1;
    if (!u) {
        cli_fail(msg, cap, "out of memory");
        goto done;
    }
    CURLUcode uc = curl_api.url_set(u, CURLUPART_URL, text, 0);
    if (uc != CURLUE_OK) {
        cli_fail(msg, cap, "--server: '%.200s' is not a URL (%s); expected e.g. http://127.0.0.1:8080",
             server, curl_api.url_strerror(uc));
        goto done;
    }
    if (curl_api.url_get(u, CURLUPART_SCHEME, &scheme, 0) != CURLUE_OK ||
        (strcmp(scheme, "http") != 0 && strcmp(scheme, "https") != 0)) {
        cli_fail(msg, cap, "--server: '%.200s': only http:// and https:// URLs are supported", server);
        goto done;
    }
    if (curl_api.url_get(u, CURLUPART_QUERY, &query, 0) == CURLUE_OK ||
        curl_api.url_get(u, CURLUPART_FRAGMENT, &fragment, 0) == CURLUE_OK) {
        cli_fail(msg, cap, "--server: '%.200s': give the daemon's base URL, without ?query or #fragment",
             server);
        goto done;
    }
    if (curl_api.url_get(u, CURLUPART_URL, &full, 0) != CURLUE_OK) {
        cli_fail(msg, cap, "--server: '%.200s' is not a usable URL", server);
        goto done;
    }
    size_t n = strlen(full);
    while (n > 0 && full[n - 1] == '/')
        n--;
    c->base = strndup(full, n);
    if (!c->base) {
        cli_fail(msg, cap, "out of memory");
        goto done;
    }
    if (token && token[0]) {
        if (!token_ok(token)) {
            cli_fail(msg, cap, "--token: a token is 1 to 4096 printable ASCII characters without "
                           "spaces");
            goto done;
        }
        size_t hn = strlen(token) + 32;
        c->auth_header = malloc(hn);
        if (!c->auth_header) {
            cli_fail(msg, cap, "out of memory");
            goto done;
        }
        snprintf(c->auth_header, hn, "Authorization: Bearer %s", token);
    }
    c->curl = curl_api.easy_init();
    if (!c->curl) {
        cli_fail(msg, cap, "cannot initialise libcurl");
        goto done;
    }
    rc = 0;
done:
    curl_api.free(scheme);
    curl_api.free(query);
    curl_api.free(fragment);
    curl_api.free(full);
    curl_api.url_cleanup(u);
    free(with_scheme);
    if (rc != 0)
        http_client_free(c);
    return rc;
}

void http_client_free(http_client *c)
{
    if (c->curl)
        curl_api.easy_cleanup(c->curl);
    if (c->auth_header) {
        /* the token should not linger in freed memory */
        memset(c->auth_header, 0, strlen(c->auth_header));
        free(c->auth_header);
    }
    free(c->base);
    memset(c, 0, sizeof *c);
}

/* Builds base + path.  Returns a malloc'd string or NULL. */
static char *http_url(const http_client *c, const char *path)
{
    size_t n = strlen(c->base) + strlen(path) + 1;
    char *url = malloc(n);
    if (url)
        snprintf(url, n, "%s%s", c->base, path);
    return url;
}

/* ---------------------------------------------------------- transfer */

typedef struct transfer {
    const http_request *rq;
    http_response *rs;
    CURL *curl;
    int sink_result;    /* 0, or what the sink returned to stop */
    int too_large;
    int oom;
} transfer;

static int body_append(http_response *rs, const char *data, size_t n)
{
    char *b = realloc(rs->body, rs->len + n + 1);
    if (!b)
        return -1;
    rs->body = b;
    memcpy(rs->body + rs->len, data, n);
    rs->len += n;
    rs->body[rs->len] = '\0';
    return 0;
}

static size_t on_write(char *ptr, size_t size, size_t nmemb, void *userdata)
{
    transfer *t = userdata;
    size_t n = size * nmemb;
    http_response *rs = t->rs;
    if (rs->status == 0)
        curl_api.easy_getinfo(t->curl, CURLINFO_RESPONSE_CODE, &rs->status);
    int success = rs->status >= 200 && rs->status < 300;
    if (success && t->rq->sink) {
        rs->received += n;
        int r = t->rq->sink(t->rq->sink_user, ptr, n);
        if (r != 0) {
            t->sink_result = r;
            return 0; /* CURLE_WRITE_ERROR: stops the transfer */
        }
        return n;
    }
    size_t bound = !success ? HTTP_ERROR_BODY_MAX
                   : t->rq->max_body ? t->rq->max_body
                                     : HTTP_BODY_MAX;
    rs->received += n;
    if (rs->len + n > bound) {
        rs->truncated = 1;
        if (success) {
            t->too_large = 1;
            return 0;
        }
        /* an error body: keep its start, read (and drop) the rest */
        size_t room = bound > rs->len ? bound - rs->len : 0;
        if (room > 0 && body_append(rs, ptr, room) != 0) {
            t->oom = 1;
            return 0;
        }
        return n;
    }
    if (body_append(rs, ptr, n) != 0) {
        t->oom = 1;
        return 0;
    }
    return n;
}

static http_outcome classify(CURLcode rc, CURL *curl)
{
    switch (rc) {
    case CURLE_OK:
        return HTTP_DONE;
    case CURLE_COULDNT_RESOLVE_HOST:
    case CURLE_COULDNT_RESOLVE_PROXY:
    case CURLE_COULDNT_CONNECT:
    case CURLE_SSL_CONNECT_ERROR:
    case CURLE_PEER_FAILED_VERIFICATION:
    case CURLE_SSL_CERTPROBLEM:
    case CURLE_SSL_CIPHER:
    case CURLE_SSL_CACERT_BADFILE:
    case CURLE_SSL_ENGINE_NOTFOUND:
    case CURLE_SSL_ENGINE_SETFAILED:
        return HTTP_CONNECT_FAILED;
    case CURLE_OPERATION_TIMEDOUT: {
        curl_off_t connected = 0;
        curl_api.easy_getinfo(curl, CURLINFO_CONNECT_TIME_T, &connected);
        return connected > 0 ? HTTP_DROPPED : HTTP_CONNECT_FAILED;
    }
    case CURLE_SEND_ERROR:
    case CURLE_RECV_ERROR:
    case CURLE_PARTIAL_FILE:
    case CURLE_GOT_NOTHING:
    case CURLE_HTTP2:
    case CURLE_HTTP2_STREAM:
        return HTTP_DROPPED;
    case CURLE_OUT_OF_MEMORY:
    case CURLE_READ_ERROR:
    case CURLE_ABORTED_BY_CALLBACK:
    case CURLE_FAILED_INIT:
        return HTTP_LOCAL_ERROR;
    default:
        return HTTP_BAD_RESPONSE;
    }
}

http_outcome http_perform(http_client *c, const http_request *rq, http_response *rs)
{
    memset(rs, 0, sizeof *rs);
    CURL *curl = c->curl;
    char errbuf[CURL_ERROR_SIZE] = "";
    struct curl_slist *headers = NULL, *h;
    char accept[160];
    http_outcome out = HTTP_LOCAL_ERROR;
    char *url = http_url(c, rq->path);
    if (!url) {
        snprintf(rs->error, sizeof rs->error, "out of memory");
        return HTTP_LOCAL_ERROR;
    }
    /* a reset keeps the connection cache: consecutive requests reuse the
     * connection */
    curl_api.easy_reset(curl);
    transfer t = {.rq = rq, .rs = rs, .curl = curl};
    if (rq->accept) {
        snprintf(accept, sizeof accept, "Accept: %s", rq->accept);
        if (!(h = curl_api.slist_append(headers, accept)))
            goto oom;
        headers = h;
    }
    if (c->auth_header) {
        if (!(h = curl_api.slist_append(headers, c->auth_header)))
            goto oom;
        headers = h;
    }
    for (size_t i = 0; i < sizeof rq->headers / sizeof rq->headers[0] && rq->headers[i]; i++) {
        if (!(h = curl_api.slist_append(headers, rq->headers[i])))
            goto oom;
        headers = h;
    }
    curl_api.easy_setopt(curl, CURLOPT_URL, url);
    if (c->cacert)
        curl_api.easy_setopt(curl, CURLOPT_CAINFO, c->cacert);
    curl_api.easy_setopt(curl, CURLOPT_PROTOCOLS_STR, "http,https");
    curl_api.easy_setopt(curl, CURLOPT_FOLLOWLOCATION, 0L);
    curl_api.easy_setopt(curl, CURLOPT_USERAGENT, "shapematch/" SM_VERSION);
    curl_api.easy_setopt(curl, CURLOPT_ERRORBUFFER, errbuf);
    curl_api.easy_setopt(curl, CURLOPT_CONNECTTIMEOUT_MS,
                     rq->connect_timeout_ms > 0 ? rq->connect_timeout_ms : c->connect_timeout_ms);
    curl_api.easy_setopt(curl, CURLOPT_WRITEFUNCTION, on_write);
    curl_api.easy_setopt(curl, CURLOPT_WRITEDATA, &t);
    if (headers)
        curl_api.easy_setopt(curl, CURLOPT_HTTPHEADER, headers);
    if (rq->mime) {
        curl_api.easy_setopt(curl, CURLOPT_MIMEPOST, rq->mime);
    } else if (rq->body) {
        curl_api.easy_setopt(curl, CURLOPT_POSTFIELDSIZE_LARGE, (curl_off_t)rq->body_len);
        curl_api.easy_setopt(curl, CURLOPT_POSTFIELDS, rq->body);
    } else if (rq->method && strcmp(rq->method, "GET") != 0)
        curl_api.easy_setopt(curl, CURLOPT_CUSTOMREQUEST, rq->method);
    if (rq->gzip)
        curl_api.easy_setopt(curl, CURLOPT_ACCEPT_ENCODING, ""); /* all curl decodes */
    if (rq->stream) {
        /* a stream may be quiet for long (the daemon's keepalive is a
         * comment every ~15 s): no time limit, but TCP keepalive so that
         * a vanished peer is noticed */
        curl_api.easy_setopt(curl, CURLOPT_TCP_KEEPALIVE, 1L);
        curl_api.easy_setopt(curl, CURLOPT_TCP_KEEPIDLE, 30L);
        curl_api.easy_setopt(curl, CURLOPT_TCP_KEEPINTVL, 10L);
    } else {
        curl_api.easy_setopt(curl, CURLOPT_LOW_SPEED_LIMIT, 1L);
        curl_api.easy_setopt(curl, CURLOPT_LOW_SPEED_TIME, HTTP_STALL_SECONDS);
    }

    CURLcode rc = curl_api.easy_perform(curl);
    long status = 0;
    curl_api.easy_getinfo(curl, CURLINFO_RESPONSE_CODE, &status);
    if (rs->status == 0)
        rs->status = status;
    char *ctype = NULL;
    if (curl_api.easy_getinfo(curl, CURLINFO_CONTENT_TYPE, &ctype) == CURLE_OK && ctype)
        snprintf(rs->content_type, sizeof rs->content_type, "%s", ctype);
    out = classify(rc, curl);
    if (rc == CURLE_WRITE_ERROR) {
        if (t.sink_result > 0) {
            out = HTTP_STOPPED;
        } else if (t.sink_result < 0) {
            out = HTTP_LOCAL_ERROR;
            snprintf(rs->error, sizeof rs->error, "the response could not be stored");
        } else if (t.too_large) {
            out = HTTP_BAD_RESPONSE;
            snprintf(rs->error, sizeof rs->error, "the response is larger than %zu bytes",
                     rq->max_body ? rq->max_body : (size_t)HTTP_BODY_MAX);
        } else {
            out = HTTP_LOCAL_ERROR;
            snprintf(rs->error, sizeof rs->error, "out of memory");
        }
    } else if (out != HTTP_DONE) {
        snprintf(rs->error, sizeof rs->error, "%s", errbuf[0] ? errbuf : curl_api.easy_strerror(rc));
        /* curl's messages end with a newline at times */
        size_t n = strlen(rs->error);
        while (n > 0 && (rs->error[n - 1] == '\n' || rs->error[n - 1] == '\r'))
            rs->error[--n] = '\0';
    } else if (rs->status < 100) {
        out = HTTP_BAD_RESPONSE;
        snprintf(rs->error, sizeof rs->error, "no HTTP status in the response");
    }
    goto done;
oom:
    snprintf(rs->error, sizeof rs->error, "out of memory");
    out = HTTP_LOCAL_ERROR;
done:
    /* the handle must not keep pointers to what is freed here */
    curl_api.easy_setopt(curl, CURLOPT_HTTPHEADER, NULL);
    curl_api.easy_setopt(curl, CURLOPT_MIMEPOST, NULL);
    curl_api.easy_setopt(curl, CURLOPT_POSTFIELDS, NULL);
    curl_api.easy_setopt(curl, CURLOPT_ERRORBUFFER, NULL);
    curl_api.slist_free_all(headers);
    free(url);
    return out;
}

void http_response_free(http_response *rs)
{
    free(rs->body);
    rs->body = NULL;
    rs->len = 0;
}

int http_content_type_is(const http_response *rs, const char *type)
{
    size_t n = strlen(type);
    if (strncasecmp(rs->content_type, type, n) != 0)
        return 0;
    char next = rs->content_type[n];
    return next == '\0' || next == ';' || next == ' ';
}

const char *http_reason(long status)
{
    switch (status) {
    case 400: return "Bad Request";
    case 401: return "Unauthorized";
    case 403: return "Forbidden";
    case 404: return "Not Found";
    case 405: return "Method Not Allowed";
    case 406: return "Not Acceptable";
    case 409: return "Conflict";
    case 413: return "Content Too Large";
    case 415: return "Unsupported Media Type";
    case 422: return "Unprocessable Content";
    case 429: return "Too Many Requests";
    case 500: return "Internal Server Error";
    case 502: return "Bad Gateway";
    case 503: return "Service Unavailable";
    case 504: return "Gateway Timeout";
    default: return "";
    }
}

/* Copies text for a message: control characters become spaces, cut at
 * cap with "...". */
static void clean_copy(char *buf, size_t cap, const char *text, size_t len)
{
    if (cap == 0)
        return;
    size_t o = 0;
    for (size_t i = 0; i < len && o + 1 < cap; i++) {
        unsigned char ch = (unsigned char)text[i];
        buf[o++] = ch < 0x20 || ch == 0x7f ? ' ' : (char)ch;
    }
    buf[o] = '\0';
    if (o + 1 >= cap && len > o && cap > 4)
        memcpy(buf + cap - 4, "...", 4);
}

void http_problem_text(const http_response *rs, char *buf, size_t cap, char *type_out,
                       size_t type_cap)
{
    if (type_out && type_cap)
        type_out[0] = '\0';
    if (cap)
        buf[0] = '\0';
    json_t *doc = rs->body && rs->len ? json_loadb(rs->body, rs->len, 0, NULL) : NULL;
    if (json_is_object(doc)) {
        const char *detail = json_string_value(json_object_get(doc, "detail"));
        const char *title = json_string_value(json_object_get(doc, "title"));
        const char *type = json_string_value(json_object_get(doc, "type"));
        const char *text = detail && detail[0] ? detail : title;
        if (text)
            clean_copy(buf, cap, text, strlen(text));
        if (type && type_out && type_cap) {
            /* OGC exception types end in the exception name */
            const char *slash = strrchr(type, '/');
            if (strstr(type, "ogcapi-processes") && slash)
                clean_copy(type_out, type_cap, slash + 1, strlen(slash + 1));
        }
    }
    json_decref(doc);
    if (cap && !buf[0] && rs->body && rs->len) {
        /* not a problem document: the first line of whatever came */
        size_t n = 0;
        while (n < rs->len && n < 200 && rs->body[n] != '\n')
            n++;
        clean_copy(buf, cap, rs->body, n);
    }
    if (cap && !buf[0])
        snprintf(buf, cap, "%s", http_reason(rs->status)[0] ? http_reason(rs->status)
                                                              : "no detail given");
}
