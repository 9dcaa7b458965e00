/* The engine's use cases for the HTTP handlers: each takes srv->lock
 * itself, calls the state machine (jobs/smd_jobs.h) under it, hands back
 * plain copies of the records it touched (smd_job_view) and runs the
 * work for after the lock (followers, trashed folders, the supervisor's
 * wake-up through srv->work_queued).  The handlers call these with
 * srv->lock NOT held and never take it for a submit or a withdraw: the
 * two-step protocols (publish without the lock, then submit under it;
 * the shared store's withdraw without it, then cancel or delete under
 * it) are written here once. */
#ifndef SMD_USECASES_H
#define SMD_USECASES_H

#include "jobs/smd_jobs.h"
#include "base/smd_metrics.h"

/* A submission the handler checked (an upload, a batch's model job):
 * published into the shared store without the lock, then submitted under
 * it.  *view: the new job, or the one its Idempotency-Key already names
 * (*created 0).  A refusal of the store is returned with err filled. */
sm_status smd_jobs_create(smd_server *srv, smd_submission *sub, smd_job *view, int *created,
                          sm_error *err);

/* Lock NOT held: a copy of job id as tenant (admin: any) sees it.  1, or
 * 0 when there is none. */
int smd_jobs_find(smd_server *srv, const char *id, const char *tenant, int admin, smd_job *view);

/* Lock NOT held: a copy of the job of owner's Idempotency-Key.  1, or 0
 * when there is none. */
int smd_jobs_find_key(smd_server *srv, const char *owner, const char *key, smd_job *view);

/* Lock NOT held: a result file (name, under results/) of a successful
 * job, opened under the lock (a concurrent delete renames the folder away
 * whole; an open descriptor keeps the file).  1 when the job is there
 * (*view; *fd the file, or -1 when the job is not successful or has no
 * such file), 0 when there is none. */
int smd_jobs_open_result(smd_server *srv, const char *id, const char *tenant, int admin,
                         const char *name, smd_job *view, int *fd);

/* Lock NOT held: the jobs queued here, the workers busy and their number
 * (/readyz). */
void smd_jobs_workload(smd_server *srv, size_t *queued, size_t *busy, size_t *slots);

/* What a DELETE does to a job (smd_jobs_withdraw's what): */
#define SMD_WITHDRAW_CANCEL 1u    /* a live job is cancelled (dismissed) */
#define SMD_WITHDRAW_DELETE 2u    /* a final job is deleted */
#define SMD_WITHDRAW_DISMISSED 4u /* with DELETE: a dismissed one only */

typedef enum smd_withdrawn {
    SMD_WITHDRAWN_NONE,       /* no such job for the caller (404) */
    SMD_WITHDRAWN_KEPT,       /* left as it was (nothing asked applies) */
    SMD_WITHDRAWN_CANCELLED,  /* dismissed (a running worker is asked to stop) */
    SMD_WITHDRAWN_DELETED,    /* gone; *view is its last record */
    SMD_WITHDRAWN_REFUSED,    /* the shared store refused: nothing changed, retry */
    SMD_WITHDRAWN_UNWRITABLE  /* the spool refused the record or the rename:
                               * nothing changed (the daemon is unready) */
} smd_withdrawn;

/* DELETE of one job: the shared store's part first without the lock
 * (the backend's withdraw; a database waiting on a frozen peer's row lock
 * stalls no thread of this daemon), then under it a live job is
 * cancelled, a final one deleted, as `what` allows.  *view (may be NULL):
 * the record after (a cancel) or the last one (a delete).  Returns the
 * outcome; err says why for the two refusals. */
smd_withdrawn smd_jobs_withdraw(smd_server *srv, const char *tenant, int admin, const char *id,
                                unsigned what, smd_job *view, sm_error *err);

/* Lock NOT held: 1 when a batch's model job other than `batch` lists job
 * id among its members (the batches this node holds). */
int smd_jobs_shared(smd_server *srv, const char *batch, const char *id);

/* Lock NOT held: copies of the jobs tenant sees (admin: all), oldest
 * first, whose state is in the mask `states` (bit 1 << state; 0: any),
 * from the offset-th match, at most limit of them: *views (malloc'd,
 * *nviews of them; free() it), *matched every match.  -1 out of memory. */
int smd_jobs_list(smd_server *srv, const char *tenant, int admin, unsigned states, int64_t offset,
                  int64_t limit, smd_job **views, size_t *nviews, int64_t *matched);

/* Lock NOT held: the engine's gauges of /metrics (jobs by state, queue,
 * workers, event followers, quarantined records) into g. */
void smd_jobs_gauges(smd_server *srv, smd_gauges *g);

/* Lock NOT held: the unfinished jobs of owner (a tenant); owner NULL:
 * those among the ids count() hands to live() (count(ctx, live, arg)
 * returns how many were live: the rate limiter's per-address list), with
 * the lock held meanwhile. */
size_t smd_jobs_unfinished(smd_server *srv, const char *owner,
                           size_t (*count)(void *ctx, int (*live)(const char *id, void *arg),
                                           void *arg),
                           void *ctx);

/* Lock NOT held: fn(srv, job, ctx) with the lock held, for job id as
 * tenant sees it: a reading of several records at one instant (a batch's
 * document over its members).  0 when there is no such job (fn not
 * called). */
int smd_jobs_inspect(smd_server *srv, const char *id, const char *tenant, int admin,
                     void (*fn)(smd_server *srv, const smd_job *job, void *ctx), void *ctx);

#endif
