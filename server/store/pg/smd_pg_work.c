/* The work thread of a node (see smd_pg_node.h): claims jobs for free
 * pool slots, forwards the events of the jobs it runs under their
 * leases, renews the leases, publishes results with the final state. */
#include <errno.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "shapematch/sm_clock.h"
#include "store/spool/smd_store.h"
#include "store/spool/smd_fifo.h"
#include "jobs/smd_jobs.h"
#include "store/pg/smd_pg_node.h"
#include "store/pg/smd_pg_node_int.h"
#include "jobs/smd_pool.h"

void node_cancel_here(smd_pg_node *n, const char *id, const char *why);

/* The lease was lost: the run stops here, nothing more is published. */
static void lease_lost(smd_pg_node *n, const char *id)
{
    pthread_mutex_lock(&n->lock);
    node_lease *l = node_find_lease(n, id);
    int was = l && !l->lost;
    if (l)
        l->lost = 1;
    pthread_mutex_unlock(&n->lock);
    if (!was)
        return;
    smd_logf(&n->srv->log, SMD_LOG_WARN, "lease_lost",
             "job %s: this node's lease was lost (expired, or the job was deleted): its run is "
             "stopped and its results are not published", id);
    node_cancel_here(n, id, "stopped on this node: its lease was lost (expired, or the job was "
                            "deleted); the run's results are not published");
}

/* The local copy of a job whose lease was lost: taken again from the
 * database by the sync scan (an API node) or forgotten (a worker). */
static void drop_local(smd_pg_node *n, const char *id)
{
    smd_server *srv = n->srv;
    smd_jobs_after after = {0};
    pthread_mutex_lock(&srv->lock);
    smd_job *job = smd_store_get(srv->store, id);
    if (job)
        smd_jobs_mirror_drop(srv, job, &after);
    pthread_mutex_unlock(&srv->lock);
    smd_jobs_after_free(&after);
}

/* The items of a job past the last one stored would hide a gap in its
 * log (they were lost: a node killed before it spooled them): the run
 * is given back instead, the job queued again with its log as stored. */
static sm_status gap(smd_pg_node *n, const node_item *it, const smd_pg_lease *l, int64_t seq,
                     sm_error *err)
{
    char msg[SM_EVENT_MESSAGE_MAX];
    snprintf(msg, sizeof msg, "queued again: events of run %d were lost on node %.100s",
             l->attempt, n->name);
    sm_status st = smd_pg_release(n->work_db, l, msg, err);
    if (st != SM_OK)
        return st;
    smd_logf(&n->srv->log, SMD_LOG_ERROR, "outbox_gap",
             "job %s: event %lld cannot be stored, the events before it are lost: the job is "
             "queued again", it->id, (long long)seq);
    lease_lost(n, it->id);
    return SM_OK;
}

static sm_status publish_final(smd_pg_node *n, const node_item *it, const smd_pg_lease *l,
                               sm_error *err)
{
    char results[PATH_MAX];
    const char *dir = NULL;
    if (it->state == SM_JOB_SUCCESSFUL &&
        smd_pathf(results, sizeof results, "%s/jobs/%s/results", smd_store_root(n->srv->store),
                  it->id) == 0)
        dir = results;
    int held = 0;
    sm_status st = smd_pg_publish(n->work_db, l, it->state, it->message, it->json, it->seq, dir,
                                  &held, err);
    if (st == SM_OK && held == SMD_PG_GAP)
        return gap(n, it, l, it->seq, err);
    sm_job_state now = SM_JOB_ACCEPTED;
    int attempt = 0, found = 0;
    sm_error e;
    if (st == SM_OK && !held &&
        smd_pg_state(n->work_db, it->id, &now, &attempt, &found, &e) == SM_OK && found &&
        now == it->state && attempt == l->attempt)
        smd_logf(&n->srv->log, SMD_LOG_INFO, "outbox_duplicate",
                 "job %s: its %s end was stored already (a replay)", it->id,
                 sm_job_state_name(it->state));
    else if (st == SM_OK && !held)
        smd_logf(&n->srv->log, SMD_LOG_WARN, "lease_lost",
                 "job %s: lease lost before the end: its %s is not published", it->id,
                 sm_job_state_name(it->state));
    return st;
}

