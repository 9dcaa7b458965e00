/* The spool's local queue of jobs to run on this node (part of both
 * backends, jobs/smd_backend.h: the spool's queue of accepted jobs, and
 * PostgreSQL's jobs this node claimed).  Entries are job ids; the job's
 * state itself lives in the store.
 *
 * An in-memory FIFO: the store is the durable copy,
 * and the daemon rebuilds the queue from it at start (queued jobs in
 * submission order).  Not thread-safe by itself: the daemon calls it
 * with its lock held. */
#ifndef SMD_FIFO_H
#define SMD_FIFO_H

#include <stddef.h>

#include "base/smd_util.h"

typedef struct smd_queue_ops {
    const char *name;
    /* Appends id.  0, or -1 when out of memory. */
    int (*push)(void *impl, const char *id);
    /* Takes the oldest id into id_out: 1, or 0 when empty. */
    int (*pop)(void *impl, char id_out[SMD_ID_LEN + 1]);
    /* Drops id wherever it is: 1 when it was there, 0 otherwise. */
    int (*remove)(void *impl, const char *id);
    /* 0-based position of id, or -1 when absent. */
    long (*position)(void *impl, const char *id);
    size_t (*depth)(void *impl);
    void (*destroy)(void *impl);
} smd_queue_ops;

typedef struct smd_queue {
    const smd_queue_ops *ops;
    void *impl;
} smd_queue;

/* In-memory FIFO.  NULL when out of memory. */
smd_queue *smd_queue_local_new(void);
void smd_queue_free(smd_queue *q);

static inline int smd_queue_push(smd_queue *q, const char *id) { return q->ops->push(q->impl, id); }
static inline int smd_queue_pop(smd_queue *q, char id[SMD_ID_LEN + 1]) { return q->ops->pop(q->impl, id); }
static inline int smd_queue_remove(smd_queue *q, const char *id) { return q->ops->remove(q->impl, id); }
static inline long smd_queue_position(smd_queue *q, const char *id) { return q->ops->position(q->impl, id); }
static inline size_t smd_queue_depth(smd_queue *q) { return q->ops->depth(q->impl); }

#endif
