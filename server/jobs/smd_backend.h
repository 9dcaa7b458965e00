/* Where jobs live and how work is handed out: the one interface the job
 * engine (smd_jobs.c, smd_pool.c) calls, with two implementations that
 * shapematchd.c picks at start:
 *
 *   store/spool/smd_spool_backend.c   the embedded spool and its FIFO
 *   store/pg/smd_pg_backend.c         PostgreSQL (--database), stacked on
 *                                     the spool: the spool is the node's
 *                                     local replica (records, event logs,
 *                                     inputs and results served from disk),
 *                                     the database the shared store and
 *                                     queue of every node
 *
 * The records of both are the spool's: `spool` and `fifo` below are the
 * node's local replica, and the api/ handlers read job files through
 * them (store/spool/smd_store.h).  What differs between the backends is
 * the ops table: the engine never asks which one runs.
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
#include "jobs/smd_job.h"

struct smd_server;
struct smd_store;
struct smd_queue;
struct smd_submission;
struct smd_jobs_after;

typedef struct smd_backend smd_backend;

typedef struct smd_backend_ops {
    const char *name; /* "spool", "postgresql" */

    /* ---- the job records (the local replica) */
    smd_job *(*get)(smd_backend *b, const char *id);
    /* The job submitted with this Idempotency-Key, or NULL. */
    smd_job *(*find_key)(smd_backend *b, const char *owner, const char *key);
    size_t (*count)(smd_backend *b);
    smd_job *(*at)(smd_backend *b, size_t i); /* submission order */
    /* The job's folder (name "") or a file in it; -1 on overflow. */
    int (*path)(smd_backend *b, const char *id, const char *name, char *buf, size_t cap);
    /* A prepared upload folder becomes the accepted job (smd_store_commit). */
    sm_status (*commit)(smd_backend *b, const char *dir, smd_job *job, sm_event *first,
                        sm_error *err);
    sm_status (*save)(smd_backend *b, smd_job *job, sm_error *err);
    sm_status (*load_events)(smd_backend *b, smd_job *job, sm_error *err);
    /* Appends ev to the job's log (numbers it). */
    sm_status (*append)(smd_backend *b, smd_job *job, sm_event *ev, sm_error *err);
    /* The job leaves the table (smd_store_unlink). */
    void (*unlink)(smd_backend *b, smd_job *job);
    /* The job's folder into trash/ (path: remove it after the lock); -1, errno. */
    int (*trash)(smd_backend *b, const char *id, char *path, size_t cap);
    int (*can_trash)(smd_backend *b);
    /* 1 when the records can be written again (the spool is writable). */
    int (*writable)(smd_backend *b);
    void (*remove_results)(smd_backend *b, const smd_job *job, int partial_only);

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
    /* A job accepted by this node: 1 queued here, 0 queued elsewhere (the
     * shared queue: a worker node claims it), -1 out of memory. */
    int (*enqueue)(smd_backend *b, const char *id);
    /* The next job to run here: 1 and its id, or 0 when none. */
    int (*next)(smd_backend *b, char id[SMD_ID_LEN + 1]);
    /* A queued job leaves the local queue (cancelled). */
    void (*dequeue)(smd_backend *b, const char *id);

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
    struct smd_store *spool; /* the local records (both backends) */
    struct smd_queue *fifo;  /* the local queue of jobs to run here */
    void *impl;              /* the shared store (PostgreSQL's node), or NULL */
};

/* The calls, one per op (the engine uses these). */
static inline smd_job *smd_backend_get(smd_backend *b, const char *id)
{ return b->ops->get(b, id); }
static inline smd_job *smd_backend_find_key(smd_backend *b, const char *owner, const char *key)
{ return b->ops->find_key(b, owner, key); }
static inline size_t smd_backend_count(smd_backend *b)
{ return b->ops->count(b); }
static inline smd_job *smd_backend_at(smd_backend *b, size_t i)
{ return b->ops->at(b, i); }
static inline int smd_backend_path(smd_backend *b, const char *id, const char *name, char *buf, size_t cap)
{ return b->ops->path(b, id, name, buf, cap); }
static inline sm_status smd_backend_commit(smd_backend *b, const char *dir, smd_job *job, sm_event *first, sm_error *err)
{ return b->ops->commit(b, dir, job, first, err); }
static inline sm_status smd_backend_save(smd_backend *b, smd_job *job, sm_error *err)
{ return b->ops->save(b, job, err); }
static inline sm_status smd_backend_load_events(smd_backend *b, smd_job *job, sm_error *err)
{ return b->ops->load_events(b, job, err); }
static inline sm_status smd_backend_append(smd_backend *b, smd_job *job, sm_event *ev, sm_error *err)
{ return b->ops->append(b, job, ev, err); }
static inline void smd_backend_unlink(smd_backend *b, smd_job *job)
{ b->ops->unlink(b, job); }
static inline int smd_backend_trash(smd_backend *b, const char *id, char *path, size_t cap)
{ return b->ops->trash(b, id, path, cap); }
static inline int smd_backend_can_trash(smd_backend *b)
{ return b->ops->can_trash(b); }
static inline int smd_backend_writable(smd_backend *b)
{ return b->ops->writable(b); }
static inline void smd_backend_remove_results(smd_backend *b, const smd_job *job, int partial_only)
{ b->ops->remove_results(b, job, partial_only); }
static inline sm_status smd_backend_read_summary(smd_backend *b, const smd_job *job, sm_event *finished, double *when, sm_error *err)
{ return b->ops->read_summary(b, job, finished, when, err); }
static inline int smd_backend_final_event_missing(smd_backend *b, const smd_job *job)
{ return b->ops->final_event_missing(b, job); }
static inline int smd_backend_enqueue(smd_backend *b, const char *id)
{ return b->ops->enqueue(b, id); }
static inline int smd_backend_next(smd_backend *b, char id[SMD_ID_LEN + 1])
{ return b->ops->next(b, id); }
static inline void smd_backend_dequeue(smd_backend *b, const char *id)
{ b->ops->dequeue(b, id); }
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
