/* Points as CSV (see sm_points_csv.h). */
#include "sm_points_csv.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* A number longer than this is no plain decimal anyone writes (%.17g
 * needs 24 characters); refusing it bounds the copy for strtod. */
#define FIELD_MAX 64
/* Header lines are kept for the output: bounded. */
#define HEADER_MAX 1024

typedef struct line_fields {
    int count;
    double v[3];
    int bad_field;        /* 1-based field that is not a number, 0 none */
    char bad_text[FIELD_MAX + 1];
} line_fields;

static int is_space(char c)
{
    return c == ' ' || c == '\t';
}

/* Parses one trimmed field as a plain finite decimal: 1 yes, 0 no. */
static int parse_number(const char *s, size_t n, double *out)
{
    if (n == 0 || n > FIELD_MAX)
        return 0;
    char buf[FIELD_MAX + 1];
    int digits = 0;
    for (size_t i = 0; i < n; i++) {
        char c = s[i];
        if (c >= '0' && c <= '9')
            digits++;
        else if (c != '+' && c != '-' && c != '.' && c != 'e' && c != 'E')
            return 0;
        buf[i] = c;
    }
    buf[n] = '\0';
    if (!digits)
        return 0;
    char *end;
    double v = strtod(buf, &end);
    if (end != buf + n || !isfinite(v))
        return 0;
    *out = v;
    return 1;
}

/* Splits the line [s, s+n) into fields and parses up to 3 of them;
 * count is the number of fields (more than 3 counted too). */
static void split_line(const char *s, size_t n, line_fields *lf)
{
    lf->count = 0;
    lf->bad_field = 0;
    size_t i = 0;
    for (;;) {
        size_t start = i;
        while (i < n && s[i] != ',')
            i++;
        size_t a = start, b = i;
        while (a < b && is_space(s[a]))
            a++;
        while (b > a && is_space(s[b - 1]))
            b--;
        if (lf->count < 3 && !lf->bad_field && !parse_number(s + a, b - a, &lf->v[lf->count])) {
            lf->bad_field = lf->count + 1;
            size_t k = b - a > FIELD_MAX ? FIELD_MAX : b - a;
            memcpy(lf->bad_text, s + a, k);
            lf->bad_text[k] = '\0';
        }
        lf->count++;
        if (i >= n)
            return;
        i++; /* the comma */
    }
}

/* The bad field's text made printable for a message. */
static void printable(char *t)
{
    for (; *t; t++)
        if ((unsigned char)*t < 0x20 || (unsigned char)*t > 0x7e)
            *t = '?';
}

typedef struct builder {
    sm_points *p;
    int64_t cap, max_points;
} builder;

static sm_status add_point(builder *b, const double *v, long line, sm_error *err)
{
    sm_points *p = b->p;
    if (b->max_points > 0 && p->n >= b->max_points)
        return sm_error_set(err, SM_ERR_NOMEM, "line %ld: more than %lld points", line,
                            (long long)b->max_points);
    if (p->n == b->cap) {
        int64_t ncap = b->cap ? 2 * b->cap : 1024;
        double *grown = realloc(p->xyz, (size_t)ncap * (size_t)p->dim * sizeof *grown);
        if (!grown)
            return sm_error_set(err, SM_ERR_NOMEM, "line %ld: out of memory", line);
        p->xyz = grown;
        b->cap = ncap;
    }
    memcpy(p->xyz + (size_t)p->n * (size_t)p->dim, v, (size_t)p->dim * sizeof *v);
    p->n++;
    return SM_OK;
}

/* One non-blank line; first: no point or header seen yet. */
static sm_status parse_line(builder *b, const char *s, size_t n, long line, int first,
                            sm_error *err)
{
    sm_points *p = b->p;
    if (memchr(s, '\0', n))
        return sm_error_set(err, SM_ERR_FORMAT, "line %ld: NUL byte", line);
    line_fields lf;
    split_line(s, n, &lf);
    if (first && lf.bad_field) { /* the header */
        if (n > HEADER_MAX)
            return sm_error_set(err, SM_ERR_FORMAT, "line %ld: header longer than %d bytes", line,
                                HEADER_MAX);
        if (!(p->header = malloc(n + 1)))
            return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
        memcpy(p->header, s, n);
        p->header[n] = '\0';
        return SM_OK;
    }
    if (lf.count < 2 || lf.count > 3 || (p->dim && lf.count != p->dim))
        return sm_error_set(err, SM_ERR_FORMAT, "line %ld: expected %s coordinates, found %d", line,
                            p->dim == 3 ? "3" : p->dim == 2 ? "2" : "2 or 3", lf.count);
    if (lf.bad_field) {
        printable(lf.bad_text);
        return sm_error_set(err, SM_ERR_FORMAT,
                            "line %ld, field %d: '%s' is not a finite decimal number", line,
                            lf.bad_field, lf.bad_text);
    }
    p->dim = lf.count;
    return add_point(b, lf.v, line, err);
}

