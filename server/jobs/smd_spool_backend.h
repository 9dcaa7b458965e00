/* The embedded backend (jobs/smd_backend.h): one node, its spool
 * (store/spool/smd_store.h) the only store and its FIFO
 * (store/spool/smd_fifo.h) the only queue. */
#ifndef SMD_SPOOL_BACKEND_H
#define SMD_SPOOL_BACKEND_H

#include "jobs/smd_backend.h"
#include "store/spool/smd_fifo.h"
#include "store/spool/smd_store.h"

extern const smd_backend_ops smd_spool_backend_ops;

/* b over an open spool and its queue (both borrowed). */
void smd_spool_backend_init(smd_backend *b, smd_store *spool, smd_queue *fifo);

#endif
