/* shapematch-worker JOB_DIR: runs one matching job for shapematchd.
 *
 * Reads JOB_DIR/job.json and the inputs it names and runs the job through
 * the shared job runner (proto/job/: the same checks, run,
 * result set and summary as `shapematch run`).  What is the worker's own
 * is the framing: one NDJSON event per iteration on fd 3 (stdout when fd 3
 * is not open, for running it by hand), snapshots (params.save_every K)
 * into JOB_DIR/results.tmp/snapshots/, the result set into
 * JOB_DIR/results.tmp/ renamed to JOB_DIR/results/ when complete, then
 * "finished" with the summary.  A job that cannot take a single step is
 * "failed" (exit 3), as for `shapematch run`.  SIGTERM stops the run at
 * the next iteration ("cancelled", exit 5).  Exit codes: smd_worker.h. */
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <math.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>


#include "shapematch/sm_clock.h"
#include "shapematch/sm_atomic.h"
#include "shapematch/sm_field.h"
#include "shapematch/sm_io.h"
#include "job/sm_job_inputs.h"
#include "job/sm_job_model.h"
#include "job/sm_job_results.h"
#include "sm_payload.h"
#include "sm_proto_events.h"
#include "sm_proto_vocab.h"
#include "base/smd_util.h"
#include "worker/smd_job_file.h"
#include "worker/smd_worker.h"

/* The one global: set by the SIGTERM handler, polled by the core. */
static volatile sig_atomic_t stop_requested;
_Static_assert(sizeof(sig_atomic_t) == sizeof(int), "the core polls a volatile int");

static void on_stop_signal(int sig)
{
    (void)sig;
    stop_requested = 1;
}

/* The live mesh (GET /v1/jobs/{id}/mesh/latest): the current shape,
 * replaced atomically (not fsync'ed: it is a view, not a result). */
typedef struct live_mesh {
    const sm_job_inputs *in;
    int every;                   /* params.live_every: also every k iterations */
    double last;                 /* monotonic time of the last publication */
    double *disp, *dist;         /* scratch: nverts*dim, nverts */
    int warned;                  /* a failed publication is reported once */
} live_mesh;

typedef struct worker {
    int events_fd;
    const char *job_dir;
    int save_every;              /* params.save_every: K > 0 writes snapshots */
    live_mesh live;
} worker;

/* One event line; a failing pipe means the daemon is gone: nothing to
 * report it to, the run stops at the next iteration. */
static void emit(worker *w, const sm_event *ev)
{
    char *line = sm_event_to_json(ev);
    if (!line)
        return;
    size_t len = strlen(line);
    char *buf = realloc(line, len + 2);
    if (!buf) {
        free(line);
        return;
    }
    buf[len] = '\n';
    const char *p = buf;
    size_t left = len + 1;
    while (left > 0) {
        ssize_t n = write(w->events_fd, p, left);
        if (n < 0 && errno == EINTR)
            continue;
        if (n <= 0) {
            stop_requested = 1;
            break;
        }
        p += n;
        left -= (size_t)n;
    }
    free(buf);
}

