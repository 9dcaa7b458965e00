/* Request bodies held in memory (see smd_body.h). */
#include "base/smd_body.h"

#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

static _Atomic uint64_t held;

void smd_body_release(smd_body *b)
{
    atomic_fetch_sub(&held, (uint64_t)b->cap);
    free(b->buf);
    b->buf = NULL;
    b->len = b->cap = 0;
}

int smd_body_append(smd_body *b, const char *data, size_t n)
{
    if (n > b->max || b->len > b->max - n) {
        smd_body_release(b);
        return SMD_BODY_TOO_LARGE;
    }
    if (b->len + n + 1 > b->cap) {
        size_t cap = b->cap ? b->cap : 65536;
        while (cap < b->len + n + 1)
            cap *= 2;
        uint64_t grow = (uint64_t)(cap - b->cap);
        if (atomic_fetch_add(&held, grow) + grow > b->budget) {
            atomic_fetch_sub(&held, grow);
            smd_body_release(b);
            return SMD_BODY_BUSY;
        }
        char *t = realloc(b->buf, cap);
        if (!t) {
            atomic_fetch_sub(&held, grow);
            smd_body_release(b);
            return SMD_BODY_NOMEM;
        }
        b->buf = t;
        b->cap = cap;
    }
    memcpy(b->buf + b->len, data, n);
    b->len += n;
    b->buf[b->len] = '\0';
    return SMD_BODY_OK;
}

uint64_t smd_body_held(void)
{
    return atomic_load(&held);
}
