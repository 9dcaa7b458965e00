/* The binary mesh payload (proto/PAYLOAD.md).  Two modes, picked by the
 * first byte: the bytes as given (header checks, CRCs), or with both CRCs
 * recomputed so that mutations reach the body checks (padding, indices,
 * non-finite values) instead of dying at the checksum.  A payload that
 * decodes must re-encode to the same bytes. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

#include "sm_payload.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static void put_le32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1)
        return 0;
    int fix_crcs = data[0] & 1;
    size_t len = size - 1;
    uint8_t *buf = malloc(len ? len : 1);
    if (!buf)
        return 0;
    memcpy(buf, data + 1, len);
    if (fix_crcs && len >= 44) {
        put_le32(buf + 32, (uint32_t)crc32(0L, buf, 32));
        put_le32(buf + len - 4, (uint32_t)crc32(0L, buf, (uInt)(len - 4)));
    }
    sm_error err;
    sm_error_clear(&err);
    sm_payload *p = NULL;
    if (sm_payload_decode(buf, len, &p, &err) == SM_OK) {
        if (fix_crcs) {
            size_t n = 0;
            unsigned char *again = NULL;
            if (sm_payload_encode(p->mesh, NULL, p->displacement, p->distance,
                                  &again, &n, &err) != SM_OK ||
                n != len || memcmp(again, buf, len) != 0)
                abort(); /* decode and encode disagree */
            free(again);
        }
        sm_payload_free(p);
    } else if (p != NULL || err.msg[0] == '\0') {
        abort();
    }
    free(buf);
    return 0;
}
