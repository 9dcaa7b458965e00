/* Server-Sent Events parser (see sse.h). */
#include "sse.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define SSE_DEFAULT_MAX_LINE (64 * 1024)

static const unsigned char utf8_bom[3] = {0xef, 0xbb, 0xbf};

void sse_init(sse_parser *p, size_t max_line, sse_event_fn fn, void *user)
{
    memset(p, 0, sizeof *p);
    p->on_event = fn;
    p->user = user;
    p->max_line = max_line ? max_line : SSE_DEFAULT_MAX_LINE;
    p->at_start = 1;
    p->retry_ms = -1;
}

static void clear_block(sse_parser *p)
{
    p->data_len = 0;
    p->have_data = 0;
    p->type[0] = '\0';
    p->id[0] = '\0';
    p->has_id = 0;
}

void sse_restart(sse_parser *p)
{
    clear_block(p);
    p->line_len = 0;
    p->after_cr = 0;
    p->at_start = 1;
    p->bom_matched = 0;
    p->stopped = 0;
    p->error[0] = '\0';
}

void sse_free(sse_parser *p)
{
    free(p->line);
    free(p->data);
    p->line = p->data = NULL;
    p->line_cap = p->data_cap = 0;
}

/* Grows *buf to hold need bytes (need <= bound + 1 is checked by the
 * callers), doubling. */
static int reserve(char **buf, size_t *cap, size_t need)
{
    if (need <= *cap)
        return 0;
    size_t ncap = *cap ? *cap : 256;
    while (ncap < need)
        ncap *= 2;
    char *b = realloc(*buf, ncap);
    if (!b)
        return -1;
    *buf = b;
    *cap = ncap;
    return 0;
}

static int fail(sse_parser *p, const char *what)
{
    snprintf(p->error, sizeof p->error, "%s", what);
    return -1;
}

static int dispatch(sse_parser *p)
{
    if (!p->have_data) {
        /* a block without data dispatches nothing (spec); its id, type
         * are dropped with it */
        clear_block(p);
        return 0;
    }
    /* the data buffer ends with the "\n" appended after the last line:
     * drop it */
    if (p->data_len > 0 && p->data[p->data_len - 1] == '\n')
        p->data_len--;
    if (reserve(&p->data, &p->data_cap, p->data_len + 1) != 0)
        return fail(p, "out of memory");
    p->data[p->data_len] = '\0';
    sse_event ev = {
        .type = p->type[0] ? p->type : "message",
        .id = p->id,
        .has_id = p->has_id,
        .data = p->data,
        .data_len = p->data_len,
    };
    p->events++;
    int rc = p->on_event ? p->on_event(p->user, &ev) : 0;
    clear_block(p);
    if (rc != 0) {
        p->stopped = 1;
        return -1;
    }
    return 0;
}

static int process_line(sse_parser *p)
{
    const char *line = p->line ? p->line : "";
    size_t len = p->line_len;
    if (len == 0)
        return dispatch(p);
    if (line[0] == ':') {
        p->comments++;
        return 0;
    }
    const char *colon = memchr(line, ':', len);
    size_t flen = colon ? (size_t)(colon - line) : len;
    const char *value = colon ? colon + 1 : line + len;
    size_t vlen = (size_t)(line + len - value);
    if (vlen > 0 && value[0] == ' ') {
        value++;
        vlen--;
    }
    if (flen == 4 && memcmp(line, "data", 4) == 0) {
        if (p->data_len + vlen + 1 > p->max_line)
            return fail(p, "an event's data is too long");
        if (reserve(&p->data, &p->data_cap, p->data_len + vlen + 2) != 0)
            return fail(p, "out of memory");
        memcpy(p->data + p->data_len, value, vlen);
        p->data_len += vlen;
        p->data[p->data_len++] = '\n';
        p->have_data = 1;
    } else if (flen == 5 && memcmp(line, "event", 5) == 0) {
        /* longer types than any the daemon sends are cut, not an error */
        size_t n = vlen < SSE_TYPE_MAX ? vlen : SSE_TYPE_MAX;
        memcpy(p->type, value, n);
        p->type[n] = '\0';
    } else if (flen == 2 && memcmp(line, "id", 2) == 0) {
        /* the spec ignores an id containing NUL; an id too long to be
         * one of ours is ignored the same way */
        if (!memchr(value, '\0', vlen) && vlen <= SSE_ID_MAX) {
            memcpy(p->id, value, vlen);
            p->id[vlen] = '\0';
            p->has_id = 1;
        }
    } else if (flen == 5 && memcmp(line, "retry", 5) == 0) {
        long ms = 0;
        size_t i;
        for (i = 0; i < vlen && value[i] >= '0' && value[i] <= '9' && ms < 100000000; i++)
            ms = ms * 10 + (value[i] - '0');
        if (vlen > 0 && i == vlen)
            p->retry_ms = ms;
    }
    return 0;
}

int sse_feed(sse_parser *p, const char *buf, size_t n)
{
    if (p->stopped || p->error[0])
        return -1;
    size_t i = 0;
    /* a UTF-8 byte-order mark may open the stream, possibly split */
    while (p->at_start && i < n) {
        if ((unsigned char)buf[i] == utf8_bom[p->bom_matched]) {
            p->bom_matched++;
            i++;
            if (p->bom_matched == sizeof utf8_bom)
                p->at_start = 0;
            continue;
        }
        p->at_start = 0;
        if (p->bom_matched > 0) {
            /* a partial BOM was real content after all */
            if (reserve(&p->line, &p->line_cap, p->bom_matched + 1) != 0)
                return fail(p, "out of memory");
            memcpy(p->line, utf8_bom, p->bom_matched);
            p->line_len = p->bom_matched;
        }
    }
    for (; i < n; i++) {
        char c = buf[i];
        if (c == '\n' && p->after_cr) {
            p->after_cr = 0;
            continue;
        }
        p->after_cr = 0;
        if (c == '\r' || c == '\n') {
            p->after_cr = c == '\r';
            int rc = process_line(p);
            p->line_len = 0;
            if (rc != 0)
                return -1;
            continue;
        }
        /* copy the run of ordinary bytes up to the next terminator */
        size_t j = i;
        while (j < n && buf[j] != '\r' && buf[j] != '\n')
            j++;
        size_t run = j - i;
        if (p->line_len + run > p->max_line)
            return fail(p, "a line of the event stream is too long");
        if (reserve(&p->line, &p->line_cap, p->line_len + run + 1) != 0)
            return fail(p, "out of memory");
        memcpy(p->line + p->line_len, buf + i, run);
        p->line_len += run;
        i = j - 1;
    }
    return 0;
}
