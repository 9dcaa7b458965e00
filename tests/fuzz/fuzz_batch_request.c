/* The body of POST /v1/batches (server/api/smd_batch_request.c): any bytes
 * are refused with a status the API documents (400, 413, 422, 503) and a
 * message, or give 1..max members whose ids are job ids and whose names
 * are valid and unique, an alignment of the three and a template_from
 * that reads back the same from its record; the first input
 * byte sets the targets limit (1..256). */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "api/smd_batch_request.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1)
        return 0;
    unsigned max = (unsigned)data[0] + 1;
    smd_batch_member *m = NULL;
    size_t n = 0;
    char align[16], msg[512];
    smd_batch_origin origin;
    unsigned st = smd_batch_request_parse((const char *)data + 1, size - 1, max, &m, &n, align,
                                          &origin, msg, sizeof msg);
    if (st) {
        if ((st != 400 && st != 413 && st != 422 && st != 503) || !msg[0] || m)
            abort();
        return 0;
    }
    if (n < 1 || n > max || (strcmp(align, "none") && strcmp(align, "rigid") && strcmp(align, "similarity")))
        abort();
    /* a template_from taken: its record reads back as the same origin */
    if (origin.has) {
        smd_batch_origin again;
        json_t *tf = smd_batch_origin_json(&origin);
        if (!tf || origin.round < 1 || (origin.round > 1) != (origin.previous[0] != 0) ||
            smd_batch_origin_parse(tf, &again, msg, sizeof msg) != 0 ||
            memcmp(&again, &origin, sizeof again) != 0)
            abort();
        json_decref(tf);
    }
    for (size_t i = 0; i < n; i++) {
        if (!smd_id_valid(m[i].id) || !smd_batch_name_valid(m[i].name))
            abort();
        for (size_t k = 0; k < i; k++)
            if (!strcmp(m[i].id, m[k].id) || !strcmp(m[i].name, m[k].name))
                abort();
    }
    free(m);
    return 0;
}
