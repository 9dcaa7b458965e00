/* Event streams over HTTP: GET /v1/jobs/{id}/events and the batch's.
 *
 * The follower protocol (replay, live follow, the final status, sleep
 * and wake-ups, keepalives, revocation, eviction) is the engine's
 * (jobs/smd_follow.h), which takes srv->lock itself; this is only its
 * libmicrohttpd side: the response whose content reader is
 * smd_follow_next, and the waker that suspends and resumes the
 * connection. */
#ifndef SMD_STREAM_H
#define SMD_STREAM_H

#include <stddef.h>
#include <stdint.h>

#include "base/smd_server.h"
#include "jobs/smd_follow.h"

struct MHD_Connection;
struct MHD_Response;

/* Lock NOT held: the response of an event stream as rq asks (rq->conn is
 * conn; rq->waker is filled here).  NULL when there is no such job
 * (*found 0) or it cannot start (*found 1, msg says why). */
struct MHD_Response *smd_stream_response(smd_server *srv, struct MHD_Connection *conn,
                                         smd_follow_request *rq, int *found, char *msg,
                                         size_t cap);

/* Lock NOT held (takes srv->lock, then tokens_lock): after SIGHUP
 * replaced the tokens, ends every stream opened with a token the new set
 * no longer has (it ends at once, without the final status). */
void smd_stream_revoke(smd_server *srv);

#endif
