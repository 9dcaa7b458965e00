/* A batch on the population's own template: rounds of sm_job_batch_run
 * (see sm_job_template_from.h). */
#include "job/sm_job_template_from.h"

#include <errno.h>
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "job/sm_job_results.h"
#include "job/sm_job_warp.h"
#include "shapematch/sm_atomic.h"
#include "shapematch/sm_io.h"
#include "shapematch/sm_mesh.h"
#include "shapematch/sm_path.h"
#include "shapematch/sm_sdf.h"
#include "shapematch/sm_shape_model.h"
#include "shapematch/sm_surface.h"
#include "sm_json.h"

/* ---------------------------------------------------- the distances */

/* Squared distances of m's boundary vertices at coordinates q to its
 * boundary facets at coordinates s, summed; the vertices counted into
 * *count.  -1 when out of memory. */
static double one_side(const sm_mesh *m, const double *s, const double *q, int64_t *count)
{
    int dim = m->dim;
    sm_surface surf = {.dim = dim, .nverts = m->nverts, .coords = (double *)s,
                       .nfacets = m->nbfacets, .facets = m->bfacets};
    sm_sdf *sdf = NULL;
    sm_error err;
    if (sm_sdf_new(&surf, &sdf, &err) != SM_OK)
        return -1;
    int64_t nb = 0;
    for (int32_t v = 0; v < m->nverts; v++)
        nb += m->on_boundary[v] != 0;
    double *pts = malloc(((size_t)nb * (size_t)dim + 1) * sizeof *pts);
    double *dist = malloc(((size_t)nb + 1) * sizeof *dist);
    double sum = -1;
    if (pts && dist) {
        int64_t k = 0;
        for (int32_t v = 0; v < m->nverts; v++)
            if (m->on_boundary[v])
                memcpy(pts + (size_t)(k++) * (size_t)dim, q + (size_t)v * (size_t)dim,
                       (size_t)dim * sizeof *pts);
        sm_sdf_distance(sdf, nb, pts, dist, NULL);
        sum = 0;
        for (int64_t i = 0; i < nb; i++)
            sum += dist[i] * dist[i];
        *count += nb;
    }
    free(pts);
    free(dist);
    sm_sdf_free(sdf);
    return sum;
}

double sm_job_boundary_rms(const sm_mesh *m, const double *a, const double *b)
{
    int64_t count = 0;
    double ab = one_side(m, b, a, &count), ba = ab < 0 ? -1 : one_side(m, a, b, &count);
    if (ab < 0 || ba < 0)
        return -1;
    return count > 0 ? sqrt((ab + ba) / (double)count) : 0;
}

/* ------------------------------------------------------------ rounds */

typedef struct rounds {
    const sm_batch_list *list;
    const sm_batch_opts *opts;
    const sm_rounds_opts *r;
    const char *out_dir;
    sm_rounds_outcome *ro;
    char *round_dir[SM_TEMPLATE_ROUNDS_MAX + 1];   /* [k]: round k's folder */
    char *template_of[SM_TEMPLATE_ROUNDS_MAX + 2]; /* [k]: the template round k ran on */
    double mean_quality[SM_TEMPLATE_ROUNDS_MAX + 1];
    json_t *medoid_sums;                           /* {name: sum}, medoid only */
} rounds;

static const char *summary_name(const sm_rounds_opts *r)
{
    return r->summary_file ? r->summary_file : "summary.json";
}

/* The targets of a round that ended with a result: their names, from its
 * summary (what sm_job_batch_run or r->run wrote). */
static sm_status round_members(const char *dir, const char *summary, json_t **names,
                               sm_error *err)
{
    char *path = sm_path_join(dir, summary);
    json_error_t je;
    json_t *doc = path ? json_load_file(path, 0, &je) : NULL;
    sm_status st = SM_OK;
    *names = json_array();
    if (!doc || !*names)
        st = sm_error_set(err, SM_ERR_IO, "%s: %s", path ? path : "summary.json",
                          doc ? "out of memory" : je.text);
    size_t i;
    json_t *row;
    json_array_foreach(json_object_get(doc, "targets"), i, row) {
        const char *status = json_string_value(json_object_get(row, "status"));
        if (st == SM_OK && status &&
            (strcmp(status, "finished") == 0 || strcmp(status, "not_converged") == 0 ||
             strcmp(status, "successful") == 0))
            json_array_append(*names, json_object_get(row, "name"));
    }
    json_decref(doc);
    free(path);
    return st;
}

