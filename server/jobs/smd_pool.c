/* Worker pool and supervisor thread (see smd_pool.h). */
#include "jobs/smd_pool.h"

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <math.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/eventfd.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <sys/time.h>
#include <sys/wait.h>
#include <unistd.h>

#include "shapematch/sm_clock.h"
#include "sm_proto_events.h"
#include "jobs/smd_jobs.h"
#include "worker/smd_worker.h"

#define LINE_MAX_BYTES SM_EVENT_LINE_MAX
#define TICK_SECONDS 1.0
#define RETENTION_SWEEP_SECONDS 5.0

typedef enum stop_reason {
    STOP_NONE = 0,
    STOP_CANCEL,   /* DELETE */
    STOP_TIMEOUT,  /* --job-timeout */
    STOP_SHUTDOWN  /* daemon stopping: keep the job queued */
} stop_reason;

typedef struct slot {
    smd_job *job;          /* NULL: free; reference held otherwise */
    pid_t pid;
    int pidfd;             /* -1 when pidfd_open is unavailable */
    int pipe_fd;           /* -1 after EOF */
    int exited;
    int wstatus;
    double cpu_seconds;
    double started_mono, deadline_mono, kill_at_mono; /* 0 = none */
    stop_reason stop;
    char *line;            /* partial event line */
    size_t line_len;
    int line_overflow;     /* dropping an oversized line */
    int have_finished;     /* the worker reported its result */
    sm_event finished;
    char fail_msg[SM_EVENT_MESSAGE_MAX];
} slot;

struct smd_pool {
    smd_server *srv;
    pthread_t thread;
    int thread_started;
    int wake_fd;
    slot *slots;
    size_t nslots, busy;
    int quit;              /* stop requested */
    double grace_deadline; /* monotonic: stop running jobs after it */
    char **env;            /* environment of the workers */
    char *env_threads[2];  /* its OMP_NUM_THREADS / OPENBLAS_NUM_THREADS entries */
    double tick;           /* period of keepalive checks */
    double next_tick, next_sweep, next_save_retry;
    pid_t daemon_pid;
};

/* ------------------------------------------------------------- helpers */

void smd_pool_wake(smd_pool *p)
{
    uint64_t one = 1;
    ssize_t n = write(p->wake_fd, &one, sizeof one);
    (void)n; /* a full counter still wakes the poll */
}

void smd_pool_work_queued(smd_server *srv)
{
    if (srv->pool)
        smd_pool_wake(srv->pool);
}

size_t smd_pool_busy(const smd_pool *p)
{
    return p->busy;
}

size_t smd_pool_slots(const smd_pool *p)
{
    return p->nslots;
}

static void signal_group(slot *s, int sig)
{
    if (s->pid > 0 && !s->exited)
        kill(-s->pid, sig); /* the worker's process group: helpers die too */
}

/* ---------------------------------------------------------------- spawn */

/* Forks and execs the worker for s->job.  Only async-signal-safe calls
 * happen between fork and exec: everything is prepared before. */
