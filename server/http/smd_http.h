/* HTTP front of shapematchd on libmicrohttpd: daemon setup and dispatch
 * only.  Requests are routed by the route table (smd_route_table.h),
 * authenticated, logged (one JSON line each) and counted (metrics);
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

#include "shapematch/sm_error.h"
#include "base/smd_server.h"

sm_status smd_http_start(smd_server *srv, sm_error *err);
/* Stops accepting connections (the listening socket is closed). */
void smd_http_quiesce(smd_server *srv);
/* Closes every connection and stops the threads.  Every event stream
 * must have been resumed (smd_stream_end_all) before. */
void smd_http_stop(smd_server *srv);

#endif
