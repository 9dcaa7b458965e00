/* The end of a run read back from its published results (see
 * smd_store_read_summary in smd_store.h): the store's side of a restart
 * after a final record could not be written. */
#include <errno.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "job/sm_job_runner.h"
#include "job/sm_job_warnings.h"
#include "store/spool/smd_store.h"

#define SUMMARY_MAX_BYTES (1024 * 1024)

/* The summary's warnings as the finished event's message (the text the
 * worker sent: sm_job_warnings_text). */
static void summary_warnings(json_t *doc, char *buf, size_t cap)
{
    sm_job_warnings ws = {0};
    json_t *list = json_object_get(doc, "warnings"), *w;
    size_t i;
    json_array_foreach(list, i, w) {
        const char *code = json_string_value(json_object_get(w, "code"));
        const char *msg = json_string_value(json_object_get(w, "message"));
        if (!code || !msg || ws.n == SM_JOB_WARNINGS_MAX)
            continue;
        ws.w[ws.n].code = code; /* borrowed from doc, which outlives ws */
        snprintf(ws.w[ws.n].message, sizeof ws.w[ws.n].message, "%s", msg);
        ws.n++;
    }
    sm_job_warnings_text(&ws, buf, cap);
}

sm_status smd_store_read_summary(smd_store *s, const smd_job *job, sm_event *finished,
                                 double *when, sm_error *err)
{
    char path[PATH_MAX];
    if (smd_store_path(s, job->id, "results/" SM_RESULT_SUMMARY_FILE, path, sizeof path) != 0)
        return sm_error_set(err, SM_ERR_IO, "job %s: path too long", job->id);
    struct stat st;
    char *text = NULL;
    size_t len = 0;
    if (stat(path, &st) != 0 || smd_read_file(path, SUMMARY_MAX_BYTES, &text, &len) != 0)
        return sm_error_set(err, SM_ERR_IO, "%s: %s", path, strerror(errno));
    json_error_t jerr;
    json_t *doc = json_loadb(text, len, 0, &jerr);
    free(text);
    const char *status = json_string_value(json_object_get(doc, "status"));
    json_t *code = json_object_get(doc, "exit_code");
    sm_event_init(finished, SM_EVENT_FINISHED);
    sm_status rc = SM_OK;
    /* a run that finished without converging wrote every output too
     * (exit code 10): it ends successful, "converged": false */
    if (!status || strcmp(status, "finished") != 0 || !json_is_integer(code) ||
        (json_integer_value(code) != SM_JOB_EXIT_OK &&
         json_integer_value(code) != SM_JOB_EXIT_NOT_CONVERGED))
        rc = sm_error_set(err, SM_ERR_FORMAT, "%s: not the summary of a finished run", path);
    else
        rc = sm_result_from_jansson(doc, path, &finished->result, err);
    if (rc == SM_OK)
        summary_warnings(doc, finished->message, sizeof finished->message);
    json_decref(doc);
    *when = (double)st.st_mtim.tv_sec + 1e-9 * (double)st.st_mtim.tv_nsec;
    return rc;
}
