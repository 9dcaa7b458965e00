/* The state machine's view of a cluster backend (--database): the calls
 * smd_jobs makes when the store and queue are shared by several nodes,
 * as a table (like the queue's), so that the state machine does not
 * include the backend (server/store/pg/smd_pg_node.h implements it).  Every call
 * is made with srv->lock held; see smd_pg_node.h for what each does. */
#ifndef SMD_CLUSTER_H
#define SMD_CLUSTER_H

#include "shapematch/sm_error.h"
#include "sm_proto_events.h"
#include "store/spool/smd_store.h"

struct smd_server;
struct smd_submission;
struct smd_jobs_after;
struct smd_pg_node;

typedef struct smd_cluster_ops {
    sm_status (*submit)(struct smd_server *srv, const struct smd_submission *sub, smd_job **out,
                        double *created, sm_error *err);
    void (*submitted)(struct smd_pg_node *node, const char *id);
    void (*event)(struct smd_pg_node *node, const smd_job *job, const sm_event *ev);
    void (*requeued)(struct smd_pg_node *node, const smd_job *job);
    int (*runs)(struct smd_pg_node *node, const char *id);
    sm_status (*cancel)(struct smd_server *srv, smd_job *job, struct smd_jobs_after *after,
                        sm_error *err);
    sm_status (*remove)(struct smd_pg_node *node, const char *id, int *deleted, sm_error *err);
} smd_cluster_ops;

#endif