/* The result mesh of target name in round folder dir (malloc'd path). */
static char *result_mesh_path(const char *dir, const char *name)
{
    char *tdir = sm_path_join(dir, "targets");
    char *t = tdir ? sm_path_join(tdir, name) : NULL;
    char *path = t ? sm_job_result_find(t, sm_job_result_mesh_files) : NULL;
    free(tdir);
    free(t);
    return path;
}

/* The result meshes of the targets names of round folder dir: their
 * coordinates into xs[i], the first one's mesh (its boundary built) into
 * *topo. */
static sm_status read_shapes(const char *dir, const json_t *names, sm_mesh **topo, double **xs,
                             sm_error *err)
{
    sm_status st = SM_OK;
    for (size_t i = 0; st == SM_OK && i < json_array_size(names); i++) {
        const char *name = json_string_value(json_array_get(names, i));
        char *p = result_mesh_path(dir, name);
        sm_mesh *m = NULL;
        st = p ? sm_mesh_read(p, &m, err)
               : sm_error_set(err, SM_ERR_IO, "target %s: no result mesh", name);
        free(p);
        if (st == SM_OK && !*topo && (st = sm_mesh_build_boundary(m, err)) == SM_OK)
            *topo = m, m = NULL;
        if (st == SM_OK && m && (m->nverts != (*topo)->nverts || m->dim != (*topo)->dim))
            st = sm_error_set(err, SM_ERR_INVALID, "target %s: not on the template's mesh", name);
        size_t nv = *topo ? (size_t)(*topo)->nverts * (size_t)(*topo)->dim : 0;
        if (st == SM_OK && !(xs[i] = malloc(nv * sizeof **xs)))
            st = sm_error_set(err, SM_ERR_NOMEM, "out of memory");
        if (st == SM_OK)
            memcpy(xs[i], (m ? m : *topo)->coords, nv * sizeof **xs);
        sm_mesh_free(m);
    }
    return st;
}

/* sums[i]: the sum over j != i of the two-sided RMS boundary distance
 * between shapes i and j, j first moved onto i by align over the
 * corresponding vertices (so that a pose is not a difference of shape). */
static sm_status pair_sums(const sm_mesh *topo, double *const *xs, size_t n, sm_shape_align align,
                           double *sums, sm_error *err)
{
    size_t nv = (size_t)topo->nverts * (size_t)topo->dim;
    double *moved = malloc((nv + 1) * sizeof *moved);
    sm_status st = moved ? SM_OK : sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    for (size_t i = 0; st == SM_OK && i < n; i++)
        for (size_t j = i + 1; st == SM_OK && j < n; j++) {
            memcpy(moved, xs[j], nv * sizeof *moved);
            sm_shape_align_onto(moved, xs[i], topo->nverts, topo->dim, align, NULL);
            double d = sm_job_boundary_rms(topo, xs[i], moved);
            if (d < 0)
                st = sm_error_set(err, SM_ERR_NOMEM, "out of memory");
            sums[i] += d, sums[j] += d;
        }
    free(moved);
    return st;
}

/* The medoid of round folder dir: the smallest sum of two-sided RMS
 * distances to the others (sm_job_template_from.h), into ro->medoid, its
 * result mesh into *path; the sums into x->medoid_sums. */
static sm_status find_medoid(rounds *x, const char *dir, char **path, sm_error *err)
{
    json_t *names;
    sm_status st = round_members(dir, summary_name(x->r), &names, err);
    size_t n = st == SM_OK ? json_array_size(names) : 0;
    if (st == SM_OK && n == 0)
        st = sm_error_set(err, SM_ERR_INVALID, "no target ended with a result");
    sm_mesh *topo = NULL;
    double **xs = calloc(n + 1, sizeof *xs), *sums = calloc(n + 1, sizeof *sums);
    if (st == SM_OK && (!xs || !sums))
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    if (st == SM_OK)
        st = read_shapes(dir, names, &topo, xs, err);
    if (st == SM_OK)
        st = pair_sums(topo, xs, n, x->opts->model.align, sums, err);
    size_t best = 0;
    x->medoid_sums = st == SM_OK ? json_object() : NULL;
    for (size_t i = 0; st == SM_OK && i < n; i++) {
        if (sums[i] < sums[best])
            best = i;
        json_object_set_new(x->medoid_sums, json_string_value(json_array_get(names, i)),
                            json_real(sums[i]));
    }
    if (st == SM_OK) {
        const char *name = json_string_value(json_array_get(names, best));
        snprintf(x->ro->medoid, sizeof x->ro->medoid, "%s", name);
        if (!(*path = result_mesh_path(dir, name)))
            st = sm_error_set(err, SM_ERR_IO, "target %s: no result mesh", name);
    }
    for (size_t i = 0; xs && i < n; i++)
        free(xs[i]);
    free(xs), free(sums);
    sm_mesh_free(topo);
    json_decref(names);
    return st;
}

