/* The body of POST /v1/batches (server/api/smd_batch_request.c): any bytes
 * are refused with a status the API documents (400, 413, 422, 503) and a
 * message, or give 1..max members whose ids are job ids and whose names
 * are valid and unique, and an alignment of the three; the first input
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
    unsigned st = smd_batch_request_parse((const char *)data + 1, size - 1, max, &m, &n, align, msg,
                                          sizeof msg);
    if (st) {
        if ((st != 400 && st != 413 && st != 422 && st != 503) || !msg[0] || m)
            abort();
        return 0;
    }
    if (n < 1 || n > max || (strcmp(align, "none") && strcmp(align, "rigid") && strcmp(align, "similarity")))
        abort();
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
