/* A batch of targets on one template, then their shape model (see
 * sm_job_batch.h). */
#include "job/sm_job_batch.h"

#include <errno.h>
#include <jansson.h>
#ifdef __GLIBC__
#include <malloc.h>
#endif
#include <math.h>
#include <omp.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <poll.h>
#include <sched.h>
#include <string.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "job/sm_job_align.h"
#include "job/sm_job_batch_warm.h"
#include "job/sm_job_results.h"
#include "job/sm_job_runner.h"
#include "job/sm_job_threads.h"
#include "shapematch/sm_atomic.h"
#include "shapematch/sm_clock.h"
#include "shapematch/sm_path.h"
#include "sm_json.h"

/* ------------------------------------------------------------- the run */

/* The template side, built once in the parent. */
typedef struct batch_template {
    sm_job_inputs in;
    sm_job_files files;
    char *warm_dir;             /* params warm_start: DIR/.warm, else NULL */
    int jobs;                   /* children at a time: opts jobs, at most the cores */
    int threads;                /* OpenMP/BLAS limit of each child */
    /* backgrounds (target_mesh) that several targets name, read once here:
     * shared[i] is target i's (NULL: its child reads its own), freed
     * through the first target that names it (shared_owner[i] 1) */
    sm_mesh **shared;
    uint8_t *shared_owner;
    size_t nshared;
} batch_template;

/* error.txt in the target's folder: why it failed, for the summary. */
static void write_error_file(const char *dir, const char *msg)
{
    char *path = sm_path_join(dir, "error.txt");
    if (path) {
        sm_atomic_write_file(path, msg, strlen(msg), 0, NULL);
        free(path);
    }
}

/* A child's cancel flag: its SIGINT/SIGTERM handler (installed after the
 * fork, in the child only) sets it and its run polls it between
 * iterations, so a target stops as a cancelled `run` does, with the
 * state reached written.  The one piece of global state here: a signal
 * handler has no other way to reach the run. */
static volatile sig_atomic_t child_cancel;
_Static_assert(_Generic((sig_atomic_t)0, int: 1, default: 0),
               "sig_atomic_t must be int to be polled by the run");

static void on_child_signal(int sig)
{
    (void)sig;
    child_cancel = 1;
}

/* The child's whole life: its target, the run, the result set.  Returns
 * the exit code (sm_job_runner.h). */
