/* libshapematch_job.so's API (shapematch_job.h): the job runner behind an
 * opaque handle.  The steps are those of `shapematch run` (client/
 * cmd_run.c): the template, the parameters checked against it, then the
 * target with the run's template side set up meanwhile, the run, the
 * result set on demand; so a job gives the CLI's vertices bit for bit. */
#include "shapematch_job.h"

#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <jansson.h>

#include "job/sm_job_arrays.h"
#include "job/sm_job_batch.h"
#include "job/sm_job_inputs.h"
#include "job/sm_job_results.h"
#include "job/sm_job_runner.h"
#include "job/sm_job_template_from.h"
#include "shapematch/sm_atomic.h"
#include "shapematch/sm_path.h"
#include "sm_json.h"
#include "sm_proto_params.h"
#include "sm_proto_vocab.h"

/* `shapematch run`'s default --format (client/args.h RUN_DEFAULT_FORMATS) */
#define API_DEFAULT_FORMATS "mesh,vtu,sol"

struct sm_run {
    sm_job_inputs in;
    sm_job_run run;
    sm_job_files names;  /* what the summary calls the inputs (owned copies) */
    char *summary;       /* JSON text, made once */
};

typedef struct api_ctx {
    sm_run_progress_fn progress;
    void *user;
} api_ctx;

static int on_progress(const sm_progress *p, void *user)
{
    const api_ctx *c = user;
    return c->progress ? c->progress(p, c->user) : 0;
}

static char *dup_or_null(const char *s)
{
    return s ? strdup(s) : NULL;
}

#define API_NFILES 7

/* What a part is called: its *_name, else its path, else "PART (array)"
 * when it is given in memory; NULL when not given. */
static const char *part_name(const char *name, const char *path, int in_memory,
                             const char *array_name)
{
    return name ? name : path ? path : in_memory ? array_name : NULL;
}

static void part_names(const sm_run_files *f, const char *out[API_NFILES])
{
    out[0] = part_name(f->template_name, f->template_mesh, f->template_arrays != NULL,
                       "template (array)");
    out[1] = part_name(f->target_mesh_name, f->target_mesh, f->target_mesh_arrays != NULL,
                       "target_mesh (array)");
    out[2] = part_name(f->target_sol_name, f->target_sol, f->target_sol_values != NULL,
                       "target_sol (array)");
    out[3] = part_name(f->target_surface_name, f->target_surface,
                       f->target_surface_arrays != NULL, "target_surface (array)");
    out[4] = part_name(f->target_image_name, f->target_image, 0, NULL);
    out[5] = part_name(NULL, f->template_surface, f->template_surface_arrays != NULL,
                       "template_surface (array)");
    out[6] = part_name(NULL, f->template_image, 0, NULL);
}

static int copy_names(const sm_run_files *f, sm_job_files *names)
{
    const char *src[API_NFILES];
    part_names(f, src);
    char *dst[API_NFILES];
    int bad = 0;
    for (int i = 0; i < API_NFILES; i++)
        bad |= (dst[i] = dup_or_null(src[i])) == NULL && src[i] != NULL;
    names->template_mesh = dst[0];
    names->target_mesh = dst[1];
    names->target_sol = dst[2];
    names->target_surface = dst[3];
    names->target_image = dst[4];
    names->template_surface = dst[5];
    names->template_image = dst[6];
    return bad ? -1 : 0;
}

static void free_names(sm_job_files *names)
{
    free((char *)names->template_mesh);
    free((char *)names->target_mesh);
    free((char *)names->target_sol);
    free((char *)names->target_surface);
    free((char *)names->target_image);
    free((char *)names->template_surface);
    free((char *)names->template_image);
}

void sm_run_free(sm_run *r)
{
    if (!r)
        return;
    sm_job_run_free(&r->run);
    sm_job_inputs_free(&r->in);
    free_names(&r->names);
    free(r->summary);
    free(r);
}

/* The parts given in memory, as core objects (NULL: read from the file). */
typedef struct api_given {
    sm_mesh *template_mesh, *target_mesh;
    sm_sol *target_sol;
    sm_surface *target_surface, *template_surface;
} api_given;

static void given_free(api_given *g)
{
    sm_mesh_free(g->template_mesh);
    sm_mesh_free(g->target_mesh);
    sm_sol_free(g->target_sol);
    sm_surface_free(g->target_surface);
    sm_surface_free(g->template_surface);
}

