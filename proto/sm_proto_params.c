/* Job parameters: JSON <-> sm_params.  The ranges here are the ones of
 * proto/params.schema.json; keep the two in step (tests/unit/
 * test_proto_params.c checks the schema's defaults against
 * sm_params_default and its bounds against this decoder). */
#include "sm_proto_params.h"

#include <float.h>
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sm_proto_events.h"
#include "sm_proto_json.h"

#define MAX_ITER_LIMIT 1000000000LL

static const char *const kind_names[] = {"ball", "elements", "vertices", "none"};

const char *sm_clamp_kind_name(sm_clamp_kind kind)
{
    if ((int)kind < 0 || (size_t)kind >= sizeof kind_names / sizeof kind_names[0])
        return NULL;
    return kind_names[kind];
}

int sm_clamp_kind_from_name(const char *name, sm_clamp_kind *out)
{
    if (!name)
        return -1;
    for (size_t i = 0; i < sizeof kind_names / sizeof kind_names[0]; i++)
        if (strcmp(name, kind_names[i]) == 0) {
            *out = (sm_clamp_kind)i;
            return 0;
        }
    return -1;
}

/* ---------------------------------------------------------------- decode */

typedef enum bound { NONE, INCL, EXCL } bound;

/* Number in a range; lo/hi ignored when their bound is NONE. */
static sm_status get_ranged(const json_t *v, const char *path, bound lo_kind,
                            double lo, bound hi_kind, double hi, double *out,
                            sm_error *err)
{
    double x;
    sm_status st = smp_get_number(v, path, 0, &x, err);
    if (st != SM_OK)
        return st;
    if (lo_kind == INCL && !(x >= lo))
        return sm_error_set(err, SM_ERR_INVALID, "%s: must be >= %g (got %.17g)", path, lo, x);
    if (lo_kind == EXCL && !(x > lo))
        return sm_error_set(err, SM_ERR_INVALID, "%s: must be > %g (got %.17g)", path, lo, x);
    if (hi_kind == INCL && !(x <= hi))
        return sm_error_set(err, SM_ERR_INVALID, "%s: must be <= %g (got %.17g)", path, hi, x);
    if (hi_kind == EXCL && !(x < hi))
        return sm_error_set(err, SM_ERR_INVALID, "%s: must be < %g (got %.17g)", path, hi, x);
    *out = x;
    return SM_OK;
}

static sm_status get_int_field(const json_t *v, const char *path, long long min,
                               long long max, int *out, sm_error *err)
{
    long long x;
    sm_status st = smp_get_integer(v, path, min, max, &x, err);
    if (st == SM_OK)
        *out = (int)x;
    return st;
}

/* A list of references: integers, at most SM_MAX_REFS, at least min_count. */
static sm_status get_refs(const json_t *v, const char *path, size_t min_count,
                          int32_t *refs, int *count, sm_error *err)
{
    if (!json_is_array(v))
        return sm_error_set(err, SM_ERR_INVALID, "%s: must be an array of integers (got %s)",
                            path, smp_type_name(v));
    size_t n = json_array_size(v);
    if (n < min_count)
        return sm_error_set(err, SM_ERR_INVALID,
                            "%s: must list at least %zu reference%s (the clamp set would be empty)",
                            path, min_count, min_count == 1 ? "" : "s");
    if (n > SM_MAX_REFS)
        return sm_error_set(err, SM_ERR_INVALID, "%s: at most %d references (got %zu)", path,
                            SM_MAX_REFS, n);
    for (size_t i = 0; i < n; i++) {
        char item[SMP_PATH_MAX];
        long long r;
        smp_path_index(item, path, i);
        sm_status st = smp_get_integer(json_array_get(v, i), item, INT32_MIN, INT32_MAX, &r, err);
        if (st != SM_OK)
            return st;
        refs[i] = (int32_t)r;
    }
    *count = (int)n;
    return SM_OK;
}

