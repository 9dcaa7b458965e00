/* The warp use case (see sm_job_warp.h). */
#include "job/sm_job_warp.h"

#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <unistd.h>

#include "shapematch/sm_path.h"
#include "shapematch/sm_surface.h"
#include "sm_json.h"
#include "sm_points_csv.h"

const char *const sm_job_result_mesh_files[] = {"result.mesh", "result.meshb", "result.mesh.gz",
                                                "result.meshb.gz", NULL};
const char *const sm_job_result_sol_files[] = {"displacement.sol", "displacement.solb",
                                               "displacement.sol.gz", "displacement.solb.gz",
                                               NULL};

char *sm_job_result_find(const char *dir, const char *const *names)
{
    for (; *names; names++) {
        char *p = sm_path_join(dir, *names);
        if (p && access(p, F_OK) == 0)
            return p;
        free(p);
    }
    return NULL;
}

/* ---------------------------------------------------------------- map */

struct sm_job_map {
    sm_mesh *tmpl;
    double *deformed;
    sm_warp *located[2]; /* per direction: locating points in its source */
    sm_warp *fields;     /* no location structure: fields only */
};

sm_status sm_job_map_new(sm_mesh *tmpl, double *deformed, unsigned directions,
                         sm_job_map **out, sm_error *err)
{
    *out = NULL;
    sm_job_map *m = calloc(1, sizeof *m);
    if (!m) {
        sm_mesh_free(tmpl);
        free(deformed);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    }
    m->tmpl = tmpl;
    m->deformed = deformed;
    for (int d = SM_WARP_FORWARD; d <= SM_WARP_INVERSE; d++)
        if ((directions & (1u << d)) && !sm_job_map_warp(m, (sm_warp_direction)d, err)) {
            sm_job_map_free(m);
            return err->code;
        }
    *out = m;
    return SM_OK;
}

sm_status sm_job_map_open(const char *dir, unsigned directions, sm_job_map **out, sm_error *err)
{
    *out = NULL;
    char *pm = sm_job_result_find(dir, sm_job_result_mesh_files);
    char *ps = sm_job_result_find(dir, sm_job_result_sol_files);
    sm_sol *d = NULL;
    sm_mesh *m = NULL;
    double *deformed = NULL;
    sm_status st;
    if (!pm || !ps) {
        st = sm_error_set(err, SM_ERR_IO, "%s has no %s (a result folder of 'run' or 'fetch')",
                          dir, !pm ? "result.mesh or result.meshb"
                                   : "displacement.sol or displacement.solb");
        goto done;
    }
    if ((st = sm_mesh_read(pm, &m, err)) != SM_OK || (st = sm_sol_read(ps, &d, err)) != SM_OK)
        goto done;
    if (d->nverts != m->nverts || d->ncomp != m->dim) {
        st = sm_error_set(err, SM_ERR_FORMAT,
                          "%s has %ld values of %d components, %s %ld vertices in %dD", ps,
                          (long)d->nverts, d->ncomp, pm, (long)m->nverts, m->dim);
        goto done;
    }
    size_t n = (size_t)m->nverts * (size_t)m->dim;
    if (!(deformed = malloc((n ? n : 1) * sizeof *deformed))) {
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory reading %s", pm);
        goto done;
    }
    memcpy(deformed, m->coords, n * sizeof *deformed);
    for (size_t i = 0; i < n; i++)
        m->coords[i] -= d->values[i];
    st = sm_job_map_new(m, deformed, directions, out, err);
    if (st != SM_OK)
        sm_error_prefix(err, "%s", dir);
    m = NULL;
    deformed = NULL;
done:
    sm_mesh_free(m);
    free(deformed);
    sm_sol_free(d);
    free(pm);
    free(ps);
    return st;
}

void sm_job_map_free(sm_job_map *m)
{
    if (!m)
        return;
    sm_warp_free(m->located[0]);
    sm_warp_free(m->located[1]);
    sm_warp_free(m->fields);
    sm_mesh_free(m->tmpl);
    free(m->deformed);
    free(m);
}