/* Round k's model mean placed as the next template: moved onto round
 * k's template (same mesh) by the least-squares rigid motion over the
 * corresponding vertices (none with --model-align none) and written to
 * *next_path (rounds/K+1/template.mesh).  The model puts its mean in the
 * first member's frame, whose rotation is only as good as that member's
 * correspondence (arbitrary on a round target): left there, the
 * template turns a little each round and the rounds drift.  Placed on
 * the previous template, every template stays in the given template's
 * frame, and consecutive means are compared there: the movement is the
 * distance between this placed mean and round k's template (round
 * k - 1's placed mean), for k > 1.  Its smallest quality goes into
 * x->mean_quality[k]; *valid 0 when an element is inverted. */
static sm_status place_mean(rounds *x, int k, int *valid, char **next_path, sm_error *err)
{
    char *path = sm_path_join(x->round_dir[k], "model/mean.mesh");
    char name[32];
    snprintf(name, sizeof name, "rounds/%d/template.mesh", k + 1);
    *next_path = sm_path_join(x->out_dir, name);
    sm_mesh *m = NULL, *tk = NULL;
    double *placed = NULL;
    sm_status st = path && *next_path ? sm_mesh_read(path, &m, err)
                                      : sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    /* the elements as the result meshes hold them, positive on the
     * template; the quality before sm_mesh_build_boundary, which would
     * turn an inverted element over */
    sm_quality_stats q = {0};
    if (st == SM_OK) {
        sm_mesh_quality(m, m->coords, &q);
        x->mean_quality[k] = q.min;
        *valid = q.ninverted == 0;
        if (!*valid)
            snprintf(x->ro->message, sizeof x->ro->message,
                     "round %d: the mean shape has %ld inverted element%s (smallest quality "
                     "%.3g): it is no template; the rounds stop at round %d, on the last valid "
                     "template", k, (long)q.ninverted, q.ninverted == 1 ? "" : "s", q.min, k);
        st = sm_mesh_build_boundary(m, err);
    }
    if (st == SM_OK && (st = sm_mesh_read(x->template_of[k], &tk, err)) == SM_OK &&
        (tk->nverts != m->nverts || tk->dim != m->dim))
        st = sm_error_set(err, SM_ERR_INVALID, "round %d: the mean is not on the template's "
                          "mesh (%ld vertices, the template %ld)", k, (long)m->nverts,
                          (long)tk->nverts);
    size_t nv = m ? (size_t)m->nverts * (size_t)m->dim : 0;
    if (st == SM_OK && !(placed = malloc((nv + 1) * sizeof *placed)))
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    if (st == SM_OK) {
        memcpy(placed, m->coords, nv * sizeof *placed);
        sm_shape_align_onto(placed, tk->coords, m->nverts, m->dim,
                            x->opts->model.align == SM_SHAPE_ALIGN_NONE ? SM_SHAPE_ALIGN_NONE
                                                                        : SM_SHAPE_ALIGN_RIGID,
                            NULL);
        if (k > 1) {
            double d = sm_job_boundary_rms(m, tk->coords, placed);
            double size = sm_mesh_diameter(m, placed);
            if (d < 0)
                st = sm_error_set(err, SM_ERR_NOMEM, "out of memory");
            x->ro->movement[k - 2] = size > 0 ? d / size : d;
        }
    }
    int settled = k > 1 && x->ro->movement[k - 2] < x->r->tolerance;
    if (st == SM_OK && *valid && k < x->r->rounds && !settled) {
        char *slash = strrchr(*next_path, '/');
        *slash = '\0';
        st = sm_mkdir_p(*next_path, err);
        *slash = '/';
        if (st == SM_OK)
            st = sm_mesh_write_coords(*next_path, m, placed, err);
    }
    free(placed);
    sm_mesh_free(m);
    sm_mesh_free(tk);
    free(path);
    return st;
}