static sm_status decode_center(const json_t *v, const char *path, int dim,
                               sm_params *out, sm_error *err)
{
    if (!json_is_array(v))
        return sm_error_set(err, SM_ERR_INVALID, "%s: must be an array of %s numbers (got %s)",
                            path, dim == 3 ? "3" : dim == 2 ? "2" : "2 or 3", smp_type_name(v));
    size_t n = json_array_size(v);
    if (dim != 0 && n != (size_t)dim)
        return sm_error_set(err, SM_ERR_INVALID,
                            "%s: must have %d coordinates, the mesh dimension (got %zu)", path,
                            dim, n);
    if (dim == 0 && (n < 2 || n > 3))
        return sm_error_set(err, SM_ERR_INVALID, "%s: must have 2 or 3 coordinates (got %zu)",
                            path, n);
    for (size_t i = 0; i < 3; i++)
        out->clamp_center[i] = 0.0;
    for (size_t i = 0; i < n; i++) {
        char item[SMP_PATH_MAX];
        smp_path_index(item, path, i);
        sm_status st = smp_get_number(json_array_get(v, i), item, 0, &out->clamp_center[i], err);
        if (st != SM_OK)
            return st;
    }
    return SM_OK;
}

static sm_status decode_clamp(const json_t *clamp, const char *path, int dim,
                              sm_params *out, sm_error *err)
{
    char sub[SMP_PATH_MAX];
    if (!json_is_object(clamp))
        return sm_error_set(err, SM_ERR_INVALID, "%s: must be an object (got %s)", path,
                            smp_type_name(clamp));
    const json_t *kind = json_object_get(clamp, "kind");
    smp_path_join(sub, path, "kind");
    if (!kind)
        return sm_error_set(err, SM_ERR_INVALID,
                            "%s: required (one of \"ball\", \"elements\", \"vertices\", \"none\")",
                            sub);
    if (!json_is_string(kind))
        return sm_error_set(err, SM_ERR_INVALID, "%s: must be a string (got %s)", sub,
                            smp_type_name(kind));
    if (sm_clamp_kind_from_name(json_string_value(kind), &out->clamp) != 0) {
        char shown[SMP_PATH_MAX];
        /* reuse the key sanitizer to print the hostile string */
        smp_path_join(shown, "", json_string_value(kind));
        return sm_error_set(err, SM_ERR_INVALID,
                            "%s: unknown kind \"%s\" (expected \"ball\", \"elements\", "
                            "\"vertices\" or \"none\")",
                            sub, shown + 1);
    }

    int seen_center = 0, seen_radius = 0, seen_refs = 0;
    const char *key;
    json_t *value;
    json_object_foreach((json_t *)clamp, key, value) {
        smp_path_join(sub, path, key);
        sm_status st = SM_OK;
        if (strcmp(key, "kind") == 0)
            continue;
        if (strcmp(key, "center") == 0 && out->clamp == SM_CLAMP_BALL) {
            st = decode_center(value, sub, dim, out, err);
            seen_center = 1;
        } else if (strcmp(key, "radius") == 0 && out->clamp == SM_CLAMP_BALL) {
            st = get_ranged(value, sub, EXCL, 0, NONE, 0, &out->clamp_radius, err);
            seen_radius = 1;
        } else if (strcmp(key, "refs") == 0 &&
                   (out->clamp == SM_CLAMP_ELEMENTS || out->clamp == SM_CLAMP_VERTICES)) {
            st = get_refs(value, sub, 1, out->clamp_refs, &out->n_clamp_refs, err);
            seen_refs = 1;
        } else if (strcmp(key, "alpha") == 0 && out->clamp == SM_CLAMP_NONE) {
            st = get_ranged(value, sub, INCL, 0, NONE, 0, &out->alpha, err); /* 0: from the scale */
        } else if (strcmp(key, "center") == 0 || strcmp(key, "radius") == 0 ||
                   strcmp(key, "refs") == 0 || strcmp(key, "alpha") == 0) {
            st = sm_error_set(err, SM_ERR_INVALID, "%s: not allowed with kind \"%s\"", sub,
                              sm_clamp_kind_name(out->clamp));
        } else {
            st = sm_error_set(err, SM_ERR_INVALID,
                              "%s: unknown field (a clamp has kind, center, radius, refs, alpha)",
                              sub);
        }
        if (st != SM_OK)
            return st;
    }
    if (out->clamp == SM_CLAMP_BALL && (!seen_center || !seen_radius)) {
        smp_path_join(sub, path, seen_center ? "radius" : "center");
        return sm_error_set(err, SM_ERR_INVALID, "%s: required with kind \"ball\"", sub);
    }
    if ((out->clamp == SM_CLAMP_ELEMENTS || out->clamp == SM_CLAMP_VERTICES) && !seen_refs) {
        smp_path_join(sub, path, "refs");
        return sm_error_set(err, SM_ERR_INVALID, "%s: required with kind \"%s\"", sub,
                            sm_clamp_kind_name(out->clamp));
    }
    return SM_OK;
}

