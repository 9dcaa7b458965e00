/* A node of a cluster on one PostgreSQL database (see smd_pg_node.h):
 * lifecycle, the state machine's hooks, leases and the outbox. */
#include "store/pg/smd_pg_node.h"

#include "store/pg/smd_pg_node_int.h"

#include <errno.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "shapematch/sm_clock.h"
#include "jobs/smd_jobs.h"
#include "jobs/smd_pool.h"
#include "worker/smd_job_file.h"

/* ------------------------------------------------------------ leases */

node_lease *node_find_lease(smd_pg_node *n, const char *id)
{
    for (node_lease *l = n->leases; l; l = l->next)
        if (strcmp(l->lease.id, id) == 0)
            return l;
    return NULL;
}

int smd_pg_node_runs(smd_pg_node *n, const char *id)
{
    pthread_mutex_lock(&n->lock);
    int runs = node_find_lease(n, id) != NULL;
    pthread_mutex_unlock(&n->lock);
    return runs;
}

void node_drop_lease(smd_pg_node *n, const char *id)
{
    pthread_mutex_lock(&n->lock);
    for (node_lease **p = &n->leases; *p; p = &(*p)->next)
        if (strcmp((*p)->lease.id, id) == 0) {
            node_lease *dead = *p;
            *p = dead->next;
            free(dead);
            n->nleases--;
            break;
        }
    pthread_mutex_unlock(&n->lock);
}

/* ------------------------------------------------------------ outbox */

static void push_item(smd_pg_node *n, node_item *it)
{
    it->next = NULL;
    *n->out_tail = it;
    n->out_tail = &it->next;
    pthread_cond_signal(&n->cond);
}

node_item *node_take_item(smd_pg_node *n)
{
    node_item *it = n->out_head;
    if (it) {
        n->out_head = it->next;
        if (!n->out_head)
            n->out_tail = &n->out_head;
    }
    return it;
}

void smd_pg_node_event(smd_pg_node *n, const smd_job *job, const sm_event *ev)
{
    pthread_mutex_lock(&n->lock);
    node_lease *l = node_find_lease(n, job->id);
    node_item *it = l && !l->lost && ev->seq > l->known ? calloc(1, sizeof *it) : NULL;
    if (it && !(it->json = sm_event_to_json(ev))) {
        free(it);
        it = NULL;
    }
    if (it) {
        memcpy(it->id, job->id, sizeof it->id);
        it->ord = n->next_ord++;
        it->attempt = l->lease.attempt;
        it->token = l->lease.token;
        it->seq = ev->seq;
        it->final = smd_job_state_final(job->state);
        it->state = job->state;
        snprintf(it->message, sizeof it->message, "%s", job->message);
        push_item(n, it);
    } else if (l && !l->lost && ev->seq > l->known) {
        smd_logf(&n->srv->log, SMD_LOG_ERROR, "database_error",
                 "job %s: out of memory forwarding event %lld", job->id, (long long)ev->seq);
    }
    pthread_mutex_unlock(&n->lock);
}

void smd_pg_node_requeued(smd_pg_node *n, const smd_job *job)
{
    pthread_mutex_lock(&n->lock);
    node_lease *l = node_find_lease(n, job->id);
    node_item *it = l ? calloc(1, sizeof *it) : NULL;
    if (it) {
        memcpy(it->id, job->id, sizeof it->id);
        it->ord = n->next_ord++;
        it->attempt = l->lease.attempt;
        it->token = l->lease.token;
        it->release = 1;
        snprintf(it->message, sizeof it->message, "%s", job->message);
        push_item(n, it);
    }
    pthread_mutex_unlock(&n->lock);
}

/* ----------------------------------------------------------- uploads */

static int pending_index(smd_pg_node *n, const char *id)
{
    for (size_t i = 0; i < n->npending; i++)
        if (strcmp(n->pending[i], id) == 0)
            return (int)i;
    return -1;
}

int node_pending(smd_pg_node *n, const char *id)
{
    pthread_mutex_lock(&n->lock);
    int p = pending_index(n, id) >= 0;
    pthread_mutex_unlock(&n->lock);
    return p;
}

void smd_pg_node_submitted(smd_pg_node *n, const char *id)
{
    pthread_mutex_lock(&n->lock);
    int i = pending_index(n, id);
    if (i >= 0)
        memcpy(n->pending[i], n->pending[--n->npending], SMD_ID_LEN + 1);
    pthread_mutex_unlock(&n->lock);
}