int sm_job_map_dim(const sm_job_map *m)
{
    return m->tmpl->dim;
}

const sm_mesh *sm_job_map_template(const sm_job_map *m)
{
    return m->tmpl;
}

const sm_warp *sm_job_map_warp(sm_job_map *m, sm_warp_direction dir, sm_error *err)
{
    sm_warp **w = &m->located[dir == SM_WARP_INVERSE];
    if (!*w && sm_warp_new(m->tmpl, m->deformed, 1u << dir, w, err) != SM_OK)
        *w = NULL;
    return *w;
}

/* A warp for fields: any built one, else one without location. */
static const sm_warp *field_warp(sm_job_map *m, sm_error *err)
{
    if (m->located[0] || m->located[1])
        return m->located[0] ? m->located[0] : m->located[1];
    if (!m->fields && sm_warp_new(m->tmpl, m->deformed, 0, &m->fields, err) != SM_OK)
        m->fields = NULL;
    return m->fields;
}

/* ------------------------------------------------------------ helpers */

static sm_status stage(sm_job_warp_report *rep, sm_job_warp_stage s, sm_status st)
{
    rep->stage = s;
    return st;
}

/* The input's name in messages. */
static const char *name_of(const sm_job_warp_request *rq, const char *path)
{
    return rq->name ? rq->name : path;
}

/* A reader's message about path, said of rq->name instead. */
static void rename_msg(sm_error *err, const sm_job_warp_request *rq, const char *path)
{
    size_t n = strlen(path);
    if (!rq->name || strncmp(err->msg, path, n) != 0)
        return;
    char tail[sizeof err->msg];
    snprintf(tail, sizeof tail, "%s", err->msg + n);
    snprintf(err->msg, sizeof err->msg, "%s%s", rq->name, tail);
}

static int ends_with(const char *s, const char *suffix)
{
    size_t n = strlen(s), k = strlen(suffix);
    return n >= k && strcmp(s + n - k, suffix) == 0;
}

typedef enum out_format { OUT_UNKNOWN, OUT_MEDIT, OUT_VTU, OUT_SURFACE } out_format;

/* Medit and .vtu for both kinds; the surface formats (sm_surface_write:
 * STL, OBJ, PLY, OFF, VTK legacy) for surfaces. */
static out_format format_of(const char *path)
{
    static const char *const medit[] = {".mesh", ".meshb", ".mesh.gz", ".meshb.gz"};
    static const char *const surface[] = {".stl", ".obj", ".ply", ".off", ".vtk"};
    for (size_t i = 0; i < 4; i++)
        if (ends_with(path, medit[i]))
            return OUT_MEDIT;
    for (size_t i = 0; i < 5; i++)
        if (ends_with(path, surface[i]))
            return OUT_SURFACE;
    return ends_with(path, ".vtu") ? OUT_VTU : OUT_UNKNOWN;
}

int sm_job_warp_output_known(const char *path)
{
    return format_of(path) != OUT_UNKNOWN;
}

/* ------------------------------------------------------------- points */

static const char *const outside_names[] = {"extrapolate", "flag", "skip"};

int sm_job_warp_outside_from_name(const char *name)
{
    for (int i = 0; i < 3; i++)
        if (name && strcmp(name, outside_names[i]) == 0)
            return i;
    return -1;
}

const char *sm_job_warp_outside_name(sm_job_warp_outside outside)
{
    return (unsigned)outside < 3 ? outside_names[outside] : "extrapolate";
}

sm_job_points_format sm_job_points_format_of(const char *path)
{
    size_t n = path ? strlen(path) : 0;
    return n >= 4 && strcasecmp(path + n - 4, ".npy") == 0 ? SM_JOB_POINTS_NPY
                                                           : SM_JOB_POINTS_CSV;
}

