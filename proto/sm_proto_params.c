/* Job parameters: JSON <-> sm_params, read from the parameter table
 * (sm_params_table, shapematch/sm_params.h) plus the background rows
 * below: names, types, bounds and the encoder's order come from there.
 * proto/params.schema.json describes the same (tests/unit/
 * test_proto_params.c checks it against the tables). */
#include "sm_proto_params.h"

#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sm_proto_events.h"
#include "sm_proto_json.h"

/* The generated background's members (sm_background_params): rows of
 * the same kind as the core's, which does not know them.  Fields in
 * sm_param_info's order: name, type, offset, count_offset, min, max,
 * min_open, max_open, def, def_text, in_clamp, flag, meta, help, group. */
static const sm_param_info background_rows[] = {
    {"background_size", SM_PARAM_REAL, offsetof(sm_background_params, size), 0, 0, INFINITY, 1,
     1, 0, "the smaller mean edge of template and surface", 0, "--background-size", "H",
     "with --target-surface and no --target-mesh: side of the generated background's cells "
     "near the surface, a length in the meshes' unit", "inputs"},
    {"background_padding", SM_PARAM_REAL, offsetof(sm_background_params, padding), 0, 0,
     SM_BACKGROUND_PADDING_MAX, 1, 0, SM_BACKGROUND_PADDING_DEFAULT, NULL, 0,
     "--background-padding", "P",
     "the margin of that background around template and surface, a fraction of their box's "
     "diagonal", "inputs"},
    {"template_size", SM_PARAM_REAL, offsetof(sm_background_params, template_size), 0, 0,
     INFINITY, 1, 1, 0, "the template surface's mean edge", 0, "--template-size", "H",
     "with --template-surface or --template-image: the meshed template's element size (nglib's "
     "maxh), a length in the surface's unit", "inputs"},
    /* an integer row as the core's label (the target image's): 0 as
     * "every nonzero voxel", the run's default, so 0 is also "not given" */
    {"template_label", SM_PARAM_INT, offsetof(sm_background_params, template_label), 0, 0,
     INT_MAX, 0, 0, 0, NULL, 0, "--template-label", "N",
     "with --template-image: the label whose voxels are the template (0: every nonzero voxel)",
     "inputs"},
};

const sm_param_info *sm_background_params_table(size_t *count)
{
    *count = sizeof background_rows / sizeof background_rows[0];
    return background_rows;
}

/* ---------------------------------------------------------------- decode */

/* A number within bounds written as in sm_param_info (an infinite bound
 * is none); the message names the side that is crossed. */
static sm_status get_ranged(const json_t *v, const char *path, double lo, int lo_open,
                            double hi, int hi_open, double *out, sm_error *err)
{
    double x;
    sm_status st = smp_get_number(v, path, 0, &x, err);
    if (st != SM_OK)
        return st;
    char bound[SM_NUMBER_TEXT_LEN], got[SM_NUMBER_TEXT_LEN];
    if (!isinf(lo) && !(lo_open ? x > lo : x >= lo))
        return sm_error_set(err, SM_ERR_INVALID, "%s: must be %s %s (got %s)", path,
                            lo_open ? ">" : ">=", sm_number_text(bound, lo),
                            sm_number_text(got, x));
    if (!isinf(hi) && !(hi_open ? x < hi : x <= hi))
        return sm_error_set(err, SM_ERR_INVALID, "%s: must be %s %s (got %s)", path,
                            hi_open ? "<" : "<=", sm_number_text(bound, hi),
                            sm_number_text(got, x));
    *out = x;
    return SM_OK;
}

/* 1 when v is a string that can be a physical name: 1 to
 * SM_PARAMS_NAME_MAX bytes, no control character. */
static int is_name(const json_t *v)
{
    if (!json_is_string(v))
        return 0;
    size_t n = json_string_length(v);
    const unsigned char *s = (const unsigned char *)json_string_value(v);
    if (n < 1 || n > SM_PARAMS_NAME_MAX)
        return 0;
    for (size_t i = 0; i < n; i++)
        if (s[i] < 32 || s[i] == 127)
            return 0;
    return 1;
}

/* A list of references: integers, at most SM_MAX_REFS, at least
 * min_count.  Names (physical names, strings) only with dim 0: they stand
 * as 0 until sm_params_resolve_names turns them into their tags. */