static int run_child(batch_template *bt, const sm_batch_target *l0, const sm_batch_target *t,
                     const sm_batch_opts *o, const char *dir)
{
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_child_signal; /* no SA_RESETHAND: the terminal's and
                                      * the parent's SIGINT may both come */
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    if (o->cancel && *o->cancel)
        return SM_JOB_EXIT_CANCELLED;
    sm_job_inputs *in = &bt->in;
    sm_job_files files = bt->files;
    files.target_surface = t->target_surface;
    files.target_image = t->target_image;
    files.target_mesh = t->target_mesh;
    files.target_sol = t->target_sol;
    files.target_mesh_given = bt->shared ? bt->shared[t - l0] : NULL;
    omp_set_num_threads(o->single_thread ? 1 : bt->threads); /* sm_job_threads_apply caps it */
    sm_error err;
    sm_error_clear(&err);
    sm_status st = SM_OK;
    if (t->landmarks) {
        files.landmarks_target = t->landmarks;
        free(in->landmarks[0]), free(in->landmarks[1]);
        in->landmarks[0] = in->landmarks[1] = NULL;
        in->nlandmarks = 0;
        st = sm_job_read_landmarks(&files, in, &err);
        sm_job_landmarks_to_frame(in, in->params.image_space); /* params set already */
    }
    in->read_started = sm_clock_seconds(); /* this target's read (the template's was the parent's) */
    if (st == SM_OK)
        st = sm_job_inputs_read_target(&files, SM_JOB_NAME_PATHS, 0, in, &err);
    if (st != SM_OK) {
        write_error_file(dir, err.msg);
        return SM_JOB_EXIT_INPUT;
    }
    sm_job_run run;
    sm_job_hooks hooks = {.snapshot_dir = dir, .write_flags = SM_ATOMIC_FSYNC,
                          .cancel = (const volatile int *)&child_cancel};
    sm_job_warm warm = {.dir = bt->warm_dir, .name = t->name};
    if (bt->warm_dir) {
        hooks.start = sm_job_warm_choose;
        hooks.user = &warm;
    }
    st = sm_job_run_exec(in, &hooks, &run, &err);
    int code = run.exit_code;
    /* a start for the targets after this one; without it they start
     * from the others (or the template) */
    if (st == SM_OK && bt->warm_dir &&
        (code == SM_JOB_EXIT_OK || code == SM_JOB_EXIT_NOT_CONVERGED) &&
        sm_job_warm_record(&warm, in, &run, &err) != SM_OK)
        fprintf(stderr, "shapematch batch: %s: no warm start kept: %s\n", t->name, err.msg);
    if (st != SM_OK) {
        write_error_file(dir, err.msg);
        code = st == SM_ERR_IO ? SM_JOB_EXIT_OUTPUT : SM_JOB_EXIT_NUMERIC;
    } else if (sm_job_write_selected(in, &run, &files, dir, o->outputs, SM_ATOMIC_FSYNC, &err) !=
               SM_OK) {
        write_error_file(dir, err.msg);
        code = SM_JOB_EXIT_OUTPUT;
    } else if (run.outcome == SM_JOB_OUTCOME_FAILED) {
        write_error_file(dir, run.message);
    }
    sm_job_run_free(&run);
    return code;
}

/* The template read, the parameters set, the template side set up. */
static sm_status build_template(const sm_batch_opts *o, batch_template *bt, sm_error *err)
{
    memset(bt, 0, sizeof *bt);
    bt->files = (sm_job_files){.template_mesh = o->template_mesh,
                               .background_size = o->background_size,
                               .background_padding = o->background_padding,
                               .landmarks_template = o->template_landmarks};
    sm_job_files tf = bt->files;
    tf.landmarks_template = NULL; /* read with each target's */
    sm_status st = sm_job_inputs_read_template(&tf, SM_JOB_NAME_PATHS, &bt->in, err);
    if (st == SM_OK && (st = sm_job_inputs_set_params(&bt->in, o->params, err)) != SM_OK)
        sm_job_inputs_free(&bt->in);
    if (st != SM_OK || bt->in.params.align != SM_ALIGN_NONE)
        return st; /* with align the side is set up on the moved copy */
    sm_match_opts mo = {.template_mesh = bt->in.template_mesh, .prepared = bt->in.prepared,
                        .params = &bt->in.params};
    double t0 = sm_clock_seconds();
    bt->in.match_status = sm_match_new(&mo, &bt->in.match, &bt->in.match_error);
    bt->in.match_seconds = sm_clock_seconds() - t0;
    if (bt->in.match_status != SM_OK) {
        if (err)
            *err = bt->in.match_error;
        st = bt->in.match_status;
        sm_job_inputs_free(&bt->in);
    }
    return st;
}

/* The backgrounds that two targets or more name, read here once: each
 * child then copies its own (sm_mesh_clone, a memcpy) instead of parsing
 * the file again (the 3D example's 345k-tetrahedron background.mesh.gz:
 * about 1 s a target).  One that cannot be read is left to the children,
 * which report it as `run` does. */