/* The members of a JSON request into p, *dir, *strict and *outside;
 * SM_ERR_FORMAT naming the member. */
static sm_status parse_json(const char *text, size_t len, int64_t max_points, sm_points *p,
                            sm_warp_direction *dir, int *strict, sm_job_warp_outside *outside,
                            sm_error *err)
{
    json_error_t jerr;
    json_t *doc = json_loadb(text, len, JSON_REJECT_DUPLICATES, &jerr);
    sm_status st = SM_ERR_FORMAT;
    if (!json_is_object(doc)) {
        sm_error_set(err, st, "the body is not a JSON object%s%s", doc ? "" : ": ",
                     doc ? "" : jerr.text);
        goto done;
    }
    json_t *d = json_object_get(doc, "direction"), *s = json_object_get(doc, "strict");
    json_t *o = json_object_get(doc, "outside");
    json_t *pts = json_object_get(doc, "points");
    if (d && !(json_is_string(d) && (strcmp(json_string_value(d), "forward") == 0 ||
                                     strcmp(json_string_value(d), "inverse") == 0))) {
        sm_error_set(err, st, "direction: expected \"forward\" or \"inverse\"");
        goto done;
    }
    if (s && !json_is_boolean(s)) {
        sm_error_set(err, st, "strict: expected true or false");
        goto done;
    }
    if (o && sm_job_warp_outside_from_name(json_string_value(o)) < 0) {
        sm_error_set(err, st, "outside: expected \"extrapolate\", \"flag\" or \"skip\"");
        goto done;
    }
    if (d)
        *dir = strcmp(json_string_value(d), "inverse") == 0 ? SM_WARP_INVERSE : SM_WARP_FORWARD;
    if (s)
        *strict = json_is_true(s);
    if (o)
        *outside = (sm_job_warp_outside)sm_job_warp_outside_from_name(json_string_value(o));
    size_t n = json_array_size(pts);
    if (!json_is_array(pts) || n == 0) {
        sm_error_set(err, st, "points: expected a non-empty array of [x, y] or [x, y, z]");
        goto done;
    }
    if (max_points > 0 && n > (size_t)max_points) {
        sm_error_set(err, st = SM_ERR_NOMEM, "points: more than %lld points",
                     (long long)max_points);
        goto done;
    }
    p->dim = (int)json_array_size(json_array_get(pts, 0));
    if (p->dim != 2 && p->dim != 3) {
        sm_error_set(err, st, "points[0]: expected 2 or 3 numbers");
        goto done;
    }
    if (!(p->xyz = malloc(n * (size_t)p->dim * sizeof *p->xyz))) {
        sm_error_set(err, st = SM_ERR_NOMEM, "out of memory");
        goto done;
    }
    for (size_t i = 0; i < n; i++) {
        json_t *pt = json_array_get(pts, i);
        if (!json_is_array(pt) || json_array_size(pt) != (size_t)p->dim) {
            sm_error_set(err, st, "points[%zu]: expected %d numbers, as points[0]", i, p->dim);
            goto done;
        }
        for (int k = 0; k < p->dim; k++) {
            json_t *c = json_array_get(pt, (size_t)k);
            if (!json_is_number(c)) {
                sm_error_set(err, st, "points[%zu][%d]: not a number", i, k);
                goto done;
            }
            p->xyz[i * (size_t)p->dim + (size_t)k] = json_number_value(c);
        }
    }
    p->n = (int64_t)n;
    st = SM_OK;
done:
    json_decref(doc);
    return st;
}

/* The JSON answer, written by the one JSON writer: a flagged point (NaN,
 * which JSON has no number for) is null; skipped points are not in
 * "points", and "inside" keeps one flag per point given (which ones were
 * left out). */
