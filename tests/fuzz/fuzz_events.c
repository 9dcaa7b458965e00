/* The NDJSON event lines (worker -> daemon pipe, events.ndjson, the
 * event stream) and the result summary document.  The first byte picks
 * the decoder; an accepted event must re-encode and decode to the same
 * line. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "sm_proto_events.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1)
        return 0;
    const char *text = (const char *)data + 1;
    size_t len = size - 1;
    sm_error err;
    sm_error_clear(&err);
    if (data[0] & 1) {
        sm_result r;
        if (sm_result_from_json(text, len, &r, &err) != SM_OK && err.msg[0] == '\0')
            abort();
        return 0;
    }
    sm_event ev;
    if (sm_event_from_json(text, len, &ev, &err) != SM_OK) {
        if (err.msg[0] == '\0')
            abort();
        return 0;
    }
    char *line = sm_event_to_json(&ev);
    if (!line)
        abort();
    sm_event back;
    if (sm_event_from_json(line, strlen(line), &back, &err) != SM_OK)
        abort();
    char *again = sm_event_to_json(&back);
    if (!again || strcmp(line, again) != 0)
        abort();
    free(line);
    free(again);
    return 0;
}