static void read_shared_backgrounds(const sm_batch_list *l, batch_template *bt)
{
    bt->shared = calloc(l->n + 1, sizeof *bt->shared);
    uint8_t *owner = calloc(l->n + 1, 1);
    for (size_t i = 0; bt->shared && owner && i < l->n; i++) {
        const char *path = l->t[i].target_mesh;
        if (!path || bt->shared[i])
            continue;
        size_t uses = 0;
        for (size_t j = i; j < l->n; j++)
            uses += l->t[j].target_mesh && strcmp(l->t[j].target_mesh, path) == 0;
        sm_mesh *m = NULL;
        sm_error err;
        if (uses < 2 || sm_mesh_read_limited(path, NULL, &m, &err) != SM_OK)
            continue;
        owner[i] = 1;
        bt->nshared++;
        for (size_t j = i; j < l->n; j++)
            if (l->t[j].target_mesh && strcmp(l->t[j].target_mesh, path) == 0)
                bt->shared[j] = m;
    }
    bt->shared_owner = owner; /* the entries freed at the end */
}

static void free_shared_backgrounds(batch_template *bt, size_t n)
{
    for (size_t i = 0; bt->shared && bt->shared_owner && i < n; i++)
        if (bt->shared_owner[i])
            sm_mesh_free(bt->shared[i]);
    free(bt->shared);
    free(bt->shared_owner);
}

/* Cores this process may run on, counted now (its affinity; the online
 * processors when unknown). */
static int cores_now(void)
{
    cpu_set_t set;
    if (sched_getaffinity(0, sizeof set, &set) == 0 && CPU_COUNT(&set) > 0)
        return CPU_COUNT(&set);
    long n = sysconf(_SC_NPROCESSORS_ONLN);
    return n > 0 ? (int)n : 1;
}

/* The thread policy (children x threads <= the cores counted when the
 * batch starts: no oversubscription) and the warm folder. */
static sm_status plan_children(const sm_batch_opts *o, size_t ntargets, int host_threads,
                               const char *out_dir, batch_template *bt, sm_batch_outcome *out,
                               sm_error *err)
{
    int cores = cores_now();
    int jobs = o->jobs < 1 ? 1 : o->jobs;
    if ((size_t)jobs > ntargets)
        jobs = ntargets > 0 ? (int)ntargets : 1;
    if (jobs > cores)
        jobs = cores;
    int threads = cores / jobs;
    if (host_threads >= 1 && threads > host_threads) /* OMP_NUM_THREADS, the daemon's limit */
        threads = host_threads;
    bt->jobs = out->jobs = jobs;
    bt->threads = out->threads = o->single_thread ? 1 : threads;
    out->cores = cores;
    out->warm_start = o->params->warm_start;
    if (!o->params->warm_start)
        return SM_OK;
    if (!(bt->warm_dir = sm_path_join(out_dir, ".warm")))
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    sm_job_warm_clear(bt->warm_dir); /* a stale one, of an earlier batch into out_dir */
    return sm_mkdir_p(bt->warm_dir, err);
}

/* Running targets watched through their pidfds at most (more: the
 * sleep), far beyond any --jobs. */
#define SM_BATCH_JOBS_POLL 256

typedef struct target_state {
    pid_t pid;
    int pidfd;                  /* -1: none (not running, or no pidfd_open) */
    double started, seconds;
    int exit_code;              /* -1: killed or not run */
    const char *status;
    sm_job_warm warm;           /* its start (warm starts on) */
    char message[SM_ERROR_MSG_LEN];
} target_state;

static const char *status_of(int code)
{
    switch (code) {
    case SM_JOB_EXIT_OK: return "finished";
    case SM_JOB_EXIT_NOT_CONVERGED: return "not_converged";
    case SM_JOB_EXIT_CANCELLED: return "cancelled";
    default: return "failed";
    }
}

static void read_error_file(const char *dir, char *msg, size_t cap)
{
    char *path = sm_path_join(dir, "error.txt");
    FILE *f = path ? fopen(path, "r") : NULL;
    size_t n = f ? fread(msg, 1, cap - 1, f) : 0;
    msg[n] = '\0';
    if (f)
        fclose(f);
    free(path);
}

/* A target's process ended (wst its status): its state, and the caller's
 * callback. */