static char *json_answer(sm_warp_direction dir, sm_job_warp_outside outside, const sm_points *p,
                         const double *out, const uint8_t *inside, int64_t noutside)
{
    json_t *pts = json_array(), *in = json_array();
    for (int64_t i = 0; pts && in && i < p->n; i++) {
        json_array_append_new(in, json_integer(inside[i]));
        if (outside == SM_JOB_OUTSIDE_SKIP && !inside[i])
            continue;
        const double *x = out + (size_t)i * (size_t)p->dim;
        json_array_append_new(pts, outside == SM_JOB_OUTSIDE_FLAG && !inside[i] ? json_null()
                                   : p->dim == 3 ? json_pack("[fff]", x[0], x[1], x[2])
                                                 : json_pack("[ff]", x[0], x[1]));
    }
    json_t *doc = json_pack("{s:s,s:o*,s:o*,s:I}", "direction",
                            dir == SM_WARP_INVERSE ? "inverse" : "forward", "points", pts,
                            "inside", in, "outside", (json_int_t)noutside);
    if (doc && outside == SM_JOB_OUTSIDE_SKIP)
        json_object_set_new(doc, "skipped", json_integer((json_int_t)noutside));
    char *text = doc ? sm_json_dumps(doc, 0) : NULL;
    json_decref(doc);
    return text;
}

/* The outside policy on out: NaN rows (flag), or the kept rows moved to
 * the front (skip); the number of rows in out after it. */
static int64_t apply_outside(sm_job_warp_outside outside, int dim, int64_t n, double *out,
                             const uint8_t *inside)
{
    if (outside == SM_JOB_OUTSIDE_EXTRAPOLATE)
        return n;
    int64_t kept = 0;
    for (int64_t i = 0; i < n; i++) {
        double *x = out + (size_t)i * (size_t)dim;
        if (inside[i]) {
            if (outside == SM_JOB_OUTSIDE_SKIP && kept != i)
                memcpy(out + (size_t)kept * (size_t)dim, x, (size_t)dim * sizeof *x);
            kept++;
        } else if (outside == SM_JOB_OUTSIDE_FLAG) {
            for (int k = 0; k < dim; k++)
                x[k] = NAN;
        }
    }
    return outside == SM_JOB_OUTSIDE_SKIP ? kept : n;
}

sm_status sm_job_warp_points(sm_job_map *map, int dim, int64_t n, const double *xyz,
                             const sm_job_warp_request *rq, double *out, uint8_t *inside,
                             int64_t *kept, sm_job_warp_report *rep, sm_error *err)
{
    memset(rep, 0, sizeof *rep);
    rep->kind = SM_JOB_WARP_POINTS;
    rep->direction = rq->direction;
    rep->n = n;
    *kept = 0;
    if (dim != sm_job_map_dim(map))
        return stage(rep, SM_JOB_WARP_MAP,
                     sm_error_set(err, SM_ERR_INVALID, "%dD points and the map is %dD", dim,
                                  sm_job_map_dim(map)));
    const sm_warp *w = sm_job_map_warp(map, rq->direction, err);
    if (!w)
        return stage(rep, SM_JOB_WARP_MAP, err->code);
    sm_status st = sm_warp_points(w, rq->direction, rq->strict, n, xyz, out, inside,
                                  &rep->noutside, err);
    if (st != SM_OK)
        return stage(rep, SM_JOB_WARP_MAP, st);
    *kept = apply_outside(rq->strict ? SM_JOB_OUTSIDE_EXTRAPOLATE : rq->outside, dim, n, out,
                          inside);
    return SM_OK;
}

/* The points of a .npy file as an sm_points. */
static sm_status parse_npy(const char *bytes, size_t len, const sm_job_warp_request *rq,
                           sm_points *p, sm_error *err)
{
    int cols;
    sm_status st = sm_npy_parse(bytes, len, rq->max_points, rq->name ? rq->name : "the .npy",
                                &p->xyz, &p->n, &cols, err);
    p->dim = cols;
    p->kind = ".npy";
    return st;
}

