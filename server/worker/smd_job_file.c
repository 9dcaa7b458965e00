/* job.json (see smd_job_file.h). */
#include "worker/smd_job_file.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sm_json.h"
#include "shapematch/sm_shape_model.h"
#include "base/smd_util.h"
#include "worker/smd_worker.h"

#define JOB_FILE_MAX (1 << 20) /* a description is a few hundred bytes */

char *smd_job_file_encode(const smd_job_file *f, int indent)
{
    json_t *doc = json_object();
    int bad = !doc || !json_is_object(f->params);
    for (int i = 0; !bad && i < SM_PART_PARAMS; i++)
        if (f->part[i][0])
            bad = json_object_set_new(doc, sm_part_name((sm_part)i), json_string(f->part[i])) != 0;
    if (!bad)
        bad = json_object_set(doc, sm_part_name(SM_PART_PARAMS), f->params) != 0;
    if (!bad && f->batch)
        bad = json_object_set(doc, "batch", f->batch) != 0;
    if (!bad && f->checked_key[0]) {
        json_t *c = json_pack("{s:s}", "key", f->checked_key);
        bad = !c || json_object_set_new(doc, "checked", c) != 0;
        if (!bad && f->checked_background[0])
            bad = json_object_set_new(c, "background", json_string(f->checked_background)) != 0 ||
                  json_object_set_new(c, "distance", json_string(f->checked_distance)) != 0;
        if (!bad && f->checked_template[0])
            bad = json_object_set_new(c, "template", json_string(f->checked_template)) != 0 ||
                  json_object_set(c, "template_meshed", f->checked_template_made) != 0;
    }
    char *text = bad ? NULL : sm_json_dumps(doc, indent);
    json_decref(doc);
    return text;
}

int smd_job_file_write(const char *dir, const smd_job_file *f)
{
    char path[PATH_MAX];
    if (smd_pathf(path, sizeof path, "%s/" SMD_JOB_FILE, dir) != 0) {
        errno = ENAMETOOLONG;
        return -1;
    }
    char *text = smd_job_file_encode(f, 2);
    if (!text) {
        errno = ENOMEM;
        return -1;
    }
    int rc = smd_write_file_atomic(path, text, strlen(text));
    int saved = errno;
    free(text);
    errno = saved;
    return rc;
}

int smd_batch_name_valid(const char *s)
{
    size_t n = strlen(s);
    if (n == 0 || n > SMD_BATCH_NAME_MAX || strcmp(s, ".") == 0 || strcmp(s, "..") == 0)
        return 0;
    for (size_t i = 0; i < n; i++)
        if ((unsigned char)s[i] < 0x21 || (unsigned char)s[i] > 0x7e || s[i] == '/' ||
            s[i] == '\\' || s[i] == ',' || s[i] == '"')
            return 0;
    return 1;
}

/* The batch object of a model job: NULL when valid, else what is wrong. */
static const char *batch_problem(const json_t *b)
{
    if (!json_is_object(b))
        return "batch";
    const char *align = json_string_value(json_object_get(b, "align"));
    sm_shape_align kind;
    if (!align || sm_shape_align_parse(align, &kind) != 0)
        return "batch.align";
    /* written by the daemon from a checked request (api/smd_batch_request.c) */
    json_t *tf = json_object_get(b, "template_from");
    if (tf && !json_is_object(tf))
        return "batch.template_from";
    json_t *m = json_object_get(b, "members");
    if (!json_is_array(m) || json_array_size(m) == 0 || json_array_size(m) > SMD_BATCH_MEMBERS_MAX)
        return "batch.members";
    size_t i;
    json_t *v;
    json_array_foreach(m, i, v) {
        const char *id = json_string_value(json_object_get(v, "job"));
        const char *name = json_string_value(json_object_get(v, "name"));
        if (!id || !smd_id_valid(id) || !name || !smd_batch_name_valid(name))
            return "batch.members";
    }
    return NULL;
}

/* A path of the description: relative, inside the job folder. */
static int safe_relative(const char *rel)
{
    return rel[0] && rel[0] != '/' && !strstr(rel, "..") && strlen(rel) < PATH_MAX;
}

/* A description's "checked" member into f: NULL, or what is wrong.  The
 * key and at least one of the two pairs, nothing else. */
