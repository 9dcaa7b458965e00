/* Where jobs live and how work is handed out: what differs between the
 * two backends the job engine (smd_jobs.c, smd_pool.c) runs on, which
 * shapematchd.c picks at start:
 *
 *   jobs/smd_spool_backend.c   the embedded spool and its FIFO
 *   store/pg/smd_pg_backend.c  PostgreSQL (--database): the database is
 *                              the shared store and queue of every node
 *
 * What does not differ is not here: both keep their records in the
 * node's spool, the local replica (store/spool/smd_store.h: records,
 * event logs, inputs and results served from disk) and queue the jobs
 * this node runs in its FIFO (store/spool/smd_fifo.h); the engine and
 * the handlers use those by name (srv->store, srv->queue).  Every op
 * below is one the two backends do differently (curl's struct Curl_ssl
 * carries only what TLS libraries do differently, the same way).
 *
 * Input the other way: a shared backend's own threads (PostgreSQL's sync
 * and work threads) feed the engine as the pool does, through
 * smd_jobs_mirror_* (jobs/smd_jobs.h) with srv->lock held, and queue the
 * jobs this node claimed in the local FIFO.
 *
 * Locks: every op but publish and withdraw is called with srv->lock held
 * and returns with it held; no op releases it (publish and withdraw are
 * called without it: they may wait for the network).  A backend's own mutexes are taken after
 * srv->lock or alone. */
#ifndef SMD_BACKEND_H
#define SMD_BACKEND_H

#include <stddef.h>
#include <stdint.h>

#include "shapematch/sm_error.h"
#include "sm_proto_events.h"
#include "base/smd_util.h"
#include "store/spool/smd_job.h"

struct smd_server;
struct smd_store;
struct smd_queue;
struct smd_submission;
struct smd_jobs_after;

typedef struct smd_backend smd_backend;

typedef struct smd_backend_ops {
    const char *name; /* "spool", "postgresql" */

    /* ---- recovery at start: how an interrupted run ended, if it did */
    /* SM_OK with the run's "finished" event when its published results
     * say it finished (spool: results/summary.json); SM_ERR_IO when this
     * backend does not know it from here (PostgreSQL: the database says
     * how a job ended, not the local copy). */
    sm_status (*read_summary)(smd_backend *b, const smd_job *job, sm_event *finished,
                              double *when, sm_error *err);
    /* 1 when a final record's final event never reached the log and must
     * be written from here (PostgreSQL: 0, the database holds the log). */
    int (*final_event_missing)(smd_backend *b, const smd_job *job);

    /* ---- the queue */
    /* A job accepted by this node: 1 queued here (the local FIFO), 0
     * queued elsewhere (the shared queue: a worker node claims it), -1
     * out of memory.  A batch's model job waits until none of its members
     * is queued or running: the spool keeps it out of the FIFO until the
     * last member's final event (and links the members' results into its
     * folder then); PostgreSQL's claim skips it (and the claiming node
     * copies them in). */
    int (*enqueue)(smd_backend *b, const char *id);

    /* ---- submission, in two steps: no op releases srv->lock */
    /* srv->lock NOT held: the submission into the shared store first.
     * *created: the time the store gave it; existing: the job an
     * Idempotency-Key already names there ("" when none; then the caller
     * commits the job locally under the lock and calls submitted, also
     * when it does not commit). */
    sm_status (*publish)(smd_backend *b, const struct smd_submission *sub, double *created,
                         char existing[SMD_ID_LEN + 1], sm_error *err);
    void (*submitted)(smd_backend *b, const char *id);

    /* ---- changes the other nodes must see */
    /* An event appended locally (after the state it ends is set). */
    void (*event)(smd_backend *b, const smd_job *job, const sm_event *ev);
    /* The daemon stops while this node runs the job. */
    void (*requeued)(smd_backend *b, const smd_job *job);
    /* DELETE of a live job: *handled 1 when the backend cancelled it
     * itself (it runs, or waits, on another node; the local record
     * follows through the feed), 0 when the engine cancels it here. */
    sm_status (*cancel)(smd_backend *b, struct smd_server *srv, smd_job *job,
                        struct smd_jobs_after *after, int *handled, sm_error *err);
    /* DELETE or retention of a final job, before its local removal:
     * *deleted 0 when another node removed it first. */
    sm_status (*remove)(smd_backend *b, const char *id, int *deleted, sm_error *err);
    /* DELETE, srv->lock NOT held, before the locked cancel or delete:
     * the shared store's part of it, so that no lock of the daemon waits
     * for the network (PostgreSQL: the cancel or delete in the database;
     * cancel and remove above then use its outcome instead of asking
     * again).  final: the job was final when the caller looked; known:
     * the events its local log held.  NULL: nothing shared (the spool). */
    sm_status (*withdraw)(smd_backend *b, const char *id, int final, int64_t known,
                          sm_error *err);

    /* ---- health */
    /* 1 when it can take jobs; else 0 and why, a phrase naming what is
     * down (/readyz, upload errors). */
    int (*ready)(smd_backend *b, char *why, size_t cap);
    /* Prometheus lines of its own, appended to *text (realloc'ed). */
    void (*metrics)(smd_backend *b, char **text, size_t *len);
} smd_backend_ops;

struct smd_backend {
    const smd_backend_ops *ops;
    struct smd_store *spool; /* the local replica (both backends) */
    struct smd_queue *fifo;  /* the local queue of jobs to run here */
    void *impl;              /* the shared store (PostgreSQL's node), or NULL */
};

/* The calls, one per op (the engine uses these). */
static inline sm_status smd_backend_read_summary(smd_backend *b, const smd_job *job, sm_event *finished, double *when, sm_error *err)
{ return b->ops->read_summary(b, job, finished, when, err); }
static inline int smd_backend_final_event_missing(smd_backend *b, const smd_job *job)
{ return b->ops->final_event_missing(b, job); }
static inline int smd_backend_enqueue(smd_backend *b, const char *id)
{ return b->ops->enqueue(b, id); }
static inline sm_status smd_backend_publish(smd_backend *b, const struct smd_submission *sub, double *created, char existing[SMD_ID_LEN + 1], sm_error *err)
{ return b->ops->publish(b, sub, created, existing, err); }
static inline void smd_backend_submitted(smd_backend *b, const char *id)
{ b->ops->submitted(b, id); }
static inline void smd_backend_event(smd_backend *b, const smd_job *job, const sm_event *ev)
{ b->ops->event(b, job, ev); }
static inline void smd_backend_requeued(smd_backend *b, const smd_job *job)
{ b->ops->requeued(b, job); }
static inline sm_status smd_backend_cancel(smd_backend *b, struct smd_server *srv, smd_job *job, struct smd_jobs_after *after, int *handled, sm_error *err)
{ return b->ops->cancel(b, srv, job, after, handled, err); }
static inline sm_status smd_backend_remove(smd_backend *b, const char *id, int *deleted, sm_error *err)
{ return b->ops->remove(b, id, deleted, err); }
static inline sm_status smd_backend_withdraw(smd_backend *b, const char *id, int final, int64_t known, sm_error *err)
{ return b->ops->withdraw ? b->ops->withdraw(b, id, final, known, err) : SM_OK; }
static inline int smd_backend_ready(smd_backend *b, char *why, size_t cap)
{ return b->ops->ready(b, why, cap); }
static inline void smd_backend_metrics(smd_backend *b, char **text, size_t *len)
{ b->ops->metrics(b, text, len); }

#endif
