/* Content negotiation: Accept and Accept-Encoding (RFC 9110 12.5). */
#include <ctype.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "http/smd_negotiate.h"

/* One element of a comma-separated header: the value before ';' (trimmed)
 * and its q parameter (1 when absent, 0..1). */
typedef struct element {
    const char *value;
    size_t len;
    double q;
} element;

/* Parses the next element from *p; 0 at the end. */
static int next_element(const char **p, element *e)
{
    const char *s = *p;
    while (*s == ',' || isspace((unsigned char)*s))
        s++;
    if (!*s)
        return 0;
    const char *end = s;
    while (*end && *end != ',')
        end++;
    *p = end;
    const char *semi = memchr(s, ';', (size_t)(end - s));
    const char *vend = semi ? semi : end;
    while (vend > s && isspace((unsigned char)vend[-1]))
        vend--;
    e->value = s;
    e->len = (size_t)(vend - s);
    e->q = 1;
    for (const char *param = semi; param && param < end;) {
        param++;
        while (param < end && isspace((unsigned char)*param))
            param++;
        if (end - param >= 2 && (param[0] == 'q' || param[0] == 'Q') && param[1] == '=') {
            char num[16];
            size_t n = 0;
            for (const char *c = param + 2; c < end && *c != ';' && n + 1 < sizeof num; c++)
                if (!isspace((unsigned char)*c))
                    num[n++] = *c;
            num[n] = '\0';
            char *stop;
            double q = strtod(num, &stop);
            e->q = (stop != num && *stop == '\0' && q >= 0 && q <= 1) ? q : 0;
        }
        param = memchr(param, ';', (size_t)(end - param));
    }
    return 1;
}

/* Length of "type/subtype" in a media type (without parameters). */
static size_t media_len(const char *m)
{
    size_t n = 0;
    while (m[n] && m[n] != ';' && !isspace((unsigned char)m[n]))
        n++;
    return n;
}

int smd_accept_choose(const char *accept, const char *const *offered, int n)
{
    if (!accept || !*accept)
        return 0;
    int best = -1;
    double best_q = 0;
    for (int i = 0; i < n; i++) {
        const char *m = offered[i];
        size_t mlen = media_len(m);
        const char *slash = memchr(m, '/', mlen);
        size_t tlen = slash ? (size_t)(slash - m) : mlen;
        /* the most specific matching range decides the quality */
        int spec = -1;
        double q = 0;
        const char *p = accept;
        element e;
        while (next_element(&p, &e)) {
            int s = -1;
            if (e.len == mlen && strncasecmp(e.value, m, mlen) == 0)
                s = 2;
            else if (e.len == tlen + 2 && strncasecmp(e.value, m, tlen) == 0 &&
                     e.value[tlen] == '/' && e.value[tlen + 1] == '*')
                s = 1;
            else if (e.len == 3 && strncmp(e.value, "*/*", 3) == 0)
                s = 0;
            if (s > spec) {
                spec = s;
                q = e.q;
            }
        }
        if (spec >= 0 && q > best_q) {
            best_q = q;
            best = i;
        }
    }
    return best;
}

int smd_accepts_gzip(const char *accept_encoding)
{
    if (!accept_encoding)
        return 0;
    double gzip_q = -1, star_q = -1;
    const char *p = accept_encoding;
    element e;
    while (next_element(&p, &e)) {
        if ((e.len == 4 && strncasecmp(e.value, "gzip", 4) == 0) ||
            (e.len == 6 && strncasecmp(e.value, "x-gzip", 6) == 0))
            gzip_q = e.q;
        else if (e.len == 1 && e.value[0] == '*')
            star_q = e.q;
    }
    if (gzip_q >= 0)
        return gzip_q > 0;
    return star_q > 0;
}
