/* Event streams: GET /v1/jobs/{id}/events.
 *
 * A follower replays the job's log (events.ndjson, read by offset from
 * the in-memory index) from the requested sequence number, then follows
 * it live, and ends with a "status" event once the job is final.  Two
 * encodings: Server-Sent Events ("id: <seq>", "event: <type>",
 * "data: <json>") or NDJSON (the log lines as they are).
 *
 * Waiting costs neither a thread nor CPU: when a follower has nothing to
 * send, its content reader suspends the connection
 * (MHD_suspend_connection); the job engine names the jobs whose log or
 * state changed (and ticks for keepalives), and this module collects
 * their suspended followers under the lock and resumes them after
 * releasing it (smd_stream_jobs_changed).  A resumed follower with nothing
 * new sends a keepalive (": keepalive" in SSE, an empty line in NDJSON),
 * which is also how a client that went away is noticed. */
#ifndef SMD_STREAM_H
#define SMD_STREAM_H

#include <stddef.h>
#include <stdint.h>

#include "base/smd_server.h"
#include "store/spool/smd_job.h"

struct MHD_Connection;
struct MHD_Response;

/* The credential a stream was opened with (NULL members: a daemon
 * without tokens): the Authorization header, or the bare access_token. */
typedef struct smd_stream_credential {
    const char *authorization;
    const char *token;
} smd_stream_credential;

/* Creates the response of an event stream for job, starting after
 * sequence number after_seq (0: from the start; beyond the log: nothing
 * is replayed, the stream follows the job until it ends).  Lock held.  bytes_out
 * (may be NULL) is incremented by what is sent; cred is kept (a copy) for
 * smd_stream_revoke.  NULL when out of memory
 * or when the log cannot be opened (msg says why). */
struct MHD_Response *smd_stream_response(smd_server *srv, smd_job *job,
                                         struct MHD_Connection *conn, int sse,
                                         int64_t after_seq, uint64_t *bytes_out,
                                         const smd_stream_credential *cred, char *msg, size_t cap);
/* A stream whose events its source makes instead of a job's log
 * (GET /v1/batches/{id}/events, api/smd_batch_events.h).  The follower
 * does the rest as for a log: suspend and resume, keepalives, revocation,
 * eviction, shutdown.  It is woken by changes of its job and of every job
 * the source follows. */
typedef struct smd_stream_source {
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
} smd_stream_source;

/* As smd_stream_response, for a stream with a source (state: owned from
 * here, freed with src->free, also on failure).  Lock held. */
struct MHD_Response *smd_stream_source_response(smd_server *srv, smd_job *job,
                                                struct MHD_Connection *conn, int sse,
                                                int64_t after_seq, const smd_stream_source *src,
                                                void *state, uint64_t *bytes_out,
                                                const smd_stream_credential *cred, char *msg,
                                                size_t cap);

/* Lock NOT held (takes srv->lock, then tokens_lock): after SIGHUP
 * replaced the tokens, ends every stream opened with a token the new set
 * no longer has (it ends at once, without the final status). */
void smd_stream_revoke(smd_server *srv);

/* srv->jobs_changed (smd_server.h), lock NOT held: takes the lock,
 * collects the suspended followers of the jobs named (new events, or the
 * job ended) and, when keepalive, those idle for at least --keepalive
 * seconds (marked for a keepalive), then resumes them unlocked. */
void smd_stream_jobs_changed(smd_server *srv, const char (*ids)[SMD_ID_LEN + 1], size_t n,
                             int keepalive);
/* Lock NOT held: the stream on conn (smd_conns_stream chose it to make
 * room for a newer one) ends now: in SSE with a final comment telling
 * the client to reconnect with Last-Event-ID (the last id it got), in
 * NDJSON by its end (the client resumes with ?after=).  No-op when conn
 * is no stream (any more). */
void smd_stream_evict(smd_server *srv, struct MHD_Connection *conn);
/* Lock NOT held: resumes every suspended follower (shutdown, once
 * srv->stopping is set: each ends). */
void smd_stream_end_all(smd_server *srv);
/* Lock held: the number of open event streams (for /metrics). */
size_t smd_stream_count(const smd_server *srv);
/* After the HTTP daemon stopped (no stream left): frees the streams'
 * table. */
void smd_stream_free_all(smd_server *srv);

/* Formats one log line (without its newline) as an SSE event:
 * "id: <seq>\nevent: <type>\ndata: <line>\n\n".  seq < 1 omits the id
 * line.  Appends to *buf (growing it).  -1 when out of memory.  Exposed
 * for tests. */
int smd_sse_format(char **buf, size_t *len, size_t *cap, int64_t seq,
                   const char *type, const char *line, size_t line_len);

/* Type of an NDJSON event line ("progress", ...) into type (cap bytes);
 * "message" when it has none.  Exposed for tests. */
void smd_event_line_type(const char *line, size_t len, char *type, size_t cap);

#endif
