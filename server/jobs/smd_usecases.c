/* The engine's use cases for the handlers (see smd_usecases.h). */
#include "jobs/smd_usecases.h"
#include "jobs/smd_follow.h"
#include "jobs/smd_pool.h"
#include "worker/smd_worker.h"

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <stdlib.h>
#include <string.h>

sm_status smd_jobs_create(smd_server *srv, smd_submission *sub, smd_job *view, int *created,
                          sm_error *err)
{
    smd_jobs_after after = {0};
    smd_job *job = NULL;
    *created = 0;
    sm_status st = smd_jobs_publish(srv, sub, err); /* a shared store first, without the lock */
    pthread_mutex_lock(&srv->lock);
    if (st == SM_OK)
        st = smd_jobs_submit(srv, sub, &job, created, &after, err);
    if (st == SM_OK)
        smd_job_view(job, view);
    pthread_mutex_unlock(&srv->lock);
    smd_jobs_after_free(&after);
    return st;
}

int smd_jobs_find(smd_server *srv, const char *id, const char *tenant, int admin, smd_job *view)
{
    pthread_mutex_lock(&srv->lock);
    smd_job *job = smd_store_get(srv->store, id);
    int found = job && smd_job_visible(job, tenant, admin);
    if (found && view)
        smd_job_view(job, view);
    pthread_mutex_unlock(&srv->lock);
    return found;
}

int smd_jobs_find_key(smd_server *srv, const char *owner, const char *key, smd_job *view)
{
    pthread_mutex_lock(&srv->lock);
    smd_job *job = smd_store_find_key(srv->store, owner, key);
    if (job)
        smd_job_view(job, view);
    pthread_mutex_unlock(&srv->lock);
    return job != NULL;
}

int smd_jobs_open_result(smd_server *srv, const char *id, const char *tenant, int admin,
                         const char *name, smd_job *view, int *fd)
{
    char rel[PATH_MAX], path[PATH_MAX];
    int pathok = smd_pathf(rel, sizeof rel, SMD_RESULTS_DIR "/%s", name) == 0 &&
                 smd_store_path(srv->store, id, rel, path, sizeof path) == 0;
    *fd = -1;
    pthread_mutex_lock(&srv->lock);
    smd_job *job = smd_store_get(srv->store, id);
    int found = job && smd_job_visible(job, tenant, admin);
    if (found) {
        smd_job_view(job, view);
        if (job->state == SM_JOB_SUCCESSFUL && pathok)
            *fd = open(path, O_RDONLY | O_CLOEXEC);
    }
    pthread_mutex_unlock(&srv->lock);
    return found;
}

void smd_jobs_workload(smd_server *srv, size_t *queued, size_t *busy, size_t *slots)
{
    pthread_mutex_lock(&srv->lock);
    *queued = smd_queue_depth(srv->queue);
    *busy = smd_pool_busy(srv->pool);
    *slots = smd_pool_slots(srv->pool);
    pthread_mutex_unlock(&srv->lock);
}

/* Lock held: what `what` does to job now. */
static smd_withdrawn withdraw_locked(smd_server *srv, smd_job *job, unsigned what, smd_job *view,
                                     smd_jobs_after *after, sm_error *err)
{
    if (!smd_job_state_final(job->state)) {
        if (!(what & SMD_WITHDRAW_CANCEL))
            return SMD_WITHDRAWN_KEPT;
        /* SM_ERR_INVALID: its run ended first (a held end written now) */
        if (smd_jobs_cancel(srv, job, after) == SM_ERR_IO) {
            sm_error_set(err, SM_ERR_IO, "the spool cannot be written (%s)", strerror(errno));
            return SMD_WITHDRAWN_UNWRITABLE;
        }
        if (view)
            smd_job_view(job, view);
        return SMD_WITHDRAWN_CANCELLED;
    }
    if (!(what & SMD_WITHDRAW_DELETE) ||
        ((what & SMD_WITHDRAW_DISMISSED) && job->state != SM_JOB_DISMISSED))
        return SMD_WITHDRAWN_KEPT;
    if (view)
        smd_job_view(job, view);
    if (smd_jobs_delete(srv, job, after) != SM_OK) {
        sm_error_set(err, SM_ERR_IO, "the spool cannot be written (%s)", strerror(errno));
        return SMD_WITHDRAWN_UNWRITABLE;
    }
    return SMD_WITHDRAWN_DELETED;
}

