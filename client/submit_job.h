/* One job sent to the daemon (POST /v1/jobs, multipart/form-data): what
 * `shapematch submit` does for its one job and `shapematch batch
 * --server` for each target (cmd_submit.c).  The files are streamed from
 * disk, gzip-compressed on the way unless they are gzip already. */
#ifndef CLI_SUBMIT_JOB_H
#define CLI_SUBMIT_JOB_H

#include <stddef.h>

#include "http.h"

typedef struct submit_job {
    const char *template_path, *target_mesh, *target_sol, *target_surface, *target_image;
    const char *template_surface; /* instead of template_path: meshed by the daemon */
    const char *template_image;   /* or a label map (params template_label), likewise */
    const char *landmarks[2];  /* template's, target's, or NULL */
    const char *params_json;   /* the params part */
    const char *idempotency_key; /* or NULL */
    const char *name;          /* the job's name (part "name"), or NULL */
    int no_compress;
} submit_job;

/* Sends job j.  0 with the daemon's answer (201, or 200 for a known
 * Idempotency-Key) in *rs (the caller frees it) and its job id in id
 * (cap bytes); else an exit code, reported on stderr as "shapematch CMD"
 * (an unreadable file: CLI_EXIT_INPUT before any request), *rs freed. */
int remote_submit_job(http_client *c, const char *cmd, int token_given, const submit_job *j,
                      http_response *rs, char *id, size_t cap);

#endif