static sm_status publish_event(smd_pg_node *n, const node_item *it, const smd_pg_lease *l,
                               sm_error *err)
{
    int outcome = SMD_PG_NOT_HELD;
    sm_status st = smd_pg_append_event_at(n->work_db, it->id, l, it->json, it->seq, &outcome, err);
    if (st != SM_OK)
        return st;
    if (outcome == SMD_PG_NOT_HELD)
        lease_lost(n, it->id);
    else if (outcome == SMD_PG_GAP)
        return gap(n, it, l, it->seq, err);
    /* SMD_PG_DUPLICATE: stored before (a replay), once */
    return SM_OK;
}

/* One outbox item, under the lease it was made under.  SM_ERR_IO: kept
 * for a retry. */
static sm_status publish(smd_pg_node *n, const node_item *it, sm_error *err)
{
    pthread_mutex_lock(&n->lock);
    node_lease *found = node_find_lease(n, it->id);
    node_lease copy = found ? *found : (node_lease){0};
    pthread_mutex_unlock(&n->lock);
    if (!found || copy.lease.token != it->token)
        return SM_OK; /* an older lease's: fenced out */
    sm_status st = SM_OK;
    if (copy.lost) {
        if (!it->final && !it->release)
            return SM_OK;
    } else if (it->release) {
        st = smd_pg_release(n->work_db, &copy.lease, it->message, err);
    } else if (it->final) {
        st = publish_final(n, it, &copy.lease, err);
    } else {
        return publish_event(n, it, &copy.lease, err);
    }
    if (st != SM_OK)
        return st; /* kept with its lease (still renewed) for a retry */
    node_drop_lease(n, it->id);
    if (copy.lost)
        drop_local(n, it->id);
    return SM_OK;
}

/* Puts items back in front of the outbox (the connection failed). */
static void put_back(smd_pg_node *n, node_item *items)
{
    if (!items)
        return;
    pthread_mutex_lock(&n->lock);
    node_item **tail = &items;
    while (*tail)
        tail = &(*tail)->next;
    *tail = n->out_head;
    if (!*tail)
        n->out_tail = tail;
    n->out_head = items;
    pthread_mutex_unlock(&n->lock);
}

static void free_item(smd_pg_node *n, node_item *it)
{
    node_outbox_done(n, it);
    free(it->json);
    free(it);
}

/* The outbox could not be stored (a lost connection, a full database
 * disk, a timeout): the node is unready and claims nothing until it is. */
static void set_held(smd_pg_node *n, const node_item *first, const sm_error *err)
{
    pthread_mutex_lock(&n->lock);
    int was = n->outbox_held;
    n->outbox_held = 1;
    snprintf(n->held_why, sizeof n->held_why,
             "the events or results of job %s wait to be stored in the database: %s", first->id,
             err->msg);
    pthread_mutex_unlock(&n->lock);
    if (!was)
        smd_logf(&n->srv->log, SMD_LOG_ERROR, "outbox_held", "%s", n->held_why);
}

static void clear_held(smd_pg_node *n)
{
    pthread_mutex_lock(&n->lock);
    int was = n->outbox_held;
    n->outbox_held = 0;
    pthread_mutex_unlock(&n->lock);
    if (was)
        smd_logf(&n->srv->log, SMD_LOG_INFO, "outbox_stored", "the waiting events and results are "
                 "stored in the database");
}

/* The items on disk before the database is asked (a kill -9 while they
 * wait loses none): always while the outbox is held, and a run's end or
 * release (one file a run) at once. */
static void spill_if_needed(smd_pg_node *n, node_item *items, int down)
{
    pthread_mutex_lock(&n->lock);
    int need = down || n->outbox_held || n->outbox_full;
    pthread_mutex_unlock(&n->lock);
    for (const node_item *it = items; it && !need; it = it->next)
        need = it->final || it->release;
    if (need && items)
        node_outbox_spill(n, items);
}

