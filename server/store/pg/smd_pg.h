/* The PostgreSQL job store and queue shared by several shapematchd nodes
 * (--database; issue 12).  Without --database nothing here runs: the
 * embedded spool and in-memory queue stay the default.
 *
 * One smd_pg is one libpq connection, used by one thread at a time (the
 * caller's); a node opens one per thread that talks to the database.
 *
 * Schema (smd_pg_migrate, versioned, applied at start under an advisory
 * lock so that nodes starting together are safe):
 *   smd_schema  (version)                         applied migrations
 *   smd_jobs    id, ord (FIFO), owner, idempotency_key (unique per owner),
 *               request_hash, state, message, params, attempt, progress,
 *               nevents, lease_owner, lease_expires, lease_token,
 *               cancel_requested, created, started, finished, updated,
 *               members (2: a batch's model job, the ids of its target
 *               jobs; NULL for every other job)
 *   smd_events  (job, seq) unique, payload: the event's JSON line
 *   smd_blobs   (job, name, chunk) bytea chunks of inputs and results
 *
 * Claims take the oldest queued job with FOR UPDATE SKIP LOCKED and give
 * it a lease (owner, expiry, a fresh token from a sequence).  Everything a
 * worker node writes about a claimed job afterwards (renewal, events,
 * blobs, the final state) names the token and is refused once the lease
 * is lost (fencing): a node that was cut off does not publish results
 * over a later attempt's.  Any node requeues expired leases with
 * attempt + 1, or fails the job past --max-attempts.  A batch's model job
 * (members not NULL) is claimed only once none of its members is queued
 * or running. */
#ifndef SMD_PG_H
#define SMD_PG_H

#include <stddef.h>
#include <stdint.h>

#include "shapematch/sm_error.h"
#include "sm_proto_events.h"
#include "sm_proto_vocab.h"
#include "base/smd_util.h"

#define SMD_PG_SCHEMA_VERSION 3
/* Bytes of one smd_blobs row: uploads and results move in pieces this
 * large, never whole. */
#define SMD_PG_CHUNK (256 * 1024)
#define SMD_PG_NODE_MAX 128
/* NOTIFY channels: "<job id> <seq>" for a new event, "<job id>" for a
 * cancel or delete request. */
#define SMD_PG_CHANNEL_EVENTS "smd_events"
#define SMD_PG_CHANNEL_CANCEL "smd_cancel"
/* the message of a run stopped here because a client cancelled it */
#define SMD_PG_CANCELLED "cancelled by request (DELETE)"

typedef struct smd_pg smd_pg;

/* Connects with the libpq connection string or URI url (libpq's own
 * environment, ~/.pgpass and sslmode apply); password_file (NULL or "")
 * gives the password on its first line.  app names the connection in
 * pg_stat_activity. */
sm_status smd_pg_connect(const char *url, const char *password_file, const char *app,
                         smd_pg **out, sm_error *err);
void smd_pg_close(smd_pg *db);
/* The session's statement_timeout, lock_timeout and
 * idle_in_transaction_session_timeout (seconds; 0 keeps the server's),
 * set now and again on every reconnect: no call waits forever on a
 * frozen peer's row lock, and a session frozen inside a transaction is
 * ended by the server (its locks freed). */
sm_status smd_pg_set_timeouts(smd_pg *db, double statement, double lock, double idle,
                              sm_error *err);
/* 1 when the last failed call failed on a statement or lock timeout. */
int smd_pg_timed_out(const smd_pg *db);
/* 1 while the connection is up (as libpq last saw it). */
int smd_pg_connected(const smd_pg *db);
/* Drops and opens the connection again (LISTENs are renewed). */
sm_status smd_pg_reconnect(smd_pg *db, sm_error *err);
/* SELECT 1: the database answers now. */
sm_status smd_pg_ping(smd_pg *db, sm_error *err);

/* BEGIN / COMMIT / ROLLBACK (ROLLBACK never fails loudly): calls made in
 * between are one transaction (those that begin their own must not be). */
sm_status smd_pg_begin(smd_pg *db, sm_error *err);
sm_status smd_pg_commit(smd_pg *db, sm_error *err);
void smd_pg_rollback(smd_pg *db);

/* Applies the migrations above the database's version under
 * pg_advisory_lock, each in its own transaction; *version (may be NULL)
 * is the version after.  A database newer than this program is refused. */
sm_status smd_pg_migrate(smd_pg *db, int *version, sm_error *err);