static int spawn(smd_pool *p, slot *s, char *msg, size_t cap)
{
    smd_server *srv = p->srv;
    const smd_config *cfg = &srv->cfg;
    char job_dir[PATH_MAX], log_path[PATH_MAX];
    if (smd_store_path(srv->store, s->job->id, "", job_dir, sizeof job_dir) != 0 ||
        smd_store_path(srv->store, s->job->id, SMD_WORKER_LOG, log_path, sizeof log_path) != 0) {
        snprintf(msg, cap, "job folder path too long");
        return -1;
    }
    char *const argv[] = {(char *)cfg->worker_path, job_dir, NULL};
    struct rlimit cpu = {RLIM_INFINITY, RLIM_INFINITY}, as = {RLIM_INFINITY, RLIM_INFINITY};
    struct rlimit core = {0, 0};
    if (cfg->cpu_limit > 0) {
        cpu.rlim_cur = (rlim_t)ceil(cfg->cpu_limit);
        /* SIGXCPU at the soft limit, SIGKILL at the hard one */
        cpu.rlim_max = cpu.rlim_cur + (rlim_t)ceil(cfg->kill_grace) + 1;
    }
#if !defined(__SANITIZE_ADDRESS__)
    if (cfg->memory_limit > 0)
        as.rlim_cur = as.rlim_max = (rlim_t)cfg->memory_limit;
#endif
    int pipefd[2];
    if (pipe2(pipefd, O_CLOEXEC) != 0) {
        snprintf(msg, cap, "pipe: %s", strerror(errno));
        return -1;
    }
    sigset_t none;
    sigemptyset(&none);
    pid_t parent = p->daemon_pid;
    pid_t pid = fork();
    if (pid < 0) {
        snprintf(msg, cap, "fork: %s", strerror(errno));
        close(pipefd[0]);
        close(pipefd[1]);
        return -1;
    }
    if (pid == 0) {
        setpgid(0, 0);
        prctl(PR_SET_PDEATHSIG, SIGKILL);
        if (getppid() != parent)
            _exit(SMD_WORKER_EXIT_EXEC); /* the daemon died already */
        struct sigaction dfl;
        memset(&dfl, 0, sizeof dfl);
        dfl.sa_handler = SIG_DFL;
        const int sigs[] = {SIGPIPE, SIGTERM, SIGINT, SIGHUP, SIGCHLD, SIGXCPU};
        for (size_t i = 0; i < sizeof sigs / sizeof sigs[0]; i++)
            sigaction(sigs[i], &dfl, NULL);
        sigprocmask(SIG_SETMASK, &none, NULL);
        int ev = fcntl(pipefd[1], F_DUPFD_CLOEXEC, 10);
        int in = open("/dev/null", O_RDONLY | O_CLOEXEC);
        int logfd = open(log_path, O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
        if (ev < 0 || in < 0 || logfd < 0 || dup2(in, 0) < 0 || dup2(logfd, 1) < 0 ||
            dup2(logfd, 2) < 0 || dup2(ev, SMD_WORKER_EVENT_FD) < 0)
            _exit(SMD_WORKER_EXIT_EXEC);
        setrlimit(RLIMIT_CORE, &core);
        if (setrlimit(RLIMIT_CPU, &cpu) != 0 || setrlimit(RLIMIT_AS, &as) != 0)
            _exit(SMD_WORKER_EXIT_EXEC);
        execve(argv[0], argv, p->env);
        _exit(SMD_WORKER_EXIT_EXEC);
    }
    setpgid(pid, pid); /* also here: no race with an early kill(-pid) */
    close(pipefd[1]);
    fcntl(pipefd[0], F_SETFL, O_NONBLOCK);
    s->pid = pid;
    s->pipe_fd = pipefd[0];
#ifdef SYS_pidfd_open
    s->pidfd = (int)syscall(SYS_pidfd_open, pid, 0);
#else
    s->pidfd = -1;
#endif
    s->exited = 0;
    s->wstatus = 0;
    s->cpu_seconds = 0;
    s->stop = STOP_NONE;
    s->started_mono = sm_clock_seconds();
    s->deadline_mono = cfg->job_timeout > 0 ? s->started_mono + cfg->job_timeout : 0;
    s->kill_at_mono = 0;
    s->line_len = 0;
    s->line_overflow = 0;
    s->have_finished = 0;
    s->fail_msg[0] = '\0';
    return 0;
}

/* Lock held: moves the next queued job into a free slot. */
static int start_next(smd_pool *p, smd_jobs_after *after)
{
    smd_server *srv = p->srv;
    slot *s = NULL;
    for (size_t i = 0; i < p->nslots && !s; i++)
        if (!p->slots[i].job)
            s = &p->slots[i];
    if (!s)
        return 0;
    smd_job *job = smd_jobs_take_next(srv);
    if (!job)
        return 0;
    s->job = job;
    smd_job_ref(job);
    char msg[256], why[SM_EVENT_MESSAGE_MAX];
    if (spawn(p, s, msg, sizeof msg) != 0) {
        /* no process: fail the job right here */
        smd_textf(why, sizeof why, "cannot start the worker: %s", msg);
        smd_jobs_fail(srv, job, why, NULL, after);
        s->job = NULL;
        smd_job_unref(job);
        return 1;
    }
    p->busy++;
    smd_jobs_started(srv, job, (long)s->pid, after);
    return 1;
}

/* ------------------------------------------------------- worker events */

static void handle_line(smd_pool *p, slot *s, const char *line, size_t len, smd_jobs_after *after)
{
    smd_server *srv = p->srv;
    smd_job *job = s->job;
    if (len == 0)
        return;
    sm_event ev;
    sm_error err;
    if (sm_event_from_json(line, len, &ev, &err) != SM_OK) {
        smd_logf(&srv->log, SMD_LOG_WARN, "worker_bad_event", "job %s: %s", job->id, err.msg);
        return;
    }
    switch (ev.type) {
    case SM_EVENT_PROGRESS:
        smd_jobs_progress(srv, job, &ev, after); /* refused once cancelled */
        break;
    case SM_EVENT_WARNING:
    case SM_EVENT_ALIGNMENT: /* appended to the job's events as they come */
        smd_jobs_warning(srv, job, &ev, after);
        break;
    case SM_EVENT_FINISHED:
        s->have_finished = 1;
        s->finished = ev;
        break;
    case SM_EVENT_FAILED:
        snprintf(s->fail_msg, sizeof s->fail_msg, "%s", ev.message);
        break;
    default:
        break; /* lifecycle events are the daemon's */
    }
}

static void read_pipe(smd_pool *p, slot *s, smd_jobs_after *after)
{
    char buf[65536];
    for (int rounds = 0; rounds < 16; rounds++) { /* bounded: others need service too */
        ssize_t n = read(s->pipe_fd, buf, sizeof buf);
        if (n < 0 && errno == EINTR)
            continue;
        if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK))
            return;
        if (n <= 0) {
            close(s->pipe_fd);
            s->pipe_fd = -1;
            s->line_len = 0; /* a torn last line (killed mid-write) is dropped */
            return;
        }
        size_t start = 0;
        for (size_t i = 0; i < (size_t)n; i++) {
            if (buf[i] != '\n')
                continue;
            size_t part = i - start;
            if (s->line_overflow) {
                s->line_overflow = 0;
            } else if (s->line_len > 0) {
                if (s->line_len + part <= LINE_MAX_BYTES) {
                    memcpy(s->line + s->line_len, buf + start, part);
                    handle_line(p, s, s->line, s->line_len + part, after);
                }
            } else if (part <= LINE_MAX_BYTES) {
                handle_line(p, s, buf + start, part, after);
            }
            s->line_len = 0;
            start = i + 1;
        }
        size_t rest = (size_t)n - start;
        if (rest > 0 && !s->line_overflow) {
            if (s->line_len + rest > LINE_MAX_BYTES) {
                smd_logf(&p->srv->log, SMD_LOG_WARN, "worker_bad_event",
                         "job %s: event line longer than %d bytes dropped", s->job->id,
                         LINE_MAX_BYTES);
                s->line_overflow = 1;
                s->line_len = 0;
            } else {
                memcpy(s->line + s->line_len, buf + start, rest);
                s->line_len += rest;
            }
        }
    }
}

