/* The worker pool and its supervisor thread.
 *
 * N slots (--workers).  The supervisor takes queued jobs in FIFO order
 * while a slot is free, forks and execs shapematch-worker for each (see
 * smd_worker.h) with the resource limits applied in the child, and then
 * waits in poll(2) on: an eventfd (wake-ups from HTTP handlers), every
 * worker's event pipe, and every worker's pidfd.  It appends the workers'
 * events to the job logs (the jobs named in its smd_jobs_after, so that
 * the event streams wake their followers), enforces the wall-time
 * limit (SIGTERM, then SIGKILL after --kill-grace), reaps exited workers
 * and turns their exit status into the job's final state with a reason
 * ("worker killed by signal 9 (SIGKILL)", "exceeded the CPU limit ...").
 * Once a second it also ticks for keepalives (smd_jobs_after_tick: the
 * event streams send them to idle followers), and deletes finished jobs
 * past --retention.
 *
 * Every state change goes through the state machine (smd_jobs.h), from
 * the supervisor and from HTTP handlers alike; handlers never wait for
 * the supervisor: they call the state machine under the lock and then
 * smd_pool_wake. */
#ifndef SMD_POOL_H
#define SMD_POOL_H

#include <stddef.h>

#include "shapematch/sm_error.h"
#include "base/smd_server.h"

typedef struct smd_pool smd_pool;

/* Creates the pool (srv->pool) and starts the supervisor thread. */
sm_status smd_pool_start(smd_server *srv, sm_error *err);

/* Wakes the supervisor (new job queued, cancel requested).  Any thread,
 * lock held or not. */
void smd_pool_wake(smd_pool *p);
/* srv->work_queued, installed by main: wakes srv->pool (when started). */
void smd_pool_work_queued(smd_server *srv);

/* Lock held: worker processes running. */
size_t smd_pool_busy(const smd_pool *p);
size_t smd_pool_slots(const smd_pool *p);

/* Graceful stop (lock NOT held): no new job starts; running jobs get
 * `grace` seconds to finish, then are stopped and kept queued for the
 * next start; returns when every worker is reaped and the thread joined.
 * smd_pool_hurry (any thread) cuts the remaining grace (second signal). */
void smd_pool_stop(smd_server *srv, double grace);
void smd_pool_hurry(smd_pool *p);

void smd_pool_free(smd_pool *p);

#endif