sm_status sm_job_warp_points_bytes(sm_job_map *map, sm_job_points_format in_format,
                                   const char *bytes, size_t len,
                                   sm_job_points_format out_format,
                                   const sm_job_warp_request *rq, char **answer,
                                   size_t *answer_len, sm_job_warp_report *rep, sm_error *err)
{
    memset(rep, 0, sizeof *rep);
    rep->kind = SM_JOB_WARP_POINTS;
    *answer = NULL;
    *answer_len = 0;
    sm_points p = {0};
    sm_warp_direction dir = rq->direction;
    int strict = rq->strict;
    sm_job_warp_outside outside = rq->outside;
    int json = in_format == SM_JOB_POINTS_JSON;
    double *out = NULL;
    uint8_t *inside = NULL;
    const sm_warp *w;
    sm_status st = json ? parse_json(bytes, len, rq->max_points, &p, &dir, &strict, &outside, err)
                   : in_format == SM_JOB_POINTS_NPY
                       ? parse_npy(bytes, len, rq, &p, err)
                       : sm_points_csv_parse(bytes, len, rq->max_points, &p, err);
    rep->direction = dir;
    if (st != SM_OK) {
        if (rq->name && in_format != SM_JOB_POINTS_NPY)
            sm_error_prefix(err, "%s", rq->name);
        st = stage(rep, SM_JOB_WARP_INPUT, st);
        goto done;
    }
    if (strict)
        outside = SM_JOB_OUTSIDE_EXTRAPOLATE; /* none will be */
    sm_points_to_frame(&p, SM_POINTS_FRAME_LPS); /* Slicer's RAS markups */
    rep->n = p.n;
    if (p.dim != sm_job_map_dim(map)) {
        st = stage(rep, SM_JOB_WARP_MAP,
                   rq->name ? sm_error_set(err, SM_ERR_INVALID,
                                           "%s has %dD points and the map is %dD", rq->name,
                                           p.dim, sm_job_map_dim(map))
                            : sm_error_set(err, SM_ERR_INVALID,
                                           "points: %dD points, and the map is %dD", p.dim,
                                           sm_job_map_dim(map)));
        goto done;
    }
    out = malloc(((size_t)p.n * (size_t)p.dim + 1) * sizeof *out);
    inside = malloc((size_t)p.n + 1);
    if (!out || !inside) {
        st = stage(rep, SM_JOB_WARP_MAP, sm_error_set(err, SM_ERR_NOMEM,
                                                      "out of memory for %lld points",
                                                      (long long)p.n));
        goto done;
    }
    if (!(w = sm_job_map_warp(map, dir, err))) {
        st = stage(rep, SM_JOB_WARP_MAP, err->code);
        goto done;
    }
    /* CSV: a strict refusal names the point's line; .npy and JSON: its
     * index */
    st = sm_points_warp(w, dir, strict, &p, in_format == SM_JOB_POINTS_CSV ? bytes : NULL, len,
                        out, inside, &rep->noutside, err);
    if (st != SM_OK) {
        if (rq->name)
            sm_error_prefix(err, "%s", rq->name);
        st = stage(rep, SM_JOB_WARP_MAP, st);
        goto done;
    }
    if (json) {
        if (outside == SM_JOB_OUTSIDE_FLAG)
            apply_outside(outside, p.dim, p.n, out, inside);
        if ((*answer = json_answer(dir, outside, &p, out, inside, rep->noutside)))
            *answer_len = strlen(*answer);
    } else if (out_format == SM_JOB_POINTS_NPY) {
        int64_t rows = apply_outside(outside, p.dim, p.n, out, inside);
        st = sm_npy_encode(out, rows, p.dim, answer, answer_len, err);
        if (st != SM_OK)
            st = stage(rep, SM_JOB_WARP_OUTPUT, st);
        goto done;
    } else {
        if (outside == SM_JOB_OUTSIDE_FLAG)
            apply_outside(outside, p.dim, p.n, out, inside);
        *answer = sm_points_csv_format(&p, out, inside, outside == SM_JOB_OUTSIDE_SKIP,
                                       answer_len);
    }
    if (!*answer)
        st = stage(rep, SM_JOB_WARP_OUTPUT, sm_error_set(err, SM_ERR_NOMEM, "out of memory"));
done:
    free(out);
    free(inside);
    sm_points_release(&p);
    return st;
}

