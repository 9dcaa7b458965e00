/* The body of POST /v1/batches, read apart from the handler so that a
 * fuzz target (tests/fuzz/fuzz_batch_request.c) drives it:
 *   {"targets": [{"job": ID, "name": NAME}, ...], "model_align": A}
 * a JSON object; 1..max_targets targets, each a job id and a name (default
 * the id; smd_batch_name_valid), no id or name twice; model_align none,
 * rigid (default) or similarity. */
#ifndef SMD_BATCH_REQUEST_H
#define SMD_BATCH_REQUEST_H

#include <stddef.h>

#include "base/smd_util.h"
#include "worker/smd_job_file.h"

typedef struct smd_batch_member {
    char id[SMD_ID_LEN + 1];
    char name[SMD_BATCH_NAME_MAX + 1];
} smd_batch_member;

/* buf[0..len) into *out (n members, malloc'd: free it) and align: 0, or
 * the HTTP status of the refusal (400 not a JSON object, 413 more than
 * max_targets, 422 anything else, 503 out of memory) with msg saying why
 * (*out untouched). */
unsigned smd_batch_request_parse(const char *buf, size_t len, unsigned max_targets,
                                 smd_batch_member **out, size_t *n, char align[16], char *msg,
                                 size_t cap);

#endif
