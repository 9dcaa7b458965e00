/* The PostgreSQL backend (jobs/smd_backend.h): the records, logs and the
 * queue of the jobs this node runs are the spool's, as with the embedded
 * backend (the local replica, store/spool/smd_store.h, which the engine
 * uses by name); the ops here are what differs: the database is
 * the shared store and queue, reached through the node (smd_pg_node.h).
 * The sync and work threads feed the engine from the database
 * (smd_pg_mirror.c, smd_pg_work.c), as the pool does from its workers. */
#include "store/pg/smd_pg_node.h"

#include <stdio.h>

#include "jobs/smd_backend.h"

static smd_pg_node *node_of(smd_backend *b)
{
    return b->impl;
}

/* the database says how a job ended, not the local copy */
static sm_status pg_read_summary(smd_backend *b, const smd_job *job, sm_event *finished,
                                 double *when, sm_error *err)
{
    (void)b, (void)finished, (void)when;
    return sm_error_set(err, SM_ERR_IO, "job %s: the database holds its end", job->id);
}

/* the database holds the log: the local one follows it */
static int pg_final_event_missing(smd_backend *b, const smd_job *job)
{
    (void)b, (void)job;
    return 0;
}

/* the database's queue: a worker node claims the job (smd_pg_work.c
 * queues it in its own spool's FIFO then) */
static int pg_enqueue(smd_backend *b, const char *id)
{
    (void)b, (void)id;
    return 0;
}

static sm_status pg_publish(smd_backend *b, const struct smd_submission *sub, double *created,
                            char existing[SMD_ID_LEN + 1], sm_error *err)
{
    return smd_pg_node_publish(node_of(b), sub, created, existing, err);
}

static void pg_submitted(smd_backend *b, const char *id)
{
    smd_pg_node_submitted(node_of(b), id);
}

static void pg_event(smd_backend *b, const smd_job *job, const sm_event *ev)
{
    smd_pg_node_event(node_of(b), job, ev);
}

static void pg_requeued(smd_backend *b, const smd_job *job)
{
    smd_pg_node_requeued(node_of(b), job);
}

/* a job this node runs is cancelled here (the pool stops its worker,
 * the event goes out through the outbox); any other in the database */
static sm_status pg_cancel(smd_backend *b, struct smd_server *srv, smd_job *job,
                           struct smd_jobs_after *after, int *handled, sm_error *err)
{
    *handled = !smd_pg_node_runs(node_of(b), job->id);
    return *handled ? smd_pg_node_cancel(srv, job, after, err) : SM_OK;
}

static sm_status pg_remove(smd_backend *b, const char *id, int *deleted, sm_error *err)
{
    return smd_pg_node_delete(node_of(b), id, deleted, err);
}

static sm_status pg_withdraw(smd_backend *b, const char *id, int final, int64_t known,
                             sm_error *err)
{
    return smd_pg_node_withdraw(node_of(b), id, final, known, err);
}

static int pg_ready(smd_backend *b, char *why, size_t cap)
{
    char raw[400];
    if (smd_pg_node_ready(node_of(b), raw, sizeof raw))
        return 1;
    snprintf(why, cap, "the database does not answer (or not in time): %s", raw);
    return 0;
}

static void pg_metrics(smd_backend *b, char **text, size_t *len)
{
    smd_pg_node_metrics(node_of(b), text, len);
}

static const smd_backend_ops pg_ops = {
    .name = "postgresql",
    .read_summary = pg_read_summary,
    .final_event_missing = pg_final_event_missing,
    .enqueue = pg_enqueue,
    .publish = pg_publish,
    .submitted = pg_submitted,
    .event = pg_event,
    .requeued = pg_requeued,
    .cancel = pg_cancel,
    .remove = pg_remove,
    .withdraw = pg_withdraw,
    .ready = pg_ready,
    .metrics = pg_metrics,
};

void smd_pg_backend_stack(smd_backend *b, smd_pg_node *node)
{
    b->ops = &pg_ops;
    b->impl = node;
}
