/* The embedded backend (jobs/smd_backend.h): the spool's records
 * (smd_store.h) and its FIFO (smd_fifo.h).  Its record and queue ops are
 * exported for a backend stacked on the spool (store/pg) to reuse. */
#ifndef SMD_SPOOL_BACKEND_H
#define SMD_SPOOL_BACKEND_H

#include "jobs/smd_backend.h"
#include "store/spool/smd_fifo.h"
#include "store/spool/smd_store.h"

extern const smd_backend_ops smd_spool_backend_ops;

/* b over an open spool and its queue (both borrowed). */
void smd_spool_backend_init(smd_backend *b, smd_store *spool, smd_queue *fifo);

smd_job *smd_spool_get(smd_backend *b, const char *id);
smd_job *smd_spool_find_key(smd_backend *b, const char *owner, const char *key);
size_t smd_spool_count(smd_backend *b);
smd_job *smd_spool_at(smd_backend *b, size_t i);
int smd_spool_path(smd_backend *b, const char *id, const char *name, char *buf, size_t cap);
sm_status smd_spool_commit(smd_backend *b, const char *dir, smd_job *job, sm_event *first,
                           sm_error *err);
sm_status smd_spool_save(smd_backend *b, smd_job *job, sm_error *err);
sm_status smd_spool_load_events(smd_backend *b, smd_job *job, sm_error *err);
sm_status smd_spool_append(smd_backend *b, smd_job *job, sm_event *ev, sm_error *err);
void smd_spool_unlink(smd_backend *b, smd_job *job);
int smd_spool_trash(smd_backend *b, const char *id, char *path, size_t cap);
int smd_spool_can_trash(smd_backend *b);
int smd_spool_writable(smd_backend *b);
void smd_spool_remove_results(smd_backend *b, const smd_job *job, int partial_only);
int smd_spool_next(smd_backend *b, char id[SMD_ID_LEN + 1]);
void smd_spool_dequeue(smd_backend *b, const char *id);

#endif