sm_status sm_job_warp_points_text(sm_job_map *map, int json, const char *text, size_t len,
                                  const sm_job_warp_request *rq, char **answer,
                                  size_t *answer_len, sm_job_warp_report *rep, sm_error *err)
{
    sm_job_points_format f = json ? SM_JOB_POINTS_JSON : SM_JOB_POINTS_CSV;
    return sm_job_warp_points_bytes(map, f, text, len, f, rq, answer, answer_len, rep, err);
}

/* --------------------------------------------------------- mesh files */

sm_status sm_job_warp_mesh_file(sm_job_map *map, const char *in, const char *out,
                                const sm_job_warp_request *rq, double **coords,
                                sm_job_warp_report *rep, sm_error *err)
{
    memset(rep, 0, sizeof *rep);
    rep->direction = rq->direction;
    if (coords)
        *coords = NULL;
    const char *name = name_of(rq, in);
    out_format fmt = out ? format_of(out) : OUT_UNKNOWN;
    if (out && fmt == OUT_UNKNOWN)
        return stage(rep, SM_JOB_WARP_FORMAT,
                     sm_error_set(err, SM_ERR_INVALID, "%s: the output format is chosen by "
                                  "its extension: %s", out, SM_SURFACE_WRITE_FORMATS));
    sm_error merr, serr;
    sm_error_clear(&merr);
    sm_error_clear(&serr);
    sm_mesh *m = NULL;
    sm_surface *s = NULL;
    double *xyz = NULL;
    sm_status st;
    sm_read_limits none = {0}, *limits = rq->limits ? rq->limits : &none;
    if (sm_mesh_read_limited(in, limits, &m, &merr) != SM_OK) {
        rename_msg(&merr, rq, in);
        /* a file that is not there, or too large: no other reader */
        if (merr.code == SM_ERR_IO || merr.code == SM_ERR_NOMEM || limits->hit) {
            *err = merr;
            return stage(rep, SM_JOB_WARP_INPUT, merr.code);
        }
        if ((st = sm_surface_read_limited(in, limits, &s, &serr)) != SM_OK) {
            rename_msg(&serr, rq, in);
            if (limits->hit) {
                *err = serr;
                return stage(rep, SM_JOB_WARP_INPUT, st);
            }
            return stage(rep, SM_JOB_WARP_INPUT,
                         sm_error_set(err, st, "%s is neither a mesh (%s) nor a surface (%s)",
                                      name, merr.msg, serr.msg));
        }
    }
    int dim = m ? m->dim : s->dim;
    int32_t n = m ? m->nverts : s->nverts;
    const double *from = m ? m->coords : s->coords;
    rep->kind = m ? SM_JOB_WARP_VOLUME : SM_JOB_WARP_SURFACE;
    rep->n = n;
    const sm_warp *w;
    if (m && out && fmt != OUT_MEDIT && fmt != OUT_VTU) {
        st = stage(rep, SM_JOB_WARP_FORMAT,
                   sm_error_set(err, SM_ERR_INVALID, "%s is a volume mesh: write it as .mesh, "
                                ".meshb or .vtu (the surface formats are for surfaces)", name));
    } else if (s && out && s->dim != 3 &&
               (ends_with(out, ".stl") || ends_with(out, ".ply") || ends_with(out, ".off"))) {
        st = stage(rep, SM_JOB_WARP_FORMAT,
                   sm_error_set(err, SM_ERR_INVALID, "%s is a polyline: write it as .mesh, "
                                ".meshb, .obj, .vtk or .vtu", name));
    } else if (dim != sm_job_map_dim(map)) {
        st = stage(rep, SM_JOB_WARP_MAP,
                   sm_error_set(err, SM_ERR_INVALID, "%s is %dD and the map is %dD", name, dim,
                                sm_job_map_dim(map)));
    } else if (!(xyz = malloc(((size_t)n * (size_t)dim + 1) * sizeof *xyz))) {
        st = stage(rep, SM_JOB_WARP_MAP, sm_error_set(err, SM_ERR_NOMEM, "out of memory"));
    } else if (!(w = sm_job_map_warp(map, rq->direction, err))) {
        st = stage(rep, SM_JOB_WARP_MAP, err->code);
    } else if ((st = sm_warp_points(w, rq->direction, rq->strict, n, from, xyz, NULL,
                                    &rep->noutside, err)) != SM_OK) {
        sm_error_prefix(err, "%s: vertices", name);
        stage(rep, SM_JOB_WARP_MAP, st);
    } else if (out) {
        st = !m                 ? sm_surface_write(out, s, xyz, err)
             : fmt == OUT_MEDIT ? sm_mesh_write_coords(out, m, xyz, err)
                                : sm_vtu_write(out, m, xyz, NULL, NULL, err);
        if (st != SM_OK)
            stage(rep, SM_JOB_WARP_OUTPUT, st);
    }
    if (st == SM_OK && coords) {
        *coords = xyz;
        xyz = NULL;
    }
    free(xyz);
    sm_mesh_free(m);
    sm_surface_free(s);
    return st;
}