/* Publishes the outbox in order, progress events in transactions of up
 * to 256 (one commit, not one per event).  Whatever fails is never
 * dropped: the failed batch and everything after it are put back, in
 * order, and retried (returns -1); a later event is never stored before
 * an earlier one, so the database's gap-free seq hides nothing. */
static int drain(smd_pg_node *n, node_item *items)
{
    sm_error err;
    while (items) {
        int batch = !items->final && !items->release;
        sm_error_clear(&err);
        if (batch && smd_pg_begin(n->work_db, &err) != SM_OK)
            break;
        node_item *done = items, **cut = &items;
        int k = 0;
        sm_status st = SM_OK;
        do {
            st = publish(n, *cut, &err);
            cut = &(*cut)->next;
            k++;
        } while (st == SM_OK && batch && *cut && !(*cut)->final && !(*cut)->release && k < 256);
        if (batch && st == SM_OK)
            st = smd_pg_commit(n->work_db, &err);
        if (batch && st != SM_OK)
            smd_pg_rollback(n->work_db);
        if (st != SM_OK)
            break; /* the whole batch again, later */
        items = *cut;
        *cut = NULL;
        while (done) {
            node_item *next = done->next;
            free_item(n, done);
            done = next;
        }
    }
    if (!items)
        return 0;
    node_outbox_spill(n, items);
    if (smd_pg_connected(n->work_db))
        smd_logf(&n->srv->log, SMD_LOG_WARN, "database_error", "%s", err.msg);
    set_held(n, items, &err);
    put_back(n, items);
    if (!smd_pg_connected(n->work_db))
        node_set_down(n, err.msg);
    return -1;
}

static void renew_all(smd_pg_node *n)
{
    double now = sm_clock_seconds(), every = n->srv->cfg.lease / 3;
    for (;;) {
        smd_pg_lease due = {0};
        pthread_mutex_lock(&n->lock);
        for (node_lease *l = n->leases; l && !due.id[0]; l = l->next)
            if (!l->lost && now - l->renewed >= every) {
                due = l->lease;
                l->renewed = now;
            }
        pthread_mutex_unlock(&n->lock);
        if (!due.id[0])
            return;
        int held = 1;
        sm_error err;
        if (smd_pg_renew(n->lease_db, &due, n->srv->cfg.lease, &held, &err) != SM_OK)
            return; /* the connection: retried at the next round */
        if (held == 0)
            lease_lost(n, due.id);
        else if (held == 2)
            node_cancel_here(n, due.id, SMD_PG_CANCELLED);
    }
}

static size_t free_slots(smd_pg_node *n)
{
    smd_server *srv = n->srv;
    pthread_mutex_lock(&srv->lock);
    size_t slots = smd_pool_slots(srv->pool), used = smd_pool_busy(srv->pool) +
                                                     smd_queue_depth(srv->queue);
    pthread_mutex_unlock(&srv->lock);
    pthread_mutex_lock(&n->lock);
    int held = n->outbox_held;
    pthread_mutex_unlock(&n->lock);
    return held || atomic_load(&srv->draining) || atomic_load(&srv->unwritable) || used >= slots
               ? 0 : slots - used;
}

/* A claim that fails (the node cannot take the job: its folder, its
 * inputs) is retried with exponential backoff, 0.2 s doubling to
 * CLAIM_BACKOFF_MAX, each wait drawn uniformly from its upper half
 * (jitter: nodes failing together do not retry in step); logged when
 * the failure starts or changes, and when claims work again. */
#define CLAIM_BACKOFF_MIN 0.2
#define CLAIM_BACKOFF_MAX 10.0

static double jitter(smd_pg_node *n)
{
    /* xorshift64: no cryptographic need, only spread */
    uint64_t x = n->claim_rng ? n->claim_rng : 0x9e3779b97f4a7c15u ^ (uint64_t)getpid();
    x ^= x << 13;
    x ^= x >> 7;
    x ^= x << 17;
    n->claim_rng = x;
    return 0.5 + 0.5 * (double)(x >> 11) / 9007199254740992.0;
}

