/* The daemon's shared state, passed to every part (no globals).
 *
 * Threads: libmicrohttpd's polling threads (HTTP handlers), the
 * supervisor (worker processes, timeouts, keepalives, retention) and the
 * main thread (signals).  One mutex, `lock`, guards the store, the queue,
 * the worker slots and the event streams; it is held only for short, bounded
 * work (table updates, one status.json write, one event append), never
 * while waiting for a worker or the network.  libmicrohttpd is never
 * called with `lock` held except MHD_suspend_connection from a content
 * reader (see smd_stream.c for why that order is safe).
 *
 * The most work done under `lock` by one holder, and none of it grows
 * with a number taken from a request, a header or the spool's records:
 * - scans of the job table, O(jobs in the spool): the job list (plus at
 *   most 1000 status documents, the page limit), /metrics, the
 *   Idempotency-Key lookup, the retention sweep, unlinking a job;
 * - one event-stream refill: walks the in-memory index of events that
 *   exist (never from a requested sequence number upwards) for at most
 *   256 KiB of log (READ_BATCH), then reads and formats them unlocked;
 * - one status.json write (temporary file, fsync, rename) and one event
 *   append (write, fdatasync for lifecycle events) per state change;
 * - the supervisor's round: at most 16 reads of 64 KiB per worker pipe,
 *   and a fork per job started. */
#ifndef SMD_SERVER_H
#define SMD_SERVER_H

#include <pthread.h>
#include <stdatomic.h>

#include "base/smd_config.h"
#include "base/smd_log.h"
#include "base/smd_metrics.h"
#include "base/smd_util.h" /* SMD_ID_LEN */

struct MHD_Daemon;
struct smd_tokens; /* http/smd_auth.h: the state machine sees no HTTP header */
struct smd_store;
struct smd_queue;
struct smd_backend;
struct smd_pool;
struct smd_events;
struct smd_pg_node;
struct smd_ratelimit;
struct smd_conns;
struct smd_check_pool;
struct smd_http_app;

typedef struct smd_server {
    smd_config cfg;
    smd_logger log;
    struct smd_tokens *tokens;  /* NULL: no authentication; replaced on
                                 * SIGHUP under tokens_lock */
    pthread_mutex_t tokens_lock;
    smd_metrics metrics;
    double start_time;          /* Unix seconds */

    pthread_mutex_t lock;
    struct smd_backend *backend; /* what the backends do differently (jobs/smd_backend.h) */
    struct smd_store *store;    /* the local spool, both backends' replica, used by name
                                 * by the engine and the handlers (store/spool/smd_store.h) */
    struct smd_queue *queue;    /* the spool's FIFO of jobs to run here */
    struct smd_pool *pool;
    struct smd_pg_node *cluster; /* --database: PostgreSQL's node (store/pg/smd_pg_node.h), or
                                  * NULL; only store/pg and main use it */
    struct smd_events *events;  /* the event followers' own state (jobs/smd_follow.c) */
    /* Lock NOT held: the jobs that changed (ids) and the keepalive tick,
     * from smd_jobs_after_run.  Installed by main before any thread
     * starts (smd_follow_jobs_changed: their followers are resumed), so
     * the engine wakes no connection itself; NULL: nobody follows. */
    void (*jobs_changed)(struct smd_server *srv, const char (*ids)[SMD_ID_LEN + 1], size_t n,
                         int keepalive);
    /* Lock NOT held: a job was queued here or a worker must be stopped,
     * from smd_jobs_after_run.  Installed by main beside jobs_changed
     * (the supervisor's wake-up: smd_pool_wake); NULL: no pool. */
    void (*work_queued)(struct smd_server *srv);

    struct MHD_Daemon *httpd;
    const struct smd_http_app *app; /* what it serves (http/smd_http.h), by smd_http_start */
    struct smd_ratelimit *ratelimit; /* submission limits (smd_ratelimit.h), by smd_http_start */
    struct smd_conns *conns;    /* connection deadlines (smd_conns.h), by smd_http_start */
    struct smd_check_pool *checks; /* upload checks (smd_check.h), by smd_http_start */
    unsigned port;              /* the port actually bound */

    atomic_int draining;        /* shutdown began: refuse new jobs, /readyz 503 */
    atomic_int stopping;        /* event streams end */
    atomic_int unwritable;      /* a record or event could not be written:
                                 * /readyz 503, no new job accepted or
                                 * started until the records are written
                                 * again (smd_jobs_retry_saves) */
} smd_server;

#endif
