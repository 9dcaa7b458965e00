/* The job state machine of shapematchd: the only code that changes
 * job->state, writes lifecycle events (accepted, started, finished,
 * failed, cancelled) and progress events, and bumps the job metrics.
 *
 *   submit          -> accepted   (upload committed, queued)
 *   accepted        -> running    smd_jobs_take_next, smd_jobs_started
 *   running         -> running    smd_jobs_progress, smd_jobs_warning
 *   running         -> successful smd_jobs_finish
 *   accepted|running -> failed    smd_jobs_fail (the worker could not start,
 *                                 or ended without a result)
 *   accepted        -> dismissed  smd_jobs_cancel (at once)
 *   running         -> dismissed  smd_jobs_cancel (the worker is stopped;
 *                                 smd_jobs_cancelled when it is gone)
 *   running         -> accepted   smd_jobs_requeue (daemon shutdown) and
 *                                 smd_jobs_recover (daemon start)
 *   accepted|running -> successful smd_jobs_recover (the run had finished:
 *                                 its results are complete, its final
 *                                 record was never written)
 *   final           -> (gone)     smd_jobs_delete, smd_jobs_expire
 *
 * Durable first: a change is shown to clients (state, status document,
 * event streams, metrics) only once its record is on disk.  A cancel
 * whose record the spool refuses is refused (503).  The end of a run
 * (finish, fail, cancelled) is "held" while the spool refuses its final
 * record or its final event: the job keeps showing what it showed before
 * (running, with a message saying it is ending; or dismissed after a
 * cancel), its streams stay open, its result files stay, the daemon is
 * unready (srv->unwritable), and smd_jobs_retry_saves publishes the end
 * once both are written.  A restart in between ends the job from its
 * complete results, or runs it again: never against what clients saw.
 *
 * Everything else is refused: each function returns SM_ERR_INVALID (and
 * changes nothing) when the job is not in a state it starts from.
 *
 * It calls the backend (jobs/smd_backend.h: records, logs, the queue,
 * and what a shared store must hear; the spool or PostgreSQL, never asked
 * which) and the metrics; it calls neither the HTTP side nor the pool:
 * what must happen once the lock is released (tell who follows the jobs
 * that changed, remove folders, wake the supervisor) is collected in an
 * smd_jobs_after that the caller runs.  The engine names the jobs that
 * changed; it holds no connection and knows no follower: whoever follows
 * jobs (the event streams) installs srv->jobs_changed, which
 * smd_jobs_after_run calls.
 *
 * Every function but smd_jobs_after_run is called with srv->lock held
 * (smd_jobs_recover: at start, before any other thread runs). */
#ifndef SMD_JOBS_H
#define SMD_JOBS_H

#include <stdint.h>

#include "shapematch/sm_error.h"
#include "base/smd_server.h"
#include "jobs/smd_backend.h"
#include "store/spool/smd_fifo.h"  /* the local queue, by name */
#include "store/spool/smd_store.h" /* the local replica, by name */

/* Work for after the lock.  Starts zeroed ({0}); reusable after a run. */
typedef struct smd_jobs_after {
    smd_server *srv;      /* set with the first change or tick recorded */
    char (*changed)[SMD_ID_LEN + 1]; /* jobs whose log or state changed */
    size_t nchanged, changed_cap;
    int keepalive;        /* the supervisor's tick: idle followers are due
                           * a keepalive (smd_jobs_after_tick) */
    char **trash;         /* folders moved to trash/, to remove */
    size_t ntrash;
    int wake_pool;        /* a job was queued or must be stopped: the
                           * supervisor is woken (srv->work_queued) */
} smd_jobs_after;

/* Lock held: job's log or state changed (its followers have news).  A
 * job already last in the list is not added twice.  Out of memory the
 * change goes unreported: its followers hear of it at their next
 * keepalive, when they read the log again. */