static int fail(worker *w, int code, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static int fail(worker *w, int code, const char *fmt, ...)
{
    sm_event ev;
    sm_event_init(&ev, SM_EVENT_FAILED);
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(ev.message, sizeof ev.message, fmt, ap);
    va_end(ap);
    emit(w, &ev);
    fprintf(stderr, "shapematch-worker: %s\n", ev.message);
    return code;
}

static int on_progress(const sm_progress *p, void *user)
{
    worker *w = user;
    sm_event ev;
    sm_event_init(&ev, SM_EVENT_PROGRESS);
    ev.progress = *p;
    emit(w, &ev);
    return stop_requested != 0;
}

static void on_warning(const sm_job_warning *warning, void *user)
{
    sm_event ev;
    sm_job_warning_event(warning, &ev);
    emit(user, &ev);
}

static void on_alignment(const sm_job_alignment *a, void *user)
{
    sm_event ev;
    sm_job_alignment_event(a, &ev);
    emit(user, &ev);
}

/* Writes one live file: name under JOB_DIR, via a temporary file. */
static sm_status live_write(worker *w, const char *name, const double *coords, sm_error *err)
{
    char path[PATH_MAX];
    if (smd_pathf(path, sizeof path, "%s/%s", w->job_dir, name) != 0)
        return sm_error_set(err, SM_ERR_IO, "job folder path too long");
    sm_atomic a;
    sm_status st = sm_atomic_reserve(&a, path, err);
    if (st != SM_OK)
        return st;
    const sm_mesh *m = w->live.in->template_mesh;
    if (strcmp(name, SMD_LIVE_PAYLOAD) == 0)
        st = sm_payload_write_file(a.tmp_path, m, coords, w->live.disp, w->live.dist, err);
    else
        st = sm_mesh_write_coords(a.tmp_path, m, coords, err);
    if (st != SM_OK) {
        sm_atomic_abort(&a);
        return st;
    }
    return sm_atomic_commit(&a, 0, err);
}

/* The shape hook: publishes the live mesh (binary payload with the
 * displacement and |d|, and Medit) at the first call, every live_every
 * iterations and whenever 0.5 s have passed since the last one.  Its
 * cost is one pass over the vertices (a field evaluation each) and two
 * file writes, so by time at most twice a second.  A failure is reported
 * in the worker's log and does not stop the run. */
static int on_shape(const sm_progress *p, const double *coords, void *user)
{
    worker *w = user;
    live_mesh *l = &w->live;
    double now = sm_clock_seconds();
    int due = l->last == 0 || (l->every > 0 && p->iteration % l->every == 0) ||
              now - l->last >= SMD_LIVE_PERIOD;
    if (!due || !l->disp)
        return 0;
    const sm_mesh *m = l->in->template_mesh;
    size_t n = (size_t)m->nverts * (size_t)m->dim;
    for (size_t i = 0; i < n; i++)
        l->disp[i] = coords[i] - m->coords[i];
    sm_field_eval_points(l->in->field, m->nverts, coords, NULL, l->dist);
    sm_error err;
    sm_error_clear(&err);
    /* Medit first: a reader that finds the payload finds both */
    if ((live_write(w, SMD_LIVE_MESH, coords, &err) != SM_OK ||
         live_write(w, SMD_LIVE_PAYLOAD, coords, &err) != SM_OK) && !l->warned) {
        fprintf(stderr, "shapematch-worker: live mesh not published: %s\n", err.msg);
        l->warned = 1;
    }
    l->last = now > 0 ? now : 1e-9;
    return 0;
}

/* The live mesh's scratch, for in (none when out of memory: no live
 * mesh, the run goes on). */
static void live_init(live_mesh *l, const sm_job_inputs *in, const char *w_dir)
{
    const sm_mesh *m = in->template_mesh;
    l->in = in;
    l->every = in->params.live_every;
    /* an earlier attempt's shape is not this run's */
    char path[PATH_MAX];
    if (smd_pathf(path, sizeof path, "%s/" SMD_LIVE_PAYLOAD, w_dir) == 0)
        unlink(path);
    if (smd_pathf(path, sizeof path, "%s/" SMD_LIVE_MESH, w_dir) == 0)
        unlink(path);
    l->disp = malloc(((size_t)m->nverts * (size_t)m->dim + 1) * sizeof *l->disp);
    l->dist = malloc(((size_t)m->nverts + 1) * sizeof *l->dist);
    if (!l->disp || !l->dist) {
        free(l->disp);
        free(l->dist);
        l->disp = l->dist = NULL;
    }
}

/* An empty JOB_DIR/results.tmp/ (with snapshots/ when they are asked
 * for), before the run: what an earlier attempt left is removed. */
static int prepare_results(const worker *w, char *msg, size_t cap)
{
    char dir[PATH_MAX], final_dir[PATH_MAX], snaps[PATH_MAX];
    if (smd_pathf(dir, sizeof dir, "%s/" SMD_RESULTS_TMP_DIR, w->job_dir) != 0 ||
        smd_pathf(final_dir, sizeof final_dir, "%s/" SMD_RESULTS_DIR, w->job_dir) != 0 ||
        smd_pathf(snaps, sizeof snaps, "%s/" SM_SNAPSHOTS_DIR, dir) != 0) {
        snprintf(msg, cap, "job folder path too long");
        return -1;
    }
    smd_rmtree(dir);
    smd_rmtree(final_dir);
    if (mkdir(dir, 0750) != 0 || (w->save_every > 0 && mkdir(snaps, 0750) != 0)) {
        snprintf(msg, cap, "cannot create %s: %s", SMD_RESULTS_TMP_DIR, strerror(errno));
        return -1;
    }
    return 0;
}

/* The result set into JOB_DIR/results.tmp/, then published at once. */
static int write_outputs(worker *w, const sm_job_inputs *in, const sm_job_run *run,
                         const sm_job_files *names, char *msg, size_t cap)
{
    char dir[PATH_MAX], final_dir[PATH_MAX];
    if (smd_pathf(dir, sizeof dir, "%s/" SMD_RESULTS_TMP_DIR, w->job_dir) != 0 ||
        smd_pathf(final_dir, sizeof final_dir, "%s/" SMD_RESULTS_DIR, w->job_dir) != 0) {
        snprintf(msg, cap, "job folder path too long");
        return -1;
    }
    smd_rmtree(final_dir);
    sm_error err;
    sm_error_clear(&err);
    if (sm_job_write_results(in, run, names, dir, SM_ATOMIC_FSYNC, &err) != SM_OK) {
        smd_textf(msg, cap, "cannot write the results: %s", err.msg);
        return -1;
    }
    /* every file is complete: publish them at once */
    if (smd_fsync_dir(dir) != 0 || rename(dir, final_dir) != 0 || smd_fsync_dir(w->job_dir) != 0) {
        snprintf(msg, cap, "cannot publish the results: %s", strerror(errno));
        return -1;
    }
    return 0;
}

/* ---------------------------------------------------------------- main */

/* What the upload's check kept (smd_job_file.h), when job.json names it
 * and its key is this job's (the same inputs, params and daemon
 * version): the background and distance (paths in bg_d, "" when none)
 * and the meshed template (its path in tmpl and its figures in *made, ""
 * when none or its figures do not read).  0 when nothing is this job's. */
static int checked_of(const worker *w, const smd_job_file *jf, char bg_d[2][PATH_MAX],
                      char tmpl[PATH_MAX], sm_job_template_made *made)
{
    char key[SMD_JOB_KEY_LEN + 1];
    bg_d[0][0] = bg_d[1][0] = tmpl[0] = '\0';
    if (!jf->checked_key[0] || smd_job_file_inputs_key(w->job_dir, jf, key) != 0 ||
        strcmp(key, jf->checked_key) != 0)
        return 0;
    if (jf->checked_background[0] &&
        (smd_pathf(bg_d[0], PATH_MAX, "%s/%s", w->job_dir, jf->checked_background) != 0 ||
         smd_pathf(bg_d[1], PATH_MAX, "%s/%s", w->job_dir, jf->checked_distance) != 0))
        bg_d[0][0] = bg_d[1][0] = '\0';
    sm_error err;
    if (jf->checked_template[0]) {
        if (sm_job_template_made_from_json(jf->checked_template_made, made, &err) != SM_OK)
            fprintf(stderr, "shapematch-worker: the checked template is not used: %s\n", err.msg);
        else if (smd_pathf(tmpl, PATH_MAX, "%s/%s", w->job_dir, jf->checked_template) != 0)
            tmpl[0] = '\0';
    }
    return bg_d[0][0] || tmpl[0];
}

/* Reads the inputs job.json (read once, jf) names into in, its params
 * decoded from the object itself: 0, or the exit code (the failure
 * emitted). */
static int load_job(worker *w, const smd_job_file *jf, sm_job_inputs *in)
{
    sm_error err;
    sm_error_clear(&err);
    char full[SM_PART_PARAMS][PATH_MAX];
    const char *given[SM_PART_PARAMS] = {0};
    for (int i = 0; i < SM_PART_PARAMS; i++) {
        if (!jf->part[i][0])
            continue; /* the upload checked which parts go together */
        if (smd_pathf(full[i], sizeof full[i], "%s/%s", w->job_dir, jf->part[i]) != 0)
            return fail(w, SMD_WORKER_EXIT_USAGE, "%s: path too long", jf->part[i]);
        given[i] = full[i];
    }
    /* a generated background's size and padding come from the params
     * (sm_job_inputs_load_json), as in the upload's check */
    sm_job_files files = {.template_mesh = given[SM_PART_TEMPLATE],
                          .template_surface = given[SM_PART_TEMPLATE_SURFACE],
                          .template_image = given[SM_PART_TEMPLATE_IMAGE],
                          .target_mesh = given[SM_PART_TARGET_MESH],
                          .target_sol = given[SM_PART_TARGET_SOL],
                          .target_surface = given[SM_PART_TARGET_SURFACE],
                          .target_image = given[SM_PART_TARGET_IMAGE],
                          .landmarks_template = given[SM_PART_TEMPLATE_LANDMARKS],
                          .landmarks_target = given[SM_PART_TARGET_LANDMARKS],
                          .prepare_run = 1};
    char checked[2][PATH_MAX], tmpl[PATH_MAX];
    sm_job_template_made made;
    if (checked_of(w, jf, checked, tmpl, &made)) {
        files.checked_background = checked[0][0] ? checked[0] : NULL;
        files.checked_distance = checked[1][0] ? checked[1] : NULL;
        files.checked_template = tmpl[0] ? tmpl : NULL;
        files.checked_template_made = tmpl[0] ? &made : NULL;
    }
    sm_status st = sm_job_inputs_load_json(&files, jf->params, in, &err);
    if (st != SM_OK && st != SM_ERR_NOMEM && (files.checked_background || files.checked_template)) {
        /* the kept files do not read (a damaged copy): built instead, as
         * without them; a refusal of the inputs themselves comes again */
        fprintf(stderr, "shapematch-worker: what the upload's check built is not used: %s\n",
                err.msg);
        files.checked_background = files.checked_distance = files.checked_template = NULL;
        files.checked_template_made = NULL;
        sm_error_clear(&err);
        st = sm_job_inputs_load_json(&files, jf->params, in, &err);
    }
    if (st != SM_OK)
        return fail(w, st == SM_ERR_NOMEM ? SMD_WORKER_EXIT_NOMEM : SMD_WORKER_EXIT_INPUT, "%s",
                    err.msg);
    /* in worker.log: what a test and an operator look for */
    if (in->checked_reused)
        fprintf(stderr, "shapematch-worker: the background and distance of the upload's check "
                        "are reused (%s)\n", jf->checked_background);
    if (in->template_reused)
        fprintf(stderr, "shapematch-worker: the template meshed by the upload's check is reused "
                        "(%s)\n", jf->checked_template);
    return 0;
}

static const char *given_or_null(const char *rel) { return rel[0] ? rel : NULL; }

/* Runs the loaded job and emits how it ended: its exit code. */
static int run_job(worker *w, sm_job_inputs *in, const smd_job_file *jf)
{
    /* the summary names the inputs as job.json does (relative paths) */
    sm_job_files names = {.template_mesh = given_or_null(jf->part[SM_PART_TEMPLATE]),
                          .template_surface = given_or_null(jf->part[SM_PART_TEMPLATE_SURFACE]),
                          .template_image = given_or_null(jf->part[SM_PART_TEMPLATE_IMAGE]),
                          .target_mesh = given_or_null(jf->part[SM_PART_TARGET_MESH]),
                          .target_sol = given_or_null(jf->part[SM_PART_TARGET_SOL]),
                          .target_surface = given_or_null(jf->part[SM_PART_TARGET_SURFACE]),
                          .target_image = given_or_null(jf->part[SM_PART_TARGET_IMAGE])};
    int code = SMD_WORKER_EXIT_OK;
    char msg[512], snaps[PATH_MAX];
    sm_job_run run;
    memset(&run, 0, sizeof run);
    sm_error err;
    sm_error_clear(&err);
    w->save_every = in->params.save_every;
    if (prepare_results(w, msg, sizeof msg) != 0 ||
        smd_pathf(snaps, sizeof snaps, "%s/" SMD_RESULTS_TMP_DIR "/" SM_SNAPSHOTS_DIR, w->job_dir) != 0) {
        code = fail(w, SMD_WORKER_EXIT_OUTPUT, "%s", msg);
        goto done;
    }
    live_init(&w->live, in, w->job_dir);
    sm_job_hooks hooks = {.progress = on_progress, .shape = on_shape, .warning = on_warning,
                          .alignment = on_alignment,
                          .user = w,
                          .cancel = (const volatile int *)&stop_requested,
                          .snapshot_dir = w->save_every > 0 ? snaps : NULL,
                          .write_flags = SM_ATOMIC_FSYNC};
    sm_status st = sm_job_run_exec(in, &hooks, &run, &err);
    if ((st == SM_OK && run.outcome == SM_JOB_OUTCOME_CANCELLED) || (stop_requested && st != SM_ERR_IO)) {
        sm_event ev;
        sm_event_init(&ev, SM_EVENT_CANCELLED);
        snprintf(ev.message, sizeof ev.message, "stopped by SIGTERM");
        emit(w, &ev);
        code = SMD_WORKER_EXIT_CANCELLED;
        goto done;
    }
    if (st != SM_OK) {
        if (st == SM_ERR_IO) /* a snapshot */
            code = fail(w, SMD_WORKER_EXIT_OUTPUT, "%s", err.msg);
        else if (st == SM_ERR_NOMEM)
            code = fail(w, SMD_WORKER_EXIT_NOMEM, "%s", err.msg);
        else
            code = fail(w, SMD_WORKER_EXIT_NUMERIC, "the run failed (%s): %s", sm_status_name(st),
                        err.msg);
        goto done;
    }
    if (run.outcome == SM_JOB_OUTCOME_FAILED) {
        code = fail(w, SMD_WORKER_EXIT_NUMERIC, "%s", run.message);
        goto done;
    }
    if (write_outputs(w, in, &run, &names, msg, sizeof msg) != 0) {
        code = fail(w, SMD_WORKER_EXIT_OUTPUT, "%s", msg);
        goto done;
    }
    sm_event ev;
    sm_event_init(&ev, SM_EVENT_FINISHED);
    ev.result = run.result;
    sm_job_warnings_text(&run.warnings, ev.message, sizeof ev.message);
    emit(w, &ev);
done:
    free(w->live.disp);
    free(w->live.dist);
    sm_job_run_free(&run);
    return code;
}

/* ------------------------------------------------------ a batch's model */

/* A member's published results: JOB_DIR/members/<id>/, put there when the
 * model job was queued (the spool links the member's results/, a
 * PostgreSQL node copies them from the database): the worker reads only
 * its own folder.  A member has results only when it succeeded (results/
 * is published whole, summary.json included).  0 and the folder, or -1. */
static int member_results(const worker *w, const char *id, char *dir, size_t cap)
{
    char summary[PATH_MAX];
    struct stat st;
    if (smd_pathf(dir, cap, "%s/members/%s", w->job_dir, id) != 0 ||
        smd_pathf(summary, sizeof summary, "%s/summary.json", dir) != 0)
        return -1;
    return stat(summary, &st) == 0 && S_ISREG(st.st_mode) ? 0 : -1;
}

/* The model job: the members that succeeded into the shape model
 * (proto/job/sm_job_model.h), written to results.tmp/ and published as
 * results/.  Members without results are left out and named in the
 * "finished" message; none left is a failed job (exit 2). */
static int run_model(worker *w, const json_t *batch)
{
    const json_t *list = json_object_get(batch, "members");
    size_t n = json_array_size(list), used = 0;
    sm_model_member *m = calloc(n ? n : 1, sizeof *m);
    char (*dirs)[PATH_MAX] = calloc(n ? n : 1, sizeof *dirs);
    char left[SM_EVENT_MESSAGE_MAX] = "", msg[512];
    size_t nleft = 0, at = 0;
    int code = SMD_WORKER_EXIT_OK;
    if (!m || !dirs) {
        code = fail(w, SMD_WORKER_EXIT_NOMEM, "out of memory");
        goto done;
    }
    for (size_t i = 0; i < n; i++) {
        const json_t *v = json_array_get(list, i);
        const char *id = json_string_value(json_object_get(v, "job"));
        const char *name = json_string_value(json_object_get(v, "name"));
        if (member_results(w, id, dirs[used], sizeof dirs[used]) != 0) {
            nleft++;
            if (at < sizeof left) {
                int k = snprintf(left + at, sizeof left - at, "%s%s", at ? ", " : "", name);
                at += k > 0 ? (size_t)k : 0;
            }
            continue;
        }
        m[used].name = name;
        m[used].result_dir = dirs[used];
        used++;
    }
    if (used == 0) {
        code = fail(w, SMD_WORKER_EXIT_INPUT, "no target of the batch succeeded: no model to "
                                              "build (%zu left out: %s)", nleft, left);
        goto done;
    }
    char dir[PATH_MAX], final_dir[PATH_MAX];
    if (prepare_results(w, msg, sizeof msg) != 0 ||
        smd_pathf(dir, sizeof dir, "%s/" SMD_RESULTS_TMP_DIR, w->job_dir) != 0 ||
        smd_pathf(final_dir, sizeof final_dir, "%s/" SMD_RESULTS_DIR, w->job_dir) != 0) {
        code = fail(w, SMD_WORKER_EXIT_OUTPUT, "%s", msg[0] ? msg : "job folder path too long");
        goto done;
    }
    sm_model_opts opts = {.write_flags = SM_ATOMIC_FSYNC};
    const char *align = json_string_value(json_object_get(batch, "align"));
    if (!align || sm_shape_align_parse(align, &opts.align) != 0) { /* job.json was checked */
        code = fail(w, SMD_WORKER_EXIT_INPUT, "batch.align: expected none, rigid or similarity");
        goto done;
    }
    sm_error err;
    sm_error_clear(&err);
    sm_status st = sm_job_model_build_opts(m, used, &opts, dir, &err);
    if (st != SM_OK) {
        code = fail(w, st == SM_ERR_NOMEM   ? SMD_WORKER_EXIT_NOMEM
                       : st == SM_ERR_IO    ? SMD_WORKER_EXIT_OUTPUT
                                            : SMD_WORKER_EXIT_INPUT,
                    "the shape model failed (%s): %s", sm_status_name(st), err.msg);
        goto done;
    }
    if (smd_fsync_dir(dir) != 0 || rename(dir, final_dir) != 0 || smd_fsync_dir(w->job_dir) != 0) {
        code = fail(w, SMD_WORKER_EXIT_OUTPUT, "cannot publish the model: %s", strerror(errno));
        goto done;
    }
    sm_event ev;
    sm_event_init(&ev, SM_EVENT_FINISHED);
    ev.result.converged = 1;
    if (nleft)
        smd_textf(ev.message, sizeof ev.message, "model of %zu of %zu targets (left out, without "
                  "a result: %s)", used, n, left);
    else
        snprintf(ev.message, sizeof ev.message, "model of %zu targets", used);
    emit(w, &ev);
done:
    free(m);
    free(dirs);
    return code;
}

#ifndef SM_VERSION
#define SM_VERSION "unknown"
#endif

int main(int argc, char **argv)
{
    worker w = {.events_fd = fcntl(SMD_WORKER_EVENT_FD, F_GETFD) >= 0 ? SMD_WORKER_EVENT_FD : 1};
    if (argc == 2 && strcmp(argv[1], "--version") == 0) {
        printf("shapematch-worker %s\n", SM_VERSION);
        return 0;
    }
    if (argc == 2 && (strcmp(argv[1], "--help") == 0 || strcmp(argv[1], "-h") == 0)) {
        printf("Usage: shapematch-worker JOB_DIR\n"
               "       shapematch-worker --help | --version\n"
               "\n"
               "Runs one job of shapematchd: reads JOB_DIR/job.json (the inputs and\n"
               "parameters the daemon checked), writes the results under JOB_DIR and reports\n"
               "progress on its event pipe.  shapematchd starts one per job (its --worker\n"
               "option names this program); it is not meant to be run by hand.\n");
        return 0;
    }
    if (argc != 2 || argv[1][0] == '-') {
        fprintf(stderr, "usage: shapematch-worker JOB_DIR (started by shapematchd; see "
                        "'shapematch-worker --help')\n");
        return SMD_WORKER_EXIT_USAGE;
    }
    w.job_dir = argv[1];
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_stop_signal;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGTERM, &sa, NULL);
    sigaction(SIGINT, &sa, NULL);

    smd_job_file jf;
    sm_job_inputs in;
    sm_error err;
    if (smd_job_file_read(w.job_dir, &jf, &err) != SM_OK) {
        int code = fail(&w, SMD_WORKER_EXIT_USAGE, "%s", err.msg);
        smd_job_file_free(&jf);
        return code;
    }
    if (jf.batch) {
        int code = run_model(&w, jf.batch);
        smd_job_file_free(&jf);
        return code;
    }
    int code = load_job(&w, &jf, &in);
    if (code == 0) {
        code = run_job(&w, &in, &jf);
        sm_job_inputs_free(&in);
    }
    smd_job_file_free(&jf);
    return code;
}
