/* The job runner: the run, its hooks and its outcome (see
 * sm_job_runner.h). */
#include "job/sm_job_runner.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "job/sm_job_threads.h"
#include "shapematch/sm_atomic.h"
#include "shapematch/sm_io.h"
#include "shapematch/sm_path.h"
#include "sm_proto_vocab.h"

const char *sm_job_outcome_name(sm_job_outcome outcome)
{
    switch (outcome) {
    case SM_JOB_OUTCOME_FINISHED: return "finished";
    case SM_JOB_OUTCOME_CANCELLED: return "cancelled";
    case SM_JOB_OUTCOME_FAILED: return "failed";
    }
    return "unknown";
}

/* ------------------------------------------------------------- the run */

typedef struct run_ctx {
    const sm_job_inputs *in;
    const sm_job_hooks *hooks;
    sm_job_run *run;
    sm_status failed;            /* SM_OK, or why the hook stopped the run */
    sm_error error;
    int *snapshots;              /* the iterations written, in order */
    int nsnapshots, snapshots_cap;
} run_ctx;

/* One row per iteration: a repeated report replaces the previous. */
static int history_push(sm_job_run *run, const sm_progress *p)
{
    if (run->nhistory > 0 && run->history[run->nhistory - 1].iteration == p->iteration) {
        run->history[run->nhistory - 1] = *p;
        return 0;
    }
    if (run->nhistory == run->history_cap) {
        size_t cap = run->history_cap ? 2 * run->history_cap : 256;
        sm_progress *rows = realloc(run->history, cap * sizeof *rows);
        if (!rows)
            return -1;
        run->history = rows;
        run->history_cap = cap;
    }
    run->history[run->nhistory++] = *p;
    return 0;
}

/* One file of the snapshot directory, atomically: the template's mesh at
 * coords as .mesh or (vtu set) as .vtu with the displacement from the
 * template as read and d, the target's signed distance, at each vertex
 * (the fields of result.vtu). */
static sm_status snapshot_file(run_ctx *c, const char *name, const double *coords, int vtu)
{
    const sm_mesh *m = c->in->template_mesh;
    char *path = sm_path_join(c->hooks->snapshot_dir, name);
    double *disp = vtu ? malloc(((size_t)m->nverts * (size_t)m->dim + 1) * sizeof *disp) : NULL;
    double *dist = vtu ? malloc(((size_t)m->nverts + 1) * sizeof *dist) : NULL;
    if (!path || (vtu && (!disp || !dist))) {
        free(path);
        free(disp);
        free(dist);
        return sm_error_set(&c->error, SM_ERR_NOMEM, "out of memory");
    }
    for (size_t i = 0; disp && i < (size_t)m->nverts * (size_t)m->dim; i++)
        disp[i] = coords[i] - m->coords[i];
    if (dist)
        sm_field_eval_points(c->in->field, m->nverts, coords, NULL, dist);
    sm_atomic a;
    sm_status st = sm_atomic_reserve(&a, path, &c->error);
    if (st == SM_OK) {
        st = vtu ? sm_vtu_write(a.tmp_path, m, coords, disp, dist, &c->error)
                 : sm_mesh_write_coords(a.tmp_path, m, coords, &c->error);
        if (st == SM_OK)
            st = sm_atomic_commit(&a, c->hooks->write_flags, &c->error);
        else
            sm_atomic_abort(&a);
    }
    free(disp);
    free(dist);
    free(path);
    return st;
}

/* SNAPSHOT_DIR/snapshots.pvd: the .vtu snapshots written so far (the
 * first state, every K-th iteration, the final state), as a ParaView
 * time series whose timestep is the iteration. */
static sm_status snapshot_collection(run_ctx *c)
{
    char *path = sm_path_join(c->hooks->snapshot_dir, SM_SNAPSHOT_PVD);
    if (!path)
        return sm_error_set(&c->error, SM_ERR_NOMEM, "out of memory");
    sm_atomic a;
    sm_status st = sm_atomic_open(&a, path, &c->error);
    if (st == SM_OK) {
        fprintf(a.f, "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n"
                     "  <Collection>\n");
        for (int i = 0; i < c->nsnapshots; i++)
            fprintf(a.f, "    <DataSet timestep=\"%d\" file=\"" SM_SNAPSHOT_VTU_FORMAT "\"/>\n",
                    c->snapshots[i], c->snapshots[i]);
        fprintf(a.f, "  </Collection>\n</VTKFile>\n");
        st = sm_atomic_commit(&a, c->hooks->write_flags, &c->error);
    }
    free(path);
    return st;
}

