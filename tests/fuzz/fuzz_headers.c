/* The daemon's header parsers: Accept (smd_accept_choose), Accept-Encoding
 * (smd_accepts_gzip) and the bounded integer parser of Last-Event-ID,
 * ?after, ?offset and ?limit (smd_parse_uint).  The first byte picks the
 * parser, the rest is the header value (NUL-terminated copy).  Checks:
 * a chosen index is in range; a parsed number is within its bounds and
 * equals the decimal value of an all-digit text that fits.  Every value
 * is also read as a Host header (smd_cors_trusted_host) and as the
 * authority of an Origin (smd_cors_same_origin): an origin counts as the
 * daemon's own only when that Host names the daemon. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "http/smd_cors.h"
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
    static smd_config cfg; /* zeroed: no listen host, no public URL */
    if (!cfg.nallowed_hosts) {
        strcpy(cfg.listen_host, "127.0.0.1");
        strcpy(cfg.allowed_hosts[0], "maps.example.test");
        strcpy(cfg.allowed_hosts[1], "[::1]:8080");
        cfg.nallowed_hosts = 2;
    }
    int trusted = smd_cors_trusted_host(&cfg, text);
    char origin[600];
    if (trusted & ~1)
        abort();
    if (size < 500) {
        snprintf(origin, sizeof origin, "http://%s", text);
        if (smd_cors_same_origin(&cfg, origin, text) && !trusted)
            abort();
    }
    free(text);
    return 0;
}
