/* Event streams over HTTP (see smd_stream.h): libmicrohttpd's side of the
 * engine's followers (jobs/smd_follow.h). */
#include "api/smd_stream.h"
#include "http/smd_http.h"
#include "http/smd_mhd.h"

/* Called by smd_follow_next with srv->lock held (see smd_follow.h): the
 * connection's thread suspends its own connection. */
static void conn_sleep(void *conn)
{
    MHD_suspend_connection(conn);
}

static void conn_wake(void *conn)
{
    MHD_resume_connection(conn);
}

static const smd_follow_waker mhd_waker = {conn_sleep, conn_wake};

static ssize_t stream_read(void *cls, uint64_t pos, char *out, size_t max)
{
    (void)pos;
    ssize_t n = smd_follow_next(cls, out, max);
    return n == SMD_FOLLOW_END     ? MHD_CONTENT_READER_END_OF_STREAM
           : n == SMD_FOLLOW_ERROR ? MHD_CONTENT_READER_END_WITH_ERROR
                                   : n;
}

static void stream_free(void *cls)
{
    smd_follow_unsubscribe(cls);
}

struct MHD_Response *smd_stream_response(smd_server *srv, struct MHD_Connection *conn,
                                         smd_follow_request *rq, int *found, char *msg,
                                         size_t cap)
{
    rq->conn = conn;
    rq->waker = &mhd_waker;
    smd_follower *f = smd_follow_subscribe(srv, rq, found, msg, cap);
    if (!f)
        return NULL;
    /* the follower sleeps only in its own reader: until the response is
     * queued, a wake-up finds nothing to wake */
    struct MHD_Response *resp =
        MHD_create_response_from_callback(MHD_SIZE_UNKNOWN, 16 * 1024, stream_read, f, stream_free);
    if (!resp) {
        smd_follow_unsubscribe(f);
        snprintf(msg, cap, "out of memory");
        return NULL;
    }
    MHD_add_response_header(resp, MHD_HTTP_HEADER_CONTENT_TYPE,
                            rq->sse ? "text/event-stream; charset=utf-8" : "application/x-ndjson");
    MHD_add_response_header(resp, MHD_HTTP_HEADER_CACHE_CONTROL, "no-cache");
    MHD_add_response_header(resp, "X-Accel-Buffering", "no");
    return resp;
}

/* With srv->lock held (smd_follow_revoke): tokens_lock after it. */
static int still_valid(void *ctx, const char *authorization, const char *token)
{
    return smd_http_identify(ctx, authorization, token, NULL) == SMD_AUTH_OK;
}

void smd_stream_revoke(smd_server *srv)
{
    smd_follow_revoke(srv, still_valid, srv);
}