static void target_ended(const sm_batch_list *l, const sm_batch_opts *o, char **dirs,
                         target_state *ts, size_t i, int wst)
{
    ts[i].pid = 0;
    if (ts[i].pidfd >= 0)
        close(ts[i].pidfd);
    ts[i].pidfd = -1;
    ts[i].seconds = sm_clock_seconds() - ts[i].started;
    ts[i].exit_code = WIFEXITED(wst) ? WEXITSTATUS(wst) : -1;
    ts[i].status = status_of(ts[i].exit_code);
    read_error_file(dirs[i], ts[i].message, sizeof ts[i].message);
    if (ts[i].warm.dir)
        sm_job_warm_read_used(ts[i].warm.dir, l->t[i].name, &ts[i].warm);
    if (!WIFEXITED(wst))
        snprintf(ts[i].message, sizeof ts[i].message, "the target's process ended by "
                 "signal %d", WIFSIGNALED(wst) ? WTERMSIG(wst) : 0);
    if (o->target_done)
        o->target_done(i, l->t[i].name, ts[i].status, ts[i].exit_code, ts[i].seconds, o->user);
}

/* Waits up to 20 ms for one of the running targets to end (a pidfd per
 * child where the kernel has them, else a sleep) and reaps those that
 * did, each by its own pid: the host process (a Python interpreter, a
 * program linking libshapematch_job) may have children of its own, whose
 * exit status is not ours to take (libuv's process.c waits the same
 * way).  The bounded wait keeps a cancel seen within 20 ms.  Returns the
 * targets that ended, or -1 with err set. */
static long reap_targets(const sm_batch_list *l, const sm_batch_opts *o, char **dirs,
                         target_state *ts, sm_error *err)
{
    struct pollfd fds[SM_BATCH_JOBS_POLL];
    nfds_t nfds = 0;
    int all_pidfds = 1;
    for (size_t i = 0; i < l->n; i++) {
        if (ts[i].pid <= 0)
            continue;
        if (ts[i].pidfd < 0 || nfds == SM_BATCH_JOBS_POLL)
            all_pidfds = 0;
        else
            fds[nfds++] = (struct pollfd){ts[i].pidfd, POLLIN, 0};
    }
    if (all_pidfds && nfds > 0) {
        if (poll(fds, nfds, 20) < 0 && errno != EINTR)
            return sm_error_set(err, SM_ERR_IO, "waiting for a target: %s", strerror(errno)),
                   -1;
    } else {
        nanosleep(&(struct timespec){.tv_nsec = 20000000}, NULL);
    }
    long ended = 0;
    for (size_t i = 0; i < l->n; i++) {
        if (ts[i].pid <= 0)
            continue;
        int wst;
        pid_t pid = waitpid(ts[i].pid, &wst, WNOHANG);
        if (pid == 0 || (pid < 0 && errno == EINTR))
            continue;
        if (pid < 0) /* ECHILD: someone else reaped it (a SIGCHLD set to SIG_IGN) */
            return sm_error_set(err, SM_ERR_IO, "waiting for target %s: %s", l->t[i].name,
                                strerror(errno)), -1;
        target_ended(l, o, dirs, ts, i, wst);
        ended++;
    }
    return ended;
}