/* The inputs as `shapematch run` reads them: the params' syntax and
 * background members first, the template, the params against it, then
 * the target (prepare: the run's template side meanwhile).  A part in
 * memory is checked and copied where its file would be read; the
 * distance, once the template's dimension is known. */
static sm_status load_inputs(const sm_run_files *f, const char *params_json, sm_job_inputs *in,
                             sm_error *err)
{
    sm_params params;
    sm_background_params bg;
    size_t len = strlen(params_json);
    sm_status st = sm_job_params_from_json(params_json, len, 0, &params, &bg, err);
    if (st != SM_OK)
        return st;
    const char *names[API_NFILES];
    part_names(f, names);
    api_given g = {0};
    if ((f->template_arrays &&
         (st = sm_job_mesh_from_arrays(f->template_arrays, names[0], &g.template_mesh, err)) !=
             SM_OK) ||
        (f->target_mesh_arrays &&
         (st = sm_job_mesh_from_arrays(f->target_mesh_arrays, names[1], &g.target_mesh, err)) !=
             SM_OK) ||
        (f->target_surface_arrays &&
         (st = sm_job_surface_from_arrays(f->target_surface_arrays, names[3], &g.target_surface,
                                          err)) != SM_OK) ||
        (f->template_surface_arrays &&
         (st = sm_job_surface_from_arrays(f->template_surface_arrays, names[5],
                                          &g.template_surface, err)) != SM_OK)) {
        given_free(&g);
        return st;
    }
    sm_job_files files = {.template_mesh = names[0], .target_mesh = names[1],
                          .target_sol = names[2], .target_surface = names[3],
                          .target_image = f->target_image, .background_size = bg.size,
                          .background_padding = bg.padding,
                          .template_given = g.template_mesh, .target_mesh_given = g.target_mesh,
                          .target_surface_given = g.target_surface,
                          .template_surface = names[5], .template_image = f->template_image,
                          /* the argument, or the params' row */
                          .template_label = f->template_label ? f->template_label
                                                              : bg.template_label,
                          .template_size = bg.template_size,
                          .template_min_quality = params.min_quality,
                          .template_surface_given = g.template_surface};
    /* a meshed template stands in for the template mesh */
    if (names[5] || f->template_image)
        files.template_mesh = NULL;
    /* a file is read by its path, named (in messages) by its path too */
    if (!g.template_mesh && !files.template_surface && !files.template_image)
        files.template_mesh = f->template_mesh;
    if (!g.target_mesh)
        files.target_mesh = f->target_mesh;
    if (!f->target_sol_values)
        files.target_sol = f->target_sol;
    if (!g.target_surface)
        files.target_surface = f->target_surface;
    if ((st = sm_job_inputs_read_template(&files, SM_JOB_NAME_PATHS, in, err)) != SM_OK)
        goto done;
    if ((st = sm_job_params_from_json_for(params_json, len, in->template_mesh, &params, &bg,
                                           err)) != SM_OK ||
        (st = sm_job_inputs_set_params(in, &params, err)) != SM_OK) {
        if (st != SM_ERR_FORMAT && strncmp(err->msg, "params", 6) != 0)
            sm_error_prefix(err, "%s", params.clamp == SM_CLAMP_BALL ? "params.clamp"
                                                                     : "params.clamp.refs");
        sm_job_inputs_free(in);
        goto done;
    }
    if (f->target_sol_values &&
        (st = sm_job_sol_from_values(f->target_sol_values, f->target_sol_count, in->dim, names[2],
                                     &g.target_sol, err)) != SM_OK) {
        sm_job_inputs_free(in);
        goto done;
    }
    files.target_sol_given = g.target_sol;
    st = sm_job_inputs_read_target(&files, SM_JOB_NAME_PATHS, 1, in, err);
done:
    given_free(&g);
    return st;
}

