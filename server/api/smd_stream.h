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
 * (MHD_suspend_connection); whoever appends to the log (or ends the job,
 * or the keepalive tick) collects the suspended followers under the lock
 * and resumes them after releasing it.  A resumed follower with nothing
 * new sends a keepalive (": keepalive" in SSE, an empty line in NDJSON),
 * which is also how a client that went away is noticed. */
#ifndef SMD_STREAM_H
#define SMD_STREAM_H

#include <stddef.h>
#include <stdint.h>

#include "base/smd_server.h"
#include "jobs/smd_job.h"

struct MHD_Connection;
struct MHD_Response;

/* Connections to resume once the lock is released. */
typedef struct smd_wake_list {
    struct MHD_Connection **conns;
    size_t n, cap;
} smd_wake_list;

/* Creates the response of an event stream for job, starting after
 * sequence number after_seq (0: from the start; beyond the log: nothing
 * is replayed, the stream follows the job until it ends).  Lock held.  bytes_out
 * (may be NULL) is incremented by what is sent.  NULL when out of memory
 * or when the log cannot be opened (msg says why). */
struct MHD_Response *smd_stream_response(smd_server *srv, smd_job *job,
                                         struct MHD_Connection *conn, int sse,
                                         int64_t after_seq, uint64_t *bytes_out,
                                         char *msg, size_t cap);

/* Lock held: collects the suspended followers of job (new events, or the
 * job ended). */
void smd_stream_collect_job(smd_job *job, smd_wake_list *w);
/* Lock held: collects followers idle for at least keepalive seconds and
 * marks them for a keepalive. */
void smd_stream_collect_idle(smd_server *srv, double now, smd_wake_list *w);
/* Lock held: collects every suspended follower (shutdown). */
void smd_stream_collect_all(smd_server *srv, smd_wake_list *w);

/* Lock NOT held: resumes and empties the list. */
void smd_wake_list_resume(smd_wake_list *w);
void smd_wake_list_free(smd_wake_list *w);

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
