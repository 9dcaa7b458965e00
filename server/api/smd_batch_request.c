/* The body of POST /v1/batches (see smd_batch_request.h). */
#include "api/smd_batch_request.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <jansson.h>

#include "sm_proto_vocab.h"
#include "shapematch/sm_shape_model.h"
#include "base/smd_util.h"

/* targets[i] into m[i], unique among m[0..i-1]: 0, or 422 with msg. */
static unsigned parse_target(const json_t *t, size_t i, smd_batch_member *m, char *msg, size_t cap)
{
    const char *id = json_string_value(json_object_get(t, "job"));
    const char *name = json_object_get(t, "name") ? json_string_value(json_object_get(t, "name"))
                                                  : id;
    if (!id || !smd_id_valid(id)) {
        snprintf(msg, cap, "targets[%zu].job: expected a job id", i);
        return 422;
    }
    if (!name || !smd_batch_name_valid(name)) {
        snprintf(msg, cap, "targets[%zu].name: 1 to %d printable ASCII characters without "
                 "'/', '\\', ',', '\"' or spaces, not . or ..", i, SMD_BATCH_NAME_MAX);
        return 422;
    }
    for (size_t k = 0; k < i; k++)
        if (strcmp(m[k].id, id) == 0 || strcmp(m[k].name, name) == 0) {
            snprintf(msg, cap, "targets[%zu]: job or name given twice", i);
            return 422;
        }
    snprintf(m[i].id, sizeof m[i].id, "%s", id);
    snprintf(m[i].name, sizeof m[i].name, "%s", name);
    return 0;
}

int smd_batch_origin_parse(const json_t *tf, smd_batch_origin *o, char *msg, size_t cap)
{
    static const char *const known[] = {"mode", "round", "previous"};
    memset(o, 0, sizeof *o);
    if (!json_is_object(tf)) {
        snprintf(msg, cap, "template_from: expected an object {\"mode\": \"file|medoid|mean\", "
                 "\"round\": K, \"previous\": BATCH_ID}");
        return -1;
    }
    const char *key;
    json_t *v;
    json_object_foreach((json_t *)tf, key, v) {
        size_t k = 0;
        while (k < 3 && strcmp(key, known[k]) != 0)
            k++;
        if (k == 3) {
            snprintf(msg, cap, "template_from: unknown member '%.40s' (mode, round, previous)",
                     key);
            return -1;
        }
    }
    const char *mode = json_string_value(json_object_get(tf, "mode"));
    json_t *round = json_object_get(tf, "round"), *prev = json_object_get(tf, "previous");
    sm_template_from from;
    if (!mode || sm_template_from_parse(mode, &from) != 0) {
        snprintf(msg, cap, "template_from.mode: expected file, medoid or mean");
        return -1;
    }
    json_int_t k = json_is_integer(round) ? json_integer_value(round) : 0;
    int last = from == SM_TEMPLATE_FROM_FILE ? 1 : SM_TEMPLATE_ROUNDS_MAX;
    if (k < 1 || k > last) {
        snprintf(msg, cap, "template_from.round: expected an integer from 1 to %d", last);
        return -1;
    }
    if (prev && (!json_is_string(prev) || !smd_id_valid(json_string_value(prev)))) {
        snprintf(msg, cap, "template_from.previous: expected a batch id");
        return -1;
    }
    if ((k > 1) != (prev != NULL)) {
        snprintf(msg, cap, "template_from.previous: %s", k > 1 ? "round 2 on names the batch of "
                 "the round before" : "round 1 has no batch before it");
        return -1;
    }
    o->has = 1;
    snprintf(o->mode, sizeof o->mode, "%s", mode);
    o->round = (int)k;
    snprintf(o->previous, sizeof o->previous, "%s", prev ? json_string_value(prev) : "");
    return 0;
}

json_t *smd_batch_origin_json(const smd_batch_origin *o)
{
    if (!o->has)
        return NULL;
    json_t *tf = json_pack("{s:s,s:i}", "mode", o->mode, "round", o->round);
    if (tf && o->previous[0])
        json_object_set_new(tf, "previous", json_string(o->previous));
    return tf;
}

unsigned smd_batch_request_parse(const char *buf, size_t len, unsigned max_targets,
                                 smd_batch_member **out, size_t *nout, char align[16],
                                 smd_batch_origin *origin, char *msg, size_t cap)
{
    json_error_t jerr;
    json_t *doc = json_loadb(buf, len, JSON_REJECT_DUPLICATES, &jerr);
    unsigned status = 0;
    json_t *targets = json_object_get(doc, "targets"), *a = json_object_get(doc, "model_align");
    json_t *tf = json_object_get(doc, "template_from");
    smd_batch_origin o = {0};
    sm_shape_align kind;
    size_t n = json_array_size(targets);
    if (!json_is_object(doc)) {
        snprintf(msg, cap, "the body is not a JSON object (%s)", doc ? "not an object" : jerr.text);
        status = 400;
    } else if (!json_is_array(targets) || n == 0) {
        snprintf(msg, cap, "targets: expected a non-empty array of {\"job\": ID, \"name\": NAME}");
        status = 422;
    } else if (n > max_targets) {
        snprintf(msg, cap, "targets: %zu targets exceed the limit of %u (the daemon's "
                 "--max-batch-targets; its operator can raise it, up to %d)", n,
                 max_targets, SMD_BATCH_MEMBERS_MAX);
        status = 413;
    } else if (a && (!json_is_string(a) || sm_shape_align_parse(json_string_value(a), &kind) != 0)) {
        snprintf(msg, cap, "model_align: expected none, rigid or similarity");
        status = 422;
    } else if (tf && smd_batch_origin_parse(tf, &o, msg, cap) != 0) {
        status = 422;
    }
    smd_batch_member *m = status ? NULL : calloc(n, sizeof *m);
    if (!status && !m) {
        snprintf(msg, cap, "out of memory");
        status = 503;
    }
    snprintf(align, 16, "%s", a ? json_string_value(a) : "rigid");
    for (size_t i = 0; !status && i < n; i++)
        status = parse_target(json_array_get(targets, i), i, m, msg, cap);
    json_decref(doc);
    if (status) {
        free(m);
        return status;
    }
    *out = m;
    *nout = n;
    *origin = o;
    return 0;
}