static void try_reap(slot *s)
{
    if (s->exited || s->pid <= 0)
        return;
    int status;
    struct rusage ru;
    pid_t r = wait4(s->pid, &status, WNOHANG, &ru);
    if (r == s->pid) {
        s->exited = 1;
        s->wstatus = status;
        s->cpu_seconds = (double)ru.ru_utime.tv_sec + 1e-6 * (double)ru.ru_utime.tv_usec +
                         (double)ru.ru_stime.tv_sec + 1e-6 * (double)ru.ru_stime.tv_usec;
        if (s->pidfd >= 0) {
            close(s->pidfd);
            s->pidfd = -1;
        }
        /* anything the worker left behind in its group goes too (the group
         * id stays reserved while members exist, so this hits no one else) */
        kill(-s->pid, SIGKILL);
    } else if (r < 0 && errno == ECHILD) {
        s->exited = 1; /* cannot happen unless someone reaped it for us */
        s->wstatus = 0xff00;
    }
}

/* The reason a run ended without a result, in words. */
static void failure_reason(smd_pool *p, slot *s, char *msg, size_t cap)
{
    const smd_config *cfg = &p->srv->cfg;
    char how[128];
    smd_describe_wait_status(s->wstatus, how, sizeof how);
    if (s->stop == STOP_TIMEOUT) {
        snprintf(msg, cap, "exceeded the wall-time limit of %g s (--job-timeout); worker %s",
                 cfg->job_timeout, how);
        return;
    }
    if (WIFSIGNALED(s->wstatus)) {
        int sig = WTERMSIG(s->wstatus);
        if (cfg->cpu_limit > 0 &&
            (sig == SIGXCPU || (sig == SIGKILL && s->cpu_seconds >= cfg->cpu_limit))) {
            snprintf(msg, cap, "exceeded the CPU limit of %g s (--cpu-limit); worker %s",
                     cfg->cpu_limit, how);
            return;
        }
        snprintf(msg, cap, "worker %s", how);
        return;
    }
    int code = WIFEXITED(s->wstatus) ? WEXITSTATUS(s->wstatus) : -1;
    if (s->fail_msg[0]) {
        if (code == SMD_WORKER_EXIT_NOMEM && cfg->memory_limit > 0)
            smd_textf(msg, cap, "%s (memory limit %llu bytes, --memory-limit)", s->fail_msg,
                     (unsigned long long)cfg->memory_limit);
        else
            smd_textf(msg, cap, "%s", s->fail_msg);
        return;
    }
    if (code == SMD_WORKER_EXIT_EXEC)
        smd_textf(msg, cap, "cannot execute the worker program %s (exit status 127)",
                 cfg->worker_path);
    else if (code == 0)
        snprintf(msg, cap, "worker exited without a result");
    else
        snprintf(msg, cap, "worker %s without a reason (see worker.log)", how);
}

