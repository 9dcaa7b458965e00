/* The result set of a run and its summary (see sm_job_results.h): the
 * summary document, history.csv and history.json, the result files
 * side by side, summary.json last. */
#include "job/sm_job_results.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <zlib.h>

#include "shapematch/sm_atomic.h"
#include "shapematch/sm_io.h"
#include "shapematch/sm_path.h"
#include "sm_json.h"
#include "sm_payload.h"
#include "sm_proto_events.h"
#include "sm_proto_json.h"
#include "sm_proto_vocab.h"

#ifndef SM_VERSION
#define SM_VERSION "unknown"
#endif

/* ------------------------------------------------------------ the summary */

static int set_string(json_t *obj, const char *key, const char *value)
{
    json_t *v = sm_json_string_lossy(value ? value : "");
    return v ? smp_set(obj, key, v) : -1;
}

/* The file name of format i under outputs: FILE or FILE.gz. */
static json_t *output_name(size_t i, unsigned outputs)
{
    char name[96];
    snprintf(name, sizeof name, "%s%s", sm_result_formats[i].file,
             sm_result_output_gz(i, outputs) ? ".gz" : "");
    return json_string(name);
}

static json_t *outputs_object(unsigned chosen)
{
    json_t *outputs = json_object();
    int bad = !outputs;
    for (int k = 0; !bad && k < SM_NRESULT_KINDS; k++) {
        size_t n;
        const sm_result_format *f = sm_result_formats_of((sm_result_kind)k, &n);
        json_t *files = json_object();
        bad = !files || smp_set(outputs, sm_result_kind_name((sm_result_kind)k), files) != 0;
        for (size_t i = 0; !bad && i < n; i++) {
            size_t at = (size_t)(&f[i] - sm_result_formats);
            if (chosen & SM_RESULT_OUT_FORMAT(at))
                bad = smp_set(files, f[i].name, output_name(at, chosen)) != 0;
        }
    }
    bad = bad || smp_set(outputs, "summary", json_string(SM_RESULT_SUMMARY_FILE)) != 0;
    if (bad) {
        json_decref(outputs);
        return NULL;
    }
    return outputs;
}

static json_t *surface_health_object(const sm_job_inputs *in)
{
    const sm_surface_health *h = &in->health;
    json_t *o = json_object(), *lo = json_array(), *hi = json_array();
    for (int k = 0; k < in->dim; k++) {
        json_array_append_new(lo, json_real(h->lo[k]));
        json_array_append_new(hi, json_real(h->hi[k]));
    }
    json_object_set_new(o, "open_edges", json_integer(h->open_edges));
    json_object_set_new(o, "nonmanifold_edges", json_integer(h->nonmanifold_edges));
    json_object_set_new(o, "reoriented", json_integer(h->reoriented));
    json_object_set_new(o, "reoriented_within", json_integer(h->reoriented_within));
    json_object_set_new(o, "pieces_turned", json_integer(h->pieces_turned));
    json_object_set_new(o, "duplicates", json_integer(h->duplicates));
    json_object_set_new(o, "degenerate", json_integer(h->degenerate));
    json_object_set_new(o, "components", json_integer(h->components));
    json_object_set_new(o, "open_components", json_integer(h->open_components));
    json_object_set_new(o, "open_by_volume", json_integer(h->open_by_volume));
    json_object_set_new(o, "bbox_min", lo);
    json_object_set_new(o, "bbox_max", hi);
    json_object_set_new(o, "background_generated", json_boolean(in->background_generated));
    json_object_set_new(o, "background_vertices", json_integer(in->background->nverts));
    if (in->background_generated) { /* what sized it, defaults included */
        json_object_set_new(o, "background_size", json_real(in->background_size));
        json_object_set_new(o, "background_padding", json_real(in->background_padding));
    }
    json_object_set_new(o, "sdf_seconds", json_real(in->sdf_seconds));
    return o;
}

