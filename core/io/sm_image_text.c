/* The text-header helpers NRRD and MetaImage share (sm_image_formats.h):
 * bounded lines and lists of numbers, strict (a number must be all of
 * its token, finite, in range). */
#include "io/sm_image_formats.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

sm_status sm__image_line(sm_reader *r, const char *path, char *buf, int *found, sm_error *err)
{
    size_t n = 0;
    *found = 0;
    r->token_line = r->line;
    for (;;) {
        const unsigned char *p;
        size_t avail;
        sm_status st = sm__reader_window(r, &p, &avail);
        if (st != SM_OK)
            return sm_error_set(err, st, "%s:%ld: %s", path, r->line, r->why);
        if (avail == 0)
            break;
        const unsigned char *nl = memchr(p, '\n', avail);
        size_t take = nl ? (size_t)(nl - p) : avail;
        if (n + take >= SM_IMAGE_LINE_LEN)
            return sm_error_set(err, SM_ERR_FORMAT, "%s:%ld: header line longer than %d bytes",
                                path, r->line, SM_IMAGE_LINE_LEN - 1);
        memcpy(buf + n, p, take);
        n += take;
        *found = 1;
        sm__reader_consume(r, take + (nl ? 1 : 0));
        if (nl) {
            r->line++;
            break;
        }
    }
    buf[n] = '\0';
    if (memchr(buf, '\0', n))
        return sm_error_set(err, SM_ERR_FORMAT, "%s:%ld: NUL byte in a header line", path,
                            r->token_line);
    if (n > 0 && buf[n - 1] == '\r')
        buf[n - 1] = '\0';
    return SM_OK;
}

static int is_sep(char c)
{
    return c == ' ' || c == '\t' || c == ',' || c == '(' || c == ')';
}

int sm__image_reals(const char *s, double *v, int max, int *n)
{
    *n = 0;
    for (;;) {
        while (*s && is_sep(*s))
            s++;
        if (!*s)
            return 1;
        if (*n == max)
            return 0;
        char *end;
        errno = 0;
        double x = strtod(s, &end);
        if (end == s || errno == ERANGE || !isfinite(x) || (*end && !is_sep(*end)))
            return 0;
        v[(*n)++] = x;
        s = end;
    }
}

int sm__image_ints(const char *s, int64_t lo, int64_t hi, int64_t *v, int max, int *n)
{
    *n = 0;
    for (;;) {
        while (*s == ' ' || *s == '\t')
            s++;
        if (!*s)
            return 1;
        if (*n == max)
            return 0;
        char *end;
        errno = 0;
        long long x = strtoll(s, &end, 10);
        if (end == s || errno == ERANGE || x < lo || x > hi || (*end && *end != ' ' && *end != '\t'))
            return 0;
        v[(*n)++] = x;
        s = end;
    }
}