/* Forks the children, at most jobs at a time, and waits for them all. */
static sm_status run_targets(batch_template *bt, const sm_batch_list *l, const sm_batch_opts *o,
                             char **dirs, target_state *ts, sm_error *err)
{
    size_t next = 0, running = 0;
    int told = 0;
    fflush(NULL); /* no buffered output duplicated in the children */
    while (next < l->n || running > 0) {
        if (o->cancel && *o->cancel && !told) {
            /* cancelled: no new target, the running ones told (a Ctrl-C
             * reached them already; a signal to this process alone did
             * not) */
            told = 1;
            next = l->n;
            for (size_t i = 0; i < l->n; i++)
                if (ts[i].pid > 0)
                    kill(ts[i].pid, SIGINT);
            if (running == 0)
                break;
        }
        while (next < l->n && running < (size_t)bt->jobs) {
            size_t i = next++;
            ts[i].started = sm_clock_seconds();
            pid_t pid = fork();
            if (pid < 0)
                return sm_error_set(err, SM_ERR_IO, "cannot start a process: %s",
                                    strerror(errno));
            if (pid == 0)
                _exit(run_child(bt, l->t, &l->t[i], o, dirs[i]));
            ts[i].pid = pid;
#ifdef SYS_pidfd_open
            ts[i].pidfd = (int)syscall(SYS_pidfd_open, pid, 0);
#endif
            running++;
        }
        long ended = reap_targets(l, o, dirs, ts, err);
        if (ended < 0)
            return err->code;
        running -= (size_t)ended;
    }
    return SM_OK;
}

static int target_ok(const target_state *t)
{
    return t->exit_code == SM_JOB_EXIT_OK || t->exit_code == SM_JOB_EXIT_NOT_CONVERGED;
}

/* A target's start: the target whose map it started from (null: the
 * template), the records measured, the RMS of the target's distance at
 * the boundary's vertices of the template and of the start taken, and
 * the time the choice took. */
static json_t *start_doc(const sm_job_warm *w)
{
    json_t *d = json_object();
    json_object_set_new(d, "from", w->source[0] ? sm_json_string_lossy(w->source) : json_null());
    json_object_set_new(d, "candidates", json_integer(w->candidates));
    json_object_set_new(d, "template_distance",
                        isfinite(w->score_template) ? json_real(w->score_template) : json_null());
    json_object_set_new(d, "start_distance",
                        isfinite(w->score_start) ? json_real(w->score_start) : json_null());
    json_object_set_new(d, "seconds", isfinite(w->seconds) ? json_real(w->seconds) : json_null());
    return d;
}

static json_t *summary_doc(const sm_batch_list *l, const sm_batch_opts *o,
                           const target_state *ts, const sm_batch_outcome *out)
{
    json_t *targets = json_array(), *failed = json_array();
    for (size_t i = 0; targets && failed && i < l->n; i++) {
        const sm_batch_target *t = &l->t[i];
        json_t *row = json_pack("{s:o, s:s, s:i, s:f, s:o}", "name", sm_json_string_lossy(t->name),
                                "status", ts[i].status, "exit_code", ts[i].exit_code,
                                "seconds", ts[i].seconds, "target",
                                sm_json_string_lossy(t->target_surface ? t->target_surface
                                                     : t->target_image ? t->target_image
                                                                       : t->target_mesh));
        if (row && ts[i].message[0])
            json_object_set_new(row, "message", sm_json_string_lossy(ts[i].message));
        if (row && out->warm_start)
            json_object_set_new(row, "start", start_doc(&ts[i].warm));
        json_array_append_new(targets, row);
        if (!target_ok(&ts[i]))
            json_array_append_new(failed, sm_json_string_lossy(t->name));
    }
    json_t *doc = json_pack("{s:s, s:o, s:i, s:i, s:i, s:o, s:o, s:{s:i, s:f}, "
                            "s:{s:f, s:f, s:f, s:f}}",
                            "shapematch_version", SM_VERSION, "template",
                            sm_json_string_lossy(o->template_mesh), "targets_total", (int)l->n,
                            "targets_ok", (int)out->nok, "jobs", out->jobs, "targets", targets,
                            "failed", failed, "template_setup", "count", out->template_setups,
                            "seconds", out->template_seconds, "timings", "template",
                            out->template_seconds, "targets", out->targets_seconds, "model",
                            out->model_seconds, "total", out->total_seconds);
    if (doc) {
        json_object_set_new(doc, "model", out->model_built ? json_string("model") : json_null());
        json_object_set_new(doc, "cancelled", json_boolean(out->cancelled));
        json_object_set_new(doc, "cores", json_integer(out->cores));
        json_object_set_new(doc, "shared_backgrounds", json_integer(out->shared_backgrounds));
        json_object_set_new(doc, "threads_per_target", json_integer(out->threads));
        json_object_set_new(doc, "warm_start", json_boolean(out->warm_start));
        if (out->model_error[0])
            json_object_set_new(doc, "model_error", sm_json_string_lossy(out->model_error));
    }
    return doc;
}