/* Lock held: stop requests (cancel, wall time, shutdown) get SIGTERM to
 * the worker's group, and SIGKILL --kill-grace seconds later. */
static void apply_limits(smd_pool *p, slot *s, double now)
{
    smd_server *srv = p->srv;
    if (s->stop == STOP_NONE) {
        if (s->job->cancel_requested)
            s->stop = STOP_CANCEL;
        else if (s->deadline_mono > 0 && now >= s->deadline_mono)
            s->stop = STOP_TIMEOUT;
        else if (p->quit && now >= p->grace_deadline)
            s->stop = STOP_SHUTDOWN;
        if (s->stop != STOP_NONE) {
            smd_logf(&srv->log, SMD_LOG_INFO, "worker_stop", "job %s: SIGTERM to worker %d (%s)",
                     s->job->id, (int)s->pid,
                     s->stop == STOP_CANCEL    ? "cancel"
                     : s->stop == STOP_TIMEOUT ? "wall-time limit"
                                               : "shutdown");
            signal_group(s, SIGTERM);
            s->kill_at_mono = now + srv->cfg.kill_grace;
        }
    }
    if (s->kill_at_mono > 0 && now >= s->kill_at_mono && !s->exited) {
        smd_logf(&srv->log, SMD_LOG_WARN, "worker_kill",
                 "job %s: worker %d still running %g s after SIGTERM: SIGKILL", s->job->id,
                 (int)s->pid, srv->cfg.kill_grace);
        signal_group(s, SIGKILL);
        s->kill_at_mono = 0;
    }
}

/* Lock held: the worker of s is gone (pipe closed and reaped): the job's
 * state follows from how it ended. */
static void finish(smd_pool *p, slot *s, smd_jobs_after *after)
{
    smd_server *srv = p->srv;
    smd_job *job = s->job;
    json_t *f = json_pack("{s:i,s:f,s:f}", "pid", (int)s->pid, "cpu_seconds", s->cpu_seconds,
                          "wall_seconds", sm_clock_seconds() - s->started_mono);
    if (s->stop == STOP_SHUTDOWN && job->state == SM_JOB_RUNNING) {
        smd_jobs_requeue(srv, job, f);
    } else if (job->state == SM_JOB_DISMISSED) {
        smd_jobs_cancelled(srv, job, f, after);
    } else if (s->stop == STOP_NONE && WIFEXITED(s->wstatus) && WEXITSTATUS(s->wstatus) == 0 &&
               s->have_finished) {
        smd_jobs_finish(srv, job, &s->finished, f, after);
    } else {
        char why[SM_EVENT_MESSAGE_MAX];
        failure_reason(p, s, why, sizeof why);
        smd_jobs_fail(srv, job, why, f, after);
    }
    smd_jobs_worker_gone(srv, job, after);
    if (s->pipe_fd >= 0)
        close(s->pipe_fd);
    if (s->pidfd >= 0)
        close(s->pidfd);
    s->pipe_fd = s->pidfd = -1;
    s->pid = 0;
    s->job = NULL;
    p->busy--;
    smd_job_unref(job);
}