smd_withdrawn smd_jobs_withdraw(smd_server *srv, const char *tenant, int admin, const char *id,
                                unsigned what, smd_job *view, sm_error *err)
{
    pthread_mutex_lock(&srv->lock);
    smd_job *job = smd_store_get(srv->store, id);
    if (job && !smd_job_visible(job, tenant, admin))
        job = NULL;
    int final = job && smd_job_state_final(job->state);
    int64_t known = job ? job->nevents : 0;
    if (job && view)
        smd_job_view(job, view);
    pthread_mutex_unlock(&srv->lock);
    if (!job)
        return SMD_WITHDRAWN_NONE;
    if (final ? !(what & SMD_WITHDRAW_DELETE) : !(what & SMD_WITHDRAW_CANCEL))
        return SMD_WITHDRAWN_KEPT; /* nothing to ask the shared store */
    if (smd_backend_withdraw(srv->backend, id, final, known, err) != SM_OK)
        return SMD_WITHDRAWN_REFUSED;
    smd_jobs_after after = {0};
    smd_withdrawn out = SMD_WITHDRAWN_NONE;
    pthread_mutex_lock(&srv->lock);
    job = smd_store_get(srv->store, id);
    if (job && smd_job_visible(job, tenant, admin)) /* else deleted meanwhile */
        out = withdraw_locked(srv, job, what, view, &after, err);
    pthread_mutex_unlock(&srv->lock);
    smd_jobs_after_free(&after);
    return out;
}

int smd_jobs_shared(smd_server *srv, const char *batch, const char *id)
{
    int shared = 0;
    pthread_mutex_lock(&srv->lock);
    size_t n = smd_store_count(srv->store);
    for (size_t i = 0; i < n && !shared; i++) {
        const smd_job *b = smd_store_at(srv->store, i);
        if (!b->batch_model || strcmp(b->id, batch) == 0)
            continue;
        for (size_t k = 0; k < b->nmembers && !shared; k++)
            shared = strcmp(b->members[k], id) == 0;
    }
    pthread_mutex_unlock(&srv->lock);
    return shared;
}

int smd_jobs_list(smd_server *srv, const char *tenant, int admin, unsigned states, int64_t offset,
                  int64_t limit, smd_job **views, size_t *nviews, int64_t *matched)
{
    *nviews = 0;
    *matched = 0;
    pthread_mutex_lock(&srv->lock);
    size_t n = smd_store_count(srv->store);
    size_t cap = (size_t)limit < n ? (size_t)limit : n;
    *views = malloc((cap ? cap : 1) * sizeof **views);
    for (size_t k = 0; k < n && *views; k++) { /* oldest first */
        const smd_job *job = smd_store_at(srv->store, k);
        if ((states && !(states & (1u << job->state))) || !smd_job_visible(job, tenant, admin))
            continue;
        if (*matched >= offset && *nviews < cap)
            smd_job_view(job, &(*views)[(*nviews)++]);
        ++*matched;
    }
    pthread_mutex_unlock(&srv->lock);
    return *views ? 0 : -1;
}

void smd_jobs_gauges(smd_server *srv, smd_gauges *g)
{
    pthread_mutex_lock(&srv->lock);
    for (size_t i = 0; i < smd_store_count(srv->store); i++) {
        unsigned s = (unsigned)smd_store_at(srv->store, i)->state;
        if (s < SMD_JOB_STATES)
            g->jobs_by_state[s]++;
    }
    g->queue_depth = smd_queue_depth(srv->queue);
    g->workers_busy = smd_pool_busy(srv->pool);
    g->workers_total = smd_pool_slots(srv->pool);
    g->followers = smd_follow_count(srv);
    g->quarantined = smd_store_quarantined(srv->store);
    pthread_mutex_unlock(&srv->lock);
}

static int job_unfinished(const char *id, void *store)
{
    smd_job *job = smd_store_get(store, id);
    return job && !smd_job_state_final(job->state);
}

size_t smd_jobs_unfinished(smd_server *srv, const char *owner,
                           size_t (*count)(void *ctx, int (*live)(const char *id, void *arg),
                                           void *arg),
                           void *ctx)
{
    size_t n = 0;
    pthread_mutex_lock(&srv->lock);
    if (!owner) {
        n = count(ctx, job_unfinished, srv->store);
    } else {
        size_t all = smd_store_count(srv->store);
        for (size_t i = 0; i < all; i++) {
            const smd_job *job = smd_store_at(srv->store, i);
            n += strcmp(job->owner, owner) == 0 && !smd_job_state_final(job->state);
        }
    }
    pthread_mutex_unlock(&srv->lock);
    return n;
}

int smd_jobs_inspect(smd_server *srv, const char *id, const char *tenant, int admin,
                     void (*fn)(smd_server *srv, const smd_job *job, void *ctx), void *ctx)
{
    pthread_mutex_lock(&srv->lock);
    const smd_job *job = smd_store_get_visible(srv->store, id, tenant, admin);
    if (job)
        fn(srv, job, ctx);
    pthread_mutex_unlock(&srv->lock);
    return job != NULL;
}
