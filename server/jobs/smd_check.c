/* Check threads and their child processes (see smd_check.h). */
#include "jobs/smd_check.h"

#include <errno.h>
#include <fcntl.h>
#include <omp.h>
#include <poll.h>
#include <pthread.h>
#include <stdatomic.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "shapematch/sm_clock.h"

typedef struct task {
    smd_check_fn fn;
    void *arg;
    smd_check_result *out;
    smd_check_done_fn done;
    void *user;
    char key[SMD_CHECK_KEY_MAX + 1]; /* the client's: its share is counted by it */
    uint64_t seq;                    /* arrival order */
    double queued_at;
} task;

struct smd_check_pool {
    pthread_mutex_t mutex;
    pthread_cond_t wake;
    task queue[SMD_CHECK_QUEUE_MAX]; /* the waiting checks, [0, count), any order */
    size_t count;
    uint64_t seq;
    char (*running_key)[SMD_CHECK_KEY_MAX + 1]; /* per thread: its check's client */
    int running;
    int stop;
    double timeout;
    uint64_t memory_limit;
    int nthreads;
    pthread_t *threads;
    pid_t *children;     /* per thread: its running child, 0 none */
    atomic_int outstanding; /* submitted, not yet settled */
    int joined;
};

static void set_failure(smd_check_result *out, const char *msg)
{
    out->status = SM_ERR_IO;
    snprintf(out->msg, sizeof out->msg, "%s", msg);
}

#if defined(__SANITIZE_ADDRESS__)
/* The sanitizer build checks in the check thread itself: GCC 12's
 * AddressSanitizer does not lock its allocator around fork(), so a child
 * forked while another thread allocates can hang on its first malloc
 * (seen as checks "taking" over 60 s under load).  The deadline is then
 * applied when the check returns, and a shutdown waits for it; no
 * memory limit either (the sanitizer's shadow memory would not fit one).
 * The release build keeps the child (killable, memory-limited). */
static void run(smd_check_pool *p, int slot, const task *t)
{
    (void)slot;
    memset(t->out, 0, sizeof *t->out);
    double deadline = sm_clock_seconds() + p->timeout;
    t->fn(t->arg, t->out);
    pthread_mutex_lock(&p->mutex);
    int stopping = p->stop;
    pthread_mutex_unlock(&p->mutex);
    if (stopping) {
        memset(t->out, 0, sizeof *t->out);
        set_failure(t->out, "the daemon is shutting down");
        t->out->shutdown = 1;
    } else if (sm_clock_seconds() > deadline) {
        memset(t->out, 0, sizeof *t->out);
        t->out->status = SM_ERR_INVALID;
        t->out->timed_out = 1;
    }
}
#else
/* In the child: bounds, the check, the result down the pipe, _exit. */
static void child_main(smd_check_pool *p, const task *t, int fd)
{
    prctl(PR_SET_PDEATHSIG, SIGKILL);
    signal(SIGPIPE, SIG_DFL);
    struct rlimit core = {0, 0};
    setrlimit(RLIMIT_CORE, &core);
    if (p->memory_limit) {
        struct rlimit as = {(rlim_t)p->memory_limit, (rlim_t)p->memory_limit};
        setrlimit(RLIMIT_AS, &as);
    }
    omp_set_num_threads(1);
    smd_check_result r;
    memset(&r, 0, sizeof r);
    t->fn(t->arg, &r);
    const char *b = (const char *)&r;
    size_t left = sizeof r;
    while (left > 0) {
        ssize_t n = write(fd, b, left);
        if (n < 0 && errno == EINTR)
            continue;
        if (n <= 0)
            _exit(2);
        b += n;
        left -= (size_t)n;
    }
    _exit(0);
}

/* Reads the child's result within the deadline: 1 read, 0 the pipe closed
 * early, -1 the deadline passed. */