/* A label-map target: the image, the selection and what it holds. */
static json_t *image_object(const sm_job_inputs *in)
{
    const sm_job_image_info *im = &in->image;
    const sm_label_stats *st = &im->stats;
    json_t *o = json_object(), *lo = json_array(), *hi = json_array(), *dims = json_array(),
           *spacing = json_array();
    for (int k = 0; k < 3; k++) {
        json_array_append_new(lo, json_real(st->lo[k]));
        json_array_append_new(hi, json_real(st->hi[k]));
        json_array_append_new(dims, json_integer(im->dims[k]));
        json_array_append_new(spacing, json_real(im->spacing[k]));
    }
    json_object_set_new(o, "format", json_string(im->format));
    json_object_set_new(o, "dims", dims);
    json_object_set_new(o, "voxel_type", json_string(sm_voxel_type_name(im->type)));
    json_object_set_new(o, "spacing", spacing);
    json_object_set_new(o, "image_space", json_string(sm_image_space_name(im->space)));
    if (im->sel.has_label)
        json_object_set_new(o, "label", json_integer(im->sel.label));
    else
        json_object_set_new(o, "label", json_null()); /* every nonzero voxel, or >= level */
    json_object_set_new(o, "level", json_real(im->sel.level));
    json_object_set_new(o, "smooth", json_real(in->params.smooth));
    json_object_set_new(o, "voxels", json_integer(st->voxels));
    json_object_set_new(o, "components", json_integer(st->components));
    json_object_set_new(o, "touches_border", json_boolean(st->touches_border));
    json_object_set_new(o, "bbox_min", lo);
    json_object_set_new(o, "bbox_max", hi);
    json_object_set_new(o, "surface_triangles", json_integer(im->surface_triangles));
    json_object_set_new(o, "background_generated", json_boolean(in->background_generated));
    json_object_set_new(o, "background_vertices", json_integer(in->background->nverts));
    if (in->background_generated) {
        json_object_set_new(o, "background_size", json_real(in->background_size));
        json_object_set_new(o, "background_padding", json_real(in->background_padding));
    }
    json_object_set_new(o, "exact_vertices", json_integer(im->exact_vertices));
    json_object_set_new(o, "sdf_seconds", json_real(in->sdf_seconds));
    return o;
}

/* How a template made from a surface or a label map was meshed. */
static json_t *template_meshed_object(const sm_job_template_made *t)
{
    const sm_template_mesh_info *i = &t->mesh;
    json_t *o = json_object();
    int bad = !o;
    bad = bad || smp_set(o, "from", json_string(t->source == SM_TEMPLATE_IMAGE ? "image" : "surface"));
    if (t->source == SM_TEMPLATE_IMAGE)
        bad = bad || smp_set(o, "label", json_integer(t->label));
    bad = bad || smp_set(o, "file", json_string(SM_RESULT_TEMPLATE_FILE)) ||
          smp_set(o, "mesher", json_string("nglib")) ||
          smp_set(o, "surface_facets", json_integer(t->surface_facets)) ||
          smp_set(o, "reoriented", json_integer(t->health.reoriented)) ||
          smp_set(o, "size", json_real(i->size)) ||
          smp_set(o, "vertices", json_integer(i->nverts)) ||
          smp_set(o, "elements", json_integer(i->nelems)) ||
          smp_set(o, "min_quality", json_real(i->min_quality)) ||
          smp_set(o, "mean_quality", json_real(i->mean_quality)) ||
          smp_set(o, "passes", json_integer(i->passes)) ||
          smp_set(o, "volume", json_real(i->mesh_volume)) ||
          smp_set(o, "surface_volume", json_real(i->surface_volume)) ||
          smp_set(o, "seconds", json_real(i->seconds));
    if (bad) {
        json_decref(o);
        return NULL;
    }
    return o;
}

static json_t *warnings_array(const sm_job_warnings *ws)
{
    json_t *a = json_array();
    for (int i = 0; a && i < ws->n; i++) {
        json_t *w = json_object();
        if (!w || json_array_append_new(a, w) != 0 ||
            smp_set(w, "code", json_string(ws->w[i].code)) ||
            set_string(w, "message", ws->w[i].message) ||
            smp_set(w, "figure", smp_real_or_null(ws->w[i].figure))) {
            json_decref(a);
            return NULL;
        }
    }
    return a;
}

/* The template's Gmsh physical names: [{dim, tag, name}]. */
static json_t *names_array(const sm_mesh *m)
{
    json_t *a = json_array();
    for (int32_t i = 0; a && i < m->nnames; i++) {
        json_t *e = json_object();
        if (!e || json_array_append_new(a, e) != 0 ||
            smp_set(e, "dim", json_integer(m->names[i].dim)) ||
            smp_set(e, "tag", json_integer(m->names[i].tag)) ||
            set_string(e, "name", m->names[i].name)) {
            json_decref(a);
            return NULL;
        }
    }
    return a;
}