static int add_pending(smd_pg_node *n, const char *id)
{
    pthread_mutex_lock(&n->lock);
    int ok = n->npending < NODE_PENDING_MAX;
    if (ok)
        snprintf(n->pending[n->npending++], SMD_ID_LEN + 1, "%s", id);
    pthread_mutex_unlock(&n->lock);
    return ok ? 0 : -1;
}

/* After a failed call (its lock held): 1 when the connection was lost
 * and is back (the caller tries once more). */
static int retry_on(smd_pg *db, sm_error *err)
{
    if (smd_pg_connected(db))
        return 0;
    return smd_pg_reconnect(db, err) == SM_OK;
}

/* The "accepted" event and job.json of the upload, for the database. */
static sm_status submission_texts(const smd_submission *sub, double created, char **event,
                                  char **params, sm_error *err)
{
    sm_event ev;
    sm_event_init(&ev, SM_EVENT_ACCEPTED);
    ev.time = created;
    snprintf(ev.job_id, sizeof ev.job_id, "%s", sub->id);
    *event = sm_event_to_json(&ev);
    smd_job_file *f = calloc(1, sizeof *f);
    sm_error ferr;
    *params = f && smd_job_file_read(sub->dir, f, &ferr) == SM_OK ? smd_job_file_encode(f, 0) : NULL;
    if (f)
        smd_job_file_free(f);
    free(f);
    if (*event && *params)
        return SM_OK;
    free(*event);
    free(*params);
    return sm_error_set(err, SM_ERR_IO, "cannot read %s/job.json", sub->dir);
}

/* Lock NOT held: the database's copy, or the job the key names (*existing). */
static sm_status submit_db(smd_pg_node *n, const smd_submission *sub, double when,
                           char existing[SMD_ID_LEN + 1], int *created, sm_error *err)
{
    char *event, *params;
    if (submission_texts(sub, when, &event, &params, err) != SM_OK)
        return SM_ERR_IO;
    char *members = NULL; /* a model job's members: a text[] literal (ids need no quoting) */
    if (sub->batch_model) {
        members = malloc(sub->nmembers * (SMD_ID_LEN + 1) + 3);
        if (!members) {
            free(event);
            free(params);
            return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
        }
        size_t at = 0;
        members[at++] = '{';
        for (size_t i = 0; i < sub->nmembers; i++) {
            if (i)
                members[at++] = ',';
            memcpy(members + at, sub->members[i], strlen(sub->members[i]));
            at += strlen(sub->members[i]);
        }
        members[at++] = '}';
        members[at] = '\0';
    }
    smd_pg_job job = {sub->id, sub->owner ? sub->owner : "", sub->idempotency_key ? sub->idempotency_key : "",
                      sub->request_hash, params, event, sub->dim, sub->max_iter, sub->tol_boundary,
                      sub->dir, members, sub->name ? sub->name : ""};
    pthread_mutex_lock(&n->api_lock);
    sm_status st = node_connected(n, n->api_db, err);
    if (st == SM_OK)
        st = smd_pg_submit(n->api_db, &job, created, existing, err);
    if (st != SM_OK && retry_on(n->api_db, err)) {
        /* the connection died while idle (a database restart): once more;
         * "exists" then means the first try did commit */
        st = smd_pg_submit(n->api_db, &job, created, existing, err);
        if (st == SM_ERR_INVALID && strstr(err->msg, "exists")) {
            st = SM_OK;
            *created = 1;
        }
    }
    if (st == SM_OK && !*created)
        st = node_import(n, n->api_db, existing, NULL, err);
    pthread_mutex_unlock(&n->api_lock);
    free(event);
    free(params);
    free(members);
    return st;
}

sm_status smd_pg_node_publish(smd_pg_node *n, const smd_submission *sub, double *when,
                              char existing[SMD_ID_LEN + 1], sm_error *err)
{
    existing[0] = '\0';
    if (add_pending(n, sub->id) != 0)
        return sm_error_set(err, SM_ERR_NOMEM, "too many uploads at once");
    int created = 0;
    *when = sm_time_now();
    sm_status st = submit_db(n, sub, *when, existing, &created, err);
    if (st != SM_OK || !created) /* nothing to commit locally */
        smd_pg_node_submitted(n, sub->id);
    return st;
}

/* ------------------------------------------------------ cancel, delete */

/* n->lock held: the outcome recorded for (id, kind), taken out of the
 * table (1), or 0.  Entries older than a minute are dropped on the way. */
static int take_withdrawn(smd_pg_node *n, const char *id, int kind, node_withdrawn *out)
{
    double now = sm_clock_seconds();
    int found = 0;
    for (int i = 0; i < NODE_WITHDRAWN_MAX; i++) {
        node_withdrawn *w = &n->withdrawn[i];
        if (!w->kind)
            continue;
        if (!found && w->kind == kind && strcmp(w->id, id) == 0) {
            *out = *w;
            found = 1;
        } else if (now - w->at < 60) {
            continue;
        } else {
            free(w->evs);
        }
        memset(w, 0, sizeof *w);
    }
    return found;
}

