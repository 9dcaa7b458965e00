#include "io/sm_stream.h"

#include <string.h>
#include <strings.h>

int sm__path_has_suffix(const char *path, const char *suffix)
{
    size_t n = strlen(path), k = strlen(suffix);
    return n >= k && strcasecmp(path + n - k, suffix) == 0;
}

void sm__stream_use_c_locale(locale_t *c_locale, locale_t *saved)
{
    *c_locale = newlocale(LC_NUMERIC_MASK, "C", (locale_t)0);
    *saved = (locale_t)0;
    if (*c_locale != (locale_t)0)
        *saved = uselocale(*c_locale);
}

void sm__stream_restore_locale(locale_t c_locale, locale_t saved)
{
    if (c_locale != (locale_t)0) {
        uselocale(saved);
        freelocale(c_locale);
    }
}

/* zlib prefixes its messages with the file name it was given, which for
 * gzdopen is "<fd:N>". */
const char *sm__stream_zlib_message(const char *msg)
{
    if (!msg)
        return "unknown zlib error";
    if (strncmp(msg, "<fd:", 4) == 0) {
        const char *colon = strstr(msg, ": ");
        if (colon)
            return colon + 2;
    }
    return msg;
}