json_t *sm_job_summary_outputs(const sm_job_inputs *in, const sm_job_run *run,
                               const sm_job_files *names, unsigned outputs)
{
    const sm_mesh *m = in->template_mesh;
    json_t *res = sm_result_to_jansson(&run->result, &in->params, in->dim);
    json_t *doc = json_object();
    json_t *inputs = json_object(), *tmpl = json_object();
    int bad = !res || !doc || !inputs || !tmpl;
    bad = bad || smp_set(doc, "shapematch_version", json_string(SM_VERSION));
    bad = bad || smp_set(doc, "status", json_string(sm_job_outcome_name(run->outcome)));
    bad = bad || smp_set(doc, "exit_code", json_integer(run->exit_code));
    if (!bad) {
        /* the result members, in their order, with timings.read first */
        json_t *timings = json_object_get(res, "timings");
        json_t *t = json_object();
        const char *key;
        json_t *value;
        bad = !timings || !t || smp_set(t, "read", smp_real_or_null(in->read_seconds)) ||
              smp_set(t, "field_build", smp_real_or_null(in->field_build_seconds));
        json_object_foreach(timings, key, value) bad = bad || smp_set(t, key, json_incref(value));
        json_object_foreach(res, key, value)
        {
            if (strcmp(key, "timings") == 0)
                bad = bad || smp_set(doc, key, json_incref(t));
            else
                bad = bad || smp_set(doc, key, json_incref(value));
        }
        json_decref(t);
    }
    bad = bad || smp_set(doc, "resolution", smp_real_or_null(run->resolution));
    bad = bad || smp_set(doc, "inverted_elements", json_integer(run->inverted));
    bad = bad || smp_set(doc, "warnings", warnings_array(&run->warnings));
    if (run->alignment.done) /* only then: a run without one keeps its summary */
        bad = bad || smp_set(doc, "alignment", sm_job_alignment_json(&run->alignment, m->dim));
    bad = bad || smp_set(doc, "field_builds", json_integer(in->field_builds));
    bad = bad || set_string(inputs, "template", names->template_mesh) ||
          set_string(inputs, "target_mesh", names->target_mesh) ||
          set_string(inputs, "target_sol", names->target_sol);
    if (in->has_surface) /* a surface target: its name and health report */
        bad = bad || set_string(inputs, SM_PART_NAME_TARGET_SURFACE, names->target_surface) ||
              smp_set(doc, "target_surface", surface_health_object(in));
    if (in->has_image) /* an image target: its name and label summary */
        bad = bad || set_string(inputs, SM_PART_NAME_TARGET_IMAGE, names->target_image) ||
              smp_set(doc, "target_image", image_object(in));
    bad = bad || smp_set(tmpl, "dimension", json_integer(m->dim)) ||
          smp_set(tmpl, "vertices", json_integer(m->nverts)) ||
          smp_set(tmpl, "elements", json_integer(m->nelems)) ||
          smp_set(tmpl, "facets", json_integer(m->nfacets));
    if (m->nnames > 0) /* a Gmsh template's $PhysicalNames */
        bad = bad || smp_set(tmpl, "physical_names", names_array(m));
    if (in->template_made.source != SM_TEMPLATE_GIVEN) {
        int image = in->template_made.source == SM_TEMPLATE_IMAGE;
        bad = bad || set_string(inputs, image ? SM_PART_NAME_TEMPLATE_IMAGE
                                              : SM_PART_NAME_TEMPLATE_SURFACE,
                                image ? names->template_image : names->template_surface) ||
              smp_set(tmpl, "meshed", template_meshed_object(&in->template_made));
    }
    if (!bad) {
        bad = smp_set(doc, "inputs", inputs) != 0;
        inputs = NULL;
        bad = bad || smp_set(doc, "template", tmpl) != 0;
        tmpl = NULL;
        bad = bad || smp_set(doc, "outputs", outputs_object(sm_result_outputs_fix(outputs))) != 0;
    }
    json_decref(res);
    json_decref(inputs);
    json_decref(tmpl);
    if (bad) {
        json_decref(doc);
        return NULL;
    }
    return doc;
}

/* --------------------------------------------------------- the results */

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

static void write_history_csv(FILE *f, const sm_job_run *run)
{
    fputs("iteration,J,step,boundary_l2,boundary_max,min_quality,elapsed,accepted,rejected\n", f);
    for (size_t i = 0; i < run->nhistory; i++) {
        const sm_progress *p = &run->history[i];
        fprintf(f, "%d,", p->iteration);
        const double vals[] = {p->J, p->step, p->boundary_l2, p->boundary_max, p->min_quality,
                               p->elapsed};
        for (size_t k = 0; k < sizeof vals / sizeof vals[0]; k++) {
            csv_number(f, vals[k]);
            fputc(',', f);
        }
        fprintf(f, "%d,%d\n", p->accepted, p->rejected);
    }
}