/* ------------------------------------------------------------- fields */

sm_status sm_job_warp_field(sm_job_map *map, int dim, int32_t nverts, int ncomp, double *values,
                            const sm_job_warp_request *rq, sm_job_warp_report *rep,
                            sm_error *err)
{
    memset(rep, 0, sizeof *rep);
    rep->kind = SM_JOB_WARP_FIELD;
    rep->direction = rq->direction;
    rep->n = nverts;
    rep->ncomp = ncomp;
    const sm_mesh *t = map->tmpl;
    if (nverts != t->nverts || dim != t->dim)
        return stage(rep, SM_JOB_WARP_MAP,
                     sm_error_set(err, SM_ERR_INVALID,
                                  "%s is a %dD field on %ld vertices; the %s has %ld in %dD",
                                  rq->name ? rq->name : "the field", dim, (long)nverts,
                                  rq->direction == SM_WARP_FORWARD ? "template" : "result",
                                  (long)t->nverts, t->dim));
    const sm_warp *w = field_warp(map, err);
    sm_status st = w ? sm_warp_field(w, rq->direction, ncomp, rq->normalize, values, err)
                     : err->code;
    return st == SM_OK ? SM_OK : stage(rep, SM_JOB_WARP_MAP, st);
}

sm_status sm_job_warp_field_file(sm_job_map *map, const char *in, const char *out,
                                 const sm_job_warp_request *rq, sm_sol **field,
                                 sm_job_warp_report *rep, sm_error *err)
{
    memset(rep, 0, sizeof *rep);
    rep->kind = SM_JOB_WARP_FIELD;
    rep->direction = rq->direction;
    if (field)
        *field = NULL;
    sm_sol *s = NULL;
    sm_read_limits none = {0};
    sm_status st = sm_sol_read_limited(in, rq->limits ? rq->limits : &none, &s, err);
    if (st != SM_OK) {
        rename_msg(err, rq, in);
        return stage(rep, SM_JOB_WARP_INPUT, st);
    }
    sm_job_warp_request named = *rq;
    named.name = name_of(rq, in);
    st = sm_job_warp_field(map, s->dim, s->nverts, s->ncomp, s->values, &named, rep, err);
    if (st == SM_OK && out && (st = sm_sol_write(out, s, err)) != SM_OK)
        stage(rep, SM_JOB_WARP_OUTPUT, st);
    if (st == SM_OK && field) {
        *field = s;
        s = NULL;
    }
    sm_sol_free(s);
    return st;
}
