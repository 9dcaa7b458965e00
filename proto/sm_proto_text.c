/* Printable text (see sm_proto_text.h). */
#include "sm_proto_text.h"

#include <string.h>

static int shown(unsigned char c, const char *also)
{
    return c >= 0x20 && c < 0x7f && !(also && strchr(also, c));
}

char *sm_text_make_printable(char *s, const char *also)
{
    for (char *c = s; *c; c++)
        if (!shown((unsigned char)*c, also))
            *c = '?';
    return s;
}

char *sm_text_printable_copy(char *dst, size_t cap, const char *src, const char *also)
{
    size_t k = 0;
    for (; src && *src && k + 4 < cap; src++)
        dst[k++] = shown((unsigned char)*src, also) ? *src : '?';
    if (src && *src && k + 4 <= cap) {
        memcpy(dst + k, "...", 3);
        k += 3;
    }
    dst[k] = '\0';
    return dst;
}
