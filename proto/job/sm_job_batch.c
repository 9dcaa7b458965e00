/* A batch of targets on one template, then their shape model (see
 * sm_job_batch.h). */
#include "job/sm_job_batch.h"

#include <errno.h>
#include <jansson.h>
#include <omp.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <poll.h>
#include <string.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "job/sm_job_align.h"
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
static int run_child(batch_template *bt, const sm_batch_target *t, const sm_batch_opts *o,
                     const char *dir)
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
    if (o->jobs > 1 || o->single_thread)
        omp_set_num_threads(1);
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
    if (st == SM_OK)
        st = sm_job_inputs_read_target(&files, SM_JOB_NAME_PATHS, 0, in, &err);
    if (st != SM_OK) {
        write_error_file(dir, err.msg);
        return SM_JOB_EXIT_INPUT;
    }
    sm_job_run run;
    sm_job_hooks hooks = {.snapshot_dir = dir, .write_flags = SM_ATOMIC_FSYNC,
                          .cancel = (const volatile int *)&child_cancel};
    st = sm_job_run_exec(in, &hooks, &run, &err);
    int code = run.exit_code;
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

/* Running targets watched through their pidfds at most (more: the
 * sleep), far beyond any --jobs. */
#define SM_BATCH_JOBS_POLL 256

typedef struct target_state {
    pid_t pid;
    int pidfd;                  /* -1: none (not running, or no pidfd_open) */
    double started, seconds;
    int exit_code;              /* -1: killed or not run */
    const char *status;
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
        while (next < l->n && running < (size_t)o->jobs) {
            size_t i = next++;
            ts[i].started = sm_clock_seconds();
            pid_t pid = fork();
            if (pid < 0)
                return sm_error_set(err, SM_ERR_IO, "cannot start a process: %s",
                                    strerror(errno));
            if (pid == 0)
                _exit(run_child(bt, &l->t[i], o, dirs[i]));
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
        json_array_append_new(targets, row);
        if (!target_ok(&ts[i]))
            json_array_append_new(failed, sm_json_string_lossy(t->name));
    }
    json_t *doc = json_pack("{s:s, s:o, s:i, s:i, s:i, s:o, s:o, s:{s:i, s:f}, "
                            "s:{s:f, s:f, s:f, s:f}}",
                            "shapematch_version", SM_VERSION, "template",
                            sm_json_string_lossy(o->template_mesh), "targets_total", (int)l->n,
                            "targets_ok", (int)out->nok, "jobs", o->jobs, "targets", targets,
                            "failed", failed, "template_setup", "count", out->template_setups,
                            "seconds", out->template_seconds, "timings", "template",
                            out->template_seconds, "targets", out->targets_seconds, "model",
                            out->model_seconds, "total", out->total_seconds);
    if (doc) {
        json_object_set_new(doc, "model", out->model_built ? json_string("model") : json_null());
        json_object_set_new(doc, "cancelled", json_boolean(out->cancelled));
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
    }
    double t1 = sm_clock_seconds();
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
