/* The body of POST /v1/batches, read apart from the handler so that a
 * fuzz target (tests/fuzz/fuzz_batch_request.c) drives it:
 *   {"targets": [{"job": ID, "name": NAME}, ...], "model_align": A,
 *    "template_from": {"mode": M, "round": K, "previous": ID}}
 * a JSON object; 1..max_targets targets, each a job id and a name (default
 * the id; smd_batch_name_valid), no id or name twice; model_align none,
 * rigid (default) or similarity.  template_from (optional) records that
 * the batch is round K of `shapematch batch --server --template-from M`
 * (client/cmd_batch_remote.c): M file, medoid or mean; K 1 to
 * SM_TEMPLATE_ROUNDS_MAX, 1 with file; previous the batch of round K - 1
 * (required from round 2 on, absent in round 1; that it is a batch of the
 * caller's is smd_batches.c's check); no other member. */
#ifndef SMD_BATCH_REQUEST_H
#define SMD_BATCH_REQUEST_H

#include <stddef.h>

#include <jansson.h>

#include "base/smd_util.h"
#include "worker/smd_job_file.h"

typedef struct smd_batch_member {
    char id[SMD_ID_LEN + 1];
    char name[SMD_BATCH_NAME_MAX + 1];
} smd_batch_member;

/* A batch's template_from (has 0: the request had none). */
typedef struct smd_batch_origin {
    int has;
    char mode[8];                  /* file, medoid or mean */
    int round;                     /* 1..SM_TEMPLATE_ROUNDS_MAX */
    char previous[SMD_ID_LEN + 1]; /* round - 1's batch, "" in round 1 */
} smd_batch_origin;

/* The origin o as the batch's "template_from" object (NULL when it has
 * none or out of memory). */
json_t *smd_batch_origin_json(const smd_batch_origin *o);

/* A recorded "template_from" object into *o: 0, or -1 when it is not one
 * smd_batch_request_parse would take (msg says why). */
int smd_batch_origin_parse(const json_t *tf, smd_batch_origin *o, char *msg, size_t cap);

/* buf[0..len) into *out (n members, malloc'd: free it), align and
 * *origin: 0, or
 * the HTTP status of the refusal (400 not a JSON object, 413 more than
 * max_targets, 422 anything else, 503 out of memory) with msg saying why
 * (*out untouched). */
unsigned smd_batch_request_parse(const char *buf, size_t len, unsigned max_targets,
                                 smd_batch_member **out, size_t *n, char align[16],
                                 smd_batch_origin *origin, char *msg, size_t cap);

#endif
