/* Private to smd_pg_node*.c, smd_pg_mirror.c and smd_pg_work.c. */
#ifndef SMD_PG_NODE_INT_H
#define SMD_PG_NODE_INT_H

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
 * for the work thread. */
typedef struct node_item {
    char id[SMD_ID_LEN + 1];
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

/* smd_pg_work.c */
void *node_work_main(void *arg);
void *node_lease_main(void *arg);

#endif