static char *history_json(const sm_job_run *run)
{
    json_t *rows = json_array();
    for (size_t i = 0; rows && i < run->nhistory; i++) {
        sm_event ev;
        sm_event_init(&ev, SM_EVENT_PROGRESS);
        ev.progress = run->history[i];
        json_t *row = sm_event_to_jansson(&ev);
        if (!row || json_object_del(row, "type") != 0 || json_array_append_new(rows, row) != 0) {
            json_decref(rows);
            rows = NULL;
        }
    }
    char *text = rows ? sm_json_dumps(rows, 0) : NULL;
    json_decref(rows);
    return text;
}

typedef struct result_data {
    const sm_mesh *mesh;
    const double *coords, *displacement, *distance;
    const sm_sol *sol;
    const sm_job_run *run;
    const char *text;            /* the summary or history.json */
} result_data;

/* The binary payload compressed: encoded in memory, then gzip'd (the
 * payload writer has no .gz stream of its own). */
static sm_status write_payload_gz(const char *path, const result_data *d, sm_error *err)
{
    unsigned char *buf = NULL;
    size_t len = 0;
    sm_status st = sm_payload_encode(d->mesh, d->coords, d->displacement, d->distance, &buf,
                                     &len, err);
    if (st != SM_OK)
        return st;
    gzFile gz = gzopen(path, "wb");
    int ok = gz != NULL;
    for (size_t at = 0; ok && at < len;) {
        unsigned chunk = len - at > (1u << 30) ? (1u << 30) : (unsigned)(len - at);
        ok = gzwrite(gz, buf + at, chunk) == (int)chunk;
        at += chunk;
    }
    if (gz && gzclose(gz) != Z_OK)
        ok = 0;
    free(buf);
    return ok ? SM_OK : sm_error_set(err, SM_ERR_IO, "cannot write '%s' (gzip)", path);
}

/* One file of the set: a core writer on a reserved temporary name, or
 * text through the temporary's stream. */
static sm_status write_one(const char *dir, const sm_result_format *f, const result_data *d,
                           int gz, sm_vtu_encoding vtu, unsigned flags, sm_error *err)
{
    char name[96];
    snprintf(name, sizeof name, "%s%s", f->file, gz ? ".gz" : "");
    char *path = sm_path_join(dir, name);
    if (!path)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    sm_atomic a;
    sm_status st;
    if (f->kind == SM_RESULT_HISTORY) {
        st = sm_atomic_open(&a, path, err);
        if (st == SM_OK) {
            if (strcmp(f->name, "csv") == 0)
                write_history_csv(a.f, d->run);
            else
                fprintf(a.f, "%s\n", d->text);
            st = sm_atomic_commit(&a, flags, err);
        }
    } else if ((st = sm_atomic_reserve(&a, path, err)) == SM_OK) {
        const char *tmp = a.tmp_path;
        if (f->kind == SM_RESULT_DISPLACEMENT)
            st = sm_sol_write(tmp, d->sol, err);
        else if (strcmp(f->name, "vtu") == 0)
            st = sm_vtu_write_as(tmp, d->mesh, d->coords, d->displacement, d->distance, vtu,
                                 err);
        else if (strcmp(f->name, "binary") == 0 && gz)
            st = write_payload_gz(tmp, d, err);
        else if (strcmp(f->name, "binary") == 0)
            st = sm_payload_write_file(tmp, d->mesh, d->coords, d->displacement, d->distance, err);
        else
            st = sm_mesh_write_coords(tmp, d->mesh, d->coords, err);
        if (st == SM_OK)
            st = sm_atomic_commit(&a, flags, err);
        else
            sm_atomic_abort(&a);
    }
    if (st != SM_OK && err && !strstr(err->msg, f->file))
        sm_error_prefix(err, "cannot write %s", name);
    free(path);
    return st;
}

/* The chosen files of the set, side by side on the OpenMP threads (each
 * is formatting, then an fsync: a few tens of ms apiece for the paper's
 * size); a failure is reported for the first failing format in the
 * table's order, whatever the threads. */