static void put_withdrawn(smd_pg_node *n, const node_withdrawn *w)
{
    pthread_mutex_lock(&n->lock);
    node_withdrawn old;
    if (take_withdrawn(n, w->id, w->kind, &old)) /* a DELETE repeated: the latest counts */
        free(old.evs);
    int slot = 0;
    for (int i = 0; i < NODE_WITHDRAWN_MAX; i++) {
        if (!n->withdrawn[i].kind) {
            slot = i;
            break;
        }
        if (n->withdrawn[i].at < n->withdrawn[slot].at)
            slot = i; /* full: the oldest goes (its DELETE asks the database again) */
    }
    free(n->withdrawn[slot].evs);
    n->withdrawn[slot] = *w;
    pthread_mutex_unlock(&n->lock);
}

void node_check_timeout(smd_pg_node *n, smd_pg *db, const sm_error *err)
{
    if (!smd_pg_timed_out(db))
        return;
    /* unready for a while even though the sync thread's next round may
     * pass: the rows this node needs are held (a frozen peer) */
    pthread_mutex_lock(&n->lock);
    snprintf(n->why, sizeof n->why, "%s", err->msg);
    n->timeout_until = sm_clock_seconds() + 2 * n->srv->cfg.db_lock_timeout;
    pthread_mutex_unlock(&n->lock);
    smd_logf(&n->srv->log, SMD_LOG_ERROR, "database_timeout", "%s", err->msg);
}

sm_status smd_pg_node_withdraw(smd_pg_node *n, const char *id, int final, int64_t known,
                               sm_error *err)
{
    if (!final && smd_pg_node_runs(n, id))
        return SM_OK; /* this node runs it: the pool stops it, the outbox tells */
    node_withdrawn w = {.kind = final ? 2 : 1, .at = sm_clock_seconds()};
    snprintf(w.id, sizeof w.id, "%s", id);
    pthread_mutex_lock(&n->ctl_lock);
    sm_status st = node_connected(n, n->ctl_db, err);
    if (st == SM_OK)
        st = final ? smd_pg_delete(n->ctl_db, id, &w.result, err)
                   : smd_pg_cancel(n->ctl_db, id, &w.result, err);
    if (st != SM_OK && retry_on(n->ctl_db, err)) /* died while idle (a restart): once more */
        st = final ? smd_pg_delete(n->ctl_db, id, &w.result, err)
                   : smd_pg_cancel(n->ctl_db, id, &w.result, err);
    if (st == SM_OK && !final && w.result == 1)
        st = node_fetch_events(n->ctl_db, id, known, &w.evs, &w.nevs, err);
    if (st != SM_OK)
        node_check_timeout(n, n->ctl_db, err);
    pthread_mutex_unlock(&n->ctl_lock);
    if (st == SM_OK)
        put_withdrawn(n, &w);
    return st;
}

sm_status smd_pg_node_cancel(smd_server *srv, smd_job *job, smd_jobs_after *after, sm_error *err)
{
    smd_pg_node *n = srv->cluster;
    node_withdrawn w = {0};
    pthread_mutex_lock(&n->lock);
    int done = take_withdrawn(n, job->id, 1, &w);
    pthread_mutex_unlock(&n->lock);
    int was = w.result;
    sm_status st = SM_OK;
    if (done) {
        for (size_t i = 0; i < w.nevs; i++)
            if (w.evs[i].seq > job->nevents)
                smd_jobs_mirror_event(srv, job, &w.evs[i], after);
        free(w.evs);
    } else {
        /* not withdrawn first (a race with the job's end): asked here,
         * bounded by the session's lock and statement timeouts */
        pthread_mutex_lock(&n->ctl_lock);
        st = node_connected(n, n->ctl_db, err);
        if (st == SM_OK)
            st = smd_pg_cancel(n->ctl_db, job->id, &was, err);
        if (st != SM_OK && retry_on(n->ctl_db, err))
            st = smd_pg_cancel(n->ctl_db, job->id, &was, err);
        if (st == SM_OK && was == 1)
            st = node_catch_up_locked(n, n->ctl_db, job, after, err);
        if (st != SM_OK)
            node_check_timeout(n, n->ctl_db, err);
        pthread_mutex_unlock(&n->ctl_lock);
    }
    if (st == SM_OK && was == 2) {
        smd_jobs_mirror_state(srv, job, SM_JOB_DISMISSED, "cancelled by request (DELETE): its "
                              "worker node stops it", job->attempt, after);
    }
    if (st == SM_OK && was == 0)
        st = sm_error_set(err, SM_ERR_INVALID, "job %s: cannot cancel a job that ended", job->id);
    if (st == SM_OK)
        smd_log(&srv->log, SMD_LOG_INFO, "job_cancel_requested",
                json_pack("{s:s,s:s}", "job", job->id, "via", "database"));
    return st;
}