static const char top_fields[] =
    "clamp, free_boundary, young, poisson, max_iter, tol_step, tol_boundary, "
    "tol_boundary_rel, tol_stall, stall_window, min_quality, save_every, step_initial, step_max, refactor_every, live_every, solver, "
    "background_size, background_padding";

static sm_status decode_field(const char *key, const json_t *value, const char *sub,
                              int dim, sm_params *out, sm_background_params *bg, sm_error *err)
{
    if (strcmp(key, "clamp") == 0)
        return decode_clamp(value, sub, dim, out, err);
    if (strcmp(key, "free_boundary") == 0)
        return get_refs(value, sub, 0, out->free_refs, &out->n_free_refs, err);
    if (strcmp(key, "young") == 0)
        return get_ranged(value, sub, EXCL, 0, NONE, 0, &out->young, err);
    if (strcmp(key, "poisson") == 0)
        return get_ranged(value, sub, EXCL, -1, EXCL, 0.5, &out->poisson, err);
    if (strcmp(key, "max_iter") == 0)
        return get_int_field(value, sub, 1, MAX_ITER_LIMIT, &out->max_iter, err);
    if (strcmp(key, "tol_step") == 0)
        return get_ranged(value, sub, EXCL, 0, EXCL, 1, &out->tol_step, err);
    if (strcmp(key, "tol_boundary") == 0)
        return get_ranged(value, sub, INCL, 0, NONE, 0, &out->tol_boundary, err);
    if (strcmp(key, "tol_boundary_rel") == 0)
        return get_ranged(value, sub, INCL, 0, NONE, 0, &out->tol_boundary_rel, err);
    if (strcmp(key, "tol_stall") == 0)
        return get_ranged(value, sub, INCL, 0, EXCL, 1, &out->tol_stall, err);
    if (strcmp(key, "stall_window") == 0)
        return get_int_field(value, sub, 1, 100000, &out->stall_window, err);
    if (strcmp(key, "min_quality") == 0)
        return get_ranged(value, sub, INCL, 0, EXCL, 1, &out->min_quality, err);
    if (strcmp(key, "save_every") == 0)
        return get_int_field(value, sub, 0, INT_MAX, &out->save_every, err);
    if (strcmp(key, "step_initial") == 0)
        return get_ranged(value, sub, EXCL, 0, INCL, 1, &out->step_initial, err);
    if (strcmp(key, "step_max") == 0)
        return get_ranged(value, sub, EXCL, 0, INCL, 1, &out->step_max, err);
    if (strcmp(key, "refactor_every") == 0)
        return get_int_field(value, sub, 1, INT_MAX, &out->refactor_every, err);
    if (strcmp(key, "live_every") == 0)
        return get_int_field(value, sub, 0, INT_MAX, &out->live_every, err);
    if (strcmp(key, "solver") == 0) {
        if (!json_is_string(value) || sm_solver_kind_from_name(json_string_value(value), &out->solver) != 0)
            return sm_error_set(err, SM_ERR_INVALID, "%s: must be \"auto\", \"cholmod\" or \"amg\"", sub);
        return SM_OK;
    }
    if (strcmp(key, "background_size") == 0)
        return get_ranged(value, sub, EXCL, 0, NONE, 0, &bg->size, err);
    if (strcmp(key, "background_padding") == 0)
        return get_ranged(value, sub, EXCL, 0, INCL, SM_BACKGROUND_PADDING_MAX, &bg->padding, err);
    return sm_error_set(err, SM_ERR_INVALID, "%s: unknown field (known fields: %s)", sub,
                        top_fields);
}

static void params_reset(sm_params *out)
{
    /* zero first so padding and unused slots compare equal across decodes */
    memset(out, 0, sizeof *out);
    sm_params_default(out);
}