/* The model of the targets that ended with a result. */
static void build_model(const sm_batch_list *l, const sm_batch_opts *o, char **dirs,
                        const target_state *ts, const char *out_dir, sm_batch_outcome *out)
{
    sm_model_member *mb = calloc(l->n + 1, sizeof *mb);
    char *model_dir = sm_path_join(out_dir, "model");
    size_t n = 0;
    for (size_t i = 0; mb && i < l->n; i++)
        if (target_ok(&ts[i]))
            mb[n++] = (sm_model_member){l->t[i].name, dirs[i]};
    sm_error err;
    sm_error_clear(&err);
    if (!mb || !model_dir)
        snprintf(out->model_error, sizeof out->model_error, "out of memory");
    else if (n == 0)
        snprintf(out->model_error, sizeof out->model_error, "no target ended with a result");
    else if (sm_job_model_build_opts(mb, n, &o->model, model_dir, &err) != SM_OK)
        snprintf(out->model_error, sizeof out->model_error, "%s", err.msg);
    else
        out->model_built = 1;
    free(mb);
    free(model_dir);
}

sm_status sm_job_batch_run(const sm_batch_list *l, const sm_batch_opts *o, const char *out_dir,
                           sm_batch_outcome *out, sm_error *err)
{
    memset(out, 0, sizeof *out);
    double t0 = sm_clock_seconds();
    if (l->n == 0)
        return sm_error_set(err, SM_ERR_INVALID, "no target");
    batch_template bt;
    /* no OpenMP or BLAS pool before fork(): the parent works on one
     * thread, and puts the host's settings back at the end */
    sm_job_threads_saved threads;
    sm_job_threads_single(&threads);
    sm_status st = build_template(o, &bt, err);
    out->template_seconds = sm_clock_seconds() - t0;
    out->template_setups = st == SM_OK && bt.in.match ? 1 : 0;
    if (st == SM_OK)
        st = plan_children(o, l->n, threads.omp, out_dir, &bt, out, err);
    if (st == SM_OK)
        read_shared_backgrounds(l, &bt);
    out->shared_backgrounds = (int)bt.nshared;
    char **dirs = calloc(l->n, sizeof *dirs);
    target_state *ts = calloc(l->n, sizeof *ts);
    if (st == SM_OK && (!dirs || !ts))
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    char *tdir = st == SM_OK ? sm_path_join(out_dir, "targets") : NULL;
    for (size_t i = 0; st == SM_OK && i < l->n; i++) {
        if (!tdir || !(dirs[i] = sm_path_join(tdir, l->t[i].name)))
            st = sm_error_set(err, SM_ERR_NOMEM, "out of memory");
        else
            st = sm_mkdir_p(dirs[i], err);
        ts[i].exit_code = -1;
        ts[i].pidfd = -1;
        ts[i].status = "not_run";
        ts[i].warm.dir = bt.warm_dir;
    }
    double t1 = sm_clock_seconds();
#ifdef __GLIBC__
    /* the heap's free pages given back before the first fork: a child's
     * allocations would reuse them, and its first write to each would
     * copy the parent's page (a copy-on-write fault, which interrupts
     * the child's other threads to flush their TLBs) where a fresh page
     * needs neither (3D example: 4k of a target's 23k copies; the
     * factor's are sm_elasticity.c's unshare_values) */
    malloc_trim(0);
#endif
    if (st == SM_OK)
        st = run_targets(&bt, l, o, dirs, ts, err);
    out->targets_seconds = sm_clock_seconds() - t1;
    for (size_t i = 0; ts && i < l->n; i++)
        if (ts[i].pidfd > 0) /* left by an error */
            close(ts[i].pidfd);
    sm_job_threads_put_back(&threads); /* the model is built with them */
    for (size_t i = 0; st == SM_OK && i < l->n; i++)
        target_ok(&ts[i]) ? out->nok++ : out->nfailed++;
    double t2 = sm_clock_seconds();
    out->cancelled = o->cancel && *o->cancel;
    if (st == SM_OK && o->build_model && out->cancelled)
        snprintf(out->model_error, sizeof out->model_error, "the batch was cancelled");
    else if (st == SM_OK && o->build_model)
        build_model(l, o, dirs, ts, out_dir, out);
    out->model_seconds = sm_clock_seconds() - t2;
    out->total_seconds = sm_clock_seconds() - t0;
    if (st == SM_OK) {
        json_t *doc = summary_doc(l, o, ts, out);
        st = sm_job_write_json(out_dir, "summary.json", doc, SM_ATOMIC_FSYNC, err);
        json_decref(doc);
    }
    for (size_t i = 0; dirs && i < l->n; i++)
        free(dirs[i]);
    free(dirs);
    free(ts);
    free(tdir);
    if (bt.warm_dir)
        sm_job_warm_clear(bt.warm_dir);
    free(bt.warm_dir);
    free_shared_backgrounds(&bt, l->n);
    if (out->template_setups || bt.in.template_mesh)
        sm_job_inputs_free(&bt.in);
    return st;
}

