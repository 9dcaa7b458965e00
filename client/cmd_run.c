/* `shapematch run`: one matching job run locally, with no daemon.
 *
 * The job goes through the job runner of proto/job/ (sm_job_inputs.h,
 * sm_job_runner.h, sm_job_results.h), the one `shapematch-worker` uses
 * too: the same input checks, the same run, the same result set and
 * summary.json as a job on the daemon (sm_job_results.h lists the files).  What is the CLI's own is
 * the framing: option names in messages, the progress line (or NDJSON
 * events with --json), Ctrl-C, the exit codes and the final line. */
#include <errno.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "args.h"
#include "cli.h"
#include "fsutil.h"
#include "progress.h"
#include "shapematch/sm_atomic.h"
#include "job/sm_job_inputs.h"
#include "job/sm_job_results.h"
#include "job/sm_job_runner.h"
#include "sm_json.h"
#include "sm_proto_events.h"

_Static_assert((int)CLI_EXIT_INPUT == (int)SM_JOB_EXIT_INPUT &&
                   (int)CLI_EXIT_NUMERIC == (int)SM_JOB_EXIT_NUMERIC &&
                   (int)CLI_EXIT_OUTPUT == (int)SM_JOB_EXIT_OUTPUT &&
                   (int)CLI_EXIT_CANCELLED == (int)SM_JOB_EXIT_CANCELLED &&
                   (int)CLI_EXIT_NOT_CONVERGED == (int)SM_JOB_EXIT_NOT_CONVERGED,
               "the job runner's exit codes are the CLI's");

/* Set by SIGINT/SIGTERM and polled by sm_match_run between iterations.
 * The one piece of global state of the client: a signal handler has no
 * other way to reach the run.  The core takes a `const volatile int *`,
 * which is what sig_atomic_t is on the platforms we build for. */
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


typedef struct run_ctx {
    const run_options *opt;
    progress_display display;
    int cancel_noticed;
} run_ctx;

/* ---- NDJSON on stdout (--json) ---- */

/* {"type": TYPE, "event": TYPE}: the events of proto's schema, with the
 * older "event" member kept for scripts that read it. */
static json_t *event_object(const char *type)
{
    return json_pack("{s:s,s:s}", "type", type, "event", type);
}

/* Prints obj as one line and releases it. */
static void print_line(json_t *obj)
{
    char *text = obj ? sm_json_dumps(obj, 0) : NULL;
    json_decref(obj);
    if (text)
        printf("%s\n", text);
    free(text);
    fflush(stdout);
}

static void print_failed_event(int code, const char *msg)
{
    json_t *obj = event_object("failed");
    if (obj) {
        json_object_set_new(obj, "message", sm_json_string_lossy(msg));
        json_object_set_new(obj, "exit_code", json_integer(code));
    }
    print_line(obj);
}

static void print_progress_event(const sm_progress *p)
{
    sm_event ev;
    sm_event_init(&ev, SM_EVENT_PROGRESS);
    ev.progress = *p;
    json_t *members = sm_event_to_jansson(&ev), *obj = event_object("progress");
    const char *key;
    json_t *value;
    if (members && obj)
        json_object_foreach(members, key, value)
            if (strcmp(key, "type") != 0)
                json_object_set(obj, key, value);
    json_decref(members);
    print_line(obj);
}

/* The final line: a "finished" event of proto's events schema (the
 * summary document under "result"), plus the local run's status, exit
 * code and output directory. */