sm_status sm_job_params_from_jansson(const json_t *root, int dim, const char *path,
                                     sm_params *out, sm_background_params *bg, sm_error *err)
{
    char sub[SMP_PATH_MAX];
    sm_background_params b = {0, 0};
    if (!path)
        path = "params";
    params_reset(out);
    if (bg)
        *bg = b;
    if (dim != 0 && dim != 2 && dim != 3)
        return sm_error_set(err, SM_ERR_INVALID, "%s: mesh dimension %d is not 2 or 3", path,
                            dim);
    if (!root || !json_is_object(root))
        return sm_error_set(err, SM_ERR_INVALID, "%s: must be a JSON object (got %s)", path,
                            root ? smp_type_name(root) : "nothing");

    sm_params p;
    params_reset(&p);
    int seen_clamp = 0;
    const char *key;
    json_t *value;
    json_object_foreach((json_t *)root, key, value) {
        smp_path_join(sub, path, key);
        sm_status st = decode_field(key, value, sub, dim, &p, &b, err);
        if (st != SM_OK)
            return st;
        if (strcmp(key, "clamp") == 0)
            seen_clamp = 1;
    }
    if (!seen_clamp) {
        smp_path_join(sub, path, "clamp");
        return sm_error_set(err, SM_ERR_INVALID,
                            "%s: required (e.g. {\"kind\": \"ball\", \"center\": [0.5, 0.5], "
                            "\"radius\": 0.04} or {\"kind\": \"none\"})",
                            sub);
    }
    if (p.step_initial > p.step_max) {
        smp_path_join(sub, path, "step_initial");
        return sm_error_set(err, SM_ERR_INVALID, "%s: must be <= step_max (%.17g > %.17g)", sub,
                            p.step_initial, p.step_max);
    }
    if (dim != 0) {
        sm_status st = sm_params_validate(&p, dim, err);
        if (st != SM_OK) {
            sm_error_prefix(err, "%s", path);
            return st;
        }
    }
    *out = p;
    if (bg)
        *bg = b;
    return SM_OK;
}

sm_status sm_params_from_jansson(const json_t *root, int dim, const char *path,
                                 sm_params *out, sm_error *err)
{
    return sm_job_params_from_jansson(root, dim, path, out, NULL, err);
}

sm_status sm_job_params_from_json(const char *text, size_t len, int dim, sm_params *out,
                                  sm_background_params *bg, sm_error *err)
{
    json_t *root;
    params_reset(out);
    if (bg)
        bg->size = bg->padding = 0;
    sm_status st = smp_load(text, len, SM_PARAMS_JSON_MAX_BYTES, "params", &root, err);
    if (st != SM_OK)
        return st;
    st = sm_job_params_from_jansson(root, dim, "params", out, bg, err);
    json_decref(root);
    return st;
}

sm_status sm_params_from_json(const char *text, size_t len, int dim, sm_params *out,
                              sm_error *err)
{
    return sm_job_params_from_json(text, len, dim, out, NULL, err);
}

/* ---------------------------------------------------------------- encode */

static json_t *refs_array(const int32_t *refs, int n)
{
    json_t *a = json_array();
    if (!a)
        return NULL;
    for (int i = 0; i < n; i++)
        if (json_array_append_new(a, json_integer(refs[i])) != 0) {
            json_decref(a);
            return NULL;
        }
    return a;
}

static int all_finite(const sm_params *p)
{
    const double xs[] = {p->clamp_center[0], p->clamp_center[1], p->clamp_center[2],
                         p->clamp_radius, p->alpha, p->young, p->poisson, p->tol_step,
                         p->tol_boundary, p->tol_boundary_rel, p->tol_stall, p->min_quality,
                         p->step_initial, p->step_max};
    for (size_t i = 0; i < sizeof xs / sizeof xs[0]; i++)
        if (!isfinite(xs[i]))
            return 0;
    return 1;
}