void smd_jobs_after_changed(smd_server *srv, smd_jobs_after *a, const smd_job *job);
/* The supervisor's once-a-second tick (for keepalives). */
void smd_jobs_after_tick(smd_server *srv, smd_jobs_after *a);

/* Lock held: a job was queued here or a worker must be stopped. */
void smd_jobs_after_wake(smd_server *srv, smd_jobs_after *a);

/* Lock NOT held: hands the changed jobs and the tick to srv->jobs_changed
 * and a wake-up to srv->work_queued (when installed), removes the trashed
 * folders and empties a (a stays usable). */
void smd_jobs_after_run(smd_jobs_after *a);
void smd_jobs_after_free(smd_jobs_after *a);

/* What an upload hands over. */
typedef struct smd_submission {
    const char *dir;              /* prepared folder: inputs/ and job.json */
    const char *id;               /* fresh job id */
    const char *idempotency_key;  /* NULL or "" for none */
    const char *owner;            /* tenant, NULL or "" for none; the key is
                                   * looked up among its jobs only */
    const char *name;             /* the job's name (checked), NULL or "" none */
    uint64_t request_hash;        /* of the parts, kept with the key */
    int dim, max_iter;
    double tol_boundary;          /* params.tol_boundary, for the status */
    int32_t nverts, nelems;       /* for the log */
    uint64_t bytes;               /* upload size, for the log */
    /* a batch's model job (api/smd_batches.h): it runs once every member
     * is final; members are the ids job.json's batch lists */
    int batch_model;
    const char (*members)[SMD_ID_LEN + 1];
    size_t nmembers;
    /* set by smd_jobs_publish (zeroed: not published, the spool's case) */
    double created;               /* the time the shared store gave it, or 0 */
    char existing[SMD_ID_LEN + 1]; /* the job the key names there, or "" */
} smd_submission;

/* srv->lock NOT held: the submission into the backend's shared store
 * first (PostgreSQL; nothing for the spool), so that no backend waits
 * for the network under the lock.  Fills sub->created and sub->existing;
 * the caller then takes the lock and calls smd_jobs_submit, whatever it
 * decides (it ends the publication). */
sm_status smd_jobs_publish(smd_server *srv, smd_submission *sub, sm_error *err);

/* A new job: when the Idempotency-Key names an existing job (here, or in
 * the shared store: sub->existing), *job is that one and *created 0
 * (nothing changes); else the folder becomes an accepted job (status.json,
 * the "accepted" event), queued, counted and logged, *created 1.  *job is
 * borrowed from the backend. */
sm_status smd_jobs_submit(smd_server *srv, const smd_submission *sub, smd_job **job,
                          int *created, smd_jobs_after *after, sm_error *err);

/* The oldest queued job, now running in memory (attempt counted, times
 * set), or NULL when none is queued.  The caller starts its worker, then
 * calls smd_jobs_started, or smd_jobs_fail when it could not. */
smd_job *smd_jobs_take_next(smd_server *srv);
/* The worker (pid) runs: record saved, "started" event, metrics, log. */
sm_status smd_jobs_started(smd_server *srv, smd_job *job, long pid, smd_jobs_after *after);

/* A progress event from the worker (ignored unless running). */
sm_status smd_jobs_progress(smd_server *srv, smd_job *job, sm_event *ev, smd_jobs_after *after);
/* A warning event from the worker, appended as it is (ignored unless
 * running). */
sm_status smd_jobs_warning(smd_server *srv, smd_job *job, sm_event *ev, smd_jobs_after *after);

/* log_fields (may be NULL; taken over) are added to the job's log line. */
sm_status smd_jobs_finish(smd_server *srv, smd_job *job, const sm_event *finished,
                          json_t *log_fields, smd_jobs_after *after);
sm_status smd_jobs_fail(smd_server *srv, smd_job *job, const char *message, json_t *log_fields,
                        smd_jobs_after *after);