static sm_status get_refs(const json_t *v, const char *path, size_t min_count, int dim,
                          int32_t *refs, int *count, sm_error *err)
{
    if (!json_is_array(v))
        return sm_error_set(err, SM_ERR_INVALID,
                            "%s: must be an array of integers or physical names (got %s)", path,
                            smp_type_name(v));
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
        const json_t *x = json_array_get(v, i);
        if (json_is_string(x)) {
            char shown[SMP_PATH_MAX];
            smp_path_join(shown, "", json_string_value(x));
            if (!is_name(x))
                return sm_error_set(err, SM_ERR_INVALID,
                                    "%s: a physical name has 1 to %d characters, none a control "
                                    "character (got \"%s\")",
                                    item, SM_PARAMS_NAME_MAX, shown + 1);
            if (dim != 0)
                return sm_error_set(err, SM_ERR_INVALID,
                                    "%s: the physical name \"%s\" was not resolved against the "
                                    "template (sm_params_resolve_names)",
                                    item, shown + 1);
            refs[i] = 0;
            continue;
        }
        sm_status st = smp_get_integer(x, item, INT32_MIN, INT32_MAX, &r, err);
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

static sm_status decode_row(const sm_param_info *f, const json_t *value, const char *sub,
                            int dim, void *base, sm_error *err);

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
    const sm_param_info *alpha = sm_params_lookup("alpha");
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
            st = get_ranged(value, sub, 0, 1, INFINITY, 1, &out->clamp_radius, err);
            seen_radius = 1;
        } else if (strcmp(key, "refs") == 0 &&
                   (out->clamp == SM_CLAMP_ELEMENTS || out->clamp == SM_CLAMP_VERTICES)) {
            st = get_refs(value, sub, 1, dim, out->clamp_refs, &out->n_clamp_refs, err);
            seen_refs = 1;
        } else if (strcmp(key, alpha->name) == 0 && out->clamp == SM_CLAMP_NONE) {
            st = decode_row(alpha, value, sub, dim, out, err);
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

/* "clamp, free_boundary, young, ...": the members a params document may
 * have, for the message about an unknown one. */
static void list_fields(char *buf, size_t cap)
{
    size_t n_core, n_bg, used = 0;
    const sm_param_info *core = sm_params_table(&n_core);
    const sm_param_info *bg = sm_background_params_table(&n_bg);
    buf[0] = '\0';
    for (size_t i = 0; i < n_core + n_bg; i++) {
        const sm_param_info *f = i < n_core ? &core[i] : &bg[i - n_core];
        if (f->in_clamp)
            continue;
        int k = snprintf(buf + used, cap - used, "%s%s", used ? ", " : "", f->name);
        if (k < 0 || (size_t)k >= cap - used)
            return;
        used += (size_t)k;
    }
}

/* The member described by row f into its struct at base (sm_params or
 * sm_background_params); the clamp has decode_clamp. */
static sm_status decode_row(const sm_param_info *f, const json_t *value, const char *sub,
                            int dim, void *base, sm_error *err)
{
    char *at = (char *)base + f->offset;
    switch (f->type) {
    case SM_PARAM_REAL:
        return get_ranged(value, sub, f->min, f->min_open, f->max, f->max_open, (double *)at, err);
    case SM_PARAM_INT: {
        long long x;
        sm_status st = smp_get_integer(value, sub, (long long)f->min, (long long)f->max, &x, err);
        if (st == SM_OK)
            *(int *)at = (int)x;
        return st;
    }
    case SM_PARAM_REFS:
        return get_refs(value, sub, (size_t)f->min, dim, (int32_t *)at,
                        (int *)((char *)base + f->count_offset), err);
    case SM_PARAM_SOLVER:
    case SM_PARAM_ALIGN:
    case SM_PARAM_SPACE: {
        int k = json_is_string(value) ? sm_param_value_from_name(f, json_string_value(value)) : -1;
        if (k < 0) {
            char quoted[128]; /* "a", "b" or "c" */
            size_t o = 0;
            quoted[0] = '\0';
            for (int v = (int)f->min; v <= (int)f->max && o < sizeof quoted; v++) {
                int w = snprintf(quoted + o, sizeof quoted - o, "%s\"%s\"",
                                 v == (int)f->min ? "" : v == (int)f->max ? " or " : ", ",
                                 sm_param_value_name(f, v));
                o += w > 0 ? (size_t)w : 0;
            }
            return sm_error_set(err, SM_ERR_INVALID, "%s: must be %s", sub, quoted);
        }
        sm_param_set_value(f, base, k);
        return SM_OK;
    }
    case SM_PARAM_CLAMP:
        break;
    }
    return sm_error_set(err, SM_ERR_INVALID, "%s: no decoder for this member", sub);
}

static sm_status decode_field(const char *key, const json_t *value, const char *sub,
                              int dim, sm_params *out, sm_background_params *bg, sm_error *err)
{
    size_t n;
    const sm_param_info *f = sm_params_lookup(key);
    if (f && f->type == SM_PARAM_CLAMP)
        return decode_clamp(value, sub, dim, out, err);
    if (f && !f->in_clamp)
        return decode_row(f, value, sub, dim, out, err);
    const sm_param_info *rows = sm_background_params_table(&n);
    for (size_t i = 0; i < n; i++)
        if (strcmp(key, rows[i].name) == 0)
            return decode_row(&rows[i], value, sub, dim, bg, err);
    char known[512];
    list_fields(known, sizeof known);
    return sm_error_set(err, SM_ERR_INVALID, "%s: unknown field (known fields: %s)", sub, known);
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
    sm_background_params b = {0};
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
    const char *key;
    json_t *value;
    json_object_foreach((json_t *)root, key, value) {
        smp_path_join(sub, path, key);
        sm_status st = decode_field(key, value, sub, dim, &p, &b, err);
        if (st != SM_OK)
            return st;
    }
    /* no clamp: the default ball (kind auto, from sm_params_default) */
    if (p.step_initial > p.step_max) {
        smp_path_join(sub, path, "step_initial");
        char a[SM_NUMBER_TEXT_LEN], b[SM_NUMBER_TEXT_LEN];
        return sm_error_set(err, SM_ERR_INVALID, "%s: must be <= step_max (%s > %s)", sub,
                            sm_number_text(a, p.step_initial), sm_number_text(b, p.step_max));
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
        *bg = (sm_background_params){0};
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

/* --------------------------------------------------------- physical names */

/* The names of m of dimension dim (any when dim < 0), for messages:
 * "\"core\" (1), \"skin\" (3)" or "none". */
static void list_names(const sm_mesh *m, int dim, char *out, size_t cap)
{
    size_t at = 0;
    out[0] = '\0';
    for (int32_t i = 0; i < m->nnames && at + 1 < cap; i++) {
        if (dim >= 0 && m->names[i].dim != dim)
            continue;
        char shown[SMP_PATH_MAX];
        smp_path_join(shown, "", m->names[i].name ? m->names[i].name : "");
        int k = snprintf(out + at, cap - at, "%s\"%s\" (%d)", at ? ", " : "", shown + 1,
                         (int)m->names[i].tag);
        if (k < 0 || (size_t)k >= cap - at) {
            out[at] = '\0';
            break;
        }
        at += (size_t)k;
    }
    if (!out[0])
        snprintf(out, cap, "none");
}

/* The names in the array refs (at path) replaced by the tags of m's
 * physical groups of dimension dim (any when dim < 0). */
static sm_status resolve_list(json_t *refs, const char *path, const sm_mesh *m, int dim,
                              sm_error *err)
{
    size_t i;
    json_t *item;
    if (!json_is_array(refs))
        return SM_OK; /* the decoder names the wrong type */
    json_array_foreach(refs, i, item) {
        if (!json_is_string(item))
            continue;
        const char *name = json_string_value(item);
        int32_t k = 0;
        while (k < m->nnames && !((dim < 0 || m->names[k].dim == dim) && m->names[k].name &&
                                  strcmp(m->names[k].name, name) == 0))
            k++;
        if (k < m->nnames) {
            if (json_array_set_new(refs, i, json_integer(m->names[k].tag)) != 0)
                return sm_error_set(err, SM_ERR_NOMEM, "%s: out of memory", path);
            continue;
        }
        char where[SMP_PATH_MAX], shown[SMP_PATH_MAX], names[512];
        smp_path_index(where, path, i);
        smp_path_join(shown, "", name);
        const char *of = dim < 0 ? "" : dim == m->dim ? " of elements" : " of facets";
        if (m->nnames == 0)
            return sm_error_set(err, SM_ERR_INVALID,
                                "%s: the template has no physical names, so no group named "
                                "\"%s\" (names come from a Gmsh .msh file's $PhysicalNames; give "
                                "the references as numbers)",
                                where, shown + 1);
        list_names(m, dim, names, sizeof names);
        return sm_error_set(err, SM_ERR_INVALID,
                            "%s: the template has no physical group named \"%s\"%s (its "
                            "names%s: %s)",
                            where, shown + 1, of, of, names);
    }
    return SM_OK;
}

sm_status sm_params_resolve_names(json_t *root, const sm_mesh *m, const char *path,
                                  sm_error *err)
{
    char sub[SMP_PATH_MAX];
    if (!path)
        path = "params";
    if (!json_is_object(root) || !m)
        return SM_OK; /* the decoder says what is wrong */
    json_t *clamp = json_object_get(root, "clamp");
    json_t *kind = json_object_get(clamp, "kind");
    sm_clamp_kind k;
    if (json_is_string(kind) && sm_clamp_kind_from_name(json_string_value(kind), &k) == 0 &&
        (k == SM_CLAMP_ELEMENTS || k == SM_CLAMP_VERTICES)) {
        char clamp_path[SMP_PATH_MAX];
        smp_path_join(clamp_path, path, "clamp");
        smp_path_join(sub, clamp_path, "refs");
        /* elements by the groups of elements; vertices by any group (a
         * vertex's reference may come from a point, curve or surface) */
        sm_status st = resolve_list(json_object_get(clamp, "refs"), sub, m,
                                    k == SM_CLAMP_ELEMENTS ? m->dim : -1, err);
        if (st != SM_OK)
            return st;
    }
    smp_path_join(sub, path, "free_boundary");
    return resolve_list(json_object_get(root, "free_boundary"), sub, m, m->dim - 1, err);
}

sm_status sm_job_params_from_json_for(const char *text, size_t len, const sm_mesh *m,
                                      sm_params *out, sm_background_params *bg, sm_error *err)
{
    json_t *root;
    params_reset(out);
    if (bg)
        *bg = (sm_background_params){0};
    sm_status st = smp_load(text, len, SM_PARAMS_JSON_MAX_BYTES, "params", &root, err);
    if (st != SM_OK)
        return st;
    st = sm_params_resolve_names(root, m, "params", err);
    if (st == SM_OK)
        st = sm_job_params_from_jansson(root, m->dim, "params", out, bg, err);
    json_decref(root);
    return st;
}

sm_status sm_job_params_from_jansson_for(const json_t *root, const sm_mesh *m, sm_params *out,
                                         sm_background_params *bg, sm_error *err)
{
    params_reset(out);
    if (bg)
        *bg = (sm_background_params){0};
    if (!json_is_object(root))
        return sm_job_params_from_jansson(root, m->dim, "params", out, bg, err);
    json_t *copy = json_deep_copy(root);
    if (!copy)
        return sm_error_set(err, SM_ERR_NOMEM, "params: out of memory");
    sm_status st = sm_params_resolve_names(copy, m, "params", err);
    if (st == SM_OK)
        st = sm_job_params_from_jansson(copy, m->dim, "params", out, bg, err);
    json_decref(copy);
    return st;
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

/* What JSON can carry and the decoder reads back: finite numbers, ref
 * counts that fit the arrays, names for the enums. */
static int encodable(const sm_params *p, int dim)
{
    size_t n;
    const sm_param_info *rows = sm_params_table(&n);
    for (size_t i = 0; i < n; i++) {
        const char *at = (const char *)p + rows[i].offset;
        if (rows[i].type == SM_PARAM_REAL && !isfinite(*(const double *)at))
            return 0;
        if (sm_param_is_named(&rows[i]) &&
            !sm_param_value_name(&rows[i], sm_param_get_value(&rows[i], p)))
            return 0;
    }
    for (int c = 0; c < 3; c++)
        if (!isfinite(p->clamp_center[c]))
            return 0;
    return sm_clamp_kind_name(p->clamp) && isfinite(p->clamp_radius) && p->n_clamp_refs >= 0 &&
           p->n_clamp_refs <= SM_MAX_REFS && p->n_free_refs >= 0 &&
           p->n_free_refs <= SM_MAX_REFS && (dim == 0 || dim == 2 || dim == 3);
}

/* The clamp object: its kind and the members that kind has (alpha is the
 * table's row of kind none). */
static json_t *clamp_to_jansson(const sm_params *p, int dim)
{
    int ncenter = dim ? dim : (p->clamp_center[2] == 0.0 ? 2 : 3);
    json_t *clamp = json_object();
    int bad = !clamp || smp_set(clamp, "kind", json_string(sm_clamp_kind_name(p->clamp)));
    switch (p->clamp) {
    case SM_CLAMP_BALL: {
        json_t *center = bad ? NULL : json_array();
        for (int i = 0; center && i < ncenter; i++)
            bad = bad || json_array_append_new(center, json_real(p->clamp_center[i]));
        if (bad || !center)
            json_decref(center);
        bad = bad || !center || smp_set(clamp, "center", center);
        bad = bad || smp_set(clamp, "radius", json_real(p->clamp_radius));
        break;
    }
    case SM_CLAMP_ELEMENTS:
    case SM_CLAMP_VERTICES:
        bad = bad || smp_set(clamp, "refs", refs_array(p->clamp_refs, p->n_clamp_refs));
        break;
    case SM_CLAMP_NONE:
        bad = bad || smp_set(clamp, sm_params_lookup("alpha")->name, json_real(p->alpha));
        break;
    case SM_CLAMP_AUTO:
        break;
    }
    if (bad) {
        json_decref(clamp);
        return NULL;
    }
    return clamp;
}

/* The JSON value of row f of p (NULL: out of memory). */
static json_t *row_to_jansson(const sm_param_info *f, const sm_params *p, int dim)
{
    const char *at = (const char *)p + f->offset;
    switch (f->type) {
    case SM_PARAM_REAL: return json_real(*(const double *)at);
    case SM_PARAM_INT: return json_integer(*(const int *)at);
    case SM_PARAM_SOLVER:
    case SM_PARAM_ALIGN:
    case SM_PARAM_SPACE: return json_string(sm_param_value_name(f, sm_param_get_value(f, p)));
    case SM_PARAM_REFS:
        return refs_array((const int32_t *)at, *(const int *)((const char *)p + f->count_offset));
    case SM_PARAM_CLAMP: return clamp_to_jansson(p, dim);
    }
    return NULL;
}

/* The label-map rows (label, level, smooth, image_space) are written only when
 * they differ from their defaults: they mean something only with a target
 * image, and a job without one keeps the params document it had. */
static int image_row_default(const sm_param_info *f, const sm_params *p)
{
    if (strcmp(f->name, "label") == 0)
        return p->label == (int)f->def;
    if (strcmp(f->name, "level") == 0)
        return p->level == f->def;
    if (strcmp(f->name, "smooth") == 0)
        return p->smooth == f->def;
    if (strcmp(f->name, "image_space") == 0)
        return (int)p->image_space == (int)f->def;
    return 0;
}

json_t *sm_params_to_jansson(const sm_params *p, int dim)
{
    if (!encodable(p, dim))
        return NULL;
    json_t *root = json_object();
    size_t n;
    const sm_param_info *rows = sm_params_table(&n);
    for (size_t i = 0; root && i < n; i++)
        if (!rows[i].in_clamp && !image_row_default(&rows[i], p) &&
            smp_set(root, rows[i].name, row_to_jansson(&rows[i], p, dim))) {
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

json_t *sm_job_params_to_jansson(const sm_params *p, const sm_background_params *bg, int dim)
{
    json_t *root = sm_params_to_jansson(p, dim);
    size_t n;
    const sm_param_info *rows = sm_background_params_table(&n);
    for (size_t i = 0; root && bg && i < n; i++) {
        const char *at = (const char *)bg + rows[i].offset;
        int integer = rows[i].type == SM_PARAM_INT;
        double v = integer ? *(const int *)at : *(const double *)at;
        if (v == 0)
            continue; /* not given: left out */
        /* NULL for what the decoder would not take back */
        if (!sm_param_in_range(&rows[i], v) ||
            smp_set(root, rows[i].name,
                    integer ? json_integer(*(const int *)at) : json_real(v))) {
            json_decref(root);
            return NULL;
        }
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
