/* The shape model of a batch's results (see sm_job_model.h). */
#include "job/sm_job_model.h"

#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "job/sm_job_results.h"
#include "job/sm_job_warp.h"
#include "shapematch/sm_atomic.h"
#include "shapematch/sm_clock.h"
#include "shapematch/sm_io.h"
#include "shapematch/sm_path.h"
#include "sm_json.h"

/* The result mesh of a member folder: the first of the result files
 * (job/sm_job_warp.h's list, the order run writes them in). */
static sm_status read_member(const sm_model_member *mb, sm_mesh **out, sm_error *err)
{
    *out = NULL;
    if (!mb->result_dir)
        return sm_error_set(err, SM_ERR_INVALID, "target %s: no result folder",
                            mb->name ? mb->name : "?");
    char *path = sm_job_result_find(mb->result_dir, sm_job_result_mesh_files);
    if (!path)
        return sm_error_set(err, SM_ERR_IO, "target %s: no result.mesh in %s",
                            mb->name ? mb->name : "?", mb->result_dir);
    sm_status st = sm_mesh_read(path, out, err);
    if (st != SM_OK)
        sm_error_prefix(err, "target %s", mb->name ? mb->name : mb->result_dir);
    free(path);
    return st;
}

static int same_topology(const sm_mesh *a, const sm_mesh *b)
{
    return a->dim == b->dim && a->nverts == b->nverts && a->nelems == b->nelems &&
           memcmp(a->elems, b->elems, (size_t)a->nelems * (size_t)(a->dim + 1) *
                                          sizeof *a->elems) == 0;
}

/* Every member's coordinates; *topo keeps the first mesh. */
static sm_status read_members(const sm_model_member *members, size_t n, sm_mesh **topo,
                              double **coords, sm_error *err)
{
    for (size_t i = 0; i < n; i++) {
        sm_mesh *m;
        sm_status st = read_member(&members[i], &m, err);
        if (st != SM_OK)
            return st;
        if (i == 0) {
            *topo = m;
        } else if (!same_topology(*topo, m)) {
            sm_mesh_free(m);
            return sm_error_set(err, SM_ERR_INVALID,
                                "target %s: its result is not on the first target's mesh (%ld "
                                "vertices, %ld elements); a model needs one template",
                                members[i].name ? members[i].name : members[i].result_dir,
                                (long)(*topo)->nverts, (long)(*topo)->nelems);
        }
        size_t nv = (size_t)m->nverts * (size_t)m->dim;
        coords[i] = malloc(nv * sizeof **coords);
        if (!coords[i]) {
            if (i > 0)
                sm_mesh_free(m);
            return sm_error_set(err, SM_ERR_NOMEM, "out of memory reading the results");
        }
        memcpy(coords[i], m->coords, nv * sizeof **coords);
        if (i > 0)
            sm_mesh_free(m);
    }
    return SM_OK;
}

/* One file through a temporary name. */
typedef sm_status (*writer_fn)(const char *tmp, const void *ctx, sm_error *err);

static sm_status write_atomic(const char *dir, const char *name, writer_fn fn, const void *ctx,
                              unsigned flags, sm_error *err)
{
    char *path = sm_path_join(dir, name);
    if (!path)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    sm_atomic a;
    sm_status st = sm_atomic_reserve(&a, path, err);
    if (st == SM_OK) {
        st = fn(a.tmp_path, ctx, err);
        if (st == SM_OK)
            st = sm_atomic_commit(&a, flags, err);
        else
            sm_atomic_abort(&a);
    }
    if (st != SM_OK)
        sm_error_prefix(err, "%s", path);
    free(path);
    return st;
}

typedef struct out_ctx {
    const sm_shape_model *model;
    const sm_mesh *topo;
    const sm_model_member *members;
    double *scaled;    /* written modes: sqrt(lambda_k) u_k, each P values */
    int nwrite, mode;  /* modes written; the one mode_K.sol writes */
} out_ctx;

static sm_status write_mean_mesh(const char *tmp, const void *p, sm_error *err)
{
    const out_ctx *c = p;
    return sm_mesh_write_coords(tmp, c->topo, c->model->mean, err);
}

static sm_status write_mean_vtu(const char *tmp, const void *p, sm_error *err)
{
    const out_ctx *c = p;
    return sm_vtu_write_fields(tmp, c->topo, c->model->mean, NULL, 0, err);
}

