/* The daemon's header parsers: Accept (smd_accept_choose), Accept-Encoding
 * (smd_accepts_gzip) and the bounded integer parser of Last-Event-ID,
 * ?after, ?offset and ?limit (smd_parse_uint).  The first byte picks the
 * parser, the rest is the header value (NUL-terminated copy).  Checks:
 * a chosen index is in range; a parsed number is within its bounds and
 * equals the decimal value of an all-digit text that fits. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "http/smd_negotiate.h"
#include "base/smd_util.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static void check_uint(const char *text)
{
    static const uint64_t his[] = {1000, 9007199254740991ULL, UINT64_MAX};
    for (size_t k = 0; k < sizeof his / sizeof his[0]; k++) {
        uint64_t v = 0;
        int rc = smd_parse_uint(text, 1, his[k], &v);
        if (rc == SMD_NUM_OK && (v < 1 || v > his[k]))
            abort();
        /* an all-digit text below 10^19 has one value */
        size_t n = strlen(text);
        if (rc == SMD_NUM_OK && n > 0 && n < 20 && strspn(text, "0123456789") == n &&
            strtoull(text, NULL, 10) != v)
            abort();
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1)
        return 0;
    char *text = malloc(size);
    if (!text)
        return 0;
    memcpy(text, data + 1, size - 1);
    text[size - 1] = '\0';
    static const char *const offered[] = {"application/json", "text/event-stream",
                                          "application/x-ndjson", "text/html"};
    switch (data[0] % 3) {
    case 0: {
        int n = 1 + data[0] / 3 % 4;
        int i = smd_accept_choose(text, offered, n);
        if (i < -1 || i >= n)
            abort();
        break;
    }
    case 1:
        if (smd_accepts_gzip(text) & ~1)
            abort();
        break;
    default:
        check_uint(text);
        break;
    }
    free(text);
    return 0;
}