/* Each part at most once: a file or arrays. */
static sm_status check_parts(const sm_run_files *f, sm_error *err)
{
    static const char *const parts[] = {"template", "target_mesh", "target_sol",
                                        "target_surface"};
    const int both[] = {f->template_mesh && f->template_arrays,
                        f->target_mesh && f->target_mesh_arrays,
                        f->target_sol && f->target_sol_values,
                        f->target_surface && f->target_surface_arrays};
    for (int k = 0; k < 4; k++)
        if (both[k])
            return sm_error_set(err, SM_ERR_INVALID, "%s: give a file or arrays, not both",
                                parts[k]);
    int templates = (f->template_mesh || f->template_arrays) +
                    (f->template_surface || f->template_surface_arrays) + (f->template_image != NULL);
    if (f->template_surface && f->template_surface_arrays)
        return sm_error_set(err, SM_ERR_INVALID, "template_surface: give a file or arrays, not both");
    if (templates == 0)
        return sm_error_set(err, SM_ERR_INVALID, "template: no file given");
    if (templates > 1)
        return sm_error_set(err, SM_ERR_INVALID,
                            "template: give one template: template, template_surface or "
                            "template_image");
    int mesh = f->target_mesh || f->target_mesh_arrays;
    int sol = f->target_sol || f->target_sol_values;
    int surface = f->target_surface || f->target_surface_arrays;
    /* the combinations the CLI's options and the daemon's parts allow (the
     * inputs reader takes them for granted) */
    if (!surface && !f->target_image && !(mesh && sol))
        return sm_error_set(err, SM_ERR_INVALID, "no target: give target_mesh and target_sol, "
                                                 "target_surface or target_image");
    return SM_OK;
}

sm_status sm_run_job(const sm_run_files *files, const char *params_json,
                     sm_run_progress_fn progress, void *user, const volatile int *cancel,
                     sm_run **out, sm_error *err)
{
    sm_error local;
    if (!err)
        err = &local;
    sm_error_clear(err);
    *out = NULL;
    if (!files)
        return sm_error_set(err, SM_ERR_INVALID, "template: no file given");
    sm_status st = check_parts(files, err);
    if (st != SM_OK)
        return st;
    if (!params_json || !*params_json)
        return sm_error_set(err, SM_ERR_INVALID,
                            "params: a params document is required (at least the clamp)");
    sm_run *r = calloc(1, sizeof *r);
    if (!r || copy_names(files, &r->names) != 0) {
        if (r)
            free_names(&r->names);
        free(r);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    }
    st = load_inputs(files, params_json, &r->in, err);
    if (st != SM_OK) {
        free_names(&r->names);
        free(r);
        return st;
    }
    api_ctx c = {.progress = progress, .user = user};
    sm_job_hooks hooks = {.progress = on_progress, .user = &c, .cancel = cancel};
    if ((st = sm_job_run_exec(&r->in, &hooks, &r->run, err)) != SM_OK) {
        sm_run_free(r);
        return st;
    }
    json_t *doc = sm_job_summary_outputs(&r->in, &r->run, &r->names, 0);
    if (doc) {
        json_object_del(doc, "outputs");
        r->summary = sm_json_dumps(doc, 0);
        json_decref(doc);
    }
    *out = r;
    return SM_OK;
}

const char *sm_run_version(void)
{
    return SM_VERSION;
}

const char *sm_run_outcome(const sm_run *r)
{
    return sm_job_outcome_name(r->run.outcome);
}

int sm_run_exit_code(const sm_run *r)
{
    return r->run.exit_code;
}

const char *sm_run_message(const sm_run *r)
{
    return r->run.message;
}

const char *sm_run_summary(const sm_run *r)
{
    return r->summary;
}

int sm_run_dim(const sm_run *r)
{
    return r->in.template_mesh->dim;
}

int32_t sm_run_nverts(const sm_run *r)
{
    return r->in.template_mesh->nverts;
}

int32_t sm_run_nelems(const sm_run *r)
{
    return r->in.template_mesh->nelems;
}

const double *sm_run_coords(const sm_run *r)
{
    return r->run.coords;
}

const double *sm_run_init_coords(const sm_run *r)
{
    return r->in.template_mesh->coords;
}

const int32_t *sm_run_elems(const sm_run *r)
{
    return r->in.template_mesh->elems;
}

const int32_t *sm_run_elem_refs(const sm_run *r)
{
    return r->in.template_mesh->elem_refs;
}

const int32_t *sm_run_vert_refs(const sm_run *r)
{
    return r->in.template_mesh->vert_refs;
}