static sm_status write_modes_vtu(const char *tmp, const void *p, sm_error *err)
{
    const out_ctx *c = p;
    sm_vtu_field *f = calloc((size_t)c->nwrite + 1, sizeof *f);
    char (*names)[16] = calloc((size_t)c->nwrite + 1, sizeof *names);
    sm_status st = SM_OK;
    if (!f || !names)
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    for (int k = 0; st == SM_OK && k < c->nwrite; k++) {
        snprintf(names[k], sizeof names[k], "mode%d", k + 1);
        f[k] = (sm_vtu_field){names[k], c->scaled + (size_t)k * c->model->nvalues};
    }
    if (st == SM_OK)
        st = sm_vtu_write_fields(tmp, c->topo, c->model->mean, f, c->nwrite, err);
    free(f);
    free(names);
    return st;
}

static sm_status write_mode_sol(const char *tmp, const void *p, sm_error *err)
{
    const out_ctx *c = p;
    sm_sol *s;
    sm_status st = sm_sol_alloc(&s, c->topo->dim, c->topo->nverts, c->topo->dim, err);
    if (st != SM_OK)
        return st;
    memcpy(s->values, c->scaled + (size_t)c->mode * c->model->nvalues,
           c->model->nvalues * sizeof *s->values);
    st = sm_sol_write(tmp, s, err);
    sm_sol_free(s);
    return st;
}

/* A CSV field: the name as is, or quoted (RFC 4180) when it holds a
 * comma, quote or line break. */
static void csv_field(FILE *f, const char *s)
{
    if (!strpbrk(s, ",\"\r\n")) {
        fputs(s, f);
        return;
    }
    fputc('"', f);
    for (; *s; s++) {
        if (*s == '"')
            fputc('"', f);
        fputc(*s, f);
    }
    fputc('"', f);
}

static sm_status write_scores(const char *tmp, const void *p, sm_error *err)
{
    const out_ctx *c = p;
    const sm_shape_model *m = c->model;
    FILE *f = fopen(tmp, "w");
    if (!f)
        return sm_error_set(err, SM_ERR_IO, "cannot write the scores");
    fputs("target", f);
    for (int k = 0; k < m->nmodes; k++)
        fprintf(f, ",mode%d", k + 1);
    fputc('\n', f);
    for (int i = 0; i < m->nshapes; i++) {
        csv_field(f, c->members[i].name ? c->members[i].name : "");
        for (int k = 0; k < m->nmodes; k++)
            fprintf(f, ",%.17g", m->scores[(size_t)i * m->nmodes + k]);
        fputc('\n', f);
    }
    int bad = ferror(f);
    if (fclose(f) != 0 || bad)
        return sm_error_set(err, SM_ERR_IO, "cannot write the scores");
    return SM_OK;
}

static json_t *reals(const double *x, int n, double scale)
{
    json_t *a = json_array();
    for (int i = 0; a && i < n; i++)
        json_array_append_new(a, json_real(x[i] * scale));
    return a;
}

static json_t *summary_doc(const out_ctx *c, const sm_model_opts *o, json_t *files,
                           const double t[3])
{
    const sm_shape_model *m = c->model;
    json_t *names = json_array();
    for (int i = 0; names && i < m->nshapes; i++)
        json_array_append_new(names, sm_json_string_lossy(c->members[i].name ? c->members[i].name
                                                                             : ""));
    json_t *ve = json_array();
    for (int k = 0; ve && k < m->nmodes; k++)
        json_array_append_new(ve, json_real(m->total_variance > 0
                                                ? m->variance[k] / m->total_variance : 0));
    return json_pack("{s:i, s:i, s:I, s:s, s:i, s:i, s:i, s:f, s:o, s:o, s:o, s:o, s:o, "
                     "s:{s:i, s:i, s:i, s:I}, s:o, s:O, s:{s:f, s:f, s:f}}",
                     "members", m->nshapes, "dimension", m->dim, "vertices", (json_int_t)m->npoints,
                     "align", sm_shape_align_name(o->align),
                     "procrustes_rounds", m->gpa_rounds, "modes", m->nmodes,
                     "modes_written", c->nwrite, "total_variance", m->total_variance,
                     "variance", reals(m->variance, m->nmodes, 1), "variance_explained", ve,
                     "compactness", reals(m->compactness, m->neval, 1),
                     "generalization", reals(m->generalization, m->neval, 1),
                     "specificity", reals(m->specificity, m->neval, 1),
                     "evaluation", "modes", m->neval, "held_out",
                     m->nshapes < m->eval_shapes ? m->nshapes : m->eval_shapes,
                     "samples", m->samples, "seed", (json_int_t)m->seed,
                     "targets", names, "files", files,
                     "timings", "read", t[0], "build", t[1], "write", t[2]);
}

