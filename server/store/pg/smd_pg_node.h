/* A shapematchd node of a cluster sharing one PostgreSQL job store and
 * queue (--database; server/store/pg/smd_pg.h is the database side).
 *
 * Each node keeps its embedded spool as local scratch and as a replica:
 * - an API node (--role api|all) mirrors every job of the database into
 *   its local store (records, events with the database's seq, and the
 *   results once the job succeeded), so status, lists, event streams
 *   (SSE/NDJSON, Last-Event-ID) and results are served by the unchanged
 *   handlers; a "sync" thread LISTENs for new events and also rescans
 *   (a lost notification costs one rescan period, never an event);
 * - a worker node (--role worker|all) claims queued jobs when its pool
 *   has a free slot, copies the inputs into its spool and runs them in
 *   its pool exactly as embedded jobs; every event of a claimed job is
 *   forwarded, under its lease, by a "work" thread that also renews the
 *   leases and publishes the results with the final state in one
 *   transaction (fenced: a node that lost its lease publishes nothing).
 * - uploads go to the database before the local commit (the Idempotency-
 *   Key is unique there, so a retry on another API node finds the job).
 *
 * Locking: srv->lock is never held while waiting for the database on
 * a request's path: a DELETE asks the database first (withdraw), then
 * takes the lock; only retention, and a DELETE that raced with the job's
 * end, run their one short query under it, bounded by the session's
 * lock_timeout and statement_timeout (--database-lock-timeout); the
 * node's own mutex (outbox, leases, pending uploads) is taken after
 * srv->lock or alone, never the other way. */
#ifndef SMD_PG_NODE_H
#define SMD_PG_NODE_H

#include <stdint.h>

#include "shapematch/sm_error.h"
#include "sm_proto_events.h"
#include "base/smd_server.h"
#include "jobs/smd_backend.h"

typedef struct smd_pg_node smd_pg_node;
struct smd_jobs_after;
struct smd_submission;

/* At start, before the recovery: connects, applies the migrations, sets
 * srv->cluster and stacks the PostgreSQL backend on srv->backend (the
 * spool's, smd_pg_backend.c).  Logged on failure. */
sm_status smd_pg_node_open(smd_server *srv, sm_error *err);
/* After the pool started: the sync and work threads. */
sm_status smd_pg_node_run(smd_server *srv, sm_error *err);
/* After the pool stopped: publishes what is left, stops the threads. */
void smd_pg_node_stop(smd_server *srv);
void smd_pg_node_free(smd_pg_node *node);

/* 1 while the database answers; else 0 and why. */
int smd_pg_node_ready(smd_pg_node *node, char *why, size_t cap);
/* Prometheus lines (queue depth and leases from the database, the
 * node's own leases, database up), appended to *text (realloc'ed). */
void smd_pg_node_metrics(smd_pg_node *node, char **text, size_t *len);

/* The backend's calls (smd_pg_backend.c), srv->lock held unless said. */
/* Upload, srv->lock NOT held: the job into the database first.
 * existing: the job an Idempotency-Key already names ("" when none: then
 * the caller commits it locally, with *created the time the database
 * has, and calls smd_pg_node_submitted). */
sm_status smd_pg_node_publish(smd_pg_node *n, const struct smd_submission *sub, double *created,
                              char existing[SMD_ID_LEN + 1], sm_error *err);
void smd_pg_node_submitted(smd_pg_node *node, const char *id);
/* An event appended locally: forwarded when this node runs the job. */
void smd_pg_node_event(smd_pg_node *node, const smd_job *job, const sm_event *ev);
/* The daemon stops while this node runs the job: its lease is given back. */
void smd_pg_node_requeued(smd_pg_node *node, const smd_job *job);
/* 1 when this node holds (or just lost) the job's lease. */
int smd_pg_node_runs(smd_pg_node *node, const char *id);
/* DELETE of a live job this node does not run: cancelled in the database
 * (the worker node is told); the local record follows. */
sm_status smd_pg_node_cancel(smd_server *srv, smd_job *job, struct smd_jobs_after *after,
                             sm_error *err);
/* DELETE, srv->lock NOT held: the cancel (final 0) or delete (final 1)
 * in the database first; the locked smd_pg_node_cancel / _delete that
 * follow use its outcome and do not ask again.  A job this node runs is
 * left to the local cancel.  known: the events of the local log. */
sm_status smd_pg_node_withdraw(smd_pg_node *node, const char *id, int final, int64_t known,
                               sm_error *err);
/* DELETE or retention of a final job: *deleted 1 for the node that
 * removed it from the database. */
sm_status smd_pg_node_delete(smd_pg_node *node, const char *id, int *deleted, sm_error *err);

/* Turns b (the spool's backend) into PostgreSQL's, stacked on it. */
void smd_pg_backend_stack(smd_backend *b, smd_pg_node *node);

#endif