static int read_result(int fd, smd_check_result *r, double deadline)
{
    char *b = (char *)r;
    size_t got = 0;
    while (got < sizeof *r) {
        double left = deadline - sm_clock_seconds();
        if (left <= 0)
            return -1;
        struct pollfd pfd = {fd, POLLIN, 0};
        int rc = poll(&pfd, 1, (int)(left * 1000) + 1);
        if (rc < 0 && errno == EINTR)
            continue;
        if (rc == 0)
            continue;
        ssize_t n = read(fd, b + got, sizeof *r - got);
        if (n < 0 && errno == EINTR)
            continue;
        if (n <= 0)
            return 0;
        got += (size_t)n;
    }
    return 1;
}

/* Runs one task in a child, in check thread `slot`. */
static void run(smd_check_pool *p, int slot, const task *t)
{
    memset(t->out, 0, sizeof *t->out);
    int fds[2];
    if (pipe2(fds, O_CLOEXEC) != 0) {
        set_failure(t->out, "cannot check the upload: no pipe");
        return;
    }
    pid_t pid = fork();
    if (pid == 0) {
        close(fds[0]);
        child_main(p, t, fds[1]);
    }
    close(fds[1]);
    if (pid < 0) {
        close(fds[0]);
        set_failure(t->out, "cannot check the upload: fork failed");
        return;
    }
    pthread_mutex_lock(&p->mutex);
    p->children[slot] = pid;
    int stopping = p->stop;
    pthread_mutex_unlock(&p->mutex);
    if (stopping)
        kill(pid, SIGKILL);
    int got = read_result(fds[0], t->out, sm_clock_seconds() + p->timeout);
    close(fds[0]);
    if (got <= 0)
        kill(pid, SIGKILL);
    int status = 0;
    while (waitpid(pid, &status, 0) < 0 && errno == EINTR)
        ;
    pthread_mutex_lock(&p->mutex);
    p->children[slot] = 0;
    stopping = p->stop;
    pthread_mutex_unlock(&p->mutex);
    if (got > 0)
        return;
    memset(t->out, 0, sizeof *t->out);
    if (stopping) {
        set_failure(t->out, "the daemon is shutting down");
        t->out->shutdown = 1;
    } else if (got < 0) {
        t->out->status = SM_ERR_INVALID;
        t->out->timed_out = 1;
    } else {
        t->out->status = SM_ERR_IO;
        t->out->crashed = 1;
        t->out->signal = WIFSIGNALED(status) ? WTERMSIG(status) : 0;
    }
}

#endif

typedef struct thread_arg {
    smd_check_pool *p;
    int slot;
} thread_arg;

/* ------------------------------------------------------ scheduling
 * Fair shares of the check slots: a client (smd_check_submit_from's key:
 * an address, an IPv6 /64, an IPv4 network, a tenant) runs at most
 * share() checks at once, so with two or more threads one slot is always
 * left to other clients however many checks one sends; among waiting
 * checks, the client with the fewest running goes first, then arrival
 * order.  A check that waited a whole --check-timeout is answered busy
 * (503, Retry-After) rather than after minutes.  Mutex held in all. */

static int share(const smd_check_pool *p)
{
    return p->nthreads > 1 ? p->nthreads - 1 : 1;
}

static int running_of(const smd_check_pool *p, const char *key)
{
    int n = 0;
    for (int i = 0; i < p->nthreads; i++)
        n += p->running_key[i][0] != '\0' && strcmp(p->running_key[i], key) == 0;
    return n;
}

static size_t waiting_of(const smd_check_pool *p, const char *key)
{
    size_t n = 0;
    for (size_t i = 0; i < p->count; i++)
        n += strcmp(p->queue[i].key, key) == 0;
    return n;
}

/* The waiting check to start next, -1 when every waiting client is at its
 * share (while stopping: any, they are answered, not run). */