/* Lock held: deletes jobs whose retention ran out. */
static void sweep_retention(smd_pool *p, smd_jobs_after *after)
{
    smd_server *srv = p->srv;
    if (srv->cfg.retention <= 0)
        return;
    double now = sm_time_now();
    for (size_t i = 0; i < smd_store_count(srv->store);) {
        smd_job *job = smd_store_at(srv->store, i);
        if (!smd_job_state_final(job->state) || job->worker_active || job->finished < 0 ||
            now - job->finished < srv->cfg.retention) {
            i++;
            continue;
        }
        if (smd_jobs_expire(srv, job, after) != SM_OK)
            i++; /* the spool refused: kept, tried again next round */
        /* else it shifted the list: do not advance i */
    }
}

/* ----------------------------------------------------------- the loop */

/* What the supervisor waits on: the wake-up eventfd first, then the
 * pipes and pidfds of the running workers (owner: their slots). */
typedef struct poll_set {
    struct pollfd *fds;
    slot **owner;
    size_t n, cap;
} poll_set;

static void poll_add(poll_set *ps, int fd, slot *owner)
{
    ps->fds[ps->n] = (struct pollfd){.fd = fd, .events = POLLIN};
    ps->owner[ps->n++] = owner;
}

/* The nearest deadline of a running slot still to act on (a passed one is
 * acted on in this round and must not turn the wait into a spin). */
static double slot_wait(const smd_pool *p, const slot *s, double now, double wait)
{
    if (s->stop == STOP_NONE && s->deadline_mono > 0 && s->deadline_mono - now < wait)
        wait = s->deadline_mono - now;
    if (s->kill_at_mono > 0 && s->kill_at_mono - now < wait)
        wait = s->kill_at_mono - now;
    if (s->stop == STOP_NONE && p->quit && p->grace_deadline - now < wait)
        wait = p->grace_deadline - now;
    return wait;
}

/* Lock held: fills ps and returns the poll timeout in milliseconds. */
static int prepare_poll(smd_pool *p, poll_set *ps)
{
    ps->n = 0;
    poll_add(ps, p->wake_fd, NULL);
    double now = sm_clock_seconds();
    double wait = p->next_tick - now;
    if (atomic_load(&p->srv->unwritable) && p->next_save_retry - now < wait)
        wait = p->next_save_retry - now; /* retry the refused writes each second */
    int need_reap_poll = 0;
    for (size_t i = 0; i < p->nslots; i++) {
        slot *s = &p->slots[i];
        if (!s->job)
            continue;
        if (s->pipe_fd >= 0)
            poll_add(ps, s->pipe_fd, s);
        if (!s->exited && s->pidfd >= 0)
            poll_add(ps, s->pidfd, s);
        else if (!s->exited)
            need_reap_poll = 1; /* no pidfd: poll for the exit */
        wait = slot_wait(p, s, now, wait);
    }
    if (need_reap_poll && wait > 0.05)
        wait = 0.05;
    return wait <= 0 ? 0 : (int)ceil(wait * 1000);
}

/* Lock NOT held: waits; returns poll's result. */
static int wait_events(smd_pool *p, poll_set *ps, int timeout_ms)
{
    int rc = poll(ps->fds, ps->n, timeout_ms);
    if (rc < 0 && errno != EINTR) {
        smd_logf(&p->srv->log, SMD_LOG_ERROR, "supervisor_error", "poll: %s", strerror(errno));
        usleep(100000);
    }
    if (rc > 0 && (ps->fds[0].revents & POLLIN)) {
        uint64_t v;
        ssize_t n = read(p->wake_fd, &v, sizeof v);
        (void)n;
    }
    return rc;
}

