/* The local replica of the database's jobs (see smd_pg_node.h): import
 * of a job, catch-up of its events, the sync thread (notifications,
 * rescans, lease expiry, gauges). */
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "shapematch/sm_clock.h"
#include "store/spool/smd_store.h"
#include "store/spool/smd_fifo.h"
#include "jobs/smd_jobs.h"
#include "store/pg/smd_pg_node.h"
#include "store/pg/smd_pg_node_int.h"
#include "worker/smd_job_file.h"

/* ------------------------------------------------------------ events */

typedef struct ev_list {
    sm_event *v;
    size_t n, cap;
    int bad;
} ev_list;

static int collect(void *user, int64_t seq, const char *json)
{
    ev_list *l = user;
    if (l->n == l->cap) {
        size_t cap = l->cap ? 2 * l->cap : 16;
        sm_event *v = realloc(l->v, cap * sizeof *v);
        if (!v) {
            l->bad = 1;
            return 1;
        }
        l->v = v;
        l->cap = cap;
    }
    sm_error e;
    if (sm_event_from_json(json, strlen(json), &l->v[l->n], &e) != SM_OK) {
        l->bad = 1;
        return 1;
    }
    l->v[l->n].seq = seq;
    if (l->v[l->n].time < 0)
        l->v[l->n].time = sm_time_now();
    l->n++;
    return 0;
}

static sm_status fetch_events(smd_pg *db, const char *id, int64_t after, ev_list *l, sm_error *err)
{
    for (;;) {
        size_t before = l->n;
        int64_t from = l->n ? l->v[l->n - 1].seq : after;
        if (smd_pg_events(db, id, from, 500, collect, l, err) != SM_OK)
            return SM_ERR_IO;
        if (l->bad)
            return sm_error_set(err, SM_ERR_FORMAT, "job %s: an event in the database is not valid", id);
        if (l->n - before < 500)
            return SM_OK;
    }
}

sm_status node_fetch_events(smd_pg *db, const char *id, int64_t after, sm_event **v, size_t *n,
                            sm_error *err)
{
    ev_list l = {0};
    sm_status st = fetch_events(db, id, after, &l, err);
    if (st != SM_OK) {
        free(l.v);
        l.v = NULL;
        l.n = 0;
    }
    *v = l.v;
    *n = l.n;
    return st;
}

static int has_finished(const ev_list *l)
{
    for (size_t i = 0; i < l->n; i++)
        if (l->v[i].type == SM_EVENT_FINISHED)
            return 1;
    return 0;
}

/* ------------------------------------------------------------ import */

static smd_job *new_local(const smd_pg_info *info, const sm_event *first)
{
    smd_job *job = smd_job_new(info->id);
    if (!job)
        return NULL;
    job->state = SM_JOB_ACCEPTED;
    snprintf(job->message, sizeof job->message, "queued");
    job->created = job->updated = first->time;
    job->dim = info->dim;
    job->max_iter = info->max_iter;
    job->tol_boundary = info->tol_boundary;
    snprintf(job->owner, sizeof job->owner, "%s", info->owner);
    snprintf(job->name, sizeof job->name, "%s", info->name);
    snprintf(job->idempotency_key, sizeof job->idempotency_key, "%s", info->idempotency_key);
    job->request_hash = info->request_hash;
    job->batch_model = info->batch_model;
    return job;
}

/* Lock NOT held: a model job's members, from the job.json fetched into
 * tmp, so that the local record names them as the submitting node's does
 * (which batches share a job: DELETE /v1/batches/{id}).  *ids NULL and
 * *n 0 when there are none; SM_ERR_NOMEM out of memory. */
static sm_status read_members(const char *tmp, char (**ids)[SMD_ID_LEN + 1], size_t *n,
                              sm_error *err)
{
    smd_job_file f;
    sm_error ignored;
    *ids = NULL;
    *n = 0;
    if (smd_job_file_read(tmp, &f, &ignored) == SM_OK && f.batch) {
        json_t *list = json_object_get(f.batch, "members"), *v;
        size_t count = json_array_size(list), i;
        if (count && !(*ids = calloc(count, sizeof **ids))) {
            smd_job_file_free(&f);
            return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
        }
        json_array_foreach(list, i, v)
            snprintf((*ids)[i], sizeof (*ids)[i], "%s", json_string_value(json_object_get(v, "job")));
        *n = count;
    }
    smd_job_file_free(&f);
    return SM_OK;
}