static void claim_failed(smd_pg_node *n, const char *id, const char *msg)
{
    n->claim_fails++;
    n->claim_backoff = n->claim_backoff <= 0 ? CLAIM_BACKOFF_MIN
                       : n->claim_backoff * 2 > CLAIM_BACKOFF_MAX ? CLAIM_BACKOFF_MAX
                       : n->claim_backoff * 2;
    n->claim_next = sm_clock_seconds() + n->claim_backoff * jitter(n);
    char what[sizeof n->claim_why];
    snprintf(what, sizeof what, "job %s: %s", id, msg);
    if (strcmp(what, n->claim_why) != 0) {
        smd_logf(&n->srv->log, SMD_LOG_ERROR, "claim_failed",
                 "%s (retried with backoff up to %.0f s; logged again when this changes)", what,
                 CLAIM_BACKOFF_MAX);
        snprintf(n->claim_why, sizeof n->claim_why, "%s", what);
    }
}

static void claim_worked(smd_pg_node *n)
{
    if (n->claim_fails)
        smd_log(&n->srv->log, SMD_LOG_INFO, "claims_recovered",
                json_pack("{s:I}", "failed_claims", (json_int_t)n->claim_fails));
    n->claim_fails = 0;
    n->claim_backoff = 0;
    n->claim_next = 0;
    n->claim_why[0] = '\0';
}

/* 0 when the job was taken */
static int claim_one(smd_pg_node *n, const smd_pg_lease *got)
{
    node_lease *l = calloc(1, sizeof *l);
    sm_error err;
    if (l) {
        l->lease = *got;
        l->known = INT64_MAX; /* nothing forwarded while the copy is made */
        l->renewed = sm_clock_seconds();
        pthread_mutex_lock(&n->lock);
        l->next = n->leases;
        n->leases = l;
        n->nleases++;
        pthread_mutex_unlock(&n->lock);
    }
    if (l && node_import(n, n->work_db, got->id, l, &err) == SM_OK) {
        smd_log(&n->srv->log, SMD_LOG_INFO, "job_claimed",
                json_pack("{s:s,s:i,s:s}", "job", got->id, "attempt", got->attempt, "node", n->name));
        claim_worked(n);
        return 0;
    }
    char msg[SM_EVENT_MESSAGE_MAX];
    /* the job's message (clients read it) counts this node's failed tries */
    snprintf(msg, sizeof msg, "node %.100s could not take it (%u failed claims): %.300s", n->name,
             n->claim_fails + 1, l ? err.msg : "out of memory");
    smd_unroot(msg, n->srv->cfg.spool);
    smd_pg_unclaim(n->work_db, got, msg, &err); /* nothing ran: no attempt used */
    node_drop_lease(n, got->id);
    char *why = strstr(msg, "): ");
    claim_failed(n, got->id, why ? why + 3 : msg);
    return -1;
}

static void claim(smd_pg_node *n)
{
    if (n->claim_next > 0 && sm_clock_seconds() < n->claim_next)
        return; /* backing off */
    for (size_t k = free_slots(n); k > 0 && !atomic_load(&n->stop); k--) {
        smd_pg_lease got;
        int ok = 0;
        sm_error err;
        if (smd_pg_claim(n->work_db, n->name, n->srv->cfg.lease, &got, &ok, &err) != SM_OK || !ok)
            return;
        if (claim_one(n, &got) != 0)
            return;
    }
}

/* At the stop, once the outbox is stored (the pool has stopped: every
 * run it started ended with its end or release stored, and dropped its
 * lease): the leases left are of jobs claimed but never started (a claim
 * that was copying the job when the shutdown began).  They are given back
 * at once, with no attempt used, not left to expire (--lease seconds
 * during which no node may run them). */
