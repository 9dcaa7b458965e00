/* shapematch-worker JOB_DIR: runs one matching job for shapematchd.
 *
 * Reads JOB_DIR/job.json and the inputs it names, checks them with the
 * same rules as the daemon (smd_inputs.h), runs the core with a progress
 * callback that writes one NDJSON event per iteration to fd 3 (stdout
 * when fd 3 is not open, for running it by hand) and, when
 * params.save_every = K > 0, a snapshot of the mesh every K iterations
 * into JOB_DIR/results.tmp/snapshots/, writes every result format into
 * JOB_DIR/results.tmp/ and renames it to JOB_DIR/results/, then reports
 * "finished" with the summary.  SIGTERM stops the run at
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

#include <jansson.h>

#include "sm_io.h"
#include "sm_match.h"
#include "sm_payload.h"
#include "sm_proto_events.h"
#include "sm_proto_params.h"
#include "smd_inputs.h"
#include "smd_util.h"
#include "smd_worker.h"

/* The one global: set by the SIGTERM handler, polled by the core. */
static volatile sig_atomic_t stop_requested;
_Static_assert(sizeof(sig_atomic_t) == sizeof(int), "the core polls a volatile int");

static void on_stop_signal(int sig)
{
    (void)sig;
    stop_requested = 1;
}

typedef struct worker {
    int events_fd;
    const char *job_dir;
    sm_progress *history;
    size_t nhistory, cap;
    int history_failed;
    const sm_mesh *template_mesh;
    int save_every;              /* params.save_every: K > 0 writes snapshots */
    int snapshot_failed;
    char snapshot_error[512];
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

/* fsync of a file written by the core (which closes it without one). */
static int fsync_path(const char *path)
{
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0)
        return -1;
    int rc = fsync(fd);
    int saved = errno;
    close(fd);
    errno = saved;
    return rc;
}

/* JOB_DIR/results.tmp/snapshots/iter-NNNNN.mesh (as `shapematch run
 * --save-every` names them), written under a temporary name that keeps
 * the .mesh extension (the core picks the format from it), fsync'ed and
 * renamed: a reader of the folder never sees a torn snapshot.  The folder
 * is published with the other results when the run ends. */
static int write_snapshot(worker *w, int iteration, const double *coords)
{
    char dir[PATH_MAX], tmp[PATH_MAX], path[PATH_MAX];
    if (smd_pathf(dir, sizeof dir, "%s/" SMD_RESULTS_TMP_DIR "/" SMD_SNAPSHOTS_DIR, w->job_dir) != 0 ||
        smd_pathf(path, sizeof path, "%s/" SMD_SNAPSHOT_FORMAT, dir, iteration) != 0 ||
        smd_pathf(tmp, sizeof tmp, "%s/.tmp-" SMD_SNAPSHOT_FORMAT, dir, iteration) != 0) {
        snprintf(w->snapshot_error, sizeof w->snapshot_error, "job folder path too long");
        return -1;
    }
    sm_error err;
    sm_error_clear(&err);
    if (sm_mesh_write_coords(tmp, w->template_mesh, coords, &err) != SM_OK) {
        unlink(tmp);
        smd_textf(w->snapshot_error, sizeof w->snapshot_error,
                  "cannot write the snapshot of iteration %d: %s", iteration, err.msg);
        return -1;
    }
    if (fsync_path(tmp) != 0 || rename(tmp, path) != 0 || smd_fsync_dir(dir) != 0) {
        int saved = errno;
        unlink(tmp);
        snprintf(w->snapshot_error, sizeof w->snapshot_error,
                 "cannot write the snapshot of iteration %d: %s", iteration, strerror(saved));
        return -1;
    }
    return 0;
}

static int on_progress(const sm_progress *p, const double *coords, void *user)
{
    worker *w = user;
    if (w->nhistory == w->cap) {
        size_t ncap = w->cap ? 2 * w->cap : 256;
        sm_progress *h = realloc(w->history, ncap * sizeof *h);
        if (!h) {
            w->history_failed = 1;
            return 1;
        }
        w->history = h;
        w->cap = ncap;
    }
    w->history[w->nhistory++] = *p;
    sm_event ev;
    sm_event_init(&ev, SM_EVENT_PROGRESS);
    ev.progress = *p;
    emit(w, &ev);
    /* the iterations `shapematch run --save-every K` writes: K, 2K, ... */
    if (w->save_every > 0 && p->iteration > 0 && p->iteration % w->save_every == 0 && coords &&
        write_snapshot(w, p->iteration, coords) != 0) {
        w->snapshot_failed = 1;
        return 1;
    }
    return stop_requested != 0;
}