static sm_status write_formats(const char *dir, const result_data *d, unsigned outputs,
                               unsigned flags, sm_error *err)
{
    size_t chosen[SM_RESULT_FORMATS_N], n = 0;
    sm_status st[SM_RESULT_FORMATS_N];
    sm_error errs[SM_RESULT_FORMATS_N];
    for (size_t i = 0; i < SM_RESULT_FORMATS_N; i++)
        if (outputs & SM_RESULT_OUT_FORMAT(i))
            chosen[n++] = i;
#pragma omp parallel for schedule(dynamic, 1)
    for (size_t k = 0; k < n; k++) {
        const sm_result_format *f = &sm_result_formats[chosen[k]];
        int gz = sm_result_output_gz(chosen[k], outputs);
        sm_error_clear(&errs[k]);
        st[k] = write_one(dir, f, d, gz,
                          (outputs & SM_RESULT_OUT_VTU_ASCII) ? SM_VTU_ASCII : SM_VTU_ZLIB, flags,
                          &errs[k]);
    }
    for (size_t k = 0; k < n; k++)
        if (st[k] != SM_OK) {
            if (err)
                *err = errs[k];
            return st[k];
        }
    return SM_OK;
}

sm_status sm_job_write_json(const char *dir, const char *name, const json_t *doc, unsigned flags,
                            sm_error *err)
{
    char *text = doc ? sm_json_dumps(doc, 2) : NULL;
    char *path = sm_path_join(dir, name);
    sm_status st;
    if (!text || !path) {
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory writing %s", name);
    } else {
        size_t n = strlen(text);
        text[n] = '\n'; /* replaces the NUL: written with its length */
        st = sm_atomic_write_file(path, text, n + 1, flags, err);
    }
    free(text);
    free(path);
    return st;
}

static sm_status write_summary(const sm_job_inputs *in, const sm_job_run *run,
                               const sm_job_files *names, const char *dir, unsigned outputs,
                               unsigned flags, sm_error *err)
{
    json_t *doc = sm_job_summary_outputs(in, run, names, outputs);
    sm_status st = sm_job_write_json(dir, SM_RESULT_SUMMARY_FILE, doc, flags, err);
    json_decref(doc);
    return st;
}

sm_status sm_job_write_results(const sm_job_inputs *in, const sm_job_run *run,
                               const sm_job_files *names, const char *dir, unsigned flags,
                               sm_error *err)
{
    return sm_job_write_selected(in, run, names, dir, SM_RESULT_OUT_ALL, flags, err);
}

sm_status sm_job_write_selected(const sm_job_inputs *in, const sm_job_run *run,
                                const sm_job_files *names, const char *dir, unsigned outputs,
                                unsigned flags, sm_error *err)
{
    const sm_mesh *m = in->template_mesh;
    size_t n = (size_t)m->nverts * (size_t)m->dim;
    sm_status st;
    sm_sol *sol = NULL;
    char *history = NULL;
    double *disp = malloc((n ? n : 1) * sizeof *disp);
    double *dist = malloc(((size_t)m->nverts + 1) * sizeof *dist);
    char *old_summary = sm_path_join(dir, SM_RESULT_SUMMARY_FILE);
    if (!disp || !dist || !old_summary) {
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory preparing the results");
        goto done;
    }
    /* a summary.json left by an earlier run in the same folder must not
     * vouch for a set of files this run only partly replaced */
    if (unlink(old_summary) != 0 && errno != ENOENT) {
        st = sm_error_set(err, SM_ERR_IO, "cannot remove the previous '%s': %s", old_summary,
                          strerror(errno));
        goto done;
    }
    for (size_t i = 0; i < n; i++)
        disp[i] = run->coords[i] - m->coords[i];
    sm_field_eval_points(in->field, m->nverts, run->coords, NULL, dist);
    if ((st = sm_sol_alloc(&sol, m->dim, m->nverts, m->dim, err)) != SM_OK)
        goto done;
    memcpy(sol->values, disp, n * sizeof *disp);
    if (!(history = history_json(run))) {
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory writing the history");
        goto done;
    }
    result_data d = {.mesh = m, .coords = run->coords, .displacement = disp, .distance = dist,
                     .sol = sol, .run = run, .text = history};
    outputs = sm_result_outputs_fix(outputs);
    if ((st = write_formats(dir, &d, outputs, flags, err)) != SM_OK)
        goto done;
    if (in->template_made.source != SM_TEMPLATE_GIVEN) {
        char *path = sm_path_join(dir, SM_RESULT_TEMPLATE_FILE);
        st = path ? sm_mesh_write(path, m, err)
                  : sm_error_set(err, SM_ERR_NOMEM, "out of memory writing the template");
        free(path);
        if (st != SM_OK)
            goto done;
    }
    st = write_summary(in, run, names, dir, outputs, flags, err);
done:
    free(old_summary);
    free(history);
    sm_sol_free(sol);
    free(disp);
    free(dist);
    return st;
}