static json_t *reals(const double *v, int n)
{
    json_t *a = json_array();
    for (int i = 0; a && i < n; i++)
        json_array_append_new(a, isfinite(v[i]) ? json_real(v[i]) : json_null());
    return a;
}

/* The "template_from" object of the summaries. */
static json_t *template_from_doc(const rounds *x)
{
    const sm_rounds_opts *r = x->r;
    int n = x->ro->rounds;
    json_t *doc = json_pack("{s:s, s:o, s:i}", "mode", sm_template_from_name(r->from), "start",
                            sm_json_string_lossy(x->opts->template_mesh), "rounds", n);
    if (!doc)
        return NULL;
    json_object_set_new(doc, "stop", json_string(x->ro->stop));
    if (r->from == SM_TEMPLATE_FROM_FILE)
        return doc;
    json_object_set_new(doc, "template", json_string("template.mesh"));
    json_object_set_new(doc, "template_source", sm_json_string_lossy(x->template_of[n]));
    if (x->ro->message[0])
        json_object_set_new(doc, "message", sm_json_string_lossy(x->ro->message));
    if (r->from == SM_TEMPLATE_FROM_MEDOID) {
        json_object_set_new(doc, "medoid", sm_json_string_lossy(x->ro->medoid));
        json_object_set_new(doc, "medoid_distances", json_incref(x->medoid_sums));
        json_object_set_new(doc, "distance", json_string("two-sided RMS between the matched "
                                                         "shapes' boundaries, pairs aligned as "
                                                         "the model aligns them; sum over the "
                                                         "others"));
        return doc;
    }
    json_object_set_new(doc, "max_rounds", json_integer(r->rounds));
    json_object_set_new(doc, "tolerance", json_real(r->tolerance));
    json_object_set_new(doc, "movement", reals(x->ro->movement, n > 1 ? n - 1 : 0));
    json_object_set_new(doc, "mean_min_quality", reals(x->mean_quality + 1, n));
    return doc;
}

/* json file dir/name gets key "template_from" (atomically rewritten). */
static sm_status annotate(const char *dir, const char *name, json_t *tf, unsigned flags,
                          sm_error *err)
{
    char *path = sm_path_join(dir, name);
    json_error_t je;
    json_t *doc = path ? json_load_file(path, 0, &je) : NULL;
    sm_status st = SM_OK;
    if (!doc)
        st = sm_error_set(err, SM_ERR_IO, "%s: %s", path ? path : name, path ? je.text
                                                                               : "out of memory");
    else if (json_object_set(doc, "template_from", tf) != 0)
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    else
        st = sm_job_write_json(dir, name, doc, flags, err);
    json_decref(doc);
    free(path);
    return st;
}

/* dir/name moved to out/name (the last round's folders to the batch's). */
static sm_status move_up(const char *dir, const char *out, const char *name, sm_error *err)
{
    char *from = sm_path_join(dir, name), *to = sm_path_join(out, name);
    sm_status st = SM_OK;
    struct stat sb;
    if (!from || !to)
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    else if (stat(from, &sb) == 0 && rename(from, to) != 0)
        st = sm_error_set(err, SM_ERR_IO, "cannot move %s to %s: %s", from, to, strerror(errno));
    free(from);
    free(to);
    return st;
}

/* The last round's targets and model become the batch's, its template is
 * copied beside them, the summaries say how it was chosen. */
static sm_status finish(rounds *x, sm_batch_outcome *out, sm_error *err)
{
    int n = x->ro->rounds;
    const char *dir = x->round_dir[n];
    sm_mesh *t = NULL;
    sm_status st = move_up(dir, x->out_dir, "targets", err);
    if (st == SM_OK)
        st = move_up(dir, x->out_dir, "model", err);
    char *tpath = sm_path_join(x->out_dir, "template.mesh");
    if (st == SM_OK && (st = sm_mesh_read(x->template_of[n], &t, err)) == SM_OK)
        st = tpath ? sm_mesh_write(tpath, t, err)
                   : sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    sm_mesh_free(t);
    free(tpath);
    json_t *tf = st == SM_OK ? template_from_doc(x) : NULL;
    if (st == SM_OK && !tf)
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    const char *sname = summary_name(x->r);
    char *summary = sm_path_join(dir, sname);
    char *dest = sm_path_join(x->out_dir, sname);
    if (st == SM_OK && (!summary || !dest || rename(summary, dest) != 0))
        st = sm_error_set(err, SM_ERR_IO, "cannot move the last round's %s: %s", sname,
                          strerror(errno));
    if (st == SM_OK)
        st = annotate(x->out_dir, sname, tf, SM_ATOMIC_FSYNC, err);
    char *model_dir = sm_path_join(x->out_dir, "model");
    if (st == SM_OK && out->model_built)
        st = model_dir ? annotate(model_dir, SM_MODEL_SUMMARY_FILE, tf,
                                  x->opts->model.write_flags, err)
                       : sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    free(model_dir), free(summary), free(dest);
    json_decref(tf);
    return st;
}