json_t *sm_params_to_jansson(const sm_params *p, int dim)
{
    const char *kind = sm_clamp_kind_name(p->clamp);
    if (!kind || !all_finite(p) || p->n_clamp_refs < 0 || p->n_clamp_refs > SM_MAX_REFS ||
        p->n_free_refs < 0 || p->n_free_refs > SM_MAX_REFS ||
        (dim != 0 && dim != 2 && dim != 3))
        return NULL;
    int ncenter = dim ? dim : (p->clamp_center[2] == 0.0 ? 2 : 3);

    json_t *clamp = json_object();
    json_t *root = json_object();
    int bad = !clamp || !root;
    bad = bad || smp_set(clamp, "kind", json_string(kind));
    switch (p->clamp) {
    case SM_CLAMP_BALL: {
        json_t *center = bad ? NULL : json_array();
        for (int i = 0; center && i < ncenter; i++)
            bad = bad || json_array_append_new(center, json_real(p->clamp_center[i]));
        if (bad)
            json_decref(center);
        else
            bad = smp_set(clamp, "center", center);
        bad = bad || smp_set(clamp, "radius", json_real(p->clamp_radius));
        break;
    }
    case SM_CLAMP_ELEMENTS:
    case SM_CLAMP_VERTICES:
        bad = bad || smp_set(clamp, "refs", refs_array(p->clamp_refs, p->n_clamp_refs));
        break;
    case SM_CLAMP_NONE:
        bad = bad || smp_set(clamp, "alpha", json_real(p->alpha));
        break;
    }
    if (bad) {
        json_decref(clamp);
        json_decref(root);
        return NULL;
    }
    bad = smp_set(root, "clamp", clamp);
    bad = bad || smp_set(root, "free_boundary", refs_array(p->free_refs, p->n_free_refs));
    bad = bad || smp_set(root, "young", json_real(p->young));
    bad = bad || smp_set(root, "poisson", json_real(p->poisson));
    bad = bad || smp_set(root, "max_iter", json_integer(p->max_iter));
    bad = bad || smp_set(root, "tol_step", json_real(p->tol_step));
    bad = bad || smp_set(root, "tol_boundary", json_real(p->tol_boundary));
    bad = bad || smp_set(root, "tol_boundary_rel", json_real(p->tol_boundary_rel));
    bad = bad || smp_set(root, "tol_stall", json_real(p->tol_stall));
    bad = bad || smp_set(root, "stall_window", json_integer(p->stall_window));
    bad = bad || smp_set(root, "min_quality", json_real(p->min_quality));
    bad = bad || smp_set(root, "save_every", json_integer(p->save_every));
    bad = bad || smp_set(root, "step_initial", json_real(p->step_initial));
    bad = bad || smp_set(root, "step_max", json_real(p->step_max));
    bad = bad || smp_set(root, "refactor_every", json_integer(p->refactor_every));
    bad = bad || smp_set(root, "live_every", json_integer(p->live_every));
    bad = bad || smp_set(root, "solver", json_string(sm_solver_kind_name(p->solver) ? sm_solver_kind_name(p->solver) : "auto"));
    if (bad) {
        json_decref(root);
        return NULL;
    }
    return root;
}

char *sm_params_to_json(const sm_params *p, int dim)
{
    json_t *root = sm_params_to_jansson(p, dim);
    if (!root)
        return NULL;
    char *text = sm_json_dumps(root, 0);
    json_decref(root);
    return text;
}

/* One background member: left out when 0 (not given); -1 when it is
 * something JSON or the decoder would not take back. */
static int set_background_member(json_t *root, const char *key, double v, double max)
{
    if (v == 0)
        return 0;
    if (!(v > 0) || !(v <= max))
        return -1;
    return smp_set(root, key, json_real(v));
}

json_t *sm_job_params_to_jansson(const sm_params *p, const sm_background_params *bg, int dim)
{
    json_t *root = sm_params_to_jansson(p, dim);
    if (root && bg &&
        (set_background_member(root, "background_size", bg->size, DBL_MAX) ||
         set_background_member(root, "background_padding", bg->padding,
                               SM_BACKGROUND_PADDING_MAX))) {
        json_decref(root);
        return NULL;
    }
    return root;
}

char *sm_job_params_to_json(const sm_params *p, const sm_background_params *bg, int dim)
{
    json_t *root = sm_job_params_to_jansson(p, bg, dim);
    if (!root)
        return NULL;
    char *text = sm_json_dumps(root, 0);
    json_decref(root);
    return text;
}
