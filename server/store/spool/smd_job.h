/* The job record: what the state machine (jobs/smd_jobs.c) changes and
 * every layer reads.  Its persisted part (id .. last_progress) is written
 * by the backend (jobs/smd_backend.h: status.json in the spool); the event
 * index (event_end, log_fd) is kept by the spool, which owns the log file;
 * the runtime part is the daemon's.
 *
 * Threading: none inside; read and written with srv->lock held. */
#ifndef SMD_JOB_H
#define SMD_JOB_H

#include <stdint.h>

#include <jansson.h>

#include "shapematch/sm_error.h"
#include "sm_proto_events.h"
#include "sm_proto_vocab.h"
#include "base/smd_util.h"

#define SMD_IDEMPOTENCY_KEY_MAX SM_IDEMPOTENCY_KEY_MAX /* proto/sm_proto_vocab.h */
#define SMD_OWNER_MAX 64 /* = SMD_TENANT_MAX (smd_auth.h) */

/* At most this many members in a batch (= SMD_BATCH_MEMBERS_MAX of
 * worker/smd_job_file.h; api/smd_batches.c asserts it). */
#define SMD_JOB_MEMBERS_MAX 1000

/* Bounds of the numbers of a record (status.json is outside input: a
 * restored backup, a hand edit).  A record whose "order" or "attempt" is
 * outside them is damaged: logged ("job_skipped") and left alone on disk.
 * Inside them nothing overflows: the order of the next job saturates at
 * SMD_ORDER_MAX (jobs with equal orders run by creation time, then id),
 * and the attempt count stops at SMD_ATTEMPT_MAX. */
#define SMD_ORDER_MAX INT64_MAX
#define SMD_ATTEMPT_MAX 1000000


/* The end of a run that is not on disk yet (smd_jobs.c: durable first):
 * the state the job will have, its record and its last event, kept while
 * the spool refuses them.  Until both are written the job is shown as it
 * was (running), and nothing of this is published. */
typedef struct smd_job_ending {
    sm_job_state state;       /* successful, failed or dismissed */
    char message[SM_EVENT_MESSAGE_MAX];
    double finished;          /* Unix seconds */
    sm_event ev;              /* finished, failed or cancelled, seq 0 */
    int record_written;       /* status.json holds the final record */
    int log_level;
    const char *log_event;    /* static string */
    json_t *log_fields;       /* owned: the job's log line */
} smd_job_ending;

typedef struct smd_job {
    char id[SMD_ID_LEN + 1];
    sm_job_state state;
    char message[SM_EVENT_MESSAGE_MAX];
    double created, started, finished, updated; /* Unix seconds, < 0 = unset */
    int progress;             /* 0..100 */
    int attempt;              /* runs started so far, <= SMD_ATTEMPT_MAX */
    int64_t order;            /* submission order (FIFO across restarts), saturates */
    int dim;                  /* template dimension */
    int max_iter;             /* for the progress estimate */
    double tol_boundary;      /* params.tol_boundary (0 none): watch's bar */
    char idempotency_key[SMD_IDEMPOTENCY_KEY_MAX + 1]; /* "" = none */
    char owner[SMD_OWNER_MAX + 1]; /* tenant of the submitting token, "" = none */
    char name[SM_JOB_NAME_MAX + 1]; /* given at submission (part "name"), "" = none */
    uint64_t request_hash;    /* of the request that used the key; 0 unknown */
    int not_converged;        /* a successful job whose run did not converge
                               * (its result's converged false): the status
                               * document says "converged": false */
    int batch_model;          /* the model job of a batch (api/smd_batches.h):
                               * it waits until every member job is final */
    char (*members)[SMD_ID_LEN + 1]; /* owned: its members (the spool's gate;
                               * PostgreSQL gates in its claim: none here) */
    size_t nmembers;
    int64_t final_event_at;   /* final records: where the final event starts in
                               * events.ndjson (written after the record);
                               * 0 unknown */

    /* last progress event, shown in the status document */
    int have_progress;
    sm_progress last_progress;

    /* event log: event_end[i] is the byte offset just past event seq i+1 */
    int events_loaded;
    int64_t nevents;
    uint64_t *event_end;
    size_t event_cap;
    int log_fd;               /* append descriptor while the job is live, or -1 */

    /* runtime state (not persisted) */
    int refs;                 /* the table's reference + event streams + worker */
    int removed;              /* no longer in the table (deleted) */
    int worker_active;        /* a worker process runs (or is being reaped) */
    int cancel_requested;     /* DELETE while running: stop the worker */
    int delete_requested;     /* DELETE of a job whose worker is stopping */
    int unsaved;              /* its last record write failed: retried */
    smd_job_ending *ending;   /* owned: an end waiting for the spool, or NULL */
    struct smd_job *hash_next;
} smd_job;

/* A copy of job's plain fields, for use after srv->lock is released (the
 * status document, the replies): no log index, descriptor, members or
 * held end (those stay the table's). */
void smd_job_view(const smd_job *job, smd_job *view);

/* Sets job's members (a copy); -1 out of memory. */
int smd_job_set_members(smd_job *job, const char (*ids)[SMD_ID_LEN + 1], size_t n);

int smd_job_visible(const smd_job *job, const char *tenant, int admin);

/* A job record in memory (no times set, no log), not in any table: the
 * state machine fills it in and hands it to the backend's commit (jobs/smd_backend.h).  NULL when
 * out of memory. */
smd_job *smd_job_new(const char *id);

/* Frees a record that is in no table and has no reference (a commit
 * that failed, the spool closing). */
void smd_job_free(smd_job *job);

void smd_job_ref(smd_job *job);
/* Drops a reference; the job is freed when it is removed from the table
 * and no reference is left. */
void smd_job_unref(smd_job *job);

/* Byte offset where event seq starts (seq in 1..nevents+1; nevents+1
 * gives the end of the log).  The index must be loaded. */
uint64_t smd_job_event_offset(const smd_job *job, int64_t seq);

/* Closes the append descriptor (the job reached a final state). */
void smd_job_close_log(smd_job *job);

/* 1 for successful, failed, dismissed. */
int smd_job_state_final(sm_job_state state);

/* OGC statusInfo members (jobID, processID, type, status, message,
 * created, started, finished, updated, progress) plus, for a successful
 * job, "converged" (false: finished without reaching a match; OGC's
 * status values stay as they are, docs/api.md), and the last progress
 * figures; no links.  New reference or NULL. */
json_t *smd_job_status_fields(const smd_job *job);

#endif
