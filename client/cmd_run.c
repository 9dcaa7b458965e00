/* `shapematch run`: one matching job run locally, with no daemon.
 *
 * Reads the template mesh and the target (background mesh + signed
 * distance), checks that they fit together before spending any time,
 * runs sm_match_run with a progress callback (terminal display, NDJSON
 * events, snapshots, cancellation), then writes the outputs:
 *   result.mesh        deformed template (same topology and references)
 *   result.vtu         the same with point fields displacement, distance
 *   displacement.sol   cumulative displacement x_k - x_0 per vertex
 *   history.csv        one row per iteration
 *   summary.json       stop reason, figures, timings, inputs, parameters
 * Every file is written under a temporary name and renamed into place;
 * summary.json comes last (an older one is removed first), so its
 * presence means the set is complete and from one run. */
#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "args.h"
#include "cli.h"
#include "fsutil.h"
#include "jsonw.h"
#include "progress.h"
#include "sm_clamp.h"
#include "sm_field.h"
#include "sm_io.h"
#include "sm_match.h"
#include "sm_mesh.h"

/* Set by SIGINT/SIGTERM and polled by sm_match_run between iterations.
 * The one piece of global state of the client: a signal handler has no
 * other way to reach the run.  sm_match_run takes a `const volatile
 * int *`, which is what sig_atomic_t is on the platforms we build for. */
static volatile sig_atomic_t cancel_requested;
_Static_assert(_Generic((sig_atomic_t)0, int: 1, default: 0),
               "sig_atomic_t must be int to be shared with sm_match_run");

static void on_cancel_signal(int sig)
{
    (void)sig;
    cancel_requested = 1;
}

static void install_cancel_handlers(void)
{
    struct sigaction sa, old;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_cancel_signal;
    sigemptyset(&sa.sa_mask);
    /* SA_RESETHAND: the first signal asks for a clean stop (outputs of
     * the state reached are written); a second one gets the default
     * action and ends the process at once, for a user who cannot wait. */
    sa.sa_flags = SA_RESETHAND | SA_RESTART;
    /* A SIGINT ignored at start (a background job of a non-interactive
     * shell, nohup) stays ignored: the caller asked for immunity to the
     * terminal's Ctrl-C. */
    if (sigaction(SIGINT, NULL, &old) != 0 || old.sa_handler != SIG_IGN)
        sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
}

static double now_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* ---- run state ---- */

typedef struct history {
    sm_progress *rows;
    size_t n, cap;
} history;

typedef struct run_ctx {
    const run_options *opt;
    const sm_mesh *template_mesh;
    size_t ncoords;              /* nverts * dim */
    progress_display display;
    history hist;
    double *last_coords;         /* vertex positions at the last callback */
    int have_coords;
    int cancel_noticed;
    int failed;                  /* exit code of a failure in the callback */
    char failure[ARGS_MSG_LEN];
} run_ctx;

static int history_push(history *h, const sm_progress *p)
{
    /* one row per iteration: a repeated report replaces the previous */
    if (h->n > 0 && h->rows[h->n - 1].iteration == p->iteration) {
        h->rows[h->n - 1] = *p;
        return 0;
    }
    if (h->n == h->cap) {
        size_t cap = h->cap ? 2 * h->cap : 256;
        sm_progress *rows = realloc(h->rows, cap * sizeof *rows);
        if (!rows)
            return -1;
        h->rows = rows;
        h->cap = cap;
    }
    h->rows[h->n++] = *p;
    return 0;
}

/* ---- messages ---- */

static void print_failed_event(int code, const char *msg)
{
    jsonw w;
    jsonw_init(&w, stdout, 0);
    jsonw_object_begin(&w, NULL);
    jsonw_string(&w, "type", "failed");
    jsonw_string(&w, "event", "failed");
    jsonw_string(&w, "message", msg);
    jsonw_int(&w, "exit_code", code);
    jsonw_object_end(&w);
    fputc('\n', stdout);
    fflush(stdout);
}

/* Reports an error (stderr, and an NDJSON "failed" event with --json)
 * and returns code. */