/* ------------------------------------------------------------ outputs */

static void csv_number(FILE *f, double v)
{
    if (!isfinite(v)) {
        fputs(isnan(v) ? "nan" : v > 0 ? "inf" : "-inf", f);
        return;
    }
    /* the shortest of 15..17 digits that reads back exactly */
    char buf[40];
    for (int digits = 15; digits <= 17; digits++) {
        snprintf(buf, sizeof buf, "%.*g", digits, v);
        if (digits == 17 || strtod(buf, NULL) == v)
            break;
    }
    fputs(buf, f);
}

static int write_history_csv(const char *path, const worker *w)
{
    FILE *f = fopen(path, "w");
    if (!f)
        return -1;
    fputs("iteration,J,step,boundary_l2,boundary_max,min_quality,elapsed,accepted,rejected\n", f);
    for (size_t i = 0; i < w->nhistory; i++) {
        const sm_progress *p = &w->history[i];
        fprintf(f, "%d,", p->iteration);
        const double vals[] = {p->J, p->step, p->boundary_l2, p->boundary_max, p->min_quality,
                               p->elapsed};
        for (size_t k = 0; k < sizeof vals / sizeof vals[0]; k++) {
            csv_number(f, vals[k]);
            fputc(',', f);
        }
        fprintf(f, "%d,%d\n", p->accepted, p->rejected);
    }
    int bad = ferror(f);
    if (fflush(f) != 0 || fsync(fileno(f)) != 0)
        bad = 1;
    if (fclose(f) != 0)
        bad = 1;
    return bad ? -1 : 0;
}

static json_t *real_or_null(double v)
{
    return isfinite(v) ? json_real(v) : json_null();
}

static int write_history_json(const char *path, const worker *w)
{
    json_t *rows = json_array();
    for (size_t i = 0; rows && i < w->nhistory; i++) {
        const sm_progress *p = &w->history[i];
        json_array_append_new(
            rows, json_pack("{s:i,s:o,s:o,s:o,s:o,s:o,s:o,s:i,s:i}", "iteration", p->iteration, "J",
                            real_or_null(p->J), "step", real_or_null(p->step), "boundary_l2",
                            real_or_null(p->boundary_l2), "boundary_max",
                            real_or_null(p->boundary_max), "min_quality",
                            real_or_null(p->min_quality), "elapsed", real_or_null(p->elapsed),
                            "accepted", p->accepted, "rejected", p->rejected));
    }
    char *text = rows ? json_dumps(rows, JSON_COMPACT | JSON_PRESERVE_ORDER | JSON_REAL_PRECISION(17)) : NULL;
    json_decref(rows);
    if (!text)
        return -1;
    size_t len = strlen(text);
    text[len] = '\n'; /* replaces the NUL; written with its length */
    int rc = smd_write_file_atomic(path, text, len + 1);
    free(text);
    return rc;
}

/* An empty JOB_DIR/results.tmp/ (with snapshots/ when they are asked
 * for), before the run: what an earlier attempt left is removed. */