static long pick(const smd_check_pool *p)
{
    long best = -1;
    int best_running = 0;
    for (size_t i = 0; i < p->count; i++) {
        int r = p->stop ? 0 : running_of(p, p->queue[i].key);
        if (r >= share(p))
            continue;
        if (best < 0 || r < best_running ||
            (r == best_running && p->queue[i].seq < p->queue[best].seq)) {
            best = (long)i;
            best_running = r;
        }
    }
    return best;
}

/* The earliest waiting check that has waited longer than the timeout,
 * -1 none. */
static long expired(const smd_check_pool *p, double now)
{
    long old = -1;
    for (size_t i = 0; i < p->count; i++)
        if (now - p->queue[i].queued_at > p->timeout &&
            (old < 0 || p->queue[i].seq < p->queue[old].seq))
            old = (long)i;
    return old;
}

static task take(smd_check_pool *p, long i)
{
    task t = p->queue[i];
    p->queue[i] = p->queue[--p->count];
    return t;
}

/* Sleeps until a check may start, one expires or the pool stops. */
static void wait_for_work(smd_check_pool *p)
{
    if (p->count == 0) {
        pthread_cond_wait(&p->wake, &p->mutex);
        return;
    }
    double first = p->queue[0].queued_at;
    for (size_t i = 1; i < p->count; i++)
        if (p->queue[i].queued_at < first)
            first = p->queue[i].queued_at;
    double at = first + p->timeout + 0.01; /* the wake condition's clock is monotonic */
    struct timespec ts = {(time_t)at, (long)((at - (double)(time_t)at) * 1e9)};
    pthread_cond_timedwait(&p->wake, &p->mutex, &ts);
}

static void answer_busy(const smd_check_pool *p, const task *t)
{
    memset(t->out, 0, sizeof *t->out);
    t->out->status = SM_ERR_NOMEM;
    t->out->busy = 1;
    snprintf(t->out->msg, sizeof t->out->msg,
             "this upload waited %g s for an acceptance check (the daemon's --check-timeout) "
             "behind other checks: retry later", p->timeout);
}

static void *thread_main(void *arg)
{
    thread_arg a = *(thread_arg *)arg;
    free(arg);
    smd_check_pool *p = a.p;
    pthread_mutex_lock(&p->mutex);
    for (;;) {
        long i = -1, old = -1;
        while ((old = expired(p, sm_clock_seconds())) < 0 && (i = pick(p)) < 0) {
            if (p->stop && p->count == 0)
                break;
            wait_for_work(p);
        }
        if (old < 0 && i < 0)
            break; /* stopping, nothing left */
        if (old >= 0) {
            task t = take(p, old);
            pthread_mutex_unlock(&p->mutex);
            answer_busy(p, &t);
            t.done(t.user);
            pthread_mutex_lock(&p->mutex);
            continue;
        }
        task t = take(p, i);
        p->running++;
        memcpy(p->running_key[a.slot], t.key, sizeof t.key);
        int stopping = p->stop;
        pthread_mutex_unlock(&p->mutex);
        if (stopping) {
            memset(t.out, 0, sizeof *t.out);
            set_failure(t.out, "the daemon is shutting down");
            t.out->shutdown = 1;
        } else {
            run(p, a.slot, &t);
        }
        t.done(t.user);
        pthread_mutex_lock(&p->mutex);
        p->running--;
        p->running_key[a.slot][0] = '\0';
        pthread_cond_broadcast(&p->wake); /* a client under its share again */
    }
    pthread_mutex_unlock(&p->mutex);
    return NULL;
}