static int run_error(const run_options *o, int code, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

static int run_error(const run_options *o, int code, const char *fmt, ...)
{
    char msg[ARGS_MSG_LEN + 64];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    fprintf(stderr, "shapematch: error: %s\n", msg);
    if (o->json)
        print_failed_event(code, msg);
    return code;
}

/* "path: message", without repeating the path when the core's message
 * already names the file. */
static void file_error(char *msg, size_t cap, const char *path, const sm_error *err)
{
    const char *m = err->msg[0] ? err->msg : sm_status_name(err->code);
    size_t n = strlen(path);
    if (strncmp(m, path, n) == 0 && m[n] == ':') {
        m += n + 1;
        while (*m == ' ')
            m++;
    } else if (strstr(m, path)) {
        snprintf(msg, cap, "%s", m);
        return;
    }
    snprintf(msg, cap, "%s: %s", path, m);
}

/* ---- progress callback ---- */

static void print_progress_event(const sm_progress *p)
{
    jsonw w;
    jsonw_init(&w, stdout, 0);
    jsonw_object_begin(&w, NULL);
    jsonw_string(&w, "type", "progress");
    jsonw_string(&w, "event", "progress");
    jsonw_int(&w, "iteration", p->iteration);
    jsonw_number(&w, "J", p->J);
    jsonw_number(&w, "step", p->step);
    jsonw_number(&w, "boundary_l2", p->boundary_l2);
    jsonw_number(&w, "boundary_max", p->boundary_max);
    jsonw_number(&w, "min_quality", p->min_quality);
    jsonw_number(&w, "elapsed", p->elapsed);
    jsonw_int(&w, "accepted", p->accepted);
    jsonw_int(&w, "rejected", p->rejected);
    jsonw_object_end(&w);
    fputc('\n', stdout);
    fflush(stdout);
}

/* A core writer behind a temporary name: the core picks the format
 * from the name, so the temporary name keeps the extension. */
typedef struct write_job {
    const sm_mesh *mesh;
    const double *coords;
    const double *displacement;
    const double *distance;
    const sm_sol *sol;
} write_job;

typedef sm_status (*core_writer)(const char *path, const write_job *job, sm_error *err);

static sm_status write_mesh_job(const char *path, const write_job *j, sm_error *err)
{
    return sm_mesh_write_coords(path, j->mesh, j->coords, err);
}

static sm_status write_vtu_job(const char *path, const write_job *j, sm_error *err)
{
    return sm_vtu_write(path, j->mesh, j->coords, j->displacement, j->distance, err);
}

static sm_status write_sol_job(const char *path, const write_job *j, sm_error *err)
{
    return sm_sol_write(path, j->sol, err);
}

static int write_atomically(const char *path, core_writer fn, const write_job *job,
                            char *msg, size_t cap)
{
    char *tmp = fs_temp_name(path);
    if (!tmp) {
        snprintf(msg, cap, "out of memory writing '%s'", path);
        return -1;
    }
    sm_error err;
    sm_error_clear(&err);
    if (fn(tmp, job, &err) != SM_OK) {
        unlink(tmp);
        snprintf(msg, cap, "cannot write '%s': %s", path,
                 err.msg[0] ? err.msg : sm_status_name(err.code));
        free(tmp);
        return -1;
    }
    int rc = fs_commit_file(tmp, path, msg, cap);
    free(tmp);
    return rc;
}

static int write_snapshot(run_ctx *c, int iteration, const double *coords)
{
    char name[40];
    snprintf(name, sizeof name, "iter-%05d.mesh", iteration);
    char *path = fs_join(c->opt->outdir, name);
    if (!path) {
        snprintf(c->failure, sizeof c->failure, "out of memory");
        return -1;
    }
    write_job job = {.mesh = c->template_mesh, .coords = coords};
    int rc = write_atomically(path, write_mesh_job, &job, c->failure, sizeof c->failure);
    free(path);
    return rc;
}

static int on_progress(const sm_progress *p, const double *coords, void *user)
{
    run_ctx *c = user;
    if (history_push(&c->hist, p) != 0) {
        c->failed = CLI_EXIT_NUMERIC;
        snprintf(c->failure, sizeof c->failure, "out of memory recording the history");
        return 1;
    }
    if (coords) {
        memcpy(c->last_coords, coords, c->ncoords * sizeof *coords);
        c->have_coords = 1;
    }
    progress_update(&c->display, p);
    if (c->opt->json)
        print_progress_event(p);
    int every = c->opt->job.params.save_every;
    if (every > 0 && p->iteration > 0 && p->iteration % every == 0 && coords &&
        write_snapshot(c, p->iteration, coords) != 0) {
        c->failed = CLI_EXIT_OUTPUT;
        return 1;
    }
    if (cancel_requested && !c->cancel_noticed) {
        c->cancel_noticed = 1;
        if (!c->opt->quiet)
            progress_message(&c->display,
                             "shapematch: interrupted: stopping after this iteration "
                             "and writing the outputs (interrupt again to abort)");
    }
    return cancel_requested != 0;
}

/* ---- input checks ---- */

/* The clamp must hold at least one vertex but not all of them: an empty
 * clamp set leaves rigid motions free (singular system), a full one
 * leaves nothing to move.  The core refuses both too; checked here so
 * that the message names the flag. */
static int check_clamp_set(const job_options *j, const sm_mesh *m, char *msg, size_t cap)
{
    sm_error err;
    if (sm_clamp_check(m, &j->params, NULL, &err) == SM_OK)
        return 0;
    snprintf(msg, cap, "%s: %s", j->clamp_flag, err.msg);
    return -1;
}

static void warn_unknown_free_refs(run_ctx *c, const sm_mesh *m)
{
    const sm_params *p = &c->opt->job.params;
    for (int i = 0; i < p->n_free_refs; i++) {
        int found = 0;
        for (int32_t f = 0; f < m->nbfacets && !found; f++)
            found = m->bfacet_refs[f] == p->free_refs[i];
        if (!found)
            progress_message(&c->display,
                             "shapematch: warning: --free-boundary: no boundary facet of the "
                             "template has reference %ld",
                             (long)p->free_refs[i]);
    }
}

/* ---- outputs ---- */

typedef struct run_outcome {
    const run_options *opt;
    const sm_mesh *template_mesh;
    const sm_params *params;
    const sm_result *result;
    const history *hist;
    const char *status;          /* "finished", "cancelled", "failed" */
    const char *stop_reason;
    int exit_code;
    int32_t inverted;            /* elements with volume <= 0 at the end */
    double read_seconds;
} run_outcome;

static void csv_number(FILE *f, double v)
{
    char buf[JSON_NUMBER_LEN];
    if (isfinite(v))
        fputs(json_format_number(buf, v), f);
    else
        fprintf(f, "%g", v);
}

static void write_history(FILE *f, const history *h)
{
    fputs("iteration,J,step,boundary_l2,boundary_max,min_quality,elapsed,accepted,rejected\n", f);
    for (size_t i = 0; i < h->n; i++) {
        const sm_progress *p = &h->rows[i];
        fprintf(f, "%d,", p->iteration);
        const double vals[] = {p->J, p->step, p->boundary_l2, p->boundary_max,
                               p->min_quality, p->elapsed};
        for (size_t k = 0; k < sizeof vals / sizeof vals[0]; k++) {
            csv_number(f, vals[k]);
            fputc(',', f);
        }
        fprintf(f, "%d,%d\n", p->accepted, p->rejected);
    }
}

static void write_params_json(jsonw *w, const sm_params *p, int dim)
{
    jsonw_object_begin(w, "parameters");
    jsonw_object_begin(w, "clamp");
    jsonw_string(w, "kind", args_clamp_name(p->clamp));
    switch (p->clamp) {
    case SM_CLAMP_BALL:
        jsonw_array_begin(w, "center");
        for (int k = 0; k < dim; k++)
            jsonw_number(w, NULL, p->clamp_center[k]);
        jsonw_array_end(w);
        jsonw_number(w, "radius", p->clamp_radius);
        break;
    case SM_CLAMP_ELEMENTS:
    case SM_CLAMP_VERTICES:
        jsonw_array_begin(w, "refs");
        for (int i = 0; i < p->n_clamp_refs; i++)
            jsonw_int(w, NULL, p->clamp_refs[i]);
        jsonw_array_end(w);
        break;
    case SM_CLAMP_NONE:
        jsonw_number(w, "alpha", p->alpha);
        break;
    }
    jsonw_object_end(w);
    jsonw_array_begin(w, "free_boundary");
    for (int i = 0; i < p->n_free_refs; i++)
        jsonw_int(w, NULL, p->free_refs[i]);
    jsonw_array_end(w);
    jsonw_number(w, "young", p->young);
    jsonw_number(w, "poisson", p->poisson);
    jsonw_int(w, "max_iter", p->max_iter);
    jsonw_number(w, "tol_step", p->tol_step);
    jsonw_number(w, "tol_boundary", p->tol_boundary);
    jsonw_number(w, "min_quality", p->min_quality);
    jsonw_int(w, "save_every", p->save_every);
    jsonw_number(w, "step_initial", p->step_initial);
    jsonw_number(w, "step_max", p->step_max);
    jsonw_int(w, "refactor_every", p->refactor_every);
    jsonw_object_end(w);
}

/* The members shared with the daemon's result document (proto's
 * events.schema.json, $defs/result: same names, same meaning). */
static void write_result_members(jsonw *w, const run_outcome *s)
{
    const sm_result *r = s->result;
    jsonw_string(w, "stop_reason", s->stop_reason);
    jsonw_int(w, "iterations", r->iterations);
    jsonw_number(w, "J_initial", r->J_initial);
    jsonw_number(w, "J_final", r->J);
    jsonw_number(w, "boundary_l2", r->boundary_l2);
    jsonw_number(w, "boundary_max", r->boundary_max);
    jsonw_number(w, "min_quality", r->min_quality);
    jsonw_int(w, "accepted", r->accepted);
    jsonw_int(w, "rejected", r->rejected);
    jsonw_object_begin(w, "timings");
    jsonw_number(w, "read", s->read_seconds);
    jsonw_number(w, "setup", r->time.setup);
    jsonw_number(w, "sample", r->time.sample);
    jsonw_number(w, "assembly", r->time.assembly);
    jsonw_number(w, "factor", r->time.factor);
    jsonw_number(w, "solve", r->time.solve);
    jsonw_number(w, "step", r->time.step);
    jsonw_number(w, "total", r->time.total);
    jsonw_object_end(w);
    write_params_json(w, s->params, s->template_mesh->dim);
}

static void write_summary(FILE *f, const run_outcome *s)
{
    const sm_mesh *m = s->template_mesh;
    jsonw w;
    jsonw_init(&w, f, 1);
    jsonw_object_begin(&w, NULL);
    jsonw_string(&w, "shapematch_version", SM_VERSION);
    jsonw_string(&w, "status", s->status);
    jsonw_int(&w, "exit_code", s->exit_code);
    write_result_members(&w, s);
    jsonw_int(&w, "inverted_elements", s->inverted);
    jsonw_object_begin(&w, "inputs");
    jsonw_string(&w, "template", s->opt->template_path);
    jsonw_string(&w, "target_mesh", s->opt->target_mesh_path);
    jsonw_string(&w, "target_sol", s->opt->target_sol_path);
    jsonw_object_end(&w);
    jsonw_object_begin(&w, "template");
    jsonw_int(&w, "dimension", m->dim);
    jsonw_int(&w, "vertices", m->nverts);
    jsonw_int(&w, "elements", m->nelems);
    jsonw_int(&w, "facets", m->nfacets);
    jsonw_object_end(&w);
    jsonw_object_begin(&w, "outputs");
    jsonw_string(&w, "mesh", "result.mesh");
    jsonw_string(&w, "vtu", "result.vtu");
    jsonw_string(&w, "displacement", "displacement.sol");
    jsonw_string(&w, "history", "history.csv");
    jsonw_object_end(&w);
    jsonw_object_end(&w);
    fputc('\n', f);
}

typedef void (*stdio_writer)(FILE *f, const void *arg);

static void history_writer(FILE *f, const void *arg) { write_history(f, arg); }
static void summary_writer(FILE *f, const void *arg) { write_summary(f, arg); }

static int write_stdio_file(const char *dir, const char *name, stdio_writer fn,
                            const void *arg, char *msg, size_t cap)
{
    char *path = fs_join(dir, name);
    if (!path) {
        snprintf(msg, cap, "out of memory");
        return -1;
    }
    fs_atomic a;
    int rc = fs_atomic_open(&a, path, msg, cap);
    if (rc == 0) {
        fn(a.f, arg);
        rc = fs_atomic_commit(&a, msg, cap);
    }
    free(path);
    return rc;
}

static int write_core_file(const char *dir, const char *name, core_writer fn,
                           const write_job *job, char *msg, size_t cap)
{
    char *path = fs_join(dir, name);
    if (!path) {
        snprintf(msg, cap, "out of memory");
        return -1;
    }
    int rc = write_atomically(path, fn, job, msg, cap);
    free(path);
    return rc;
}

/* Writes the five outputs; summary.json last. */
static int write_outputs(const run_outcome *s, const sm_field *field,
                         const double *coords, char *msg, size_t cap)
{
    const sm_mesh *m = s->template_mesh;
    const char *dir = s->opt->outdir;
    size_t n = (size_t)m->nverts * (size_t)m->dim;
    int rc = -1;
    double *disp = malloc((n ? n : 1) * sizeof *disp);
    double *dist = malloc((m->nverts ? (size_t)m->nverts : 1) * sizeof *dist);
    sm_sol *sol = NULL;
    sm_error err;
    sm_error_clear(&err);
    if (!disp || !dist) {
        snprintf(msg, cap, "out of memory preparing the outputs");
        goto done;
    }
    for (size_t i = 0; i < n; i++)
        disp[i] = coords[i] - m->coords[i];
    /* consecutive vertices are usually close: the previous element found
     * is a good start for the next walk */
    int32_t hint = -1;
    for (int32_t v = 0; v < m->nverts; v++)
        dist[v] = sm_field_eval(field, coords + (size_t)v * (size_t)m->dim, &hint);
    if (sm_sol_alloc(&sol, m->dim, m->nverts, m->dim, &err) != SM_OK) {
        snprintf(msg, cap, "cannot prepare displacement.sol: %s", err.msg);
        goto done;
    }
    memcpy(sol->values, disp, n * sizeof *disp);

    write_job job = {.mesh = m, .coords = coords, .displacement = disp,
                     .distance = dist, .sol = sol};
    /* A summary.json left by an earlier run in the same directory must
     * not vouch for a set of files this run only partly replaced. */
    char *old_summary = fs_join(dir, "summary.json");
    if (!old_summary) {
        snprintf(msg, cap, "out of memory");
        goto done;
    }
    if (unlink(old_summary) != 0 && errno != ENOENT) {
        snprintf(msg, cap, "cannot remove the previous '%s': %s", old_summary, strerror(errno));
        free(old_summary);
        goto done;
    }
    free(old_summary);
    if (write_core_file(dir, "result.mesh", write_mesh_job, &job, msg, cap) != 0 ||
        write_core_file(dir, "result.vtu", write_vtu_job, &job, msg, cap) != 0 ||
        write_core_file(dir, "displacement.sol", write_sol_job, &job, msg, cap) != 0 ||
        write_stdio_file(dir, "history.csv", history_writer, s->hist, msg, cap) != 0 ||
        write_stdio_file(dir, "summary.json", summary_writer, s, msg, cap) != 0)
        goto done;
    rc = 0;
done:
    sm_sol_free(sol);
    free(disp);
    free(dist);
    return rc;
}

/* When the core reports cancellation as an error rather than as a stop
 * reason, the result may not be filled: rebuild it from the last
 * progress report, which matches the coordinates that get written. */
static void result_from_history(sm_result *r, const history *h, double started)
{
    if (h->n == 0)
        return;
    const sm_progress *first = &h->rows[0], *last = &h->rows[h->n - 1];
    r->iterations = last->iteration;
    r->J_initial = first->J;
    r->J = last->J;
    r->boundary_l2 = last->boundary_l2;
    r->boundary_max = last->boundary_max;
    r->min_quality = last->min_quality;
    r->accepted = last->accepted;
    r->rejected = last->rejected;
    if (!(r->time.total > 0))
        r->time.total = now_seconds() - started;
}

static int exit_code_of_run_status(sm_status st)
{
    switch (st) {
    case SM_ERR_FORMAT:
    case SM_ERR_INVALID:
        return CLI_EXIT_INPUT;
    case SM_ERR_CANCELLED:
        return CLI_EXIT_CANCELLED;
    default:
        return CLI_EXIT_NUMERIC;
    }
}

/* The final NDJSON line: a "finished" event of proto's events schema
 * (the summary under "result"), plus the local run's status, exit code
 * and output directory. */
static void print_finished_event(const run_outcome *s)
{
    jsonw w;
    jsonw_init(&w, stdout, 0);
    jsonw_object_begin(&w, NULL);
    jsonw_string(&w, "type", "finished");
    jsonw_string(&w, "event", "finished");
    jsonw_string(&w, "status", s->status);
    jsonw_int(&w, "exit_code", s->exit_code);
    jsonw_string(&w, "outdir", s->opt->outdir);
    jsonw_int(&w, "inverted_elements", s->inverted);
    jsonw_object_begin(&w, "result");
    write_result_members(&w, s);
    jsonw_object_end(&w);
    jsonw_object_end(&w);
    fputc('\n', stdout);
    fflush(stdout);
}

/* ---- the command ---- */

void cmd_run_help(void)
{
    printf("Usage: shapematch run --template T.mesh --target-mesh B.mesh --target-sol B.sol\n"
           "                      CLAMP [PARAMETERS] [--quiet] [--json] -o OUTDIR\n"
           "\n"
           "Deforms the template mesh onto the target shape given by its signed distance\n"
           "function (P1 on the background mesh B, negative inside), locally, no daemon.\n"
           "Mesh and solution files may be .mesh/.meshb and .sol/.solb, optionally .gz.\n"
           "\n"
           "Inputs and outputs:\n"
           "  --template FILE         template mesh (triangles in 2D, tetrahedra in 3D)\n"
           "  --target-mesh FILE      background mesh carrying the target distance\n"
           "  --target-sol FILE       signed distance of the target, one value per\n"
           "                          background vertex (scalar SolAtVertices)\n"
           "  -o, --output DIR        output directory (created if missing); receives\n"
           "                          result.mesh, result.vtu, displacement.sol,\n"
           "                          history.csv, summary.json\n"
           "\n");
    job_options_help(stdout);
    printf("\n"
           "Display:\n"
           "  -q, --quiet             no progress display\n"
           "  --json                  one JSON object per iteration on stdout (NDJSON),\n"
           "                          then {\"event\":\"finished\",...}\n"
           "  -h, --help              this help\n"
           "\n"
           "Ctrl-C stops the run after the current iteration and still writes the\n"
           "outputs (stop reason \"cancelled\"); a second Ctrl-C aborts at once.\n"
           "\n%s",
           cli_exit_codes_help);
}

int cmd_run(int argc, char **argv)
{
    /* installed first, so that an early Ctrl-C still ends in a clean
     * "cancelled" run rather than a killed process */
    install_cancel_handlers();

    run_options opt;
    char msg[ARGS_MSG_LEN];
    switch (args_parse_run(argc, argv, &opt, msg, sizeof msg)) {
    case ARGS_HELP:
        cmd_run_help();
        return CLI_EXIT_OK;
    case ARGS_ERROR:
        fprintf(stderr, "shapematch run: %s\nTry 'shapematch run --help' for more information.\n",
                msg);
        return CLI_EXIT_USAGE;
    case ARGS_OK:
        break;
    }

    run_ctx ctx;
    memset(&ctx, 0, sizeof ctx);
    ctx.opt = &opt;
    progress_init(&ctx.display, stderr, opt.quiet);

    int code = CLI_EXIT_OK;
    sm_mesh *tmpl = NULL, *checked = NULL, *bg = NULL;
    sm_sol *target = NULL;
    sm_field *field = NULL;
    double *coords = NULL;
    sm_error err;
    sm_error_clear(&err);
    char emsg[ARGS_MSG_LEN];
    double started = now_seconds();

    /* ---- inputs ---- */
    if (sm_mesh_read(opt.template_path, &tmpl, &err) != SM_OK) {
        file_error(emsg, sizeof emsg, opt.template_path, &err);
        code = run_error(&opt, CLI_EXIT_INPUT, "template: %s", emsg);
        goto done;
    }
    if (sm_mesh_read(opt.target_mesh_path, &bg, &err) != SM_OK) {
        file_error(emsg, sizeof emsg, opt.target_mesh_path, &err);
        code = run_error(&opt, CLI_EXIT_INPUT, "target mesh: %s", emsg);
        goto done;
    }
    if (tmpl->dim != bg->dim) {
        code = run_error(&opt, CLI_EXIT_INPUT,
                         "dimension mismatch: the template '%s' is %dD but the target mesh "
                         "'%s' is %dD",
                         opt.template_path, tmpl->dim, opt.target_mesh_path, bg->dim);
        goto done;
    }
    if (sm_sol_read(opt.target_sol_path, &target, &err) != SM_OK) {
        file_error(emsg, sizeof emsg, opt.target_sol_path, &err);
        code = run_error(&opt, CLI_EXIT_INPUT, "target distance: %s", emsg);
        goto done;
    }
    if (target->ncomp != 1) {
        code = run_error(&opt, CLI_EXIT_INPUT,
                         "target distance '%s' is a vector field (%d components); a scalar "
                         "signed distance is expected",
                         opt.target_sol_path, target->ncomp);
        goto done;
    }
    if (target->nverts != bg->nverts) {
        code = run_error(&opt, CLI_EXIT_INPUT,
                         "target distance '%s' has %ld values but the target mesh '%s' has "
                         "%ld vertices",
                         opt.target_sol_path, (long)target->nverts, opt.target_mesh_path,
                         (long)bg->nverts);
        goto done;
    }
    for (int32_t v = 0; v < target->nverts; v++)
        if (!isfinite(target->values[v])) {
            code = run_error(&opt, CLI_EXIT_INPUT,
                             "target distance '%s': value %ld is not finite",
                             opt.target_sol_path, (long)v + 1);
            goto done;
        }
    /* validate the template on a copy (building the boundary reorients
     * elements, and the outputs keep the input's connectivity as is) */
    if (sm_mesh_clone(tmpl, &checked, &err) != SM_OK ||
        sm_mesh_build_boundary(checked, &err) != SM_OK) {
        file_error(emsg, sizeof emsg, opt.template_path, &err);
        code = run_error(&opt, err.code == SM_ERR_NOMEM ? CLI_EXIT_NUMERIC : CLI_EXIT_INPUT,
                         "template: %s", emsg);
        goto done;
    }
    if (sm_field_new(bg, target->values, &field, &err) != SM_OK) {
        file_error(emsg, sizeof emsg, opt.target_mesh_path, &err);
        code = run_error(&opt, err.code == SM_ERR_NOMEM ? CLI_EXIT_NUMERIC : CLI_EXIT_INPUT,
                         "target mesh: %s", emsg);
        goto done;
    }
    double read_seconds = now_seconds() - started;

    /* ---- parameters against the inputs ---- */
    if (job_options_check_dim(&opt.job, tmpl->dim, msg, sizeof msg) != 0 ||
        check_clamp_set(&opt.job, checked, msg, sizeof msg) != 0) {
        code = run_error(&opt, CLI_EXIT_USAGE, "%s", msg);
        goto done;
    }
    if (sm_params_validate(&opt.job.params, tmpl->dim, &err) != SM_OK) {
        code = run_error(&opt, CLI_EXIT_USAGE, "invalid parameters: %s", err.msg);
        goto done;
    }
    warn_unknown_free_refs(&ctx, checked);

    /* ---- output directory, before the long part ---- */
    if (fs_mkdir_p(opt.outdir, msg, sizeof msg) != 0 ||
        fs_check_writable(opt.outdir, msg, sizeof msg) != 0) {
        code = run_error(&opt, CLI_EXIT_OUTPUT, "output directory: %s", msg);
        goto done;
    }

    /* ---- the run ---- */
    ctx.template_mesh = tmpl;
    ctx.ncoords = (size_t)tmpl->nverts * (size_t)tmpl->dim;
    coords = malloc((ctx.ncoords ? ctx.ncoords : 1) * sizeof *coords);
    ctx.last_coords = malloc((ctx.ncoords ? ctx.ncoords : 1) * sizeof *coords);
    if (!coords || !ctx.last_coords) {
        code = run_error(&opt, CLI_EXIT_NUMERIC, "out of memory");
        goto done;
    }
    sm_result result;
    memset(&result, 0, sizeof result);
    sm_match_opts mopts = {.template_mesh = tmpl, .prepared = checked, .target = field,
                           .params = &opt.job.params};
    sm_match_callbacks cb = {.progress = on_progress, .user = &ctx, .cancel = &cancel_requested};
    sm_status st = sm_match_run(&mopts, &cb, coords, &result, &err);
    progress_finish(&ctx.display);
    if (ctx.failed) {
        code = run_error(&opt, ctx.failed, "%s", ctx.failure);
        goto done;
    }
    int cancelled = 0;
    const double *final_coords = coords;
    if (st == SM_ERR_CANCELLED) {
        cancelled = 1;
        final_coords = ctx.have_coords ? ctx.last_coords : tmpl->coords;
        result_from_history(&result, &ctx.hist, started);
        result.stop = SM_STOP_CANCELLED;
    } else if (st != SM_OK) {
        code = run_error(&opt, exit_code_of_run_status(st), "the run failed (%s): %s",
                         sm_status_name(st), err.msg);
        goto done;
    } else if (result.stop == SM_STOP_CANCELLED) {
        cancelled = 1;
    }

    /* The core ends with a step-tolerance stop when not even the first
     * step can be taken: for the user that is a failure (nothing moved),
     * reported as such, with the outputs still written for diagnosis. */
    int stuck = !cancelled && result.stop == SM_STOP_STEP && result.iterations == 0;

    sm_quality_stats quality;
    sm_mesh_quality(checked, final_coords, &quality);
    run_outcome outcome = {
        .opt = &opt,
        .template_mesh = tmpl,
        .params = &opt.job.params,
        .result = &result,
        .hist = &ctx.hist,
        .status = cancelled ? "cancelled" : stuck ? "failed" : "finished",
        .stop_reason = cancelled ? "cancelled" : sm_stop_reason_name(result.stop),
        .exit_code = cancelled ? CLI_EXIT_CANCELLED : stuck ? CLI_EXIT_NUMERIC : CLI_EXIT_OK,
        .inverted = quality.ninverted,
        .read_seconds = read_seconds,
    };
    if (write_outputs(&outcome, field, final_coords, msg, sizeof msg) != 0) {
        code = run_error(&opt, CLI_EXIT_OUTPUT, "%s", msg);
        goto done;
    }
    code = outcome.exit_code;
    if (stuck)
        fprintf(stderr,
                "shapematch: error: no valid step from the initial mesh (boundary error %.3e); "
                "the template may already match the target (see --tol-boundary) or the "
                "parameters prevent any move (--min-quality, --tol-step)\n",
                result.boundary_l2);
    else if (!opt.quiet)
        fprintf(stderr,
                "shapematch: %s after %d iteration%s: J %.6e -> %.6e, boundary error %.3e "
                "(max %.3e), min quality %.3f%s; outputs in %s\n",
                outcome.stop_reason, result.iterations, result.iterations == 1 ? "" : "s",
                result.J_initial, result.J, result.boundary_l2, result.boundary_max,
                result.min_quality,
                quality.ninverted ? " (INVERTED ELEMENTS)" : "", opt.outdir);
    if (opt.json)
        print_finished_event(&outcome);

done:
    free(coords);
    free(ctx.last_coords);
    free(ctx.hist.rows);
    sm_field_free(field);
    sm_sol_free(target);
    sm_mesh_free(checked);
    sm_mesh_free(bg);
    sm_mesh_free(tmpl);
    return code;
}
