/* The embedded backend (see smd_spool_backend.h): what the spool does
 * where PostgreSQL does something else: recovery from the local
 * summaries, final-event repair, the local queue with its model-job gate,
 * and nothing to publish or tell. */
#include "jobs/smd_spool_backend.h"

#include <errno.h>
#include <limits.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "worker/smd_worker.h"

static sm_status spool_read_summary(smd_backend *b, const smd_job *job, sm_event *finished,
                                    double *when, sm_error *err)
{
    return smd_store_read_summary(b->spool, job, finished, when, err);
}

static int spool_final_event_missing(smd_backend *b, const smd_job *job)
{
    return smd_store_final_event_missing(b->spool, job);
}

/* A batch's model job runs once none of its members is queued or running
 * (api/smd_batches.h); a deleted member counts as ended.  It stays out of
 * the FIFO until then: queued by the last member's end (spool_event), or
 * here when that came first (a restart, a batch of ended jobs). */
static int members_live(smd_backend *b, const smd_job *model)
{
    for (size_t i = 0; i < model->nmembers; i++) {
        const smd_job *m = smd_store_get(b->spool, model->members[i]);
        if (m && !smd_job_state_final(m->state))
            return 1;
    }
    return 0;
}

/* The model job's members, in its own folder: members/<id> links to the
 * published results of each member that has them (../../<id>/results),
 * so that the worker reads only its JOB_DIR, as on PostgreSQL, where the
 * node copies them in.  A member deleted later leaves a dangling link:
 * left out of the model, as a member without results is.  One symlink
 * per member (at most SMD_JOB_MEMBERS_MAX) under the lock. */
static void link_members(smd_backend *b, const smd_job *model)
{
    char dir[PATH_MAX], link[PATH_MAX], target[PATH_MAX], summary[PATH_MAX];
    if (smd_store_path(b->spool, model->id, "members", dir, sizeof dir) != 0 ||
        (mkdir(dir, 0750) != 0 && errno != EEXIST))
        return; /* the worker finds no member: the model job fails, saying so */
    for (size_t i = 0; i < model->nmembers; i++) {
        const char *id = model->members[i];
        if (smd_store_path(b->spool, id, SMD_RESULTS_DIR "/summary.json", summary,
                           sizeof summary) != 0 ||
            access(summary, F_OK) != 0 ||
            smd_pathf(link, sizeof link, "%s/%s", dir, id) != 0 ||
            smd_pathf(target, sizeof target, "../../%s/" SMD_RESULTS_DIR, id) != 0)
            continue;
        if (symlink(target, link) != 0 && errno != EEXIST)
            continue;
    }
}

static int queue_model(smd_backend *b, const smd_job *model)
{
    link_members(b, model);
    return smd_queue_push(b->fifo, model->id);
}

static int spool_enqueue(smd_backend *b, const char *id)
{
    const smd_job *job = smd_store_get(b->spool, id);
    if (job && job->batch_model && members_live(b, job))
        return 1; /* waits: queued here later */
    if (job && job->batch_model)
        return queue_model(b, job) == 0 ? 1 : -1;
    return smd_queue_push(b->fifo, id) == 0 ? 1 : -1;
}

/* one node, one store: nothing to publish or tell */
static sm_status spool_publish(smd_backend *b, const struct smd_submission *sub, double *created,
                               char existing[SMD_ID_LEN + 1], sm_error *err)
{
    (void)b, (void)sub, (void)created, (void)err;
    existing[0] = '\0';
    return SM_OK;
}

static void spool_submitted(smd_backend *b, const char *id)
{
    (void)b, (void)id;
}

/* The final event of a job: the model jobs waiting for it (a scan of the
 * table, as the list and the metrics do) are queued when it was their
 * last live member. */
static void spool_event(smd_backend *b, const smd_job *job, const sm_event *ev)
{
    if (!smd_job_state_final(job->state) || job->batch_model ||
        (ev->type != SM_EVENT_FINISHED && ev->type != SM_EVENT_FAILED &&
         ev->type != SM_EVENT_CANCELLED))
        return;
    size_t count = smd_store_count(b->spool);
    for (size_t i = 0; i < count; i++) {
        smd_job *model = smd_store_at(b->spool, i);
        if (!model->batch_model || model->state != SM_JOB_ACCEPTED ||
            smd_queue_position(b->fifo, model->id) >= 0)
            continue;
        int member = 0;
        for (size_t k = 0; k < model->nmembers && !member; k++)
            member = strcmp(model->members[k], job->id) == 0;
        if (member && !members_live(b, model))
            queue_model(b, model); /* out of memory: runs after a restart */
    }
}

static void spool_requeued(smd_backend *b, const smd_job *job)
{
    (void)b, (void)job;
}

static sm_status spool_cancel(smd_backend *b, struct smd_server *srv, smd_job *job,
                              struct smd_jobs_after *after, int *handled, sm_error *err)
{
    (void)b, (void)srv, (void)job, (void)after, (void)err;
    *handled = 0; /* the engine dismisses it here */
    return SM_OK;
}

static sm_status spool_remove(smd_backend *b, const char *id, int *deleted, sm_error *err)
{
    (void)b, (void)id, (void)err;
    *deleted = 1; /* the engine's removal is the only one */
    return SM_OK;
}

static int spool_ready(smd_backend *b, char *why, size_t cap)
{
    (void)b;
    if (cap)
        why[0] = '\0';
    return 1; /* the spool's writability is srv->unwritable's business */
}

static void spool_metrics(smd_backend *b, char **text, size_t *len)
{
    (void)b, (void)text, (void)len;
}

const smd_backend_ops smd_spool_backend_ops = {
    .name = "spool",
    .read_summary = spool_read_summary,
    .final_event_missing = spool_final_event_missing,
    .enqueue = spool_enqueue,
    .publish = spool_publish,
    .submitted = spool_submitted,
    .event = spool_event,
    .requeued = spool_requeued,
    .cancel = spool_cancel,
    .remove = spool_remove,
    .ready = spool_ready,
    .metrics = spool_metrics,
};

void smd_spool_backend_init(smd_backend *b, smd_store *spool, smd_queue *fifo)
{
    *b = (smd_backend){.ops = &smd_spool_backend_ops, .spool = spool, .fifo = fifo};
}
