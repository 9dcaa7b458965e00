/* A meshed template's figures as JSON and back (sm_job_template.h): on
 * its own, beside the meshing, so that job.json's reader and its fuzz
 * target take it without the mesher. */
#include "job/sm_job_template.h"

#include <limits.h>
#include <stddef.h>
#include <string.h>

/* One table of the scalar members, so that writing and reading cannot
 * drift; the source and the box are written by hand. */
typedef enum made_kind { MADE_REAL, MADE_I64, MADE_I32, MADE_INT } made_kind;

typedef struct made_member {
    const char *name; /* the field's own path */
    size_t offset;
    made_kind kind;
} made_member;

#define MADE(field, kind) {#field, offsetof(sm_job_template_made, field), kind}
static const made_member made_members[] = {
    MADE(label, MADE_I64),
    MADE(surface_facets, MADE_I32),
    MADE(mesh.size, MADE_REAL),
    MADE(mesh.surface_volume, MADE_REAL),
    MADE(mesh.mesh_volume, MADE_REAL),
    MADE(mesh.min_quality, MADE_REAL),
    MADE(mesh.mean_quality, MADE_REAL),
    MADE(mesh.nverts, MADE_I32),
    MADE(mesh.nelems, MADE_I32),
    MADE(mesh.passes, MADE_INT),
    MADE(mesh.seconds, MADE_REAL),
    MADE(mesh.estimated_elements, MADE_I64),
    MADE(health.open_edges, MADE_I64),
    MADE(health.nonmanifold_edges, MADE_I64),
    MADE(health.reoriented, MADE_I64),
    MADE(health.reoriented_within, MADE_I64),
    MADE(health.pieces_turned, MADE_I64),
    MADE(health.duplicates, MADE_I64),
    MADE(health.degenerate, MADE_I64),
    MADE(health.components, MADE_I64),
    MADE(health.open_components, MADE_I64),
    MADE(health.open_by_volume, MADE_I64),
};
#undef MADE
#define NMADE (sizeof made_members / sizeof *made_members)

json_t *sm_job_template_made_to_json(const sm_job_template_made *m)
{
    json_t *o = json_object(), *lo = json_array(), *hi = json_array();
    int bad = !o || !lo || !hi ||
              json_object_set_new(o, "source", json_string(m->source == SM_TEMPLATE_IMAGE
                                                                ? "image" : "surface")) != 0;
    for (size_t i = 0; !bad && i < NMADE; i++) {
        const made_member *d = &made_members[i];
        const char *at = (const char *)m + d->offset;
        json_t *v = d->kind == MADE_REAL  ? json_real(*(const double *)at) /* NULL if not finite */
                    : d->kind == MADE_I64 ? json_integer(*(const int64_t *)at)
                    : d->kind == MADE_I32 ? json_integer(*(const int32_t *)at)
                                          : json_integer(*(const int *)at);
        bad = json_object_set_new(o, d->name, v) != 0;
    }
    for (int k = 0; !bad && k < 3; k++)
        bad = json_array_append_new(lo, json_real(m->health.lo[k])) != 0 ||
              json_array_append_new(hi, json_real(m->health.hi[k])) != 0;
    if (bad || json_object_set(o, "health.lo", lo) != 0 || json_object_set(o, "health.hi", hi) != 0) {
        json_decref(o);
        o = NULL;
    }
    json_decref(lo);
    json_decref(hi);
    return o;
}

static sm_status made_bad(sm_error *err, const char *member)
{
    return sm_error_set(err, SM_ERR_FORMAT, "a meshed template's figures: %s", member);
}

sm_status sm_job_template_made_from_json(const json_t *o, sm_job_template_made *m, sm_error *err)
{
    sm_job_template_made t;
    memset(&t, 0, sizeof t);
    const char *source = json_string_value(json_object_get(o, "source"));
    if (!json_is_object(o) || !source ||
        (strcmp(source, "surface") != 0 && strcmp(source, "image") != 0))
        return made_bad(err, "source");
    t.source = strcmp(source, "image") == 0 ? SM_TEMPLATE_IMAGE : SM_TEMPLATE_SURFACE;
    for (size_t i = 0; i < NMADE; i++) {
        const made_member *d = &made_members[i];
        const json_t *v = json_object_get(o, d->name);
        char *at = (char *)&t + d->offset;
        if (d->kind == MADE_REAL) {
            if (!json_is_number(v))
                return made_bad(err, d->name);
            *(double *)at = json_number_value(v);
            continue;
        }
        json_int_t n = json_integer_value(v);
        if (!json_is_integer(v) || (d->kind == MADE_I32 && (n < INT32_MIN || n > INT32_MAX)) ||
            (d->kind == MADE_INT && (n < INT_MIN || n > INT_MAX)))
            return made_bad(err, d->name);
        if (d->kind == MADE_I64)
            *(int64_t *)at = n;
        else if (d->kind == MADE_I32)
            *(int32_t *)at = (int32_t)n;
        else
            *(int *)at = (int)n;
    }
    const char *box[2] = {"health.lo", "health.hi"};
    for (int b = 0; b < 2; b++) {
        const json_t *a = json_object_get(o, box[b]);
        if (!json_is_array(a) || json_array_size(a) != 3)
            return made_bad(err, box[b]);
        for (size_t k = 0; k < 3; k++) {
            const json_t *v = json_array_get(a, k);
            if (!json_is_number(v))
                return made_bad(err, box[b]);
            (b ? t.health.hi : t.health.lo)[k] = json_number_value(v);
        }
    }
    *m = t;
    return SM_OK;
}
