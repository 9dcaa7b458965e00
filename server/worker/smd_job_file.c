/* job.json (see smd_job_file.h). */
#include "worker/smd_job_file.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sm_json.h"
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

/* A path of the description: relative, inside the job folder. */
static int safe_relative(const char *rel)
{
    return rel[0] && rel[0] != '/' && !strstr(rel, "..") && strlen(rel) < PATH_MAX;
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
    if (!why && !f->part[SM_PART_TEMPLATE][0])
        why = "template missing";
    if (!why && !json_is_object(params))
        why = "params";
    if (why) {
        json_decref(doc);
        memset(f, 0, sizeof *f);
        return sm_error_set(err, SM_ERR_FORMAT, "%s is not a job description (%s)", SMD_JOB_FILE,
                            why);
    }
    f->params = json_incref(params);
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

void smd_job_file_free(smd_job_file *f)
{
    json_decref(f->params);
    f->params = NULL;
}