/* SNAPSHOT_DIR/iter-NNNNN.mesh and .vtu, then the collection. */
static sm_status write_snapshot(run_ctx *c, int iteration, const double *coords)
{
    char name[64], vtu[64];
    snprintf(name, sizeof name, SM_SNAPSHOT_FORMAT, iteration);
    snprintf(vtu, sizeof vtu, SM_SNAPSHOT_VTU_FORMAT, iteration);
    if (c->nsnapshots == c->snapshots_cap) {
        int cap = c->snapshots_cap ? 2 * c->snapshots_cap : 64;
        int *grown = realloc(c->snapshots, (size_t)cap * sizeof *grown);
        if (!grown)
            return sm_error_set(&c->error, SM_ERR_NOMEM, "out of memory");
        c->snapshots = grown;
        c->snapshots_cap = cap;
    }
    sm_status st = snapshot_file(c, name, coords, 0);
    if (st == SM_OK)
        st = snapshot_file(c, vtu, coords, 1);
    if (st == SM_OK) {
        c->snapshots[c->nsnapshots++] = iteration;
        st = snapshot_collection(c);
    }
    if (st != SM_OK)
        sm_error_prefix(&c->error, "cannot write the snapshot of iteration %d", iteration);
    return st;
}

static int on_progress(const sm_progress *p, const double *coords, void *user)
{
    run_ctx *c = user;
    if (history_push(c->run, p) != 0) {
        c->failed = sm_error_set(&c->error, SM_ERR_NOMEM, "out of memory recording the history");
        return 1;
    }
    const sm_job_hooks *h = c->hooks;
    /* the first state (iteration 0) and every K-th; the final one after
     * the run (final_snapshot) */
    int every = c->in->params.save_every;
    if (h->snapshot_dir && every > 0 && p->iteration % every == 0 && coords &&
        (c->failed = write_snapshot(c, p->iteration, coords)) != SM_OK)
        return 1;
    if (h->shape && coords && h->shape(p, coords, h->user))
        return 1;
    return h->progress ? h->progress(p, h->user) : 0;
}

/* The final state among the snapshots, unless the last one written is
 * it (a run whose last iteration is a multiple of K). */
static sm_status final_snapshot(run_ctx *c)
{
    const sm_job_run *run = c->run;
    if (!c->hooks->snapshot_dir || c->in->params.save_every <= 0 || run->nhistory == 0)
        return SM_OK;
    int last = run->history[run->nhistory - 1].iteration;
    if (c->nsnapshots > 0 && c->snapshots[c->nsnapshots - 1] == last)
        return SM_OK;
    return write_snapshot(c, last, run->coords);
}

/* Hands warnings from index from on to the hook. */
static void tell_warnings(const run_ctx *c, int from)
{
    for (int i = from; c->hooks->warning && i < c->run->warnings.n; i++)
        c->hooks->warning(&c->run->warnings.w[i], c->hooks->user);
}

/* The run under the thread policy: from the template side set up while
 * the inputs were read (in->match, consumed) when there is one, else
 * from scratch. */
static sm_status run_match(sm_job_inputs *in, const sm_match_opts *opts,
                           const sm_match_callbacks *cb, sm_job_run *run, sm_error *err)
{
    if (in->match_status != SM_OK) {
        if (err)
            *err = in->match_error;
        return in->match_status;
    }
    int limit = sm_job_threads_apply(opts->template_mesh->nelems);
    sm_status st;
    if (in->match) {
        sm_match_use_coverage(in->match, opts->coverage);
        st = opts->start ? sm_match_set_start(in->match, opts->start, err) : SM_OK;
        if (st == SM_OK)
            st = sm_match_execute(in->match, opts->target, cb, run->coords, &run->result, err);
        sm_match_free(in->match);
        in->match = NULL;
    } else {
        st = sm_match_run(opts, cb, run->coords, &run->result, err);
    }
    sm_job_threads_restore(limit);
    return st;
}

/* A cancel during the alignment ends the run there, without setting up
 * the descent (its factorization alone can take seconds): the template
 * as read is the state reached, and what only the descent measures (J,
 * the boundary error, the quality) is unknown: NaN, null in summary.json. */
static void cancelled_in_alignment(const sm_job_inputs *in, sm_job_run *run)
{
    const sm_mesh *m = in->template_mesh;
    memcpy(run->coords, m->coords, (size_t)m->nverts * (size_t)m->dim * sizeof *run->coords);
    sm_result *r = &run->result;
    memset(r, 0, sizeof *r);
    r->stop = SM_STOP_CANCELLED;
    r->J_initial = r->J = r->boundary_l2 = r->boundary_max = r->boundary_rms = NAN;
    r->min_quality = NAN;
    r->diameter = sm_mesh_diameter(m, m->coords);
    r->time.total = run->alignment.result.seconds;
    run->outcome = SM_JOB_OUTCOME_CANCELLED;
    run->exit_code = SM_JOB_EXIT_CANCELLED;
    snprintf(run->message, sizeof run->message,
             "cancelled during the alignment (%.3g s): the template was not moved",
             run->alignment.result.seconds);
}

