/* Connection deadlines of shapematchd: slow clients cannot starve the
 * daemon (issue 8).
 *
 * libmicrohttpd's --connection-timeout is an inactivity timeout, reset by
 * every byte, so a client trickling one byte a second holds its socket
 * forever, and enough of them fill --max-connections.  This registry
 * records every connection (MHD_OPTION_NOTIFY_CONNECTION) with the time
 * its current phase began, and closes, by shutdown(2) of its socket
 * (libmicrohttpd then sees the end of the stream and cleans up):
 * - a connection whose request line and headers are not complete
 *   --header-timeout after it opened, or after its previous request ended
 *   (idle keep-alive connections included), however steadily they come;
 * - a request whose body (an upload) arrives slower than
 *   --min-upload-rate bytes per second on average, once --header-timeout
 *   has passed since its headers, or that brings no byte for
 *   --body-stall-timeout (a body that sent much, then stopped: its average
 *   rate would hold it for hours);
 * - when fewer than --reserved-connections of --max-connections are
 *   free, the oldest connections still sending their headers after
 *   SMD_CONNS_BUSY_HEADERS seconds, until the reserve is free again (at
 *   each new connection and at each sweep): a short request (/healthz, a
 *   status) sends its headers at once, so it always finds a socket.
 * - when the reserve is still short, the uploads with the lowest average
 *   rate (sending for more than SMD_CONNS_BUSY_HEADERS).
 * Long-lived requests (bodies being received, event streams) are capped
 * per address (--max-streams-per-ip; an IPv6 client per /64) and together
 * (--max-connections minus the reserve), so that floods of streams or
 * slow uploads always leave the reserve to /healthz and status requests
 * (issue 28).  At the total cap every address has a fair share, the cap
 * over the addresses holding any: a new stream ends the oldest stream of
 * the address most over its share, never one of an address within it
 * (issue 37: from four addresses an attacker evicted a victim's one
 * stream 14 times in 20 s); when none is over, the new stream is refused.
 * Suspended connections (event streams, uploads being checked) and
 * replies being sent are exempt from the deadlines;
 * --max-connections-per-ip still bounds what one address holds.
 *
 * A sweep thread runs every SMD_CONNS_SWEEP seconds.  One mutex guards the
 * registry; a socket is shut down only with it held, and libmicrohttpd
 * reports a connection closed (which removes it, under the mutex) before it
 * closes the descriptor, so a descriptor number is never reused under us.
 * No libmicrohttpd call is made with the mutex held. */
#ifndef SMD_CONNS_H
#define SMD_CONNS_H

#include <microhttpd.h>
#include <stddef.h>
#include <stdint.h>

#include "shapematch/sm_error.h"

#define SMD_CONNS_SWEEP 0.25
#define SMD_CONNS_BUSY_HEADERS 1.0

typedef struct smd_conns smd_conns;

typedef struct smd_conns_limits {
    double header_timeout;     /* seconds */
    uint64_t min_upload_rate;  /* bytes per second, 0 = none */
    double body_stall;         /* seconds a body may bring no byte, 0 = none */
    unsigned max_connections;
    unsigned reserved;         /* < max_connections */
    unsigned max_long_per_ip;  /* bodies and streams of one address, 0 = no cap */
    unsigned ipv4_prefix;      /* an address is its key (smd_ratelimit_address_key):
                                  an IPv6 one its /64, an IPv4 one its network of
                                  these bits (--submit-ipv4-prefix; 0: 32) */
} smd_conns_limits;

typedef struct smd_conns_counts {
    uint64_t header_deadline;  /* closed: headers too slow */
    uint64_t slow_body;        /* closed: body under the minimum rate */
    uint64_t evicted;          /* closed: to keep the reserve free */
    uint64_t long_refused;     /* bodies and streams refused by the caps */
    uint64_t streams_evicted;  /* streams told to end for newer ones at the caps */
    size_t open;
} smd_conns_counts;

/* Starts the sweep thread.  NULL with err set on failure. */
smd_conns *smd_conns_new(const smd_conns_limits *limits, sm_error *err);
/* Stops the sweep; call after the HTTP daemon has stopped. */
void smd_conns_free(smd_conns *c);

/* MHD_OPTION_NOTIFY_CONNECTION callback, cls = the registry. */
void smd_conns_notify(void *cls, struct MHD_Connection *conn, void **socket_context,
                      enum MHD_ConnectionNotificationCode code);

/* The request's headers are complete (first call of the access handler):
 * the header deadline no longer applies; receiving says a body follows
 * (the body rate applies until smd_conns_body_done).  -1 when that body
 * is refused: its address already sends --max-streams-per-ip bodies or
 * holds that many streams, or all of them together hold
 * --max-connections minus the reserve (answer 503 without reading it). */
int smd_conns_request(struct MHD_Connection *conn, int receiving);
/* The request becomes an event stream, under the same caps: 0, or -1
 * when refused (answer 503).  At a cap a stream makes room: the oldest of
 * the same address when that address is at --max-streams-per-ip, else
 * the oldest of the address most over its fair share of the total (its
 * own included): *evict is its connection, no longer counted, which the
 * caller must end (smd_follow_evict).  Refused when no address is over
 * its share, or the cap is full of request bodies. */
int smd_conns_stream(struct MHD_Connection *conn, struct MHD_Connection **evict);
/* Body bytes received so far by the request. */
void smd_conns_body(struct MHD_Connection *conn, uint64_t bytes);
/* The body is complete, or no longer read. */
void smd_conns_body_done(struct MHD_Connection *conn);
/* The request is over: the connection waits for the next one. */
void smd_conns_idle(struct MHD_Connection *conn);

void smd_conns_get_counts(smd_conns *c, smd_conns_counts *out);

/* The client's address as text ("?" when unknown), for logs and limits. */
void smd_conn_address(struct MHD_Connection *conn, char *buf, size_t cap);

#endif
