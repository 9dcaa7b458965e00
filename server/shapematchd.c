/* shapematchd: the HTTP job daemon of shapematch.
 *
 * main: configuration, the spool (with crash recovery), the worker pool,
 * the HTTP front, then it waits for SIGTERM/SIGINT and stops gracefully:
 * no new job (503, /readyz 503); running jobs get --shutdown-grace to
 * finish, then are stopped and stay queued for the next start; then no
 * new connection, event streams end, everything is freed.  A second signal cuts the grace.
 * Signals are blocked in every thread we start and taken by the main
 * thread with sigwaitinfo/sigtimedwait.  Threads that libraries start
 * before main (OpenBLAS, pulled in by CHOLMOD) do not block them, so a
 * tiny handler forwards a signal that lands there to the main thread. */
#include <errno.h>
#include <limits.h>
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include "sm_proto_events.h"
#include "http/smd_auth.h"
#include "http/smd_http.h"
#include "jobs/smd_jobs.h"
#include "store/pg/smd_pg_node.h"
#include "jobs/smd_spool_backend.h"
#include "jobs/smd_pool.h"
#include "api/smd_route_table.h"
#include "base/smd_server.h"
#include "api/smd_stream.h"
#include "jobs/smd_follow.h"
#include "http/smd_tls.h"

/* The one global: the main thread's id, written once before the handler
 * is installed. */
static pid_t main_tid;

static void forward_signal(int sig)
{
    int saved = errno;
    syscall(SYS_tgkill, getpid(), main_tid, sig); /* pending there until taken */
    errno = saved;
}

static const char *env_lookup(const char *name, void *user)
{
    (void)user;
    return getenv(name);
}

/* shapematch-worker next to this executable. */
static int default_worker_path(char *out, size_t cap)
{
    char self[PATH_MAX];
    ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
    if (n <= 0)
        return -1;
    self[n] = '\0';
    char *slash = strrchr(self, '/');
    if (!slash)
        return -1;
    *slash = '\0';
    return smd_pathf(out, cap, "%s/shapematch-worker", self);
}

/* Event streams and uploads hold descriptors: use what the system allows. */
static void raise_fd_limit(smd_server *srv)
{
    struct rlimit rl;
    if (getrlimit(RLIMIT_NOFILE, &rl) != 0)
        return;
    rlim_t want = rl.rlim_max == RLIM_INFINITY ? 65536 : rl.rlim_max;
    if (want > 65536)
        want = 65536;
    if (rl.rlim_cur < want) {
        rl.rlim_cur = want;
        setrlimit(RLIMIT_NOFILE, &rl);
        getrlimit(RLIMIT_NOFILE, &rl);
    }
    if ((rlim_t)srv->cfg.max_connections + 64 > rl.rlim_cur)
        smd_logf(&srv->log, SMD_LOG_WARN, "config",
                 "--max-connections %u is close to the descriptor limit %llu",
                 srv->cfg.max_connections, (unsigned long long)rl.rlim_cur);
}

typedef struct stopper {
    smd_server *srv;
    volatile int done;
} stopper;

static void *stop_pool(void *arg)
{
    stopper *s = arg;
    smd_pool_stop(s->srv, s->srv->cfg.shutdown_grace);
    __atomic_store_n(&s->done, 1, __ATOMIC_RELEASE);
    return NULL;
}