sm_status sm_job_run_exec(sm_job_inputs *in, const sm_job_hooks *hooks, sm_job_run *run,
                          sm_error *err)
{
    memset(run, 0, sizeof *run);
    const sm_mesh *m = in->template_mesh;
    size_t n = (size_t)m->nverts * (size_t)m->dim;
    run->coords = malloc((n ? n : 1) * sizeof *run->coords);
    if (!run->coords)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for a mesh of %ld vertices",
                            (long)m->nverts);
    sm_job_hooks none = {0};
    run_ctx c = {.in = in, .hooks = hooks ? hooks : &none, .run = run, .failed = SM_OK};
    sm_error_clear(&c.error);
    /* the alignment first: from here on the run sees the moved template
     * (view), while in keeps the template as read for the outputs */
    sm_status st = sm_job_align(in, c.hooks->cancel, &run->alignment, err);
    if (st != SM_OK)
        return st;
    if (run->alignment.cancelled) {
        cancelled_in_alignment(in, run);
        return SM_OK;
    }
    if (run->alignment.done && in->match) { /* set up on the unmoved template */
        sm_match_free(in->match);
        in->match = NULL;
    }
    if (run->alignment.done && c.hooks->alignment)
        c.hooks->alignment(&run->alignment, c.hooks->user);
    sm_job_inputs view;
    sm_job_aligned_view(in, &run->alignment, &view);
    sm_match_opts opts = {.template_mesh = view.template_mesh, .prepared = view.prepared,
                          .target = in->field, .params = &view.params};
    sm_match_callbacks cb = {.progress = on_progress, .user = &c, .cancel = c.hooks->cancel};
    st = sm_job_check_sign(&view, &run->warnings, err);
    if (st != SM_OK)
        return st;
    tell_warnings(&c, 0);
    int told = run->warnings.n;
    /* the target's samples: its own surface when it has one (kept for
     * the alignment when there was one), else the zero level set of its
     * field (sm_coverage.h) */
    sm_coverage *cov = NULL;
    const sm_surface *exact = in->surface ? in->surface : in->has_surface ? in->target_surface : NULL;
    if (in->coverage && !run->alignment.done) { /* built beside the set-up */
        cov = in->coverage;
        in->coverage = NULL;
        st = SM_OK;
    } else {
        st = sm_coverage_new(in->field, exact, view.prepared ? view.prepared : in->prepared,
                             view.params.free_refs, view.params.n_free_refs, &cov, err);
    }
    if (st != SM_OK) {
        sm_error_prefix(err, "target");
        return st;
    }
    opts.coverage = cov;
    double *start = NULL;
    if (c.hooks->start && (start = malloc((n ? n : 1) * sizeof *start)) &&
        !c.hooks->start(view.prepared, &view.params, in->field, &run->alignment, start,
                         c.hooks->user)) {
        free(start);
        start = NULL;
    }
    opts.start = start;
    st = run_match(run->alignment.done ? &view : in, &opts, &cb, run, err);
    free(start);
    if (c.failed == SM_OK && st == SM_OK)
        c.failed = final_snapshot(&c);
    free(c.snapshots);
    if (c.failed != SM_OK) {
        if (err)
            *err = c.error;
        sm_coverage_free(cov);
        return c.failed;
    }
    if (st != SM_OK) {
        sm_coverage_free(cov);
        return st;
    }
    const sm_result *r = &run->result;
    if (r->stop == SM_STOP_CANCELLED) {
        run->outcome = SM_JOB_OUTCOME_CANCELLED;
        run->exit_code = SM_JOB_EXIT_CANCELLED;
    } else if ((r->stop == SM_STOP_STEP || r->stop == SM_STOP_QUALITY) && r->iterations == 0) {
        run->outcome = SM_JOB_OUTCOME_FAILED;
        run->exit_code = SM_JOB_EXIT_NUMERIC;
        snprintf(run->message, sizeof run->message,
                 "no valid step from the initial mesh (boundary RMS %.3e, L2 %.3e); the template "
                 "may already match the target (see tol_boundary) or the parameters prevent any "
                 "move (min_quality, tol_step)",
                 r->boundary_rms, r->boundary_l2);
    } else {
        run->outcome = SM_JOB_OUTCOME_FINISHED;
        run->exit_code = SM_JOB_EXIT_OK;
    }
    sm_quality_stats q;
    sm_mesh_quality(in->prepared, run->coords, &q);
    run->inverted = q.ninverted;
    sm_job_check_result(&view, run->coords, r, run->outcome == SM_JOB_OUTCOME_FINISHED,
                        &run->warnings, &run->resolution);
    if (run->resolution > 0 && r->distance.result_to_target.rms > SM_JOB_RESOLVED_FACTOR * run->resolution)
        run->result.converged = 0;
    if (!sm_job_check_coverage(&view, cov, r, run->resolution,
                               run->outcome == SM_JOB_OUTCOME_FINISHED, &run->warnings))
        run->result.converged = 0;
    sm_coverage_free(cov);
    if (run->outcome != SM_JOB_OUTCOME_FINISHED)
        run->result.converged = 0;
    else if (!run->result.converged)
        run->exit_code = SM_JOB_EXIT_NOT_CONVERGED;
    tell_warnings(&c, told);
    return SM_OK;
}

void sm_job_run_free(sm_job_run *run)
{
    if (!run)
        return;
    free(run->coords);
    free(run->history);
    sm_job_alignment_free(&run->alignment);
    run->coords = NULL;
    run->history = NULL;
    run->nhistory = run->history_cap = 0;
}