/* The next non-blank line at or after *at: its start in *at, its length
 * without the line end, CRs and trailing blanks in *n; *line counts every
 * line passed (1-based).  0, or -1 at the end of the text.  The one line
 * walk of the parser and of sm_points_csv_line. */
static int next_line(const char *text, size_t len, size_t *at, size_t *n, long *line)
{
    size_t i = *at;
    /* after a line: skip to the start of the next */
    if (*line > 0) {
        const char *nl = i < len ? memchr(text + i, '\n', len - i) : NULL;
        if (!nl)
            return -1;
        i = (size_t)(nl - text) + 1;
    }
    while (i < len) {
        const char *nl = memchr(text + i, '\n', len - i);
        size_t end = nl ? (size_t)(nl - text) : len;
        size_t k = end - i;
        (*line)++;
        /* CR of CRLF ends (any number: a header is kept without them),
         * trailing blanks */
        while (k > 0 && (text[i + k - 1] == '\r' || is_space(text[i + k - 1])))
            k--;
        size_t a = 0;
        while (a < k && is_space(text[i + a]))
            a++;
        if (a < k) {
            *at = i;
            *n = k;
            return 0;
        }
        i = end + 1;
    }
    return -1;
}

sm_status sm_points_csv_parse(const char *text, size_t len, int64_t max_points, sm_points *out,
                              sm_error *err)
{
    memset(out, 0, sizeof *out);
    builder b = {out, 0, max_points};
    long line = 0;
    size_t i = 0, n;
    int seen = 0;
    sm_status st = SM_OK;
    while (st == SM_OK && next_line(text, len, &i, &n, &line) >= 0) {
        st = parse_line(&b, text + i, n, line, !seen, err);
        seen = 1;
        i += n;
    }
    if (st == SM_OK && out->n == 0)
        st = sm_error_set(err, SM_ERR_FORMAT, "no point (one per line: x,y or x,y,z)");
    if (st != SM_OK)
        sm_points_release(out);
    return st;
}

void sm_points_release(sm_points *p)
{
    if (!p)
        return;
    free(p->xyz);
    free(p->header);
    memset(p, 0, sizeof *p);
}

char *sm_points_csv_format(const sm_points *p, const double *out, const uint8_t *inside,
                           size_t *len)
{
    /* a line: 3 numbers of at most 24 characters, commas, the flag */
    size_t cap = (p->header ? strlen(p->header) : 0) + 32 + (size_t)p->n * 84;
    char *buf = malloc(cap);
    if (!buf)
        return NULL;
    size_t k;
    if (p->header)
        k = (size_t)snprintf(buf, cap, "%s,inside\n", p->header);
    else
        k = (size_t)snprintf(buf, cap, p->dim == 3 ? "x,y,z,inside\n" : "x,y,inside\n");
    for (int64_t i = 0; i < p->n; i++) {
        const double *x = out + (size_t)i * (size_t)p->dim;
        for (int d = 0; d < p->dim; d++)
            k += (size_t)snprintf(buf + k, cap - k, "%.17g,", x[d]);
        k += (size_t)snprintf(buf + k, cap - k, "%d\n", inside[i] ? 1 : 0);
    }
    *len = k;
    return buf;
}

long sm_points_csv_line(const char *text, size_t len, int header, int64_t index)
{
    long line = 0;
    size_t i = 0, n;
    int64_t k = header ? -1 : 0;
    while (next_line(text, len, &i, &n, &line) >= 0) {
        if (k++ == index)
            return line;
        i += n;
    }
    return 0;
}

sm_status sm_points_warp(const sm_warp *w, sm_warp_direction dir, int strict, const sm_points *p,
                         const char *text, size_t len, double *out, uint8_t *inside,
                         int64_t *noutside, sm_error *err)
{
    sm_status st = sm_warp_points(w, dir, 0, p->n, p->xyz, out, inside, noutside, err);
    if (st != SM_OK || !strict || *noutside == 0)
        return st;
    int64_t i = 0;
    while (inside[i])
        i++;
    /* the core's strict message for that point alone, with its distance:
     * "point 1 is outside the ... (distance D)" */
    double y[3];
    sm_error one;
    sm_error_clear(&one);
    const char *what = "is outside";
    if (sm_warp_points(w, dir, 1, 1, p->xyz + (size_t)i * (size_t)p->dim, y, NULL, NULL, &one) !=
            SM_OK &&
        strncmp(one.msg, "point 1 ", 8) == 0)
        what = one.msg + 8;
    const double *x = p->xyz + (size_t)i * (size_t)p->dim;
    char coords[96];
    if (p->dim == 3)
        snprintf(coords, sizeof coords, "(%.6g, %.6g, %.6g)", x[0], x[1], x[2]);
    else
        snprintf(coords, sizeof coords, "(%.6g, %.6g)", x[0], x[1]);
    if (text)
        return sm_error_set(err, SM_ERR_INVALID, "line %ld: point %s %s",
                            sm_points_csv_line(text, len, p->header != NULL, i), coords, what);
    return sm_error_set(err, SM_ERR_INVALID, "points[%lld]: point %s %s", (long long)i, coords,
                        what);
}