/* DELETE of a live job: a queued one is dismissed at once; a running one
 * is dismissed and its worker asked to stop (after->wake_pool).  The
 * dismissed record is written first: SM_ERR_IO (errno set, the daemon
 * unready) when the spool refuses it, and the job is left as it was (a
 * restart must not run a job clients were told is dismissed).  A job
 * whose run is over but whose end is held is not dismissed: its end is
 * written now (then SM_ERR_INVALID: it ended first) or SM_ERR_IO. */
sm_status smd_jobs_cancel(smd_server *srv, smd_job *job, smd_jobs_after *after);
/* smd_jobs_cancel with its message (the status, the log line) saying why
 * the run stops when no client asked: a cluster node that lost its lease. */
sm_status smd_jobs_stop(smd_server *srv, smd_job *job, const char *message, smd_jobs_after *after);
/* The worker of a cancelled job is gone: the "cancelled" event. */
sm_status smd_jobs_cancelled(smd_server *srv, smd_job *job, json_t *log_fields,
                             smd_jobs_after *after);
/* The daemon stops while the job runs: queued again for the next start. */
sm_status smd_jobs_requeue(smd_server *srv, smd_job *job, json_t *log_fields);

/* Lock held, once a second by the supervisor: while srv->unwritable is
 * set (a record or event write failed), writes the records that failed
 * again and the held ends (record, then event; then each is published:
 * state, metrics, log line, the job into after->changed); when all are
 * written (and the spool is writable) the flag clears and jobs are
 * accepted and started again.  A scan of the job table, at most one
 * status.json write and one event append per job waiting. */
void smd_jobs_retry_saves(smd_server *srv, smd_jobs_after *after);

/* The worker slot of job is free again (after one of the above); a DELETE
 * that came while it was stopping now removes the job's files. */
void smd_jobs_worker_gone(smd_server *srv, smd_job *job, smd_jobs_after *after);

/* DELETE of a final job, and the retention sweep: the job leaves the
 * table (its followers end) and its folder goes to trash/ (at once, or
 * when its worker is gone).  When the spool refuses the rename (read-only,
 * no permission) the job stays, visible and unchanged, and SM_ERR_IO is
 * returned with errno set: a delete is durable or refused. */
sm_status smd_jobs_delete(smd_server *srv, smd_job *job, smd_jobs_after *after);
sm_status smd_jobs_expire(smd_server *srv, smd_job *job, smd_jobs_after *after);

/* Daemon start, after the backend is open: a live job whose run had
 * finished (the backend's read_summary: results/summary.json complete;
 * not with PostgreSQL, where the database knows) ends successful as that run did, with
 * no second run (held when the spool still refuses its record); other
 * jobs that were running are queued again ("re-queued after a daemon
 * restart"), partial results of every live job are removed, their logs
 * repaired, and every accepted job is queued in submission order.  A requeued record that the spool refuses
 * (full) keeps the job queued in memory, unsaved: the daemon is unready
 * and starts nothing until it is written.  A job whose log cannot be
 * loaded is logged and left out of the table.  Sets *queued.  SM_ERR_NOMEM when the queue
 * cannot take them. */
sm_status smd_jobs_recover(smd_server *srv, size_t *queued, sm_error *err);

/* The feed of a shared backend (PostgreSQL's sync thread, an input like
 * the pool's): the local record follows a job another node runs.  mirror_event appends ev (its seq must be the
 * next) and applies it (started, progress, finished, failed,
 * cancelled); mirror_state takes a change that has no event (a requeue
 * after a lost lease, a cancel request); mirror_drop removes the local
 * copy of a job deleted elsewhere (or stale). */
sm_status smd_jobs_mirror_event(smd_server *srv, smd_job *job, sm_event *ev,
                                smd_jobs_after *after);
void smd_jobs_mirror_state(smd_server *srv, smd_job *job, sm_job_state state, const char *message,
                           int attempt, smd_jobs_after *after);
void smd_jobs_mirror_drop(smd_server *srv, smd_job *job, smd_jobs_after *after);

#endif