/* A job as submitted to the shared queue. */
typedef struct smd_pg_job {
    const char *id;
    const char *owner;            /* "" none */
    const char *idempotency_key;  /* "" none */
    uint64_t request_hash;
    const char *params;           /* job.json text */
    const char *first_event;      /* the "accepted" event's JSON (seq 1) */
    int dim, max_iter;
    double tol_boundary;
    const char *dir;              /* NULL, or a folder whose job.json and
                                   * inputs/ become blobs (same transaction) */
    const char *members;          /* a model job's members as a text[] literal
                                   * ("{id,id}"), NULL for every other job */
    const char *name;             /* the job's name, "" none */
} smd_pg_job;

/* Inserts an accepted job and its first event in one transaction, or,
 * when (owner, idempotency_key) is taken, changes nothing and copies the
 * existing job's id into existing (*created 0). */
sm_status smd_pg_submit(smd_pg *db, const smd_pg_job *job, int *created,
                        char existing[SMD_ID_LEN + 1], sm_error *err);

typedef struct smd_pg_lease {
    char id[SMD_ID_LEN + 1];
    int attempt;                  /* runs started, this one included */
    int64_t token;                /* fences every later write */
} smd_pg_lease;

/* Claims the oldest queued job for node for lease seconds: *got 1 and
 * lease filled, or *got 0 when none is queued (or all are being claimed
 * by others right now). */
sm_status smd_pg_claim(smd_pg *db, const char *node, double lease, smd_pg_lease *out, int *got,
                       sm_error *err);
/* Extends the lease: *held 1, or 2 when a cancel was requested (stop the
 * run, then publish "dismissed"), or 0 when it was lost (expired,
 * requeued, deleted): stop the run, publish nothing. */
sm_status smd_pg_renew(smd_pg *db, const smd_pg_lease *l, double lease, int *held,
                       sm_error *err);
/* The job's final state (successful, failed, dismissed), its message and
 * its last event (final_event, JSON without seq, may be NULL: they agree),
 * in one transaction under the lease: *held 0 (nothing written) when the
 * lease was lost.  A run that ended before a cancel reached it stays what
 * it ended as. */
sm_status smd_pg_complete(smd_pg *db, const smd_pg_lease *l, sm_job_state state,
                          const char *message, const char *final_event, int *held,
                          sm_error *err);

/* Appends an event (its JSON without seq: seq is set here, the next of
 * the job, unique) and NOTIFYs it, in one transaction.  fence NULL: any
 * node (API side); else only while the lease is held (*seq 0 when not).
 * *seq is the number given. */
sm_status smd_pg_append_event(smd_pg *db, const char *id, const smd_pg_lease *fence,
                              const char *json, int64_t *seq, sm_error *err);

/* What smd_pg_append_event_at did. */
enum { SMD_PG_NOT_HELD = 0,  /* the lease is lost: nothing stored */
       SMD_PG_APPENDED = 1,  /* stored as seq expect */
       SMD_PG_DUPLICATE = 2, /* the job has expect events already: this one, stored before
                              * (a replay after a restart, or a commit whose answer was lost) */
       SMD_PG_GAP = 3 };     /* the job has fewer than expect - 1: storing it would hide a gap */
/* smd_pg_append_event under the lease, only as the job's event number
 * expect: idempotent by (job, lease, seq), never out of turn. */
sm_status smd_pg_append_event_at(smd_pg *db, const char *id, const smd_pg_lease *fence,
                                 const char *json, int64_t expect, int *outcome, sm_error *err);

/* Leases past their expiry: requeued with a message (attempt kept: the
 * next claim counts it), or failed with the reason once attempt reached
 * max_attempts (a "failed" event is appended).  Safe from every node at
 * once (the rows are locked, SKIP LOCKED). */
sm_status smd_pg_expire(smd_pg *db, int max_attempts, size_t *requeued, size_t *failed,
                        sm_error *err);

/* After smd_pg_expire: the leases still past their expiry, because a
 * session holds their rows locked (a node frozen inside a transaction,
 * until the server's idle_in_transaction_session_timeout ends it): *n
 * of them (at most 16 counted), their ids space-separated into ids. */
sm_status smd_pg_expired_held(smd_pg *db, char *ids, size_t cap, size_t *n, sm_error *err);

/* DELETE on an API node: a queued job is dismissed at once (*was 1), a
 * running one gets cancel_requested and a NOTIFY on smd_cancel to its
 * worker node (*was 2); 0 when the job is final or unknown. */
sm_status smd_pg_cancel(smd_pg *db, const char *id, int *was, sm_error *err);