/* srv->lock held. */
static sm_status commit_import(smd_pg_node *n, const smd_pg_info *info, const char *tmp,
                               const char (*members)[SMD_ID_LEN + 1], size_t nmembers,
                               ev_list *evs, node_lease *lease, smd_jobs_after *after, sm_error *err)
{
    smd_server *srv = n->srv;
    smd_job *old = smd_store_get(srv->store, info->id);
    if (old && !lease)
        return SM_OK; /* imported meanwhile (by another thread of this node) */
    if (old && old->worker_active)
        return sm_error_set(err, SM_ERR_INVALID, "job %s still runs here", info->id);
    if (old)
        smd_jobs_mirror_drop(srv, old, after);
    smd_job *job = new_local(info, &evs->v[0]);
    if (job && smd_job_set_members(job, members, nmembers) != 0) {
        smd_job_free(job);
        job = NULL;
    }
    if (!job)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    sm_event first = evs->v[0];
    if (smd_store_commit(srv->store, tmp, job, &first, err) != SM_OK)
        return SM_ERR_IO;
    for (size_t i = 1; i < evs->n; i++)
        smd_jobs_mirror_event(srv, job, &evs->v[i], after);
    if (!lease) {
        if (!smd_job_state_final(info->state))
            smd_jobs_mirror_state(srv, job, info->state, info->message, info->attempt, after);
        return SM_OK;
    }
    pthread_mutex_lock(&n->lock);
    lease->known = job->nevents;
    pthread_mutex_unlock(&n->lock);
    char msg[SM_EVENT_MESSAGE_MAX];
    snprintf(msg, sizeof msg, "claimed by node %s", n->name);
    smd_jobs_mirror_state(srv, job, SM_JOB_ACCEPTED, msg, lease->lease.attempt - 1, after);
    if (smd_queue_push(srv->queue, job->id) != 0)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    smd_jobs_after_wake(srv, after);
    return SM_OK;
}

/* A batch's model job about to run here: the results of its successful
 * members into members/<id>/ of its folder (the worker reads them there;
 * this node's replica of them may lag behind the database). */
typedef struct members_fetch {
    smd_pg *db;
    const char *dir;
    sm_status st;
    sm_error *err;
} members_fetch;

static int fetch_member(void *user, const char *member)
{
    members_fetch *f = user;
    char path[PATH_MAX];
    size_t count;
    if (!smd_id_valid(member) || smd_pathf(path, sizeof path, "%s/members/%s", f->dir, member) != 0) {
        f->st = sm_error_set(f->err, SM_ERR_IO, "member %.40s: bad id or path too long", member);
        return 1;
    }
    f->st = smd_pg_blob_get_tree(f->db, member, "results/", path, &count, f->err);
    return f->st != SM_OK;
}

static sm_status fetch_members(smd_pg *db, const char *id, const char *tmp, sm_error *err)
{
    char dir[PATH_MAX];
    if (smd_pathf(dir, sizeof dir, "%s/members", tmp) != 0 || mkdir(dir, 0755) != 0)
        return sm_error_set(err, SM_ERR_IO, "%s/members: cannot create it", tmp);
    members_fetch f = {db, tmp, SM_OK, err};
    sm_status st = smd_pg_batch_done(db, id, fetch_member, &f, err);
    return st != SM_OK ? st : f.st;
}

/* The folder the store commits: job.json, inputs/ (a run) or results/
 * (a successful job mirrored). */
static sm_status fetch_folder(smd_pg *db, const smd_pg_info *info, const char *tmp, int run,
                              sm_error *err)
{
    char path[PATH_MAX];
    size_t count;
    int found;
    smd_rmtree(tmp);
    if (mkdir(tmp, 0755) != 0 || smd_pathf(path, sizeof path, "%s/job.json", tmp) != 0)
        return sm_error_set(err, SM_ERR_IO, "%s: cannot create it", tmp);
    sm_status st = smd_pg_blob_get(db, info->id, "job.json", path, &found, err);
    if (st == SM_OK && smd_pathf(path, sizeof path, "%s/inputs", tmp) == 0)
        st = run ? smd_pg_blob_get_tree(db, info->id, "inputs/", path, &count, err)
                 : (mkdir(path, 0755), SM_OK);
    if (st == SM_OK && run && info->batch_model)
        st = fetch_members(db, info->id, tmp, err);
    if (st == SM_OK && !run && info->state == SM_JOB_SUCCESSFUL &&
        smd_pathf(path, sizeof path, "%s/results", tmp) == 0)
        st = smd_pg_blob_get_tree(db, info->id, "results/", path, &count, err);
    return st;
}