static sm_status run_batch(const sm_rounds_opts *r, const sm_batch_list *list,
                           const sm_batch_opts *o, int k, const char *dir,
                           sm_batch_outcome *out, sm_error *err)
{
    return r->run ? r->run(list, o, k, dir, out, r->run_user, err)
                  : sm_job_batch_run(list, o, dir, out, err);
}

static void set_stop(rounds *x, const char *stop)
{
    snprintf(x->ro->stop, sizeof x->ro->stop, "%s", stop);
}

/* Round k on x->template_of[k]; decides the next template or the stop
 * (*last set). */
static sm_status run_round(rounds *x, int k, sm_batch_outcome *out, int *last, sm_error *err)
{
    const sm_rounds_opts *r = x->r;
    char name[16];
    snprintf(name, sizeof name, "rounds/%d", k);
    x->round_dir[k] = sm_path_join(x->out_dir, name);
    sm_status st = x->round_dir[k] ? sm_mkdir_p(x->round_dir[k], err)
                                   : sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    sm_batch_opts o = *x->opts;
    o.template_mesh = x->template_of[k];
    /* medoid: round 1's model is not needed */
    o.build_model = r->from == SM_TEMPLATE_FROM_MEAN || k > 1;
    if (st == SM_OK)
        st = run_batch(x->r, x->list, &o, k, x->round_dir[k], out, err);
    if (st != SM_OK)
        return st;
    x->ro->rounds = k;
    *last = 1;
    char *next = NULL;
    int valid = 1;
    if (out->cancelled) {
        set_stop(x, "cancelled");
    } else if (r->from == SM_TEMPLATE_FROM_MEDOID) {
        if (k == 1 && (st = find_medoid(x, x->round_dir[k], &next, err)) != SM_OK) {
            /* no medoid to run on: round 1 is the batch, and says why */
            set_stop(x, "no_medoid");
            snprintf(x->ro->message, sizeof x->ro->message, "no medoid: %.400s", err->msg);
            sm_error_clear(err);
            st = SM_OK;
        }
        if (k == 2)
            set_stop(x, "medoid");
    } else if (!out->model_built) {
        set_stop(x, "model_failed");
        snprintf(x->ro->message, sizeof x->ro->message, "round %d: no model: %.400s", k,
                 out->model_error);
    } else if ((st = place_mean(x, k, &valid, &next, err)) != SM_OK) {
        free(next);
        return st;
    } else {
        int settled = k > 1 && x->ro->movement[k - 2] < r->tolerance;
        const char *stop = !valid    ? "mean_inverted"
                           : settled ? "converged"
                           : k == r->rounds ? "rounds" : NULL;
        if (stop) { /* place_mean wrote no next template */
            set_stop(x, stop);
            free(next);
            next = NULL;
        }
    }
    if (next) {
        x->template_of[k + 1] = next;
        *last = 0;
    }
    if (r->round_done)
        r->round_done(k, x->template_of[k], k > 1 ? x->ro->movement[k - 2] : NAN, next,
                      x->opts->user);
    return st;
}