sm_status sm_job_batch_remodel(const char *batch_dir, const sm_model_opts *opts, size_t *members,
                               sm_error *err)
{
    char *path = sm_path_join(batch_dir, "summary.json");
    json_error_t je;
    json_t *doc = path ? json_load_file(path, 0, &je) : NULL;
    json_t *targets = doc ? json_object_get(doc, "targets") : NULL;
    sm_status st = SM_OK;
    if (!path)
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    else if (!doc)
        st = sm_error_set(err, SM_ERR_IO, "%s: %s", path, je.text);
    else if (!json_is_array(targets))
        st = sm_error_set(err, SM_ERR_FORMAT, "%s: no \"targets\" array", path);
    size_t n = targets ? json_array_size(targets) : 0, k = 0;
    sm_model_member *mb = calloc(n + 1, sizeof *mb);
    char **dirs = calloc(n + 1, sizeof *dirs);
    char *tdir = sm_path_join(batch_dir, "targets");
    if (st == SM_OK && (!mb || !dirs || !tdir))
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    for (size_t i = 0; st == SM_OK && i < n; i++) {
        json_t *row = json_array_get(targets, i);
        const char *name = json_string_value(json_object_get(row, "name"));
        const char *status = json_string_value(json_object_get(row, "status"));
        if (!name || !status || strchr(name, '/') || name[0] == '.')
            st = sm_error_set(err, SM_ERR_FORMAT, "%s: target %zu has no usable name or status",
                              path, i + 1);
        else if (strcmp(status, "finished") == 0 || strcmp(status, "not_converged") == 0) {
            if (!(dirs[k] = sm_path_join(tdir, name)))
                st = sm_error_set(err, SM_ERR_NOMEM, "out of memory");
            mb[k] = (sm_model_member){name, dirs[k]};
            k++;
        }
    }
    if (st == SM_OK && k == 0)
        st = sm_error_set(err, SM_ERR_INVALID, "%s: no target ended with a result", path);
    char *model_dir = st == SM_OK ? sm_path_join(batch_dir, "model") : NULL;
    if (st == SM_OK)
        st = model_dir ? sm_job_model_build_opts(mb, k, opts, model_dir, err)
                       : sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    if (members)
        *members = k;
    for (size_t i = 0; dirs && i < k; i++)
        free(dirs[i]);
    free(dirs), free(mb), free(tdir), free(model_dir), free(path);
    json_decref(doc);
    return st;
}