const sm_progress *sm_run_history(const sm_run *r, size_t *n)
{
    *n = r->run.nhistory;
    return r->run.history;
}

sm_status sm_run_write(const sm_run *r, const char *dir, const char *formats, sm_error *err)
{
    unsigned outputs = 0;
    char why[256];
    if (sm_result_outputs_parse(formats ? formats : API_DEFAULT_FORMATS, &outputs, why,
                                sizeof why) != 0)
        return sm_error_set(err, SM_ERR_INVALID, "formats: %s", why);
    sm_status st = sm_mkdir_p(dir, err);
    if (st != SM_OK)
        return st;
    return sm_job_write_selected(&r->in, &r->run, &r->names, dir, outputs, SM_ATOMIC_FSYNC, err);
}

/* ------------------------------------------------------------ a batch */

sm_status sm_run_batch(const char *template_path, const char *list_csv, size_t list_len,
                       const char *params_json, const char *model_align, int jobs,
                       const char *out_dir, sm_error *err)
{
    return sm_run_batch_from(template_path, NULL, 0, 0, list_csv, list_len, params_json,
                             model_align, jobs, out_dir, err);
}

sm_status sm_run_batch_from(const char *template_path, const char *template_from, int rounds,
                            double tolerance, const char *list_csv, size_t list_len,
                            const char *params_json, const char *model_align, int jobs,
                            const char *out_dir, sm_error *err)
{
    if (!template_path || !list_csv || !out_dir)
        return sm_error_set(err, SM_ERR_INVALID, "a batch needs a template, targets and a folder");
    sm_shape_align align = SM_SHAPE_ALIGN_RIGID;
    if (model_align && sm_shape_align_parse(model_align, &align) != 0)
        return sm_error_set(err, SM_ERR_INVALID,
                            "model_align: '%.64s' is not none, rigid or similarity", model_align);
    sm_batch_list list = {0};
    sm_status st = sm_batch_list_parse(&list, list_csv, list_len, NULL, err);
    if (st == SM_OK && list.n == 0)
        st = sm_error_set(err, SM_ERR_INVALID, "no target");
    if (st == SM_OK)
        st = sm_batch_list_finish(&list, err);
    /* the parameters need the template's dimension */
    sm_mesh *t = NULL;
    if (st == SM_OK)
        st = sm_mesh_read(template_path, &t, err);
    sm_params params;
    sm_background_params bg = {0};
    if (st == SM_OK)
        st = sm_job_params_from_json(params_json ? params_json : "{}",
                                     params_json ? strlen(params_json) : 2, t->dim, &params, &bg,
                                     err);
    sm_mesh_free(t);
    unsigned outputs = 0;
    char msg[256];
    if (st == SM_OK && sm_result_outputs_parse(API_DEFAULT_FORMATS, &outputs, msg, sizeof msg))
        st = sm_error_set(err, SM_ERR_INVALID, "%s", msg);
    if (st == SM_OK)
        st = sm_mkdir_p(out_dir, err);
    if (st == SM_OK) {
        long cpus = sysconf(_SC_NPROCESSORS_ONLN);
        sm_batch_opts o = {.template_mesh = template_path, .params = &params,
                           .background_size = bg.size, .background_padding = bg.padding,
                           .outputs = outputs,
                           .jobs = jobs > 0 ? jobs : (int)(cpus > 1 ? cpus : 1),
                           .single_thread = 1, .build_model = 1,
                           .model = {.align = align}};
        sm_batch_outcome out;
        sm_rounds_opts r = {.rounds = rounds, .tolerance = tolerance};
        sm_rounds_outcome ro;
        if (!template_from)
            st = sm_job_batch_run(&list, &o, out_dir, &out, err);
        else if (sm_template_from_parse(template_from, &r.from) != 0)
            st = sm_error_set(err, SM_ERR_INVALID, "template_from: '%.64s' is not file, medoid "
                              "or mean", template_from);
        else if (r.from != SM_TEMPLATE_FROM_MEAN && (rounds || tolerance))
            st = sm_error_set(err, SM_ERR_INVALID, "rounds and tolerance go with template_from "
                              "mean, not %s", template_from);
        else
            st = sm_job_batch_rounds(&list, &o, &r, out_dir, &out, &ro, err);
    }
    sm_batch_list_free(&list);
    return st;
}