static void give_back_unstarted(smd_pg_node *n)
{
    for (;;) {
        smd_pg_lease got = {0};
        pthread_mutex_lock(&n->lock);
        for (node_lease *l = n->leases; l && !got.id[0]; l = l->next)
            if (!l->lost)
                got = l->lease;
        pthread_mutex_unlock(&n->lock);
        if (!got.id[0])
            return;
        char msg[SM_EVENT_MESSAGE_MAX];
        snprintf(msg, sizeof msg, "queued again: node %.100s stopped before it started the job",
                 n->name);
        sm_error err;
        sm_status st = node_connected(n, n->work_db, &err);
        if (st == SM_OK)
            st = smd_pg_unclaim(n->work_db, &got, msg, &err);
        if (st == SM_OK)
            smd_logf(&n->srv->log, SMD_LOG_INFO, "job_released",
                     "job %s: given back unstarted at the stop (attempt %d not used)", got.id,
                     got.attempt);
        else
            smd_logf(&n->srv->log, SMD_LOG_WARN, "database_error",
                     "job %s: not given back at the stop (its lease expires instead): %s", got.id,
                     err.msg);
        node_drop_lease(n, got.id);
    }
}

/* Waits up to 0.2 s for the outbox; takes it whole. */
static node_item *wait_items(smd_pg_node *n)
{
    pthread_mutex_lock(&n->lock);
    if (!n->out_head && !atomic_load(&n->stop)) {
        struct timespec until;
        clock_gettime(CLOCK_REALTIME, &until);
        until.tv_nsec += 200 * 1000 * 1000;
        if (until.tv_nsec >= 1000000000L) {
            until.tv_sec++;
            until.tv_nsec -= 1000000000L;
        }
        pthread_cond_timedwait(&n->cond, &n->lock, &until);
    }
    node_item *items = n->out_head;
    n->out_head = NULL;
    n->out_tail = &n->out_head;
    pthread_mutex_unlock(&n->lock);
    return items;
}

void *node_work_main(void *arg)
{
    smd_pg_node *n = arg;
    double stop_at = 0, backoff = 0.1;
    for (;;) {
        int stopping = atomic_load(&n->stop);
        if (stopping && !stop_at)
            stop_at = sm_clock_seconds() + 5; /* what is left after that waits for expiry */
        pthread_mutex_lock(&n->lock);
        int empty = !n->out_head;
        pthread_mutex_unlock(&n->lock);
        if (stopping && (empty || sm_clock_seconds() > stop_at)) {
            if (empty)
                give_back_unstarted(n);
            node_item *left = wait_items(n); /* on disk for the next start */
            node_outbox_spill(n, left);
            put_back(n, left);
            return NULL;
        }
        sm_error err;
        if (node_connected(n, n->work_db, &err) != SM_OK) {
            node_item *wait = wait_items(n);
            spill_if_needed(n, wait, 1);
            put_back(n, wait);
            struct timespec ts = {0, (long)(backoff * 1e9)};
            nanosleep(&ts, NULL);
            backoff = backoff * 2 > 0.8 ? 0.8 : backoff * 2;
            continue;
        }
        node_item *items = wait_items(n);
        spill_if_needed(n, items, 0);
        if (drain(n, items) != 0) {
            /* retried with backoff, 0.1 s doubling to 2 s */
            struct timespec ts = {(time_t)backoff, (long)((backoff - (time_t)backoff) * 1e9)};
            nanosleep(&ts, NULL);
            backoff = backoff * 2 > 2 ? 2 : backoff * 2;
            continue;
        }
        backoff = 0.1;
        clear_held(n);
        if (!stopping && n->srv->cfg.role != SMD_ROLE_API)
            claim(n);
    }
}

/* Renews every lease a third of --lease after the last renewal, on its
 * own connection: a long outbox or a busy daemon lock does not make this
 * node lose the jobs it runs. */
void *node_lease_main(void *arg)
{
    smd_pg_node *n = arg;
    double backoff = 0.1;
    while (!atomic_load(&n->stop)) {
        sm_error err;
        if (node_connected(n, n->lease_db, &err) != SM_OK) {
            backoff = backoff * 2 > 1 ? 1 : backoff * 2;
        } else {
            backoff = 0.1;
            renew_all(n);
        }
        struct timespec ts = {0, (long)(backoff * 1e9)};
        nanosleep(&ts, NULL);
    }
    return NULL;
}
