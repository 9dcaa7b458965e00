/* job.json's reader (server/worker/smd_job_file.c): any bytes are refused or
 * give a description whose paths stay inside the job folder and whose
 * params are an object, with a template or (a batch's model job) a batch
 * whose member names are valid, and a "checked" background and template
 * whose paths stay inside it too (the template's figures an object, which
 * sm_job_template_made_from_json reads or refuses); an accepted one
 * encodes and reads back the same, compact and indented. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "job/sm_job_template.h"
#include "worker/smd_job_file.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static void same_again(const smd_job_file *f, int indent)
{
    char *text = smd_job_file_encode(f, indent);
    if (!text)
        abort();
    smd_job_file g;
    sm_error err;
    if (smd_job_file_parse(text, strlen(text), &g, &err) != SM_OK)
        abort();
    for (int i = 0; i < SM_PART_PARAMS; i++)
        if (strcmp(f->part[i], g.part[i]) != 0)
            abort();
    if (strcmp(f->checked_key, g.checked_key) != 0 ||
        strcmp(f->checked_background, g.checked_background) != 0 ||
        strcmp(f->checked_distance, g.checked_distance) != 0 ||
        strcmp(f->checked_template, g.checked_template) != 0 ||
        !f->checked_template_made != !g.checked_template_made ||
        (f->checked_template_made && !json_equal(f->checked_template_made, g.checked_template_made)))
        abort();
    if (!json_equal(f->params, g.params) || !f->batch != !g.batch ||
        (f->batch && !json_equal(f->batch, g.batch)))
        abort();
    smd_job_file_free(&g);
    free(text);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static smd_job_file f; /* 16 KiB of paths: kept off the fuzzer's stack */
    sm_error err;
    if (smd_job_file_parse((const char *)data, size, &f, &err) != SM_OK) {
        if (f.params || f.batch || f.part[SM_PART_TEMPLATE][0] || f.checked_key[0] ||
            f.checked_template_made)
            abort();
        return 0;
    }
    if (!json_is_object(f.params) || (!f.part[SM_PART_TEMPLATE][0] && !f.part[SM_PART_TEMPLATE_SURFACE][0] &&
                                      !f.part[SM_PART_TEMPLATE_IMAGE][0] && !f.batch))
        abort();
    size_t i;
    json_t *m;
    json_array_foreach(json_object_get(f.batch, "members"), i, m)
        if (!smd_batch_name_valid(json_string_value(json_object_get(m, "name"))))
            abort();
    for (int i = 0; i < SM_PART_PARAMS; i++)
        if (f.part[i][0] == '/' || strstr(f.part[i], ".."))
            abort();
    if (f.checked_key[0] && (f.checked_background[0] == '/' || strstr(f.checked_background, "..") ||
                             f.checked_distance[0] == '/' || strstr(f.checked_distance, "..") ||
                             f.checked_template[0] == '/' || strstr(f.checked_template, "..") ||
                             strlen(f.checked_key) != SMD_JOB_KEY_LEN))
        abort();
    if (!f.checked_template[0] != !f.checked_template_made ||
        (f.checked_template_made && !json_is_object(f.checked_template_made)))
        abort();
    if (f.checked_template_made) {
        /* the figures read or are refused; read, writing and reading them
         * again is a fixed point */
        sm_job_template_made made, twice;
        if (sm_job_template_made_from_json(f.checked_template_made, &made, &err) == SM_OK) {
            json_t *once = sm_job_template_made_to_json(&made), *again = NULL;
            if (once && (sm_job_template_made_from_json(once, &twice, &err) != SM_OK ||
                         !(again = sm_job_template_made_to_json(&twice)) || !json_equal(once, again)))
                abort();
            json_decref(once);
            json_decref(again);
        }
    }
    same_again(&f, 0);
    same_again(&f, 2);
    smd_job_file_free(&f);
    return 0;
}
