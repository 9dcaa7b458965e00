/* HTTP front of shapematchd on libmicrohttpd: daemon setup and dispatch
 * only.  Requests are routed by what main hands over (smd_http_app: the
 * api/ layer's route table, api/smd_route_table.c), authenticated, logged (one JSON line each) and counted (metrics);
 * replies are made by the reply layer (smd_reply.h).
 *
 * libmicrohttpd runs with its internal polling threads (epoll, a pool of
 * --http-threads), suspend/resume enabled for event streams, and these
 * limits: --max-connections in total, --max-connections-per-ip,
 * --connection-timeout of inactivity (slow or stalled requests are
 * closed; suspended event streams are exempt and get keepalives instead),
 * --connection-memory per connection (request line + headers + send
 * buffer; larger headers get 431/413 from libmicrohttpd).  The inactivity
 * timeout is reset by every byte: the absolute header deadline, the
 * minimum body rate and the reserve of sockets for short requests are
 * smd_conns.h's (a registry fed by MHD_OPTION_NOTIFY_CONNECTION and the
 * handler); the submission limits smd_ratelimit.h's. */
#ifndef SMD_HTTP_H
#define SMD_HTTP_H

#include <stddef.h>

#include "shapematch/sm_error.h"
#include "base/smd_server.h"
#include "http/smd_auth.h"
#include "http/smd_reply.h"

/* What the front serves, from above (api/smd_route_table.c: smd_api), so
 * that http/ includes nothing of the handlers.  Every call is made
 * without srv->lock. */
typedef struct smd_http_app {
    /* A new request's route: sets req->route (NULL: no row takes its
     * method), req->allowed, req->route_label, req->public_path and what
     * the path captures (id, bad_id, pid, arg). */
    void (*route)(smd_request *req, const char *path, unsigned method);
    /* Answers a request whose req->route is set (or attaches req->upload). */
    enum MHD_Result (*handle)(struct MHD_Connection *conn, smd_request *req);
    /* The next piece of req->upload's body (*size 0: the body is in). */
    enum MHD_Result (*body)(struct MHD_Connection *conn, smd_request *req, const char *data,
                            size_t *size);
    /* Frees req->upload (NULL allowed) and clears it. */
    void (*body_free)(smd_request *req);
    /* Around the daemon: open before it starts (SM_OK or logged why),
     * quiesce before it stops (suspended requests answered), close after. */
    sm_status (*open)(smd_server *srv, sm_error *err);
    void (*quiesce)(smd_server *srv);
    void (*close)(smd_server *srv);
} smd_http_app;

/* A credential (the Authorization header, else a bare token; NULL when
 * absent) against the daemon's current tokens, taking tokens_lock (SIGHUP
 * replaces them); fills who (may be NULL) as smd_tokens_identify.
 * SMD_AUTH_OK when the daemon has no tokens.  After srv->lock or alone. */
smd_auth_result smd_http_identify(smd_server *srv, const char *authorization, const char *token,
                                  smd_identity *who);

sm_status smd_http_start(smd_server *srv, const smd_http_app *app, sm_error *err);
/* Stops accepting connections (the listening socket is closed). */
void smd_http_quiesce(smd_server *srv);
/* Closes every connection and stops the threads.  Every event stream
 * must have been resumed (smd_follow_end_all) before. */
void smd_http_stop(smd_server *srv);

#endif