sm_status smd_pg_node_delete(smd_pg_node *n, const char *id, int *deleted, sm_error *err)
{
    node_withdrawn w = {0};
    pthread_mutex_lock(&n->lock);
    int done = take_withdrawn(n, id, 2, &w);
    pthread_mutex_unlock(&n->lock);
    if (done) {
        free(w.evs);
        *deleted = w.result;
        return SM_OK;
    }
    pthread_mutex_lock(&n->ctl_lock);
    sm_status st = node_connected(n, n->ctl_db, err);
    if (st == SM_OK)
        st = smd_pg_delete(n->ctl_db, id, deleted, err);
    if (st != SM_OK && retry_on(n->ctl_db, err))
        st = smd_pg_delete(n->ctl_db, id, deleted, err);
    if (st != SM_OK)
        node_check_timeout(n, n->ctl_db, err);
    pthread_mutex_unlock(&n->ctl_lock);
    return st;
}

/* ------------------------------------------------------------ status */

sm_status node_connected(smd_pg_node *n, smd_pg *db, sm_error *err)
{
    if (smd_pg_connected(db))
        return SM_OK;
    sm_status st = smd_pg_reconnect(db, err);
    if (st != SM_OK)
        node_set_down(n, err->msg);
    return st;
}

void node_set_down(smd_pg_node *n, const char *why)
{
    pthread_mutex_lock(&n->lock);
    snprintf(n->why, sizeof n->why, "%s", why);
    pthread_mutex_unlock(&n->lock);
    if (atomic_exchange(&n->up, 0))
        smd_logf(&n->srv->log, SMD_LOG_ERROR, "database_down", "%s", why);
}

void node_set_up(smd_pg_node *n)
{
    if (!atomic_exchange(&n->up, 1))
        smd_logf(&n->srv->log, SMD_LOG_INFO, "database_up", "the database answers");
}

int smd_pg_node_ready(smd_pg_node *n, char *why, size_t cap)
{
    pthread_mutex_lock(&n->lock);
    int up = atomic_load(&n->up);
    int ready = up && sm_clock_seconds() >= n->timeout_until && !n->outbox_held && !n->outbox_full;
    if (!ready)
        snprintf(why, cap, "%s", up && n->outbox_full ? n->full_why
                                 : up && n->outbox_held ? n->held_why : n->why);
    pthread_mutex_unlock(&n->lock);
    return ready;
}

void smd_pg_node_metrics(smd_pg_node *n, char **text, size_t *len)
{
    pthread_mutex_lock(&n->lock);
    size_t mine = n->nleases;
    pthread_mutex_unlock(&n->lock);
    char add[1024];
    int k = snprintf(add, sizeof add,
                     "# HELP shapematch_cluster_queue_depth Jobs queued in the shared database.\n"
                     "# TYPE shapematch_cluster_queue_depth gauge\n"
                     "shapematch_cluster_queue_depth %lld\n"
                     "# HELP shapematch_cluster_leases Jobs running under a lease, cluster-wide.\n"
                     "# TYPE shapematch_cluster_leases gauge\n"
                     "shapematch_cluster_leases %lld\n"
                     "# HELP shapematch_node_leases Leases this node holds.\n"
                     "# TYPE shapematch_node_leases gauge\n"
                     "shapematch_node_leases %zu\n"
                     "# HELP shapematch_database_up 1 while the database answers.\n"
                     "# TYPE shapematch_database_up gauge\n"
                     "shapematch_database_up %d\n",
                     (long long)atomic_load(&n->queued), (long long)atomic_load(&n->leased), mine,
                     atomic_load(&n->up));
    char *grown = k > 0 ? realloc(*text, *len + (size_t)k + 1) : NULL;
    if (!grown)
        return;
    memcpy(grown + *len, add, (size_t)k + 1);
    *text = grown;
    *len += (size_t)k;
}

/* --------------------------------------------------------- lifecycle */