sm_status node_import(smd_pg_node *n, smd_pg *db, const char *id, node_lease *lease, sm_error *err)
{
    smd_server *srv = n->srv;
    smd_pg_info info;
    int found = 0;
    ev_list evs = {0};
    char tmp[PATH_MAX];
    sm_status st = smd_pg_job_info(db, id, &info, &found, err);
    if (st == SM_OK && !found)
        st = sm_error_set(err, SM_ERR_INVALID, "job %s is not in the database", id);
    if (st == SM_OK && smd_pathf(tmp, sizeof tmp, "%s/pg-%s-%s", smd_store_tmp_dir(srv->store), id,
                                 lease ? "run" : db == n->api_db ? "api" : "sync") != 0)
        st = sm_error_set(err, SM_ERR_IO, "path too long");
    if (st == SM_OK)
        st = fetch_folder(db, &info, tmp, lease != NULL, err);
    if (st == SM_OK)
        st = fetch_events(db, id, 0, &evs, err);
    if (st == SM_OK && (evs.n == 0 || evs.v[0].type != SM_EVENT_ACCEPTED))
        st = sm_error_set(err, SM_ERR_FORMAT, "job %s: its first event is not 'accepted'", id);
    char (*members)[SMD_ID_LEN + 1] = NULL;
    size_t nmembers = 0;
    if (st == SM_OK && info.batch_model)
        st = read_members(tmp, &members, &nmembers, err);
    smd_jobs_after after = {0};
    if (st == SM_OK) {
        pthread_mutex_lock(&srv->lock);
        st = commit_import(n, &info, tmp, (const char (*)[SMD_ID_LEN + 1])members, nmembers, &evs,
                           lease, &after, err);
        pthread_mutex_unlock(&srv->lock);
    }
    free(members);
    smd_jobs_after_free(&after);
    if (found)
        smd_rmtree(tmp); /* gone when committed */
    free(evs.v);
    return st;
}

/* ---------------------------------------------------------- catch-up */

sm_status node_catch_up_locked(smd_pg_node *n, smd_pg *db, smd_job *job, smd_jobs_after *after,
                               sm_error *err)
{
    ev_list evs = {0};
    sm_status st = smd_store_load_events(n->srv->store, job, err);
    if (st == SM_OK)
        st = fetch_events(db, job->id, job->nevents, &evs, err);
    for (size_t i = 0; st == SM_OK && i < evs.n; i++)
        smd_jobs_mirror_event(n->srv, job, &evs.v[i], after);
    free(evs.v);
    return st;
}

/* Lock NOT held: results first (when the job succeeded), then the events
 * and the state, under the lock. */
static sm_status catch_up(smd_pg_node *n, const smd_pg_info *info, int64_t local_n, sm_error *err)
{
    smd_server *srv = n->srv;
    ev_list evs = {0};
    sm_status st = fetch_events(n->sync_db, info->id, local_n, &evs, err);
    char tmp[PATH_MAX], final[PATH_MAX];
    if (st == SM_OK && has_finished(&evs) &&
        smd_pathf(tmp, sizeof tmp, "%s/jobs/%s/results.pg", smd_store_root(srv->store), info->id) == 0 &&
        smd_pathf(final, sizeof final, "%s/jobs/%s/results", smd_store_root(srv->store), info->id) == 0) {
        size_t count;
        smd_rmtree(tmp);
        st = smd_pg_blob_get_tree(n->sync_db, info->id, "results/", tmp, &count, err);
        smd_rmtree(final);
        if (st == SM_OK && rename(tmp, final) != 0)
            st = sm_error_set(err, SM_ERR_IO, "job %s: cannot move its results into place", info->id);
    }
    smd_jobs_after after = {0};
    pthread_mutex_lock(&srv->lock);
    smd_job *job = st == SM_OK ? smd_store_get(srv->store, info->id) : NULL;
    for (size_t i = 0; job && i < evs.n; i++)
        smd_jobs_mirror_event(srv, job, &evs.v[i], &after);
    if (job && !smd_job_state_final(info->state))
        smd_jobs_mirror_state(srv, job, info->state, info->message, info->attempt, &after);
    pthread_mutex_unlock(&srv->lock);
    smd_jobs_after_free(&after);
    free(evs.v);
    return st;
}

/* -------------------------------------------------------------- scan */

static int cmp_id(const void *a, const void *b)
{
    return strcmp((const char *)a, (const char *)b);
}

typedef struct scan_plan {
    size_t *todo;          /* indexes into the list: import (local_n < 0) or catch up */
    int64_t *local_n;
    size_t ntodo;
    char (*gone)[SMD_ID_LEN + 1];
    size_t ngone;
} scan_plan;