static void shutdown_daemon(smd_server *srv, const sigset_t *signals)
{
    /* Keep listening while running jobs finish: clients can still follow
     * them and fetch results, /readyz says 503 (a balancer stops sending
     * work here) and new jobs get 503 with Retry-After. */
    atomic_store(&srv->draining, 1);
    pthread_mutex_lock(&srv->lock);
    size_t busy = smd_pool_busy(srv->pool);
    pthread_mutex_unlock(&srv->lock);
    smd_log(&srv->log, SMD_LOG_INFO, "shutting_down",
            json_pack("{s:I,s:f}", "running_jobs", (json_int_t)busy, "grace_seconds",
                      srv->cfg.shutdown_grace));
    stopper st = {srv, 0};
    pthread_t thread;
    if (pthread_create(&thread, NULL, stop_pool, &st) != 0) {
        smd_pool_hurry(srv->pool);
        stop_pool(&st);
    } else {
        struct timespec tick = {0, 100 * 1000 * 1000};
        while (!__atomic_load_n(&st.done, __ATOMIC_ACQUIRE)) {
            int sig = sigtimedwait(signals, NULL, &tick);
            if (sig == SIGTERM || sig == SIGINT) {
                smd_logf(&srv->log, SMD_LOG_WARN, "shutting_down",
                         "second signal: stopping running jobs now");
                smd_pool_hurry(srv->pool);
            }
        }
        pthread_join(thread, NULL);
    }
    smd_http_quiesce(srv);
    /* end the event streams: they must all be resumed before MHD stops */
    atomic_store(&srv->stopping, 1);
    smd_follow_end_all(srv);
    smd_http_stop(srv);
    smd_follow_free_all(srv);
}

/* Step 1: flags, environment, the worker program, the tokens.  Returns
 * -1 to go on, or the exit code (0 for --help / --version, 2 for a bad
 * configuration). */
static int configure(smd_server *srv, int argc, char **argv)
{
    char msg[512];
    switch (smd_config_parse(&srv->cfg, argc, argv, env_lookup, NULL, msg, sizeof msg)) {
    case SMD_CONFIG_HELP:
        smd_config_help(stdout);
        return 0;
    case SMD_CONFIG_VERSION:
        printf("shapematchd %s\n", SM_VERSION);
        return 0;
    case SMD_CONFIG_ERROR:
        fprintf(stderr, "shapematchd: %s\n", msg);
        return 2;
    case SMD_CONFIG_OK:
        break;
    }
    srv->log.fd = 2;
    srv->log.level = (smd_log_level)srv->cfg.log_level;
    srv->start_time = sm_time_now();
    if (!srv->cfg.worker_path[0] &&
        default_worker_path(srv->cfg.worker_path, sizeof srv->cfg.worker_path) != 0) {
        smd_logf(&srv->log, SMD_LOG_ERROR, "config", "cannot locate shapematch-worker: use --worker");
        return 2;
    }
    if (access(srv->cfg.worker_path, X_OK) != 0) {
        smd_logf(&srv->log, SMD_LOG_ERROR, "config", "worker program %s: %s (--worker)",
                 srv->cfg.worker_path, strerror(errno));
        return 2;
    }
    if (srv->cfg.tokens_file[0] &&
        smd_tokens_load(srv->cfg.tokens_file, &srv->tokens, msg, sizeof msg) != 0) {
        smd_logf(&srv->log, SMD_LOG_ERROR, "config", "--tokens-file %s", msg);
        return 2;
    }
    if (srv->cfg.tls_cert[0] && smd_tls_load(srv->cfg.tls_cert, srv->cfg.tls_key, msg, sizeof msg) != 0) {
        smd_logf(&srv->log, SMD_LOG_ERROR, "config", "--tls-cert/--tls-key: %s", msg);
        return 2;
    }
#if defined(__SANITIZE_ADDRESS__)
    if (srv->cfg.memory_limit > 0)
        smd_logf(&srv->log, SMD_LOG_WARN, "config",
                 "ASan build: the worker memory limit (RLIMIT_AS) is not applied");
#endif
    return -1;
}

/* Step 2: every thread inherits the blocked mask; signals are taken with
 * sigwaitinfo / sigtimedwait by the main thread. */