static void print_finished_event(const run_options *o, const sm_job_run *run, json_t *summary)
{
    json_t *obj = event_object("finished");
    if (obj) {
        json_object_set_new(obj, "status", json_string(sm_job_outcome_name(run->outcome)));
        json_object_set_new(obj, "exit_code", json_integer(run->exit_code));
        json_object_set_new(obj, "outdir", sm_json_string_lossy(o->outdir));
        json_object_set_new(obj, "inverted_elements", json_integer(run->inverted));
        json_object_set(obj, "result", summary);
    }
    print_line(obj);
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

/* ---- progress hook ---- */

static int on_progress(const sm_progress *p, void *user)
{
    run_ctx *c = user;
    progress_update(&c->display, p);
    if (c->opt->json)
        print_progress_event(p);
    if (cancel_requested && !c->cancel_noticed) {
        c->cancel_noticed = 1;
        if (!c->opt->quiet)
            progress_message(&c->display,
                             "shapematch: interrupted: stopping after this iteration "
                             "and writing the outputs (interrupt again to abort)");
    }
    return cancel_requested != 0;
}

/* ---- checks that name the CLI's options ---- */

/* Parameters against the inputs: the dimension of the ball, the ranges,
 * then the clamp set (which must hold a vertex, not all of them, and
 * leave no rigid rotation free), each message naming the option. */
/* The target surface's health report, on stderr (also with --quiet:
 * it says what was repaired). */
static void print_surface_health(const run_options *o, const sm_job_inputs *in)
{
    const sm_surface_health *h = &in->health;
    fprintf(stderr,
            "shapematch: target surface %s: %lld component(s) (%lld open), open edges (holes) "
            "%lld, non-manifold edges %lld, reoriented %lld (%lld within a piece, %lld "
            "piece(s) turned over), duplicate %lld, degenerate %lld; ",
            o->target_surface_path, (long long)h->components, (long long)h->open_components,
            (long long)h->open_edges, (long long)h->nonmanifold_edges, (long long)h->reoriented,
            (long long)h->reoriented_within, (long long)h->pieces_turned,
            (long long)h->duplicates, (long long)h->degenerate);
    if (in->target_deferred)
        fprintf(stderr, "its background after the alignment\n");
    else
        fprintf(stderr, "distance on %s (%d vertices) in %.3f s\n",
                in->background_generated ? "a generated background" : o->target_mesh_path,
                in->background->nverts, in->sdf_seconds);
}

/* How the template was meshed (from --template-surface or
 * --template-image), on stderr also with --quiet: the run's template is
 * one nobody has seen yet. */
static void print_template_meshed(const run_options *o, const sm_job_inputs *in)
{
    const sm_template_mesh_info *i = &in->template_made.mesh;
    int d = in->template_mesh->dim;
    fprintf(stderr,
            "shapematch: template %s meshed by nglib in %.2f s: %d vertices, %d %s at size %g, "
            "quality min %.3f mean %.3f%s; volume %.6g (the surface encloses %.6g); written "
            "to %s/" SM_RESULT_TEMPLATE_FILE "\n",
            o->template_surface_path ? o->template_surface_path : o->template_image_path,
            i->seconds, (int)i->nverts, (int)i->nelems, d == 3 ? "tetrahedra" : "triangles",
            i->size, i->min_quality, i->mean_quality,
            i->passes > 1 ? " (optimised again)" : "", i->mesh_volume, i->surface_volume,
            o->outdir);
}

/* The target image's label summary, on stderr (also with --quiet: it
 * says which voxels became the target). */
static void print_image_summary(const run_options *o, const sm_job_inputs *in)
{
    const sm_job_image_info *im = &in->image;
    const sm_label_stats *s = &im->stats;
    char what[64];
    if (im->sel.has_label)
        snprintf(what, sizeof what, "label %lld", (long long)im->sel.label);
    else if (im->type == SM_VOXEL_F32 || im->type == SM_VOXEL_F64)
        snprintf(what, sizeof what, "values >= %g", im->sel.level);
    else
        snprintf(what, sizeof what, "every nonzero voxel");
    fprintf(stderr,
            "shapematch: target image %s: %s, %lld x %lld x %lld %s, spacing %g x %g x %g; %s: "
            "%lld voxels, %lld component(s), world box (%s) [%g, %g] x [%g, %g] x [%g, %g]; ",
            o->target_image_path, im->format, (long long)im->dims[0], (long long)im->dims[1],
            (long long)im->dims[2], sm_voxel_type_name(im->type), im->spacing[0], im->spacing[1],
            im->spacing[2], what, (long long)s->voxels, (long long)s->components,
            im->space == SM_IMAGE_SPACE_RAS ? "RAS" : "LPS", s->lo[0], s->hi[0], s->lo[1],
            s->hi[1], s->lo[2], s->hi[2]);
    if (in->target_deferred)
        fprintf(stderr, "its background after the alignment\n");
    else
        fprintf(stderr, "distance on %s (%d vertices, %lld exact) in %.3f s\n",
                in->background_generated ? "a generated background" : o->target_mesh_path,
                in->background->nverts, (long long)im->exact_vertices, in->sdf_seconds);
}

static int apply_params(run_options *o, sm_job_inputs *in)
{
    char msg[ARGS_MSG_LEN];
    sm_error err;
    sm_error_clear(&err);
    if (job_options_check_dim(&o->job, in->dim, msg, sizeof msg) != 0)
        return run_error(o, CLI_EXIT_USAGE, "%s", msg);
    if (job_options_resolve_names(&o->job, in->template_mesh, msg, sizeof msg) != 0)
        return run_error(o, CLI_EXIT_USAGE, "%s", msg);
    if (sm_params_validate(&o->job.params, in->dim, &err) != SM_OK)
        return run_error(o, CLI_EXIT_USAGE, "invalid parameters: %s", err.msg);
    if (sm_job_inputs_set_params(in, &o->job.params, &err) != SM_OK)
        return run_error(o, CLI_EXIT_USAGE, "%s: %s",
                         o->job.clamp_flag ? o->job.clamp_flag : "the default clamp", err.msg);
    return 0;
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

/* The alignment's one line (even with --quiet it is part of the result:
 * the matrix is in summary.json). */
static void on_alignment(const sm_job_alignment *a, void *user)
{
    run_ctx *c = user;
    const sm_align_result *r = &a->result;
    char start[48] = "moments";
    if (a->landmarks > 0)
        snprintf(start, sizeof start, "%ld landmarks", (long)a->landmarks);
    char after[128] = "";
    if (a->background_after)
        snprintf(after, sizeof after, "; background generated around the moved template in %.2f s",
                 a->background_seconds);
    progress_message(&c->display,
                     "shapematch: aligned (%s, from %s): onto the target's %s, scale %.6g, "
                     "boundary RMS %.3e -> %.3e, target to template %.3e, %d iterations, %.2f s%s",
                     sm_align_mode_name(a->mode), start, a->exact ? "surface" : "field",
                     r->scale, r->rms_before, r->rms_after, r->target_rms_after, r->iterations,
                     r->seconds, after);
}

static int exit_code_of_run_status(sm_status st)
{
    switch (st) {
    case SM_ERR_FORMAT:
    case SM_ERR_INVALID:
        return CLI_EXIT_INPUT;
    case SM_ERR_IO: /* a snapshot */
        return CLI_EXIT_OUTPUT;
    default:
        return CLI_EXIT_NUMERIC;
    }
}

/* The last word on stderr. */
static void print_final_line(const run_options *o, const sm_job_run *run)
{
    const sm_result *r = &run->result;
    if (run->outcome == SM_JOB_OUTCOME_FAILED)
        fprintf(stderr,
                "shapematch: error: no valid step from the initial mesh (boundary RMS %.3e, "
                "L2 %.3e); the template may already match the target (see --tol-boundary) or "
                "the parameters prevent any move (--min-quality, --tol-step)\n",
                r->boundary_rms, r->boundary_l2);
    else if (run->outcome == SM_JOB_OUTCOME_CANCELLED && run->message[0])
        fprintf(stderr, "shapematch: %s; outputs in %s\n", run->message, o->outdir);
    else if (!o->quiet || !r->converged) {
        char figures[256];
        progress_format_figures(figures, sizeof figures, &r->distance, r->boundary_rms,
                                r->boundary_max, r->boundary_l2);
        fprintf(stderr,
                "shapematch: %s after %d iteration%s, %s: %s, min quality %.3f, J %.6e -> "
                "%.6e%s; outputs in %s\n",
                sm_stop_reason_name(r->stop), r->iterations, r->iterations == 1 ? "" : "s",
                r->converged ? "converged" : "NOT CONVERGED", figures, r->min_quality,
                r->J_initial, r->J, run->inverted ? " (INVERTED ELEMENTS)" : "", o->outdir);
    }
    /* warnings even with --quiet: they are about the result, not progress */
    for (int i = 0; i < run->warnings.n; i++)
        fprintf(stderr, "shapematch: warning: %s: %s\n", run->warnings.w[i].code,
                run->warnings.w[i].message);
}

/* ---- the command ---- */

void cmd_run_help(void)
{
    printf("Usage: shapematch run --template T.mesh --target-mesh B.mesh --target-sol B.sol\n"
           "                      CLAMP [PARAMETERS] [--format LIST] [--quiet] [--json]\n"
           "                      -o OUTDIR\n"
           "       shapematch run --template T.mesh --target-surface S [--target-mesh B.mesh]\n"
           "                      CLAMP [PARAMETERS] [--format LIST] [--quiet] [--json]\n"
           "                      -o OUTDIR\n"           "       shapematch run --template T.mesh --target-image IMG [--label N]\n"
           "                      CLAMP [PARAMETERS] [--format LIST] [--quiet] [--json]\n"
           "                      -o OUTDIR\n"
           "       shapematch run --template-surface A.stl --target-surface B.stl -o OUTDIR\n"
           "       shapematch run --template-image IMG [--template-label N] TARGET -o OUTDIR\n"
           "\n"
           "Deforms the template mesh onto the target shape given by its signed distance\n"
           "function (P1 on the background mesh B, negative inside), locally, no daemon.\n"
           "Meshes may be .mesh/.meshb, Gmsh .msh or VTK .vtk/.vtu; solutions .sol/.solb;\n"
           "any optionally .gz.  Or: --target-surface S [--target-mesh B] matches onto a\n"
           "surface (STL, OBJ, PLY, OFF, VTK, Medit, Gmsh): its exact signed distance is\n"
           "computed on B, or on a background generated around template and surface.\n"
           "Or: --target-image IMG matches onto a label of a segmentation (NIfTI .nii[.gz],\n"
           "NRRD .nrrd/.nhdr, MetaImage .mha/.mhd): the distance to its boundary likewise.\n"
           "\n"
           "Inputs and outputs:\n"
           "  --template FILE         template mesh (triangles in 2D, tetrahedra in 3D)\n"
           "  --template-surface FILE or the template meshed (Netgen's nglib) from a\n"
           "                          closed surface (the --target-surface formats; a\n"
           "                          closed curve in 2D), written to OUTDIR/template.mesh\n"
           "  --template-image FILE   or from the boundary of a label-map image's label\n"
           "                          (--template-label below)\n"
           "  --target-mesh FILE      background mesh carrying the target distance\n"
           "  --target-sol FILE       signed distance of the target, one value per\n"
           "                          background vertex (scalar SolAtVertices)\n"
           "  --target-surface FILE   target surface instead of --target-sol; its health\n"
           "                          report (holes, reoriented facets, ...) on stderr\n"           "  --target-image FILE     label-map image instead of --target-sol (--label,\n"
           "                          --level, --image-space); its label summary on stderr\n"
           "  --landmarks T.csv,G.csv landmark pairs (rows x,y[,z], template's then\n"
           "                          target's) that start --align (Kabsch/Umeyama)\n");
    job_options_help_background(stdout);
    printf("  -o, --output DIR        output directory (created if missing); receives\n"
           "                          the --format files, history.csv and summary.json\n"
           "  --format LIST           comma-separated: mesh (result.mesh), meshb\n"
           "                          (result.meshb), vtu (result.vtu for ParaView,\n"
           "                          zlib-compressed), vtu-ascii (result.vtu in ASCII),\n"
           "                          binary (result.smmesh, proto/PAYLOAD.md), sol\n"
           "                          (displacement.sol), solb (displacement.solb); gz\n"
           "                          compresses them (FILE.gz; not result.vtu, which is\n"
           "                          compressed inside); default " RUN_DEFAULT_FORMATS "\n"
           "                          (the same files as 'shapematch fetch --format')\n"
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
           cli_exit_codes_run_help);
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

    int code;
    sm_job_inputs in;
    sm_job_run run;
    json_t *summary = NULL;
    memset(&run, 0, sizeof run);
    sm_error err;
    sm_error_clear(&err);
    int meshed = opt.template_surface_path || opt.template_image_path;
    const sm_job_files files = {.template_mesh = meshed ? NULL : opt.template_path,
                                .template_surface = opt.template_surface_path,
                                .template_image = opt.template_image_path,
                                .template_label = opt.job.background.template_label,
                                .template_size = opt.job.background.template_size,
                                .template_min_quality = opt.job.params.min_quality,
                                .target_mesh = opt.target_mesh_path,
                                .target_sol = opt.target_sol_path,
                                .target_surface = opt.target_surface_path,
                                .target_image = opt.target_image_path,
                                .background_size = opt.job.background.size,
                                .background_padding = opt.job.background.padding,
                                .landmarks_template = opt.landmarks ? opt.landmarks_template : NULL,
                                .landmarks_target = opt.landmarks ? opt.landmarks_target : NULL};

    /* ---- the template, the parameters against it, then the target
     * (the run's template side is set up meanwhile) ---- */
    sm_status st = sm_job_inputs_read_template(&files, SM_JOB_NAME_PATHS, &in, &err);
    if (st != SM_OK)
        return run_error(&opt, st == SM_ERR_NOMEM ? CLI_EXIT_NUMERIC : CLI_EXIT_INPUT, "%s", err.msg);
    if (meshed)
        print_template_meshed(&opt, &in);
    if ((code = apply_params(&opt, &in)) != 0)
        goto done;
    st = sm_job_inputs_read_target(&files, SM_JOB_NAME_PATHS, 1, &in, &err);
    if (st != SM_OK)
        return run_error(&opt, st == SM_ERR_NOMEM ? CLI_EXIT_NUMERIC : CLI_EXIT_INPUT, "%s", err.msg);
    if (in.has_surface)
        print_surface_health(&opt, &in);
    if (in.has_image)
        print_image_summary(&opt, &in);
    progress_set_goal(&ctx.display, in.params.max_iter, in.params.tol_boundary);
    warn_unknown_free_refs(&ctx, in.prepared);

    /* ---- output directory, before the long part ---- */
    if (fs_output_dir(opt.outdir, msg, sizeof msg) != 0) {
        code = run_error(&opt, CLI_EXIT_OUTPUT, "output directory: %s", msg);
        goto done;
    }

    /* ---- the run ---- */
    sm_job_hooks hooks = {.progress = on_progress, .alignment = on_alignment, .user = &ctx,
                          .cancel = &cancel_requested,
                          .snapshot_dir = opt.outdir, .write_flags = SM_ATOMIC_FSYNC};
    st = sm_job_run_exec(&in, &hooks, &run, &err);
    progress_finish(&ctx.display);
    if (st != SM_OK) {
        if (st == SM_ERR_IO || st == SM_ERR_NOMEM)
            code = run_error(&opt, exit_code_of_run_status(st), "%s", err.msg);
        else
            code = run_error(&opt, exit_code_of_run_status(st), "the run failed (%s): %s",
                             sm_status_name(st), err.msg);
        goto done;
    }

    /* ---- the result set; also for a failed start (for diagnosis) and a
     * cancelled run (the state reached) ---- */
    if (sm_job_write_selected(&in, &run, &files, opt.outdir, opt.outputs, SM_ATOMIC_FSYNC,
                              &err) != SM_OK) {
        code = run_error(&opt, CLI_EXIT_OUTPUT, "%s", err.msg);
        goto done;
    }
    code = run.exit_code;
    print_final_line(&opt, &run);
    if (opt.json && (summary = sm_job_summary_outputs(&in, &run, &files, opt.outputs)) != NULL)
        print_finished_event(&opt, &run, summary);

done:
    json_decref(summary);
    sm_job_run_free(&run);
    sm_job_inputs_free(&in);
    return code;
}