/* srv->lock held: what each database job needs here. */
static void plan_job(smd_pg_node *n, const smd_pg_info *row, size_t i, scan_plan *p,
                     smd_jobs_after *after)
{
    smd_server *srv = n->srv;
    if (node_pending(n, row->id) || smd_pg_node_runs(n, row->id))
        return;
    smd_job *job = smd_store_get(srv->store, row->id);
    sm_error err;
    if (job && smd_store_load_events(srv->store, job, &err) != SM_OK)
        return;
    if (job && job->nevents > row->nevents && !job->worker_active) {
        smd_jobs_mirror_drop(srv, job, after); /* a stale copy: taken again */
        job = NULL;
    }
    if (!job || job->nevents < row->nevents) {
        p->todo[p->ntodo] = i;
        p->local_n[p->ntodo++] = job ? job->nevents : -1;
    } else if (!smd_job_state_final(row->state)) {
        smd_jobs_mirror_state(srv, job, row->state, row->message, row->attempt, after);
    }
}

/* srv->lock held: local copies of jobs the database no longer has. */
static void plan_gone(smd_pg_node *n, const char (*ids)[SMD_ID_LEN + 1], size_t nids, scan_plan *p)
{
    smd_server *srv = n->srv;
    size_t count = smd_store_count(srv->store);
    p->gone = count ? calloc(count, sizeof *p->gone) : NULL;
    for (size_t i = 0; p->gone && i < count; i++) {
        smd_job *job = smd_store_at(srv->store, i);
        if ((nids && bsearch(job->id, ids, nids, sizeof *ids, cmp_id)) || job->worker_active ||
            node_pending(n, job->id) || smd_pg_node_runs(n, job->id))
            continue;
        memcpy(p->gone[p->ngone++], job->id, SMD_ID_LEN + 1);
    }
}

static void apply_gone(smd_pg_node *n, const scan_plan *p, smd_jobs_after *after)
{
    for (size_t i = 0; i < p->ngone; i++) {
        smd_job *job = smd_store_get(n->srv->store, p->gone[i]);
        if (job)
            smd_jobs_mirror_drop(n->srv, job, after);
    }
}

static sm_status sync_scan(smd_pg_node *n, sm_error *err)
{
    smd_server *srv = n->srv;
    smd_pg_info *rows;
    size_t nrows;
    if (smd_pg_list(n->sync_db, &rows, &nrows, err) != SM_OK)
        return SM_ERR_IO;
    char (*ids)[SMD_ID_LEN + 1] = nrows ? calloc(nrows, sizeof *ids) : NULL;
    scan_plan p = {nrows ? calloc(nrows, sizeof *p.todo) : NULL,
                   nrows ? calloc(nrows, sizeof *p.local_n) : NULL, 0, NULL, 0};
    sm_status st = SM_OK;
    if (nrows && (!ids || !p.todo || !p.local_n))
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    for (size_t i = 0; st == SM_OK && i < nrows; i++)
        memcpy(ids[i], rows[i].id, SMD_ID_LEN + 1);
    if (st == SM_OK && nrows)
        qsort(ids, nrows, sizeof *ids, cmp_id);
    smd_jobs_after after = {0};
    pthread_mutex_lock(&srv->lock);
    for (size_t i = 0; st == SM_OK && i < nrows; i++)
        plan_job(n, &rows[i], i, &p, &after);
    if (st == SM_OK)
        plan_gone(n, (const char (*)[SMD_ID_LEN + 1])ids, nrows, &p);
    apply_gone(n, &p, &after);
    pthread_mutex_unlock(&srv->lock);
    smd_jobs_after_free(&after);
    for (size_t k = 0; st == SM_OK && k < p.ntodo; k++) {
        const smd_pg_info *row = &rows[p.todo[k]];
        sm_error e;
        sm_status one = p.local_n[k] < 0 ? node_import(n, n->sync_db, row->id, NULL, &e)
                                         : catch_up(n, row, p.local_n[k], &e);
        if (one != SM_OK && !smd_pg_connected(n->sync_db))
            st = sm_error_set(err, SM_ERR_IO, "%s", e.msg);
        else if (one != SM_OK)
            smd_logf(&srv->log, SMD_LOG_WARN, "mirror_error", "%s", e.msg);
    }
    free(p.todo);
    free(p.local_n);
    free(p.gone);
    free(ids);
    free(rows);
    return st;
}

/* ------------------------------------------------------------ thread */

/* A cancel for a job this node runs: its worker is stopped here, the
 * status saying why (a DELETE, or the lease lost). */