/* Lock held: reads the pipes and reaps the workers that poll reported. */
static void service_fds(smd_pool *p, const poll_set *ps, int rc, smd_jobs_after *after)
{
    for (size_t k = 1; rc > 0 && k < ps->n; k++) {
        slot *s = ps->owner[k];
        if (!ps->fds[k].revents || !s->job)
            continue;
        if (ps->fds[k].fd == s->pipe_fd)
            read_pipe(p, s, after);
        else if (ps->fds[k].fd == s->pidfd)
            try_reap(s);
    }
}

/* Lock held: ends the runs whose worker is gone, applies the limits to
 * the others. */
static void service_slots(smd_pool *p, double now, smd_jobs_after *after)
{
    for (size_t i = 0; i < p->nslots; i++) {
        slot *s = &p->slots[i];
        if (!s->job)
            continue;
        if (!s->exited && (s->pidfd < 0 || s->pipe_fd < 0))
            try_reap(s);
        if (s->exited && s->pipe_fd >= 0) {
            /* the worker is gone: take what is left in the pipe and close
             * it without waiting for EOF (a helper it started may still
             * hold the write end; the group was killed in try_reap) */
            read_pipe(p, s, after);
            if (s->pipe_fd >= 0) {
                close(s->pipe_fd);
                s->pipe_fd = -1;
                s->line_len = 0;
            }
        }
        if (s->exited && s->pipe_fd < 0) {
            finish(p, s, after);
            continue;
        }
        apply_limits(p, s, now);
    }
}

/* Lock held: held ends retried, the keepalive tick, the retention sweep. */
static void periodic(smd_pool *p, double now, smd_jobs_after *after)
{
    smd_server *srv = p->srv;
    if (now >= p->next_save_retry) {
        p->next_save_retry = now + 1.0;
        smd_jobs_retry_saves(srv, after);
    }
    if (now >= p->next_tick) {
        p->next_tick = now + p->tick;
        smd_jobs_after_tick(srv, after);
    }
    if (now >= p->next_sweep) {
        /* often enough that a job outlives its retention by at most half
         * of it (and by 5 s at most) */
        double every = srv->cfg.retention / 2;
        p->next_sweep = now + (every < 0.5                       ? 0.5
                               : every > RETENTION_SWEEP_SECONDS ? RETENTION_SWEEP_SECONDS
                                                                 : every);
        sweep_retention(p, after);
    }
}

static void *supervise(void *arg)
{
    smd_pool *p = arg;
    smd_server *srv = p->srv;
    smd_jobs_after after = {0};
    poll_set ps = {0};
    ps.cap = 1 + 2 * p->nslots;
    ps.fds = calloc(ps.cap, sizeof *ps.fds);
    ps.owner = calloc(ps.cap, sizeof *ps.owner);
    if (!ps.fds || !ps.owner) {
        smd_logf(&srv->log, SMD_LOG_ERROR, "supervisor_error", "out of memory");
        free(ps.fds);
        free(ps.owner);
        return NULL;
    }
    for (;;) {
        pthread_mutex_lock(&srv->lock);
        int timeout_ms = prepare_poll(p, &ps);
        int done = p->quit && p->busy == 0;
        pthread_mutex_unlock(&srv->lock);
        if (done)
            break;
        int rc = wait_events(p, &ps, timeout_ms);

        pthread_mutex_lock(&srv->lock);
        double now = sm_clock_seconds();
        service_fds(p, &ps, rc, &after);
        service_slots(p, now, &after);
        while (!p->quit && !atomic_load(&srv->draining) && !atomic_load(&srv->unwritable) &&
               start_next(p, &after)) {
        }
        periodic(p, now, &after);
        after.wake_pool = 0; /* the pool is awake: no wake-up needed */
        pthread_mutex_unlock(&srv->lock);
        smd_jobs_after_run(&after);
    }
    smd_jobs_after_free(&after);
    free(ps.fds);
    free(ps.owner);
    return NULL;
}