static int prepare_results(const worker *w, char *msg, size_t cap)
{
    char dir[PATH_MAX], final_dir[PATH_MAX], snaps[PATH_MAX];
    if (smd_pathf(dir, sizeof dir, "%s/" SMD_RESULTS_TMP_DIR, w->job_dir) != 0 ||
        smd_pathf(final_dir, sizeof final_dir, "%s/" SMD_RESULTS_DIR, w->job_dir) != 0 ||
        smd_pathf(snaps, sizeof snaps, "%s/" SMD_SNAPSHOTS_DIR, dir) != 0) {
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

static int write_outputs(worker *w, const smd_inputs *in, const double *coords,
                         const sm_result *result, char *msg, size_t cap)
{
    const sm_mesh *m = in->template_mesh;
    size_t n = (size_t)m->nverts * (size_t)m->dim;
    char dir[PATH_MAX], final_dir[PATH_MAX], path[PATH_MAX];
    if (smd_pathf(dir, sizeof dir, "%s/" SMD_RESULTS_TMP_DIR, w->job_dir) != 0 ||
        smd_pathf(final_dir, sizeof final_dir, "%s/" SMD_RESULTS_DIR, w->job_dir) != 0) {
        snprintf(msg, cap, "job folder path too long");
        return -1;
    }
    smd_rmtree(final_dir);
    int rc = -1;
    sm_error err;
    sm_error_clear(&err);
    sm_sol *sol = NULL;
    double *disp = malloc((n ? n : 1) * sizeof *disp);
    double *dist = malloc(((size_t)m->nverts + 1) * sizeof *dist);
    char *summary = NULL;
    if (!disp || !dist) {
        snprintf(msg, cap, "out of memory preparing the results");
        goto done;
    }
    for (size_t i = 0; i < n; i++)
        disp[i] = coords[i] - m->coords[i];
    int32_t hint = -1;
    for (int32_t v = 0; v < m->nverts; v++)
        dist[v] = sm_field_eval(in->field, coords + (size_t)v * (size_t)m->dim, &hint);
    if (sm_sol_alloc(&sol, m->dim, m->nverts, m->dim, &err) != SM_OK)
        goto core_error;
    memcpy(sol->values, disp, n * sizeof *disp);
#define OUT(name) (smd_pathf(path, sizeof path, "%s/%s", dir, name) == 0 ? path : "")
    if (sm_mesh_write_coords(OUT(SMD_RESULT_MESH), m, coords, &err) != SM_OK ||
        sm_mesh_write_coords(OUT(SMD_RESULT_MESHB), m, coords, &err) != SM_OK ||
        sm_vtu_write(OUT(SMD_RESULT_VTU), m, coords, disp, dist, &err) != SM_OK ||
        sm_payload_write_file(OUT(SMD_RESULT_PAYLOAD), m, coords, disp, dist, &err) != SM_OK ||
        sm_sol_write(OUT(SMD_RESULT_DISPLACEMENT), sol, &err) != SM_OK ||
        sm_sol_write(OUT(SMD_RESULT_DISPLACEMENT_B), sol, &err) != SM_OK)
        goto core_error;
    if (write_history_csv(OUT(SMD_RESULT_HISTORY_CSV), w) != 0 ||
        write_history_json(OUT(SMD_RESULT_HISTORY_JSON), w) != 0) {
        snprintf(msg, cap, "cannot write the history: %s", strerror(errno));
        goto done;
    }
    summary = sm_result_to_json(result, &in->params, in->dim);
    if (!summary || smd_write_file_atomic(OUT(SMD_RESULT_SUMMARY), summary, strlen(summary)) != 0) {
        snprintf(msg, cap, "cannot write the summary: %s", summary ? strerror(errno) : "out of memory");
        goto done;
    }
#undef OUT
    /* every file is complete: publish them at once */
    if (smd_fsync_dir(dir) != 0 || rename(dir, final_dir) != 0 || smd_fsync_dir(w->job_dir) != 0) {
        snprintf(msg, cap, "cannot publish the results: %s", strerror(errno));
        goto done;
    }
    rc = 0;
    goto done;
core_error:
    smd_textf(msg, cap, "cannot write the results: %s", err.msg);
done:
    free(summary);
    sm_sol_free(sol);
    free(disp);
    free(dist);
    return rc;
}

/* ---------------------------------------------------------------- main */

/* A path from job.json: relative, inside the job folder. */
static int job_path(const char *job_dir, json_t *doc, const char *key, char *out, size_t cap)
{
    const char *rel = json_string_value(json_object_get(doc, key));
    if (!rel || !*rel || rel[0] == '/' || strstr(rel, ".."))
        return -1;
    return smd_pathf(out, cap, "%s/%s", job_dir, rel);
}

int main(int argc, char **argv)
{
    worker w = {.events_fd = fcntl(SMD_WORKER_EVENT_FD, F_GETFD) >= 0 ? SMD_WORKER_EVENT_FD : 1};
    if (argc != 2 || argv[1][0] == '-') {
        fprintf(stderr, "usage: shapematch-worker JOB_DIR\n"
                        "Runs one shapematchd job (started by the daemon; see server/smd_worker.h).\n");
        return SMD_WORKER_EXIT_USAGE;
    }
    w.job_dir = argv[1];
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_stop_signal;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGTERM, &sa, NULL);
    sigaction(SIGINT, &sa, NULL);

    char path[PATH_MAX], tpl[PATH_MAX], bg[PATH_MAX], sol[PATH_MAX];
    char *text = NULL;
    size_t len = 0;
    if (smd_pathf(path, sizeof path, "%s/" SMD_JOB_FILE, w.job_dir) != 0 ||
        smd_read_file(path, 1 << 20, &text, &len) != 0)
        return fail(&w, SMD_WORKER_EXIT_USAGE, "cannot read %s: %s", SMD_JOB_FILE, strerror(errno));
    json_error_t jerr;
    json_t *doc = json_loadb(text, len, 0, &jerr);
    free(text);
    json_t *params = json_object_get(doc, "params");
    char *params_text = json_is_object(params) ? json_dumps(params, JSON_COMPACT) : NULL;
    int paths_ok = doc && job_path(w.job_dir, doc, "template", tpl, sizeof tpl) == 0 &&
                   job_path(w.job_dir, doc, "target_mesh", bg, sizeof bg) == 0 &&
                   job_path(w.job_dir, doc, "target_sol", sol, sizeof sol) == 0;
    json_decref(doc);
    if (!paths_ok || !params_text) {
        free(params_text);
        return fail(&w, SMD_WORKER_EXIT_USAGE, "%s is not a job description", SMD_JOB_FILE);
    }

    smd_inputs in;
    sm_error err;
    sm_error_clear(&err);
    sm_status st = smd_inputs_load(tpl, bg, sol, params_text, strlen(params_text), &in, &err);
    free(params_text);
    if (st != SM_OK)
        return fail(&w, st == SM_ERR_NOMEM ? SMD_WORKER_EXIT_NOMEM : SMD_WORKER_EXIT_INPUT, "%s",
                    err.msg);

    int code = SMD_WORKER_EXIT_OK;
    char msg[512];
    w.template_mesh = in.template_mesh;
    w.save_every = in.params.save_every;
    size_t n = (size_t)in.template_mesh->nverts * (size_t)in.template_mesh->dim;
    double *coords = malloc((n ? n : 1) * sizeof *coords);
    if (!coords) {
        code = fail(&w, SMD_WORKER_EXIT_NOMEM, "out of memory for a mesh of %ld vertices",
                    (long)in.template_mesh->nverts);
        goto done;
    }
    if (prepare_results(&w, msg, sizeof msg) != 0) {
        code = fail(&w, SMD_WORKER_EXIT_OUTPUT, "%s", msg);
        goto done;
    }
    sm_result result;
    memset(&result, 0, sizeof result);
    sm_match_opts opts = {.template_mesh = in.template_mesh, .target = in.field, .params = &in.params};
    sm_match_callbacks cb = {.progress = on_progress, .user = &w,
                             .cancel = (const volatile int *)&stop_requested};
    st = sm_match_run(&opts, &cb, coords, &result, &err);
    if (w.history_failed) {
        code = fail(&w, SMD_WORKER_EXIT_NOMEM, "out of memory recording the history");
        goto done;
    }
    if (w.snapshot_failed) {
        code = fail(&w, SMD_WORKER_EXIT_OUTPUT, "%s", w.snapshot_error);
        goto done;
    }
    if ((st == SM_OK && result.stop == SM_STOP_CANCELLED) || stop_requested) {
        sm_event ev;
        sm_event_init(&ev, SM_EVENT_CANCELLED);
        snprintf(ev.message, sizeof ev.message, "stopped by SIGTERM");
        emit(&w, &ev);
        code = SMD_WORKER_EXIT_CANCELLED;
        goto done;
    }
    if (st != SM_OK) {
        code = fail(&w, st == SM_ERR_NOMEM ? SMD_WORKER_EXIT_NOMEM : SMD_WORKER_EXIT_NUMERIC,
                    "the run failed (%s): %s", sm_status_name(st), err.msg);
        goto done;
    }
    if (write_outputs(&w, &in, coords, &result, msg, sizeof msg) != 0) {
        code = fail(&w, SMD_WORKER_EXIT_OUTPUT, "%s", msg);
        goto done;
    }
    sm_event ev;
    sm_event_init(&ev, SM_EVENT_FINISHED);
    ev.result = result;
    emit(&w, &ev);
done:
    free(coords);
    free(w.history);
    smd_inputs_free(&in);
    return code;
}