static void take_signals(sigset_t *signals)
{
    sigemptyset(signals);
    sigaddset(signals, SIGTERM);
    sigaddset(signals, SIGINT);
    sigaddset(signals, SIGHUP);
    pthread_sigmask(SIG_BLOCK, signals, NULL);
    main_tid = gettid();
    struct sigaction fwd;
    memset(&fwd, 0, sizeof fwd);
    fwd.sa_handler = forward_signal;
    sigfillset(&fwd.sa_mask);
    fwd.sa_flags = SA_RESTART;
    sigaction(SIGTERM, &fwd, NULL);
    sigaction(SIGINT, &fwd, NULL);
    sigaction(SIGHUP, &fwd, NULL);
    struct sigaction ign;
    memset(&ign, 0, sizeof ign);
    ign.sa_handler = SIG_IGN;
    sigaction(SIGPIPE, &ign, NULL);
}

/* Step 3: the backend (the spool and its queue, PostgreSQL stacked on
 * them with --database) and the recovery of interrupted jobs, the worker
 * pool, the HTTP front.  0, or -1 (logged). */
static int start_parts(smd_server *srv, size_t *queued)
{
    sm_error err;
    sm_error_clear(&err);
    if (smd_store_open(srv->cfg.spool, &srv->log, &srv->store, &err) != SM_OK) {
        smd_logf(&srv->log, SMD_LOG_ERROR, "startup", "spool: %s", err.msg);
        return -1;
    }
    srv->queue = smd_queue_local_new();
    srv->backend = malloc(sizeof *srv->backend);
    if (!srv->queue || !srv->backend) {
        smd_logf(&srv->log, SMD_LOG_ERROR, "startup", "out of memory");
        return -1;
    }
    /* the spool's backend; --database stacks PostgreSQL's on it */
    smd_spool_backend_init(srv->backend, srv->store, srv->queue);
    if (srv->cfg.database[0] && smd_pg_node_open(srv, &err) != SM_OK) {
        smd_logf(&srv->log, SMD_LOG_ERROR, "startup", "%s (--database)", err.msg);
        return -1;
    }
    if (smd_jobs_recover(srv, queued, &err) != SM_OK) {
        smd_logf(&srv->log, SMD_LOG_ERROR, "startup", "%s", err.msg);
        return -1;
    }
    if (smd_pool_start(srv, &err) != SM_OK) {
        smd_logf(&srv->log, SMD_LOG_ERROR, "startup", "%s", err.msg);
        return -1;
    }
    if (srv->cluster && smd_pg_node_run(srv, &err) != SM_OK) {
        smd_logf(&srv->log, SMD_LOG_ERROR, "startup", "%s", err.msg);
        smd_pool_stop(srv, 0);
        return -1;
    }
    if (smd_http_start(srv, &smd_api, &err) != SM_OK) {
        smd_logf(&srv->log, SMD_LOG_ERROR, "startup", "%s", err.msg);
        smd_pool_stop(srv, 0);
        smd_pg_node_stop(srv);
        return -1;
    }
    smd_log(&srv->log, SMD_LOG_INFO, "listening",
            json_pack("{s:s,s:i,s:s,s:i,s:i,s:I,s:I,s:b,s:s,s:s}", "address", srv->cfg.listen_host,
                      "port", (int)srv->port, "spool", srv->cfg.spool, "workers", srv->cfg.workers,
                      "http_threads", srv->cfg.http_threads, "jobs",
                      (json_int_t)smd_store_count(srv->store), "queued", (json_int_t)*queued, "auth",
                      srv->tokens != NULL, "worker", srv->cfg.worker_path, "version", SM_VERSION));
    return 0;
}

/* SIGHUP, TLS part: the next handshakes use the new pair. */
static void reload_tls(smd_server *srv)
{
    char msg[512];
    if (!srv->cfg.tls_cert[0])
        return;
    if (smd_tls_load(srv->cfg.tls_cert, srv->cfg.tls_key, msg, sizeof msg) != 0)
        smd_logf(&srv->log, SMD_LOG_ERROR, "reload", "SIGHUP: %s; the certificate in use is kept",
                 msg);
    else
        smd_log(&srv->log, SMD_LOG_INFO, "tls_reloaded",
                json_pack("{s:s,s:s}", "cert", srv->cfg.tls_cert, "key", srv->cfg.tls_key));
}