static sm_status check_opts(const sm_batch_opts *o, sm_rounds_opts *r, const char *out_dir,
                            sm_error *err)
{
    if (r->rounds == 0)
        r->rounds = SM_TEMPLATE_ROUNDS_DEFAULT;
    if (r->tolerance == 0)
        r->tolerance = SM_TEMPLATE_TOLERANCE_DEFAULT;
    if ((unsigned)r->from > SM_TEMPLATE_FROM_MEAN)
        return sm_error_set(err, SM_ERR_INVALID, "template_from: not file, medoid or mean");
    if (r->from == SM_TEMPLATE_FROM_FILE)
        return SM_OK;
    if (r->rounds < 2 || r->rounds > SM_TEMPLATE_ROUNDS_MAX)
        return sm_error_set(err, SM_ERR_INVALID, "rounds: %d is not from 2 (the first round "
                            "matches the given template) to %d", r->rounds,
                            SM_TEMPLATE_ROUNDS_MAX);
    if (!(r->tolerance > 0 && r->tolerance < 1))
        return sm_error_set(err, SM_ERR_INVALID, "the mean's tolerance %g is not in (0, 1)",
                            r->tolerance);
    if (o->template_landmarks)
        return sm_error_set(err, SM_ERR_INVALID, "template landmarks belong to the given "
                            "template, not to a %s", sm_template_from_name(r->from));
    if (!o->build_model)
        return sm_error_set(err, SM_ERR_INVALID, "template from the %s: the rounds build the "
                            "model (no --no-model)", sm_template_from_name(r->from));
    static const char *const kept[] = {"targets", "rounds", "model"};
    for (size_t i = 0; i < 3; i++) {
        char *p = sm_path_join(out_dir, kept[i]);
        struct stat sb;
        int there = p && stat(p, &sb) == 0;
        free(p);
        if (there)
            return sm_error_set(err, SM_ERR_IO, "%s/%s exists (an earlier batch): the rounds "
                                "write a new folder", out_dir, kept[i]);
    }
    return SM_OK;
}

sm_status sm_job_batch_rounds(const sm_batch_list *list, const sm_batch_opts *opts,
                              const sm_rounds_opts *r_in, const char *out_dir,
                              sm_batch_outcome *out, sm_rounds_outcome *ro, sm_error *err)
{
    memset(ro, 0, sizeof *ro);
    memset(out, 0, sizeof *out);
    sm_rounds_opts r = *r_in;
    sm_status st = check_opts(opts, &r, out_dir, err);
    if (st != SM_OK)
        return st;
    rounds x = {.list = list, .opts = opts, .r = &r, .out_dir = out_dir, .ro = ro};
    for (int k = 0; k <= SM_TEMPLATE_ROUNDS_MAX; k++)
        x.mean_quality[k] = NAN;
    for (int k = 0; k < SM_TEMPLATE_ROUNDS_MAX; k++)
        ro->movement[k] = NAN;
    if (r.from == SM_TEMPLATE_FROM_FILE) {
        st = run_batch(&r, list, opts, 1, out_dir, out, err);
        ro->rounds = 1;
        set_stop(&x, "file");
        json_t *tf = st == SM_OK ? template_from_doc(&x) : NULL;
        if (st == SM_OK)
            st = annotate(out_dir, summary_name(&r), tf, SM_ATOMIC_FSYNC, err);
        char *model_dir = sm_path_join(out_dir, "model");
        if (st == SM_OK && out->model_built && model_dir)
            st = annotate(model_dir, SM_MODEL_SUMMARY_FILE, tf, opts->model.write_flags, err);
        free(model_dir);
        json_decref(tf);
        return st;
    }
    x.template_of[1] = strdup(opts->template_mesh);
    if (!x.template_of[1])
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    int last = 0;
    for (int k = 1; st == SM_OK && !last; k++)
        st = run_round(&x, k, out, &last, err);
    if (st == SM_OK)
        st = finish(&x, out, err);
    for (int k = 0; k <= SM_TEMPLATE_ROUNDS_MAX; k++)
        free(x.round_dir[k]);
    for (int k = 0; k <= SM_TEMPLATE_ROUNDS_MAX + 1; k++)
        free(x.template_of[k]);
    json_decref(x.medoid_sums);
    return st;
}

sm_status sm_job_rounds_keep_template_from(const char *batch_dir, unsigned write_flags,
                                           sm_error *err)
{
    char *path = sm_path_join(batch_dir, "summary.json");
    char *model_dir = sm_path_join(batch_dir, "model");
    json_error_t je;
    json_t *doc = path ? json_load_file(path, 0, &je) : NULL;
    json_t *tf = json_object_get(doc, "template_from");
    sm_status st = SM_OK;
    if (!path || !model_dir)
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    else if (!doc)
        st = sm_error_set(err, SM_ERR_IO, "%s: %s", path, je.text);
    else if (tf)
        st = annotate(model_dir, SM_MODEL_SUMMARY_FILE, tf, write_flags, err);
    json_decref(doc);
    free(path);
    free(model_dir);
    return st;
}