static void cancel_here(smd_pg_node *n, const char *id, const char *why)
{
    smd_server *srv = n->srv;
    if (!smd_pg_node_runs(n, id))
        return;
    smd_jobs_after after = {0};
    pthread_mutex_lock(&srv->lock);
    smd_job *job = smd_store_get(srv->store, id);
    if (job && (job->state == SM_JOB_RUNNING || job->state == SM_JOB_ACCEPTED))
        smd_jobs_stop(srv, job, why, &after);
    pthread_mutex_unlock(&srv->lock);
    smd_jobs_after_free(&after);
}

void node_cancel_here(smd_pg_node *n, const char *id, const char *why);
void node_cancel_here(smd_pg_node *n, const char *id, const char *why)
{
    cancel_here(n, id, why);
}

static void sleep_for(double s)
{
    struct timespec ts = {(time_t)s, (long)((s - (double)(time_t)s) * 1e9)};
    nanosleep(&ts, NULL);
}

/* Notifications for up to 0.5 s: cancels are acted on, events only wake
 * the scan.  -1 when the connection failed. */
static int take_notifications(smd_pg_node *n, sm_error *err)
{
    char channel[64], payload[256];
    double timeout = 0.5;
    int r;
    while ((r = smd_pg_wait(n->sync_db, timeout, channel, sizeof channel, payload, sizeof payload,
                            err)) == 1) {
        if (strcmp(channel, SMD_PG_CHANNEL_CANCEL) == 0)
            cancel_here(n, payload, SMD_PG_CANCELLED);
        timeout = 0.02; /* gather the burst, then scan */
    }
    return r;
}

static sm_status sweep(smd_pg_node *n, sm_error *err)
{
    size_t requeued, failed;
    int64_t queued, leased;
    if (smd_pg_expire(n->sync_db, n->srv->cfg.max_attempts, &requeued, &failed, err) != SM_OK ||
        smd_pg_depth(n->sync_db, &queued, &leased, err) != SM_OK)
        return SM_ERR_IO;
    if (requeued || failed)
        smd_log(&n->srv->log, SMD_LOG_WARN, "leases_expired",
                json_pack("{s:I,s:I}", "requeued", (json_int_t)requeued, "failed", (json_int_t)failed));
    char held[16 * (SMD_ID_LEN + 1) + 1];
    size_t nheld = 0;
    if (smd_pg_expired_held(n->sync_db, held, sizeof held, &nheld, err) != SM_OK)
        return SM_ERR_IO;
    if (nheld)
        smd_log(&n->srv->log, SMD_LOG_WARN, "leases_expired_held",
                json_pack("{s:s,s:s}", "jobs", held, "why",
                          "their rows are locked by another session (a node frozen inside a "
                          "transaction?): requeued once it commits, or once the server ends it "
                          "(--database-idle-timeout)"));
    atomic_store(&n->queued, queued);
    atomic_store(&n->leased, leased);
    return SM_OK;
}

void *node_sync_main(void *arg)
{
    smd_pg_node *n = arg;
    smd_server *srv = n->srv;
    double backoff = 0.1, last_sweep = -1e9;
    sm_error err;
    if (smd_pg_listen(n->sync_db, SMD_PG_CHANNEL_EVENTS, &err) != SM_OK ||
        smd_pg_listen(n->sync_db, SMD_PG_CHANNEL_CANCEL, &err) != SM_OK)
        node_set_down(n, err.msg);
    while (!atomic_load(&n->stop)) {
        if (node_connected(n, n->sync_db, &err) != SM_OK) {
            sleep_for(backoff); /* reconnect with backoff: 0.1 s doubling to 5 s */
            backoff = backoff * 2 > 5 ? 5 : backoff * 2;
            continue;
        }
        sm_status st = take_notifications(n, &err) < 0 ? SM_ERR_IO : SM_OK;
        if (st == SM_OK && srv->cfg.role != SMD_ROLE_WORKER)
            st = sync_scan(n, &err);
        double now = sm_clock_seconds();
        if (st == SM_OK && now - last_sweep >= srv->cfg.lease / 3) {
            st = sweep(n, &err);
            last_sweep = now;
        }
        if (st != SM_OK && !smd_pg_connected(n->sync_db)) {
            node_set_down(n, err.msg);
            continue;
        }
        if (st != SM_OK && smd_pg_timed_out(n->sync_db)) {
            node_check_timeout(n, n->sync_db, &err);
            continue;
        }
        if (st != SM_OK)
            smd_logf(&srv->log, SMD_LOG_WARN, "database_error", "%s", err.msg);
        backoff = 0.1;
        node_set_up(n);
    }
    return NULL;
}