smd_check_pool *smd_check_pool_new(int threads, double timeout, uint64_t memory_limit,
                                   sm_error *err)
{
    smd_check_pool *p = calloc(1, sizeof *p);
    if (p) {
        p->threads = calloc((size_t)threads, sizeof *p->threads);
        p->children = calloc((size_t)threads, sizeof *p->children);
        p->running_key = calloc((size_t)threads, sizeof *p->running_key);
    }
    if (!p || !p->threads || !p->children || !p->running_key) {
        if (p) {
            free(p->threads);
            free(p->children);
            free(p->running_key);
        }
        free(p);
        sm_error_set(err, SM_ERR_NOMEM, "out of memory");
        return NULL;
    }
    pthread_mutex_init(&p->mutex, NULL);
    pthread_condattr_t ca;
    pthread_condattr_init(&ca);
    pthread_condattr_setclock(&ca, CLOCK_MONOTONIC); /* as sm_clock_seconds */
    pthread_cond_init(&p->wake, &ca);
    pthread_condattr_destroy(&ca);
    p->timeout = timeout;
    p->memory_limit = memory_limit;
    for (int i = 0; i < threads; i++) {
        thread_arg *a = malloc(sizeof *a);
        if (a) {
            a->p = p;
            a->slot = i;
        }
        if (!a || pthread_create(&p->threads[i], NULL, thread_main, a) != 0) {
            free(a);
            sm_error_set(err, SM_ERR_IO, "cannot start the upload check threads");
            smd_check_pool_free(p);
            return NULL;
        }
        p->nthreads = i + 1;
    }
    return p;
}

int smd_check_submit_from(smd_check_pool *p, const char *key, smd_check_fn fn, void *arg,
                          smd_check_result *out, smd_check_done_fn done, void *user)
{
    pthread_mutex_lock(&p->mutex);
    int rc;
    if (p->stop || p->count >= SMD_CHECK_QUEUE_MAX) {
        rc = -1;
    } else if (waiting_of(p, key && key[0] ? key : "-") >= SMD_CHECK_WAITING_PER_CLIENT) {
        rc = -2;
    } else {
        task *t = &p->queue[p->count++];
        *t = (task){fn, arg, out, done, user, "", p->seq++, sm_clock_seconds()};
        /* "-": the shared key (a client key starts "a:" or "t:"); an empty
         * running_key marks an idle thread */
        snprintf(t->key, sizeof t->key, "%s", key && key[0] ? key : "-");
        atomic_fetch_add(&p->outstanding, 1);
        pthread_cond_broadcast(&p->wake);
        rc = 0;
    }
    pthread_mutex_unlock(&p->mutex);
    return rc;
}

int smd_check_submit(smd_check_pool *p, smd_check_fn fn, void *arg, smd_check_result *out,
                     smd_check_done_fn done, void *user)
{
    return smd_check_submit_from(p, "", fn, arg, out, done, user);
}

void smd_check_counts(smd_check_pool *p, uint64_t *running, uint64_t *waiting)
{
    *running = *waiting = 0;
    if (!p)
        return;
    pthread_mutex_lock(&p->mutex);
    *running = (uint64_t)p->running;
    *waiting = (uint64_t)p->count;
    pthread_mutex_unlock(&p->mutex);
}

void smd_check_settled(smd_check_pool *p)
{
    if (p)
        atomic_fetch_sub(&p->outstanding, 1);
}

void smd_check_pool_stop(smd_check_pool *p, double wait)
{
    if (!p || p->joined)
        return;
    pthread_mutex_lock(&p->mutex);
    p->stop = 1;
    for (int i = 0; i < p->nthreads; i++)
        if (p->children[i] > 0)
            kill(p->children[i], SIGKILL);
    pthread_cond_broadcast(&p->wake);
    pthread_mutex_unlock(&p->mutex);
    for (int i = 0; i < p->nthreads; i++)
        pthread_join(p->threads[i], NULL);
    p->joined = 1;
    double until = sm_clock_seconds() + wait;
    while (atomic_load(&p->outstanding) > 0 && sm_clock_seconds() < until)
        usleep(10000);
}

void smd_check_pool_free(smd_check_pool *p)
{
    if (!p)
        return;
    smd_check_pool_stop(p, 0);
    pthread_cond_destroy(&p->wake);
    pthread_mutex_destroy(&p->mutex);
    free(p->threads);
    free(p->children);
    free(p->running_key);
    free(p);
}
