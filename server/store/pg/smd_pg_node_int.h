/* Private to smd_pg_node*.c, smd_pg_mirror.c and smd_pg_work.c. */
#ifndef SMD_PG_NODE_INT_H
#define SMD_PG_NODE_INT_H

#include <limits.h>
#include <pthread.h>
#include <stdatomic.h>

#include "jobs/smd_jobs.h"
#include "store/pg/smd_pg.h"

typedef struct smd_pg_node smd_pg_node; /* (as in smd_pg_node.h) */

#define NODE_PENDING_MAX 1024

typedef struct node_lease {
    smd_pg_lease lease;
    int64_t known;        /* events the database had at the claim */
    int lost;             /* renewal refused: the run is stopped, nothing published */
    double renewed;       /* monotonic seconds */
    struct node_lease *next;
} node_lease;

/* An event (or the end, or a release) of a job this node runs, waiting
 * for the work thread; on disk too (SPOOL/outbox/<ord>.json) once the
 * work thread spooled it (smd_pg_outbox.c). */
typedef struct node_item {
    char id[SMD_ID_LEN + 1];
    uint64_t ord;         /* the outbox's order: the file's name */
    int attempt;          /* the lease it was made under */
    int64_t token;
    size_t spooled;       /* bytes of its file; 0 while in memory only */
    int64_t seq;
    char *json;
    int final, release;
    sm_job_state state;
    char message[SM_EVENT_MESSAGE_MAX];
    struct node_item *next;
} node_item;

/* The database's part of a DELETE, done before srv->lock is taken
 * (smd_pg_node_withdraw) and used under it by cancel or delete. */
#define NODE_WITHDRAWN_MAX 64
typedef struct node_withdrawn {
    char id[SMD_ID_LEN + 1];
    int kind;             /* 0 free, 1 cancel (result: was), 2 delete (result: deleted) */
    int result;
    double at;            /* monotonic seconds: unused ones are dropped after a minute */
    sm_event *evs;        /* a queued job's cancel: the events after the local log's */
    size_t nevs;
} node_withdrawn;

struct smd_pg_node {
    smd_server *srv;
    char name[SMD_PG_NODE_MAX];
    smd_pg *api_db;           /* uploads: under api_lock (held while one is copied) */
    smd_pg *ctl_db;           /* cancel, delete: under ctl_lock (short queries, taken
                               * before srv->lock by a DELETE, smd_pg_node_withdraw;
                               * with it only by retention and races) */
    smd_pg *sync_db;          /* the sync thread's */
    smd_pg *work_db;          /* the work thread's */
    smd_pg *lease_db;         /* the lease thread's: renewals never wait for the outbox */
    pthread_mutex_t api_lock;
    pthread_mutex_t ctl_lock;
    pthread_mutex_t lock;     /* what follows */
    pthread_cond_t cond;      /* the work thread waits on it */
    node_item *out_head, **out_tail;
    node_lease *leases;
    size_t nleases;
    char pending[NODE_PENDING_MAX][SMD_ID_LEN + 1]; /* uploads between database and spool */
    size_t npending;
    node_withdrawn withdrawn[NODE_WITHDRAWN_MAX];
    double timeout_until;     /* monotonic: unready until then (a call timed out) */
    int outbox_held;          /* the outbox failed to be stored: retried, unready meanwhile */
    uint64_t next_ord;        /* the next item's ord */
    uint64_t outbox_bytes;    /* of the files in outbox_dir (the work thread's) */
    int outbox_full;          /* --outbox-max reached or a write failed: unready */
    char full_why[512];
    char outbox_dir[PATH_MAX];
    double claim_next;        /* the work thread's: no claim before (monotonic s) */
    double claim_backoff;     /* the last wait's bound, s; 0 while claims work */
    unsigned claim_fails;     /* failed claims in a row */
    uint64_t claim_rng;       /* jitter */
    char claim_why[SM_EVENT_MESSAGE_MAX + 64]; /* the failure last logged */
    char held_why[SM_ERROR_MSG_LEN + 128];
    char why[512];
    atomic_int up, stop;
    atomic_llong queued, leased;
    pthread_t sync_thread, work_thread, lease_thread;
    int have_sync, have_work, have_lease;
};

node_lease *node_find_lease(smd_pg_node *n, const char *id);
void node_drop_lease(smd_pg_node *n, const char *id);
node_item *node_take_item(smd_pg_node *n);
int node_pending(smd_pg_node *n, const char *id);
/* Reconnects db when it is down (logged once, /readyz fails meanwhile). */
sm_status node_connected(smd_pg_node *n, smd_pg *db, sm_error *err);
void node_set_down(smd_pg_node *n, const char *why);
void node_set_up(smd_pg_node *n);

/* smd_pg_mirror.c.  Lock NOT held: the database's job id into the local
 * store (record, events, results when successful); with lease, for a
 * run here: inputs too, queued locally for the pool. */
sm_status node_import(smd_pg_node *n, smd_pg *db, const char *id, node_lease *lease,
                      sm_error *err);
/* srv->lock held: the events of job the local log lacks (small: a
 * cancel), applied now. */
sm_status node_catch_up_locked(smd_pg_node *n, smd_pg *db, smd_job *job, smd_jobs_after *after,
                               sm_error *err);
/* Lock NOT held: the events of id after seq after, into a new array. */
sm_status node_fetch_events(smd_pg *db, const char *id, int64_t after, sm_event **v, size_t *n,
                            sm_error *err);
/* A failed call on db: the node is unready when it timed out (a row
 * lock held by a frozen session, a statement cancelled). */
void node_check_timeout(smd_pg_node *n, smd_pg *db, const sm_error *err);
void *node_sync_main(void *arg);

/* smd_pg_outbox.c: the outbox on disk, in the node's spool.  Loads the
 * items a previous process left, in order, into the outbox (before the
 * threads start), with the leases they were made under (renewed again:
 * the job is not run again while they wait); a job whose items do not
 * end its run (the process was killed while it ran) gets a release after
 * them.  SM_ERR_IO when the folder cannot be made or read. */
sm_status node_outbox_open(smd_pg_node *n, sm_error *err);
/* The work thread: writes the items of the list not on disk yet, in
 * order (durable writes), while --outbox-max allows; stops at the first
 * it cannot write (later ones are never on disk without it). */
void node_outbox_spill(smd_pg_node *n, node_item *items);
/* An item stored in the database (or dropped): its file is removed. */
void node_outbox_done(smd_pg_node *n, node_item *it);

/* smd_pg_work.c */
void *node_work_main(void *arg);
void *node_lease_main(void *arg);

#endif