static sm_status open_db(smd_server *srv, const char *what, smd_pg **db, sm_error *err)
{
    char app[64];
    snprintf(app, sizeof app, "shapematchd %s", what);
    sm_status st = smd_pg_connect(srv->cfg.database, srv->cfg.database_password_file, app, db, err);
    if (st == SM_OK)
        st = smd_pg_set_timeouts(*db, srv->cfg.db_statement_timeout, srv->cfg.db_lock_timeout,
                                 srv->cfg.db_idle_timeout, err);
    return st;
}

static smd_pg_node *node_new(smd_server *srv)
{
    smd_pg_node *n = calloc(1, sizeof *n);
    if (!n)
        return NULL;
    n->srv = srv;
    n->out_tail = &n->out_head;
    pthread_mutex_init(&n->lock, NULL);
    pthread_mutex_init(&n->api_lock, NULL);
    pthread_mutex_init(&n->ctl_lock, NULL);
    pthread_cond_init(&n->cond, NULL);
    char host[64] = "node";
    gethostname(host, sizeof host - 1);
    snprintf(n->name, sizeof n->name, "%s:%ld", host, (long)getpid());
    atomic_store(&n->up, 1);
    return n;
}

sm_status smd_pg_node_open(smd_server *srv, sm_error *err)
{
    smd_pg_node *n = node_new(srv);
    if (!n)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    int version = 0;
    sm_status st = open_db(srv, "api", &n->api_db, err);
    if (st == SM_OK)
        st = smd_pg_migrate(n->api_db, &version, err);
    if (st == SM_OK)
        st = open_db(srv, "ctl", &n->ctl_db, err);
    if (st == SM_OK)
        st = open_db(srv, "sync", &n->sync_db, err);
    if (st == SM_OK)
        st = open_db(srv, "work", &n->work_db, err);
    if (st == SM_OK)
        st = open_db(srv, "lease", &n->lease_db, err);
    if (st == SM_OK)
        st = node_outbox_open(n, err); /* before recovery and the sync thread see the jobs */
    if (st != SM_OK) {
        smd_pg_node_free(n);
        return st;
    }
    srv->cluster = n;
    smd_pg_backend_stack(srv->backend, n);
    smd_log(&srv->log, SMD_LOG_INFO, "database",
            json_pack("{s:i,s:s,s:s}", "schema_version", version, "node", n->name, "role",
                      srv->cfg.role == SMD_ROLE_API ? "api"
                      : srv->cfg.role == SMD_ROLE_WORKER ? "worker" : "all"));
    return SM_OK;
}

sm_status smd_pg_node_run(smd_server *srv, sm_error *err)
{
    smd_pg_node *n = srv->cluster;
    if (pthread_create(&n->sync_thread, NULL, node_sync_main, n) != 0)
        return sm_error_set(err, SM_ERR_NOMEM, "cannot start the database thread");
    n->have_sync = 1;
    if (pthread_create(&n->work_thread, NULL, node_work_main, n) != 0)
        return sm_error_set(err, SM_ERR_NOMEM, "cannot start the database thread");
    n->have_work = 1;
    if (pthread_create(&n->lease_thread, NULL, node_lease_main, n) != 0)
        return sm_error_set(err, SM_ERR_NOMEM, "cannot start the database thread");
    n->have_lease = 1;
    return SM_OK;
}

void smd_pg_node_stop(smd_server *srv)
{
    smd_pg_node *n = srv->cluster;
    if (!n)
        return;
    pthread_mutex_lock(&n->lock);
    atomic_store(&n->stop, 1);
    pthread_cond_broadcast(&n->cond);
    pthread_mutex_unlock(&n->lock);
    if (n->have_sync)
        pthread_join(n->sync_thread, NULL);
    if (n->have_work)
        pthread_join(n->work_thread, NULL);
    if (n->have_lease)
        pthread_join(n->lease_thread, NULL);
    n->have_sync = n->have_work = n->have_lease = 0;
}

void smd_pg_node_free(smd_pg_node *n)
{
    if (!n)
        return;
    node_item *it;
    while ((it = node_take_item(n)) != NULL) {
        free(it->json);
        free(it);
    }
    while (n->leases) {
        node_lease *next = n->leases->next;
        free(n->leases);
        n->leases = next;
    }
    for (int i = 0; i < NODE_WITHDRAWN_MAX; i++)
        free(n->withdrawn[i].evs);
    smd_pg_close(n->api_db);
    smd_pg_close(n->ctl_db);
    smd_pg_close(n->sync_db);
    smd_pg_close(n->work_db);
    smd_pg_close(n->lease_db);
    pthread_cond_destroy(&n->cond);
    pthread_mutex_destroy(&n->api_lock);
    pthread_mutex_destroy(&n->ctl_lock);
    pthread_mutex_destroy(&n->lock);
    free(n);
}
