/* Streaming JSON writer (see jsonw.h). */
#include "jsonw.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void jsonw_init(jsonw *w, FILE *f, int pretty)
{
    memset(w, 0, sizeof *w);
    w->f = f;
    w->pretty = pretty;
}

/* Length of the valid UTF-8 sequence at s (1..4), or 0 if invalid. */
static int utf8_sequence(const unsigned char *s)
{
    unsigned c = s[0];
    if (c < 0x80)
        return 1;
    int n;
    unsigned cp;
    if (c >= 0xc2 && c <= 0xdf) {
        n = 2;
        cp = c & 0x1f;
    } else if (c >= 0xe0 && c <= 0xef) {
        n = 3;
        cp = c & 0x0f;
    } else if (c >= 0xf0 && c <= 0xf4) {
        n = 4;
        cp = c & 0x07;
    } else {
        return 0;
    }
    for (int i = 1; i < n; i++) {
        if ((s[i] & 0xc0) != 0x80)
            return 0;
        cp = (cp << 6) | (s[i] & 0x3f);
    }
    /* overlong forms, surrogates and values above U+10FFFF */
    if ((n == 3 && cp < 0x800) || (n == 4 && cp < 0x10000) || cp > 0x10ffff ||
        (cp >= 0xd800 && cp <= 0xdfff))
        return 0;
    return n;
}

void json_write_string(FILE *f, const char *s)
{
    const unsigned char *p = (const unsigned char *)s;
    fputc('"', f);
    while (*p) {
        unsigned c = *p;
        if (c == '"' || c == '\\') {
            fputc('\\', f);
            fputc((int)c, f);
            p++;
        } else if (c < 0x20) {
            switch (c) {
            case '\n': fputs("\\n", f); break;
            case '\r': fputs("\\r", f); break;
            case '\t': fputs("\\t", f); break;
            case '\b': fputs("\\b", f); break;
            case '\f': fputs("\\f", f); break;
            default: fprintf(f, "\\u%04x", c); break;
            }
            p++;
        } else {
            int n = utf8_sequence(p);
            if (n == 0) {
                fputs("\\ufffd", f);
                p++;
            } else {
                fwrite(p, 1, (size_t)n, f);
                p += n;
            }
        }
    }
    fputc('"', f);
}

const char *json_format_number(char *buf, double v)
{
    /* the shortest of 15..17 significant digits that reads back exactly:
     * 0.3 stays "0.3", yet every double round-trips */
    for (int digits = 15; digits <= 17; digits++) {
        snprintf(buf, JSON_NUMBER_LEN, "%.*g", digits, v);
        if (digits == 17 || strtod(buf, NULL) == v)
            break;
    }
    return buf;
}

static void newline_indent(jsonw *w)
{
    if (!w->pretty)
        return;
    fputc('\n', w->f);
    for (int i = 0; i < w->depth; i++)
        fputs("  ", w->f);
}

/* Separator, indentation and "key": before any value. */
static void prefix(jsonw *w, const char *key)
{
    if (w->depth > 0) {
        int first = w->count[w->depth - 1]++ == 0;
        if (!first)
            fputc(',', w->f);
        /* arrays stay on one line ("center": [0, 0]): ours only hold
         * a few scalars */
        if (w->inline_level[w->depth - 1]) {
            if (!first && w->pretty)
                fputc(' ', w->f);
        } else {
            newline_indent(w);
        }
    }
    if (key) {
        json_write_string(w->f, key);
        fputs(w->pretty ? ": " : ":", w->f);
    }
}

static void open_container(jsonw *w, const char *key, char c)
{
    prefix(w, key);
    fputc(c, w->f);
    if (w->depth < JSONW_MAX_DEPTH) {
        w->count[w->depth] = 0;
        w->inline_level[w->depth] = c == '[';
        w->depth++;
    }
}

static void close_container(jsonw *w, char c)
{
    if (w->depth == 0)
        return;
    w->depth--;
    if (w->count[w->depth] > 0 && !w->inline_level[w->depth])
        newline_indent(w);
    fputc(c, w->f);
}

void jsonw_object_begin(jsonw *w, const char *key) { open_container(w, key, '{'); }
void jsonw_object_end(jsonw *w) { close_container(w, '}'); }
void jsonw_array_begin(jsonw *w, const char *key) { open_container(w, key, '['); }
void jsonw_array_end(jsonw *w) { close_container(w, ']'); }

void jsonw_string(jsonw *w, const char *key, const char *value)
{
    prefix(w, key);
    if (value)
        json_write_string(w->f, value);
    else
        fputs("null", w->f);
}

void jsonw_number(jsonw *w, const char *key, double value)
{
    prefix(w, key);
    if (isfinite(value)) {
        char buf[JSON_NUMBER_LEN];
        fputs(json_format_number(buf, value), w->f);
    } else {
        fputs("null", w->f);
    }
}

void jsonw_int(jsonw *w, const char *key, long long value)
{
    prefix(w, key);
    fprintf(w->f, "%lld", value);
}

void jsonw_bool(jsonw *w, const char *key, int value)
{
    prefix(w, key);
    fputs(value ? "true" : "false", w->f);
}

void jsonw_null(jsonw *w, const char *key)
{
    prefix(w, key);
    fputs("null", w->f);
}
