/* Followers of jobs' events: the engine's side of GET /v1/jobs/{id}/events
 * and GET /v1/batches/{id}/events (api/smd_stream.c is the HTTP side).
 *
 * A follower replays a job's log (events.ndjson, read by offset from the
 * in-memory index) from the requested sequence number, then follows it
 * live, and ends with a "status" event once the job is final; or, with a
 * source (a batch), sends what its source makes of the jobs it follows.
 * Two encodings: Server-Sent Events ("id: <seq>", "event: <type>",
 * "data: <json>") or NDJSON (the log lines as they are).
 *
 * The follower protocol is here, written once, and takes srv->lock
 * itself: the HTTP layer calls these with the lock NOT held and never
 * takes it.  Waiting costs neither a thread nor CPU: when a follower has
 * nothing to send, smd_follow_next puts its connection to sleep (the
 * waker's sleep, libmicrohttpd's suspend) with the lock still held, so
 * no event can be appended between "nothing to send" and "asleep" (a
 * lost wake-up).  Everyone else only *collects* sleeping followers under
 * the lock (clearing their flag) and wakes them after releasing it: the
 * engine names the jobs that changed (smd_jobs_after), and
 * smd_follow_jobs_changed (installed as srv->jobs_changed) takes the lock
 * once, collects their followers and wakes them.  So the HTTP library's
 * own mutex is only ever taken inside srv->lock by the thread that owns
 * the connection, and srv->lock is never requested while it is held: no
 * lock cycle.  A collected connection is still asleep until it is woken,
 * so it cannot be closed (and its follower freed) in between.  A woken
 * follower with nothing new sends a keepalive (": keepalive" in SSE, an
 * empty line in NDJSON), which is also how a client that went away is
 * noticed. */
#ifndef SMD_FOLLOW_H
#define SMD_FOLLOW_H

#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

#include "base/smd_server.h"
#include "store/spool/smd_job.h"

typedef struct smd_follower smd_follower;

/* How a follower's connection sleeps and wakes (the HTTP layer's). */
typedef struct smd_follow_waker {
    /* srv->lock held: the connection sleeps until wake (takes no lock of
     * the daemon) */
    void (*sleep)(void *conn);
    /* srv->lock NOT held */
    void (*wake)(void *conn);
} smd_follow_waker;

/* The credential a stream was opened with (NULL members: a daemon
 * without tokens): the Authorization header, or the bare access_token. */
typedef struct smd_follow_credential {
    const char *authorization;
    const char *token;
} smd_follow_credential;

/* A stream whose events its source makes instead of a job's log (a
 * batch, api/smd_batch_events.h).  The follower does the rest as for a
 * log: sleep and wake, keepalives, revocation, eviction, shutdown.  It is
 * woken by changes of its job and of every job the source follows. */
typedef struct smd_follow_source {
    /* Lock held: appends to *buf (SSE when sse, else NDJSON lines) the
     * events of what changed since the last call, and sets *next_seq to
     * one past the last event id it sent (what an evicted SSE client is
     * told to resume from).  0 (with or without events), 1 when what it
     * appended ends the stream, -1 out of memory. */
    int (*refill)(void *state, smd_server *srv, smd_job *job, int sse, int64_t *next_seq,
                  char **buf, size_t *len, size_t *cap);
    /* Lock held: 1 when a change of job id concerns the stream. */
    int (*follows)(const void *state, const char *id);
    void (*free)(void *state);
} smd_follow_source;

/* What a follower is asked for. */
typedef struct smd_follow_request {
    const char *id;         /* the job (a batch: its model job) */
    const char *tenant;     /* who asks (admin: any job) */
    int admin;
    int sse;                /* text/event-stream, else NDJSON */
    int64_t after_seq;      /* 0: from the start; beyond the log: nothing replayed */
    uint64_t *bytes_out;    /* may be NULL: incremented by what is sent */
    smd_follow_credential cred; /* copied, for smd_follow_revoke */
    void *conn;             /* the connection, for the waker and eviction */
    const smd_follow_waker *waker;
    const smd_follow_source *src; /* NULL: the job's log */
    void *src_state;        /* owned from here, freed by src->free (also on failure) */
} smd_follow_request;

/* Lock NOT held: a follower of job rq->id as rq->tenant sees it, linked
 * (woken by the job's changes from now).  NULL when there is no such job
 * (*found 0), or out of memory or when its log cannot be opened (*found 1,
 * msg says why). */
smd_follower *smd_follow_subscribe(smd_server *srv, const smd_follow_request *rq, int *found,
                                   char *msg, size_t cap);

/* What smd_follow_next returns besides a byte count: */
#define SMD_FOLLOW_END (-1)   /* the stream ended */
#define SMD_FOLLOW_ERROR (-2) /* it cannot go on (log unreadable, out of memory) */

/* Lock NOT held: up to max bytes of the stream into out: their number,
 * 0 when there is nothing to hand out now (the connection was put to
 * sleep until a wake-up; or, when a read of the log gave nothing, the
 * HTTP library asks again), or SMD_FOLLOW_END / SMD_FOLLOW_ERROR. */
ssize_t smd_follow_next(smd_follower *f, char *out, size_t max);

/* Lock NOT held: unlinks and frees (the connection is gone). */
void smd_follow_unsubscribe(smd_follower *f);

/* srv->jobs_changed (smd_server.h), lock NOT held: collects the sleeping
 * followers of the jobs named (new events, or the job ended) and, when
 * keepalive, those idle for at least --keepalive seconds (marked for a
 * keepalive), then wakes them unlocked. */
void smd_follow_jobs_changed(smd_server *srv, const char (*ids)[SMD_ID_LEN + 1], size_t n,
                             int keepalive);
/* Lock NOT held: the stream on conn ends now (room for a newer one): in
 * SSE with a final comment telling the client to reconnect with
 * Last-Event-ID (the last id it got), in NDJSON by its end (the client
 * resumes with ?after=).  No-op when conn follows nothing (any more). */
void smd_follow_evict(smd_server *srv, void *conn);
/* Lock NOT held: ends every stream opened with a credential for which
 * valid(ctx, authorization, token) is 0 (called with srv->lock held, for
 * the streams opened with one), at once, without the final status. */
void smd_follow_revoke(smd_server *srv,
                       int (*valid)(void *ctx, const char *authorization, const char *token),
                       void *ctx);
/* Lock NOT held: wakes every sleeping follower (shutdown, once
 * srv->stopping is set: each ends). */
void smd_follow_end_all(smd_server *srv);
/* Lock held: the number of open followers (for /metrics). */
size_t smd_follow_count(const smd_server *srv);
/* After the HTTP daemon stopped (no follower left): frees their table. */
void smd_follow_free_all(smd_server *srv);

/* Formats one log line (without its newline) as an SSE event:
 * "id: <seq>\nevent: <type>\ndata: <line>\n\n".  seq < 1 omits the id
 * line.  Appends to *buf (growing it).  -1 when out of memory.  Exposed
 * for tests. */
int smd_sse_format(char **buf, size_t *len, size_t *cap, int64_t seq, const char *type,
                   const char *line, size_t line_len);

/* Type of an NDJSON event line ("progress", ...) into type (cap bytes);
 * "message" when it has none.  Exposed for tests. */
void smd_event_line_type(const char *line, size_t len, char *type, size_t cap);

#endif