/* ------------------------------------------------------------ lifecycle */

/* The daemon's environment with the thread counts of the numerical
 * libraries set (unless the operator set them): N workers each running
 * cores-many OpenMP/BLAS threads would oversubscribe the machine. */
static int build_env(smd_pool *p)
{
    extern char **environ;
    const smd_config *cfg = &p->srv->cfg;
    long cores = sysconf(_SC_NPROCESSORS_ONLN);
    int threads = cfg->worker_threads > 0 ? cfg->worker_threads
                                          : (int)(cores / cfg->workers > 1 ? cores / cfg->workers : 1);
    size_t n = 0;
    while (environ && environ[n])
        n++;
    p->env = calloc(n + 3, sizeof *p->env);
    if (!p->env)
        return -1;
    size_t k = 0;
    for (size_t i = 0; i < n; i++)
        p->env[k++] = environ[i];
    static const char *const names[2] = {"OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS"};
    for (int i = 0; i < 2; i++) {
        if (getenv(names[i]))
            continue; /* the operator's choice wins */
        if (asprintf(&p->env_threads[i], "%s=%d", names[i], threads) < 0) {
            p->env_threads[i] = NULL;
            return -1;
        }
        p->env[k++] = p->env_threads[i];
    }
    return 0;
}

sm_status smd_pool_start(smd_server *srv, sm_error *err)
{
    smd_pool *p = calloc(1, sizeof *p);
    if (!p)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    p->srv = srv;
    p->nslots = (size_t)srv->cfg.workers;
    p->daemon_pid = getpid();
    p->slots = calloc(p->nslots, sizeof *p->slots);
    p->wake_fd = eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);
    if (!p->slots || p->wake_fd < 0 || build_env(p) != 0) {
        sm_status st = sm_error_set(err, SM_ERR_NOMEM, "worker pool: %s",
                                    p->wake_fd < 0 ? strerror(errno) : "out of memory");
        smd_pool_free(p);
        return st;
    }
    for (size_t i = 0; i < p->nslots; i++) {
        p->slots[i].pipe_fd = p->slots[i].pidfd = -1;
        p->slots[i].line = malloc(LINE_MAX_BYTES);
        if (!p->slots[i].line) {
            smd_pool_free(p);
            return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
        }
    }
    /* keepalives are due every --keepalive seconds: tick at least twice
     * as often */
    p->tick = srv->cfg.keepalive / 2 < TICK_SECONDS ? srv->cfg.keepalive / 2 : TICK_SECONDS;
    p->next_tick = sm_clock_seconds() + p->tick;
    p->next_sweep = sm_clock_seconds();
    srv->pool = p;
    int rc = pthread_create(&p->thread, NULL, supervise, p);
    if (rc != 0) {
        srv->pool = NULL;
        smd_pool_free(p);
        return sm_error_set(err, SM_ERR_NOMEM, "cannot start the supervisor thread: %s",
                            strerror(rc));
    }
    p->thread_started = 1;
    smd_pool_wake(p); /* jobs recovered from the spool start at once */
    return SM_OK;
}

void smd_pool_stop(smd_server *srv, double grace)
{
    smd_pool *p = srv->pool;
    if (!p || !p->thread_started)
        return;
    pthread_mutex_lock(&srv->lock);
    if (!p->quit) {
        p->quit = 1;
        p->grace_deadline = sm_clock_seconds() + grace;
    }
    pthread_mutex_unlock(&srv->lock);
    smd_pool_wake(p);
    pthread_join(p->thread, NULL);
    p->thread_started = 0;
}

void smd_pool_hurry(smd_pool *p)
{
    pthread_mutex_lock(&p->srv->lock);
    p->grace_deadline = 0;
    pthread_mutex_unlock(&p->srv->lock);
    smd_pool_wake(p);
}

void smd_pool_free(smd_pool *p)
{
    if (!p)
        return;
    for (size_t i = 0; p->slots && i < p->nslots; i++)
        free(p->slots[i].line);
    free(p->slots);
    free(p->env);
    free(p->env_threads[0]);
    free(p->env_threads[1]);
    if (p->wake_fd >= 0)
        close(p->wake_fd);
    free(p);
}