static sm_status write_summary(const char *dir, const out_ctx *c, const sm_model_opts *o,
                               json_t *files, const double t[3], sm_error *err)
{
    json_t *doc = summary_doc(c, o, files, t);
    sm_status st = sm_job_write_json(dir, SM_MODEL_SUMMARY_FILE, doc, o->write_flags, err);
    json_decref(doc);
    return st;
}

static sm_status write_model(const char *dir, out_ctx *c, const sm_model_opts *o,
                             json_t *files, sm_error *err)
{
    const sm_shape_model *m = c->model;
    c->scaled = malloc(((size_t)c->nwrite * m->nvalues + 1) * sizeof *c->scaled);
    if (!c->scaled)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the modes");
    for (int k = 0; k < c->nwrite; k++) {
        double s = sqrt(m->variance[k]);
        for (size_t v = 0; v < m->nvalues; v++)
            c->scaled[(size_t)k * m->nvalues + v] = s * m->modes[(size_t)k * m->nvalues + v];
    }
    static const struct { const char *name; writer_fn fn; } fixed[] = {
        {"mean.mesh", write_mean_mesh}, {"mean.vtu", write_mean_vtu},
        {"modes.vtu", write_modes_vtu}, {"scores.csv", write_scores}};
    sm_status st = SM_OK;
    for (size_t i = 0; st == SM_OK && i < sizeof fixed / sizeof fixed[0]; i++) {
        st = write_atomic(dir, fixed[i].name, fixed[i].fn, c, o->write_flags, err);
        json_array_append_new(files, json_string(fixed[i].name));
    }
    for (c->mode = 0; st == SM_OK && c->mode < c->nwrite; c->mode++) {
        char name[32];
        snprintf(name, sizeof name, "mode_%d.sol", c->mode + 1);
        st = write_atomic(dir, name, write_mode_sol, c, o->write_flags, err);
        json_array_append_new(files, json_string(name));
    }
    return st;
}

sm_status sm_job_model_build_opts(const sm_model_member *members, size_t n,
                                  const sm_model_opts *opts, const char *out_dir,
                                  sm_error *err)
{
    sm_model_opts o = opts ? *opts : (sm_model_opts){.align = SM_SHAPE_ALIGN_RIGID};
    if (!members || n < 1 || n > (size_t)INT32_MAX / 2 || !out_dir)
        return sm_error_set(err, SM_ERR_INVALID, "a shape model needs at least one target");
    double t[3], t0 = sm_clock_seconds();
    sm_mesh *topo = NULL;
    double **coords = calloc(n, sizeof *coords);
    sm_shape_model *model = NULL;
    json_t *files = json_array();
    out_ctx c = {.members = members};
    sm_status st = coords && files ? SM_OK : sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    if (st == SM_OK)
        st = read_members(members, n, &topo, coords, err);
    t[0] = sm_clock_seconds() - t0;
    if (st == SM_OK) {
        sm_shape_model_opts so = {.align = o.align, .eval_modes = o.eval_modes,
                                  .eval_shapes = o.eval_shapes, .samples = o.samples,
                                  .seed = o.seed};
        st = sm_shape_model_build((const double *const *)coords, (int)n, topo->nverts, topo->dim,
                                  &so, &model, err);
    }
    for (size_t i = 0; coords && i < n; i++)
        free(coords[i]);
    free(coords);
    t[1] = sm_clock_seconds() - t0 - t[0];
    if (st == SM_OK)
        st = sm_mkdir_p(out_dir, err);
    if (st == SM_OK) {
        int mx = o.max_modes > 0 ? o.max_modes : SM_JOB_MODEL_MAX_MODES;
        c.model = model;
        c.topo = topo;
        c.nwrite = model->nmodes < mx ? model->nmodes : mx;
        st = write_model(out_dir, &c, &o, files, err);
    }
    t[2] = sm_clock_seconds() - t0 - t[0] - t[1];
    if (st == SM_OK)
        st = write_summary(out_dir, &c, &o, files, t, err);
    free(c.scaled);
    json_decref(files);
    sm_shape_model_free(model);
    sm_mesh_free(topo);
    return st;
}

sm_status sm_job_model_build(const sm_model_member *members, size_t n, sm_shape_align align,
                             const char *out_dir, sm_error *err)
{
    sm_model_opts o = {.align = align};
    return sm_job_model_build_opts(members, n, &o, out_dir, err);
}