static const char *checked_problem(const json_t *c, smd_job_file *f)
{
    const char *key = json_string_value(json_object_get(c, "key"));
    const json_t *bgv = json_object_get(c, "background"), *dv = json_object_get(c, "distance");
    const json_t *tv = json_object_get(c, "template"), *made = json_object_get(c, "template_meshed");
    const char *bg = json_string_value(bgv), *d = json_string_value(dv);
    const char *tmpl = json_string_value(tv);
    size_t members = 1 + (bgv ? 2 : 0) + (tv ? 2 : 0);
    if (!json_is_object(c) || !key || strlen(key) != SMD_JOB_KEY_LEN ||
        strspn(key, "0123456789abcdef") != SMD_JOB_KEY_LEN || json_object_size(c) != members ||
        members == 1 || (bgv && (!bg || !d || !safe_relative(bg) || !safe_relative(d))) ||
        (tv && (!tmpl || !json_is_object(made) || !safe_relative(tmpl))))
        return "checked";
    snprintf(f->checked_key, sizeof f->checked_key, "%s", key);
    if (bg) {
        snprintf(f->checked_background, sizeof f->checked_background, "%s", bg);
        snprintf(f->checked_distance, sizeof f->checked_distance, "%s", d);
    }
    if (tmpl) {
        snprintf(f->checked_template, sizeof f->checked_template, "%s", tmpl);
        f->checked_template_made = json_incref((json_t *)made);
    }
    return NULL;
}

sm_status smd_job_file_parse(const char *text, size_t len, smd_job_file *f, sm_error *err)
{
    memset(f, 0, sizeof *f);
    json_error_t jerr;
    json_t *doc = json_loadb(text, len, 0, &jerr);
    if (!json_is_object(doc)) {
        json_decref(doc);
        return sm_error_set(err, SM_ERR_FORMAT, "%s is not a job description (%s)", SMD_JOB_FILE,
                            doc ? "not an object" : jerr.text);
    }
    const char *why = NULL;
    for (int i = 0; !why && i < SM_PART_PARAMS; i++) {
        json_t *v = json_object_get(doc, sm_part_name((sm_part)i));
        if (!v)
            continue;
        if (!json_is_string(v) || !safe_relative(json_string_value(v)))
            why = sm_part_name((sm_part)i);
        else
            snprintf(f->part[i], sizeof f->part[i], "%s", json_string_value(v));
    }
    json_t *params = json_object_get(doc, sm_part_name(SM_PART_PARAMS));
    json_t *batch = json_object_get(doc, "batch");
    json_t *checked = json_object_get(doc, "checked");
    if (!why && batch)
        why = batch_problem(batch);
    if (!why && checked)
        why = checked_problem(checked, f);
    if (!why && !batch && !f->part[SM_PART_TEMPLATE][0] && !f->part[SM_PART_TEMPLATE_SURFACE][0] &&
        !f->part[SM_PART_TEMPLATE_IMAGE][0])
        why = "template missing";
    if (!why && !json_is_object(params))
        why = "params";
    if (why) {
        json_decref(doc);
        json_decref(f->checked_template_made);
        memset(f, 0, sizeof *f);
        return sm_error_set(err, SM_ERR_FORMAT, "%s is not a job description (%s)", SMD_JOB_FILE,
                            why);
    }
    f->params = json_incref(params);
    f->batch = batch ? json_incref(batch) : NULL;
    json_decref(doc);
    return SM_OK;
}

sm_status smd_job_file_read(const char *dir, smd_job_file *f, sm_error *err)
{
    memset(f, 0, sizeof *f);
    char path[PATH_MAX], *text = NULL;
    size_t len = 0;
    if (smd_pathf(path, sizeof path, "%s/" SMD_JOB_FILE, dir) != 0)
        return sm_error_set(err, SM_ERR_IO, "%s: path too long", dir);
    if (smd_read_file(path, JOB_FILE_MAX, &text, &len) != 0)
        return sm_error_set(err, SM_ERR_IO, "cannot read %s: %s", SMD_JOB_FILE, strerror(errno));
    sm_status st = smd_job_file_parse(text, len, f, err);
    free(text);
    return st;
}

int smd_job_file_inputs_key(const char *dir, const smd_job_file *f,
                            char key[SMD_JOB_KEY_LEN + 1])
{
    char *params = f->params ? sm_json_dumps(f->params, 0) : NULL;
    if (!params) {
        errno = ENOMEM;
        return -1;
    }
    uint64_t h = smd_fnv1a(SMD_FNV_OFFSET, SM_VERSION, sizeof SM_VERSION);
    h = smd_fnv1a(h, params, strlen(params) + 1);
    free(params);
    char path[PATH_MAX];
    for (int i = 0; i < SM_PART_PARAMS; i++) {
        if (!f->part[i][0])
            continue;
        h = smd_fnv1a(h, &i, sizeof i);
        if (smd_pathf(path, sizeof path, "%s/%s", dir, f->part[i]) != 0) {
            errno = ENAMETOOLONG;
            return -1;
        }
        if (smd_fnv1a_file(&h, path) != 0)
            return -1;
    }
    snprintf(key, SMD_JOB_KEY_LEN + 1, "%016llx", (unsigned long long)h);
    return 0;
}

void smd_job_file_free(smd_job_file *f)
{
    json_decref(f->params);
    json_decref(f->batch);
    json_decref(f->checked_template_made);
    f->params = NULL;
    f->batch = NULL;
    f->checked_template_made = NULL;
}
