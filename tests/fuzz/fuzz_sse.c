/* The client's Server-Sent Events parser, fed in chunks: the first two
 * bytes give a chunk size (1..256) and a line bound, so a field or a CRLF
 * split across chunks and the line limit are both exercised.  Every event
 * handed to the callback must be NUL-terminated at data_len and carry an
 * id only when its block had one. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "sse.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static int on_event(void *user, const sse_event *ev)
{
    (void)user;
    if (!ev->type || !ev->data || !ev->id || ev->data[ev->data_len] != '\0')
        abort();
    if (!ev->has_id && ev->id[0] != '\0')
        abort();
    if (strlen(ev->type) > SSE_TYPE_MAX || strlen(ev->id) > SSE_ID_MAX)
        abort();
    return 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 2)
        return 0;
    size_t chunk = (size_t)data[0] + 1;
    size_t max_line = 16 + (size_t)data[1] * 4;
    data += 2;
    size -= 2;
    sse_parser p;
    sse_init(&p, max_line, on_event, NULL);
    for (size_t off = 0; off < size; off += chunk) {
        size_t n = size - off < chunk ? size - off : chunk;
        if (sse_feed(&p, (const char *)data + off, n) != 0)
            break;
        if (off + n == size / 2)
            sse_restart(&p); /* a reconnect in the middle */
    }
    sse_free(&p);
    return 0;
}