/* SIGHUP: the tokens file again (a daemon started without one stays
 * open); a file that does not load keeps the tokens in use. */
static void reload(smd_server *srv)
{
    reload_tls(srv);
    if (!srv->cfg.tokens_file[0]) {
        smd_logf(&srv->log, SMD_LOG_INFO, "reload", "SIGHUP: no --tokens-file, nothing to reload");
        return;
    }
    char msg[512];
    smd_tokens *fresh;
    if (smd_tokens_load(srv->cfg.tokens_file, &fresh, msg, sizeof msg) != 0) {
        smd_logf(&srv->log, SMD_LOG_ERROR, "reload", "SIGHUP: --tokens-file %s; the tokens in use are kept",
                 msg);
        return;
    }
    pthread_mutex_lock(&srv->tokens_lock);
    smd_tokens *old = srv->tokens;
    srv->tokens = fresh;
    pthread_mutex_unlock(&srv->tokens_lock);
    smd_tokens_free(old);
    smd_stream_revoke(srv); /* a removed token's open streams end now */
    smd_log(&srv->log, SMD_LOG_INFO, "tokens_reloaded",
            json_pack("{s:s,s:I}", "file", srv->cfg.tokens_file, "tokens",
                      (json_int_t)smd_tokens_count(fresh)));
}

/* Step 4: serve until SIGTERM or SIGINT. */
static void wait_for_stop(smd_server *srv, const sigset_t *signals)
{
    for (;;) {
        int sig = sigwaitinfo(signals, NULL);
        if (sig == SIGTERM || sig == SIGINT) {
            smd_logf(&srv->log, SMD_LOG_INFO, "signal", "%s: shutting down",
                     sig == SIGTERM ? "SIGTERM" : "SIGINT");
            return;
        }
        if (sig == SIGHUP)
            reload(srv);
    }
}

int main(int argc, char **argv)
{
    smd_server *srv = calloc(1, sizeof *srv);
    if (!srv) {
        fprintf(stderr, "shapematchd: out of memory\n");
        return 1;
    }
    int code = configure(srv, argc, argv);
    if (code >= 0) {
        smd_tokens_free(srv->tokens);
        free(srv);
        return code;
    }
    code = 1;
    /* the engine names the jobs that changed; the event streams wake
     * their followers (before any thread runs the engine) */
    srv->jobs_changed = smd_follow_jobs_changed;
    srv->work_queued = smd_pool_work_queued; /* the supervisor starts what was queued */
    sigset_t signals;
    take_signals(&signals);
    raise_fd_limit(srv);

    const char *route_labels[64]; /* outlives the metrics: main's frame */
    size_t nlabels = smd_route_labels(route_labels, sizeof route_labels / sizeof route_labels[0]);
    int metrics_ok = smd_metrics_init(&srv->metrics, route_labels, nlabels) == 0;
    int lock_ok = pthread_mutex_init(&srv->lock, NULL) == 0 &&
                  pthread_mutex_init(&srv->tokens_lock, NULL) == 0;
    size_t queued = 0;
    if (!metrics_ok || !lock_ok) {
        smd_logf(&srv->log, SMD_LOG_ERROR, "startup", "cannot initialise locks");
    } else if (start_parts(srv, &queued) == 0) {
        wait_for_stop(srv, &signals);
        shutdown_daemon(srv, &signals);
        code = 0;
    }
    smd_pg_node_stop(srv); /* after the pool: gives back the leases of stopped runs */
    smd_pool_free(srv->pool);
    smd_queue_free(srv->queue);
    smd_store_close(srv->store);
    smd_pg_node_free(srv->cluster);
    free(srv->backend);
    smd_tokens_free(srv->tokens);
    if (lock_ok)
        pthread_mutex_destroy(&srv->lock);
    if (metrics_ok)
        smd_metrics_destroy(&srv->metrics);
    smd_logf(&srv->log, code == 0 ? SMD_LOG_INFO : SMD_LOG_ERROR, "stopped", "shapematchd stopped");
    free(srv);
    return code;
}
