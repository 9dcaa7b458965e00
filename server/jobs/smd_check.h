/* Acceptance checks of uploads off the HTTP threads (issues 8 and 13).
 *
 * Parsing and checking an upload (sm_job_inputs_load: up to hundreds of
 * MB of mesh, a decompression-heavy gzip) used to hold an HTTP thread for
 * seconds, during which /healthz and status requests on that thread
 * waited.  Now the upload handler suspends its connection and queues the
 * check here; one of --check-threads threads forks a child process that
 * runs it and writes its small result back through a pipe, and the
 * thread resumes the connection, whose handler then answers (201, 413,
 * 422).  The child bounds what one upload may cost:
 * - time: killed (SIGKILL) after --check-timeout, answered 422 naming
 *   the flag;
 * - memory: RLIMIT_AS of --memory-limit (not under AddressSanitizer), and
 *   whatever it allocates is gone with it, so the daemon's own RSS does
 *   not grow with the uploads it checked.
 * The child runs with one OpenMP thread and leaves by _exit (no atexit
 * handlers of the daemon run in it).
 *
 * Fair shares (issue 37): each check belongs to a client (its address, an
 * IPv6 /64, an IPv4 network of --submit-ipv4-prefix, or its tenant with
 * tokens), which runs at most --check-threads - 1 checks at once (1 with
 * one thread): however many checks one client sends, a slot stays free
 * for another's.  Waiting checks start fewest-running client first, then
 * in arrival order.  A check still waiting after a whole --check-timeout
 * is answered busy (the caller answers 503 with Retry-After) instead of
 * after minutes.
 *
 * At most SMD_CHECK_QUEUE_MAX checks wait, SMD_CHECK_WAITING_PER_CLIENT of
 * one client; beyond, submission fails (503 with Retry-After).  The pool
 * has its own mutex; no server lock is taken here. */
#ifndef SMD_CHECK_H
#define SMD_CHECK_H

#include <stddef.h>
#include <stdint.h>

#include "shapematch/sm_error.h"

#define SMD_CHECK_QUEUE_MAX 256
/* Checks one client may have waiting; beyond, its uploads get 503 at once
 * and leave the rest of the queue to others. */
#define SMD_CHECK_WAITING_PER_CLIENT 64
/* Longest client key (smd_ratelimit_address_key's, or "t:" + a tenant). */
#define SMD_CHECK_KEY_MAX 80

/* What a check sends back (a plain struct: it crosses the pipe). */
typedef struct smd_check_result {
    sm_status status;        /* SM_OK: accepted */
    int limit_hit;           /* SM_LIMIT_* of sm_read_limits, 0 none */
    int timed_out;           /* stopped at --check-timeout */
    int crashed;             /* the child died (signal, or no result) */
    int signal;              /* its signal when it did */
    int shutdown;            /* not checked: the daemon stops */
    int busy;                /* not checked: it waited a --check-timeout for a slot */
    int storage;             /* the check passed, storing it failed */
    int stage;               /* a warp: the step that failed (api/smd_warp.c) */
    char msg[512];           /* why, when status != SM_OK */
    int dim, max_iter;
    double tol_boundary;
    int32_t nverts, nelems;
} smd_check_result;

/* The check itself, run in the child: fills out (status and msg, or the
 * summary of the accepted job). */
typedef void (*smd_check_fn)(void *arg, smd_check_result *out);
/* Called from a check thread once *out is final (the connection can be
 * resumed); the task is forgotten by the pool before the call. */
typedef void (*smd_check_done_fn)(void *user);

typedef struct smd_check_pool smd_check_pool;

/* threads >= 1; timeout in seconds; memory_limit bytes (0 none); in the
 * AddressSanitizer build checks run in the thread, see smd_check.c.  NULL
 * with err set on failure. */
smd_check_pool *smd_check_pool_new(int threads, double timeout, uint64_t memory_limit,
                                   sm_error *err);
/* Queues a check.  0, or -1 when the queue is full or the pool stops
 * (nothing is called then).  fn(arg, out) runs in a child; done(user)
 * follows, in a check thread. */
int smd_check_submit(smd_check_pool *p, smd_check_fn fn, void *arg, smd_check_result *out,
                     smd_check_done_fn done, void *user);
/* The same for a client, key (its share, above; "" or NULL: the shared
 * one); -2 when that client already has SMD_CHECK_WAITING_PER_CLIENT
 * checks waiting. */
int smd_check_submit_from(smd_check_pool *p, const char *key, smd_check_fn fn, void *arg,
                          smd_check_result *out, smd_check_done_fn done, void *user);
/* The caller is done with a submitted check's request (answered, or the
 * request is gone): smd_check_pool_stop waits for every one. */
void smd_check_settled(smd_check_pool *p);
/* Checks running and waiting, for /metrics. */
void smd_check_counts(smd_check_pool *p, uint64_t *running, uint64_t *waiting);
/* Stops: waiting checks are answered at once (status SM_ERR_IO, "the
 * daemon is shutting down"), running children are killed (the same);
 * every done() has been called, and it waits up to `wait` seconds for
 * every submitted check to be settled (its connection resumed and
 * answered: libmicrohttpd must not stop with it still pending). */
void smd_check_pool_stop(smd_check_pool *p, double wait);
/* Stops (without waiting) if not stopped yet, and frees. */
void smd_check_pool_free(smd_check_pool *p);

#endif