/* Queued jobs, and leases held (running jobs), cluster-wide. */
sm_status smd_pg_depth(smd_pg *db, int64_t *queued, int64_t *leased, sm_error *err);

/* Job state (and attempt) as the database has it; *found 0 when absent. */
sm_status smd_pg_state(smd_pg *db, const char *id, sm_job_state *state, int *attempt,
                       int *found, sm_error *err);

/* Streams the file at path into the blob (job, name) in SMD_PG_CHUNK
 * rows, replacing it; fence as for smd_pg_append_event (*held 0: the
 * lease was lost, nothing kept). */
sm_status smd_pg_blob_put(smd_pg *db, const char *id, const char *name,
                          const smd_pg_lease *fence, const char *path, int *held,
                          sm_error *err);
/* Streams the blob into a new file at path (chunk by chunk, single-row
 * mode: never the whole blob in memory); *found 0 when there is none. */
sm_status smd_pg_blob_get(smd_pg *db, const char *id, const char *name, const char *path,
                          int *found, sm_error *err);

/* What a node needs to mirror a job it did not accept. */
typedef struct smd_pg_info {
    char id[SMD_ID_LEN + 1];
    char owner[65];
    char idempotency_key[SM_IDEMPOTENCY_KEY_MAX + 1];
    uint64_t request_hash;
    sm_job_state state;
    char message[SM_EVENT_MESSAGE_MAX];
    int attempt, dim, max_iter;
    double tol_boundary;
    int64_t nevents;
    int64_t lease_token;          /* 0 when not running */
    int batch_model;              /* members is not NULL */
    char name[SM_JOB_NAME_MAX + 1]; /* "" none */
} smd_pg_info;

/* The members of model job id that ended successful (their results are
 * blobs): fn(user, member id) for each; fn returns 0 to go on. */
sm_status smd_pg_batch_done(smd_pg *db, const char *id,
                            int (*fn)(void *user, const char *member), void *user,
                            sm_error *err);

sm_status smd_pg_job_info(smd_pg *db, const char *id, smd_pg_info *out, int *found,
                          sm_error *err);
/* Every job (id, state, message, attempt, nevents; other fields zero),
 * in submission order, into a new array (*n entries; free it). */
sm_status smd_pg_list(smd_pg *db, smd_pg_info **out, size_t *n, sm_error *err);
/* Calls fn with the JSON of each event of id with seq > after, at most
 * limit of them, in order; fn returns 0 to go on.  *last: the last seq given. */
sm_status smd_pg_events(smd_pg *db, const char *id, int64_t after, int limit,
                        int (*fn)(void *user, int64_t seq, const char *json), void *user,
                        sm_error *err);

/* smd_pg_complete, and the files under results_dir (NULL: none) become
 * the blobs "results/<path>" (replacing any), in the same transaction;
 * the final event only as event number expect (smd_pg_append_event_at):
 * *held SMD_PG_GAP, nothing written, when the job has fewer events. */
sm_status smd_pg_publish(smd_pg *db, const smd_pg_lease *l, sm_job_state state,
                         const char *message, const char *final_event, int64_t expect,
                         const char *results_dir, int *held, sm_error *err);
/* The node stops (shutdown) while it runs the job: queued again at once,
 * attempt kept (no-op when the lease was lost). */
sm_status smd_pg_release(smd_pg *db, const smd_pg_lease *l, const char *message, sm_error *err);
/* The node could not take a job it claimed (its inputs could not be
 * copied here): queued again as smd_pg_release does, and the claim's
 * attempt given back, since nothing ran (--max-attempts counts runs). */
sm_status smd_pg_unclaim(smd_pg *db, const smd_pg_lease *l, const char *message, sm_error *err);
/* Deletes a final job (its events and blobs go with it): *deleted 1 for
 * the one caller that removed it. */
sm_status smd_pg_delete(smd_pg *db, const char *id, int *deleted, sm_error *err);
/* Blobs under "prefix" (e.g. "results/") into files under dir (made as
 * needed); *count files written. */
sm_status smd_pg_blob_get_tree(smd_pg *db, const char *id, const char *prefix, const char *dir,
                               size_t *count, sm_error *err);

/* LISTEN on channel (kept across smd_pg_reconnect). */
sm_status smd_pg_listen(smd_pg *db, const char *channel, sm_error *err);
/* Waits up to timeout seconds for a notification: 1 and channel and
 * payload copied (truncated to their caps), 0 on timeout, -1 when the
 * connection failed (err set). */
int smd_pg_wait(smd_pg *db, double timeout, char *channel, size_t ccap, char *payload,
                size_t pcap, sm_error *err);

#endif
