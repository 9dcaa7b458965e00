/* Point lists: CSV, Slicer .fcsv and .mrk.json (see sm_points_csv.h). */
#include "sm_points_csv.h"

#include <ctype.h>
#include <errno.h>
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "shapematch/sm_decimal.h"

/* A number longer than this is no plain decimal anyone writes (%.17g
 * needs 24 characters): sm_decimal_parse's bound, and its messages'. */
#define FIELD_MAX 64
/* Header lines are kept for the output: bounded. */
#define HEADER_MAX 1024
/* Columns of a header that names x, y[, z] among others. */
#define COLS_MAX 64
/* Slicer's .fcsv columns when the file does not list them. */
#define FCSV_COLUMNS "id,x,y,z,ow,ox,oy,oz,vis,sel,lock,label,desc,associatedNodeID"

static int is_space(char c)
{
    return c == ' ' || c == '\t';
}

/* Parses one trimmed field as a plain finite decimal: 1 yes, 0 no
 * (the core's exact conversion: strtod's double, at a tenth of its
 * cost). */
static int parse_number(const char *s, size_t n, double *out)
{
    return sm_decimal_parse(s, n, out);
}

/* A field of a line: its text trimmed of blanks, and of its quotes when
 * it was "quoted" (raw keeps them, for writing it back). */
typedef struct field {
    const char *s, *raw;
    size_t n, raw_n;
} field;

/* Splits [s, s+n) at the commas outside double quotes ("" is a quote in
 * a quoted field) into at most max fields; returns the number of fields
 * (those past max counted too), or -1 for an unterminated quote. */
static int split_fields(const char *s, size_t n, field *f, int max)
{
    int count = 0;
    size_t i = 0;
    for (;;) {
        size_t a = i;
        while (a < n && is_space(s[a]))
            a++;
        size_t b = a, end;
        int quoted = a < n && s[a] == '"';
        if (quoted) {
            b = a + 1;
            for (;; b++) {
                if (b >= n)
                    return -1;
                if (s[b] == '"') {
                    if (b + 1 < n && s[b + 1] == '"')
                        b++;
                    else
                        break;
                }
            }
            end = b + 1;
            while (end < n && s[end] != ',')
                end++;
        } else {
            end = a;
            while (end < n && s[end] != ',')
                end++;
            b = end;
            while (b > a && is_space(s[b - 1]))
                b--;
        }
        if (count < max) {
            f[count].s = quoted ? s + a + 1 : s + a;
            f[count].n = quoted ? b - a - 1 : b - a;
            size_t r = end;
            while (r > a && is_space(s[r - 1]))
                r--;
            f[count].raw = s + a;
            f[count].raw_n = r - a;
        }
        count++;
        if (end >= n)
            return count;
        i = end + 1;
    }
}

/* The field's text made printable for a message. */
static void printable(char *out, size_t cap, const field *f)
{
    size_t k = f->n < cap - 1 ? f->n : cap - 1;
    for (size_t i = 0; i < k; i++)
        out[i] = (unsigned char)f->s[i] < 0x20 || (unsigned char)f->s[i] > 0x7e ? '?' : f->s[i];
    out[k] = '\0';
}

static int names(const field *f, const char *name)
{
    size_t n = strlen(name);
    if (f->n != n)
        return 0;
    for (size_t i = 0; i < n; i++)
        if (tolower((unsigned char)f->s[i]) != name[i])
            return 0;
    return 1;
}

typedef struct builder {
    sm_points *p;
    int64_t cap, max_points;
    size_t lines_cap, lines_len;
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
        if (p->ncols) {
            int64_t *at = realloc(p->line_at, (size_t)(ncap + 1) * sizeof *at);
            if (!at)
                return sm_error_set(err, SM_ERR_NOMEM, "line %ld: out of memory", line);
            p->line_at = at;
        }
        b->cap = ncap;
    }
    memcpy(p->xyz + (size_t)p->n * (size_t)p->dim, v, (size_t)p->dim * sizeof *v);
    p->n++;
    return SM_OK;
}

/* Keeps the line of the point just added (named columns). */
static sm_status keep_line(builder *b, const char *s, size_t n, sm_error *err)
{
    sm_points *p = b->p;
    if (b->lines_len + n > b->lines_cap) {
        size_t ncap = b->lines_cap ? 2 * b->lines_cap : 4096;
        while (ncap < b->lines_len + n)
            ncap *= 2;
        char *grown = realloc(p->lines, ncap);
        if (!grown)
            return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
        p->lines = grown;
        b->lines_cap = ncap;
    }
    memcpy(p->lines + b->lines_len, s, n);
    b->lines_len += n;
    p->line_at[p->n - 1] = (int64_t)(b->lines_len - n);
    p->line_at[p->n] = (int64_t)b->lines_len;
    return SM_OK;
}

static sm_status set_header(sm_points *p, const char *s, size_t n, long line, sm_error *err)
{
    if (n > HEADER_MAX)
        return sm_error_set(err, SM_ERR_FORMAT, "line %ld: header longer than %d bytes", line,
                            HEADER_MAX);
    if (!(p->header = malloc(n + 1)))
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    memcpy(p->header, s, n);
    p->header[n] = '\0';
    return SM_OK;
}

/* The header's columns: with x and y among them (and z), the points are
 * those columns; a header of exactly x,y[,z] needs no lines kept. */
static sm_status name_columns(sm_points *p, long line, sm_error *err)
{
    field f[COLS_MAX];
    int count = split_fields(p->header, strlen(p->header), f, COLS_MAX);
    int col[3] = {-1, -1, -1}, inside = -1;
    for (int c = 0; c < count && c < COLS_MAX; c++) {
        for (int d = 0; d < 3; d++)
            if (col[d] < 0 && names(&f[c], d == 0 ? "x" : d == 1 ? "y" : "z"))
                col[d] = c;
        if (names(&f[c], "inside")) /* the last: a warp's own, at the end */
            inside = c;
    }
    if ((col[0] < 0 || col[1] < 0) && inside >= 0 && (count == 3 || count == 4)) {
        /* a warp's output of unnamed columns: every other field */
        for (int c = 0, d = 0; c < count; c++)
            if (c != inside)
                col[d++] = c;
        if (count == 3)
            col[2] = -1;
    }
    if (col[0] < 0 || col[1] < 0)
        return SM_OK; /* every field a coordinate */
    if (count < 0 || count > COLS_MAX)
        return sm_error_set(err, SM_ERR_FORMAT, "line %ld: a header of at most %d columns, "
                            "quotes closed", line, COLS_MAX);
    p->dim = col[2] >= 0 ? 3 : 2;
    int plain = count == p->dim && inside < 0;
    for (int d = 0; d < p->dim; d++)
        plain = plain && col[d] == d;
    if (plain)
        return SM_OK;
    p->ncols = count;
    memcpy(p->col, col, sizeof col);
    p->inside_col = inside;
    if (!(p->line_at = calloc(1, sizeof *p->line_at)))
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    return SM_OK;
}

/* One line of points. */
static sm_status parse_point(builder *b, const char *s, size_t n, long line, sm_error *err)
{
    sm_points *p = b->p;
    field f[COLS_MAX];
    int max = p->ncols ? p->ncols : 3;
    int count = split_fields(s, n, f, max);
    if (count < 0)
        return sm_error_set(err, SM_ERR_FORMAT, "line %ld: a quote is not closed", line);
    double v[3];
    if (p->ncols) {
        if (count != p->ncols)
            return sm_error_set(err, SM_ERR_FORMAT, "line %ld: expected %d fields as the header "
                                "names, found %d", line, p->ncols, count);
        for (int d = 0; d < p->dim; d++)
            if (!parse_number(f[p->col[d]].s, f[p->col[d]].n, &v[d])) {
                char t[FIELD_MAX + 1];
                printable(t, sizeof t, &f[p->col[d]]);
                return sm_error_set(err, SM_ERR_FORMAT, "line %ld, field %d (%c): '%s' is not a "
                                    "finite decimal number", line, p->col[d] + 1, "xyz"[d], t);
            }
        sm_status st = add_point(b, v, line, err);
        return st == SM_OK ? keep_line(b, s, n, err) : st;
    }
    if (count < 2 || count > 3 || (p->dim && count != p->dim))
        return sm_error_set(err, SM_ERR_FORMAT, "line %ld: expected %s coordinates, found %d", line,
                            p->dim == 3 ? "3" : p->dim == 2 ? "2" : "2 or 3", count);
    for (int d = 0; d < count; d++)
        if (!parse_number(f[d].s, f[d].n, &v[d])) {
            char t[FIELD_MAX + 1];
            printable(t, sizeof t, &f[d]);
            return sm_error_set(err, SM_ERR_FORMAT,
                                "line %ld, field %d: '%s' is not a finite decimal number", line,
                                d + 1, t);
        }
    p->dim = count;
    return add_point(b, v, line, err);
}

/* A first line whose first field is not a number is the header (a
 * line of numbers with a bad one later is a point with an error). */
static int is_header(const char *s, size_t n)
{
    field f[1];
    double v;
    return split_fields(s, n, f, 1) < 0 || !parse_number(f[0].s, f[0].n, &v);
}

/* The next line at or after *at that is neither blank nor a '#'
 * comment: its start in *at, its length without the line end, CRs and
 * trailing blanks in *n; *line counts every line passed (1-based).  0,
 * or -1 at the end of the text.  The one line walk of the parser and of
 * sm_points_csv_line. */
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
        if (a < k && text[i + a] != '#') {
            *at = i;
            *n = k;
            return 0;
        }
        i = end + 1;
    }
    return -1;
}

/* The value after "# key =" on a comment line of [s, s+n), or NULL. */
static const char *comment_value(const char *s, size_t n, const char *key, size_t *vn)
{
    size_t k = strlen(key), i = 0;
    while (i < n && (is_space(s[i]) || s[i] == '#'))
        i++;
    if (n - i < k || strncmp(s + i, key, k) != 0)
        return NULL;
    i += k;
    while (i < n && is_space(s[i]))
        i++;
    if (i >= n || s[i] != '=')
        return NULL;
    i++;
    while (i < n && is_space(s[i]))
        i++;
    size_t e = n;
    while (e > i && (is_space(s[e - 1]) || s[e - 1] == '\r'))
        e--;
    *vn = e - i;
    return s + i;
}

/* Slicer's .fcsv: its leading comments state the frame and the columns. */
static sm_status fcsv_header(sm_points *p, const char *text, size_t len, sm_error *err)
{
    p->kind = "Slicer .fcsv";
    p->frame = SM_POINTS_FRAME_RAS; /* Slicer before 4.11 wrote no frame: RAS */
    const char *columns = FCSV_COLUMNS;
    size_t ncolumns = strlen(FCSV_COLUMNS);
    size_t i = 0;
    long line = 0;
    while (i < len) {
        const char *nl = memchr(text + i, '\n', len - i);
        size_t end = nl ? (size_t)(nl - text) : len, vn;
        line++;
        if (text[i] != '#')
            break;
        const char *v;
        if ((v = comment_value(text + i, end - i, "CoordinateSystem", &vn))) {
            if ((vn == 3 && !strncmp(v, "RAS", 3)) || (vn == 1 && v[0] == '0'))
                p->frame = SM_POINTS_FRAME_RAS;
            else if ((vn == 3 && !strncmp(v, "LPS", 3)) || (vn == 1 && v[0] == '1'))
                p->frame = SM_POINTS_FRAME_LPS;
            else
                return sm_error_set(err, SM_ERR_FORMAT, "line %ld: CoordinateSystem is LPS or "
                                    "RAS (or 1, 0), found '%.*s'", line, (int)(vn > 16 ? 16 : vn), v);
        } else if ((v = comment_value(text + i, end - i, "columns", &vn))) {
            /* a first name starting with '#' would make the header line
             * we write a comment (found by fuzz_points) */
            if (vn > 0 && v[0] == '#')
                return sm_error_set(err, SM_ERR_FORMAT, "line %ld: the .fcsv's columns start "
                                    "with '#'", line);
            columns = v;
            ncolumns = vn;
        }
        i = end + 1;
    }
    sm_status st = set_header(p, columns, ncolumns, line, err);
    if (st == SM_OK)
        st = name_columns(p, line, err);
    if (st == SM_OK && !p->ncols && p->dim == 0)
        st = sm_error_set(err, SM_ERR_FORMAT, "the .fcsv's columns name no x, y, z");
    return st;
}

static sm_status parse_lines(const char *text, size_t len, builder *b, sm_error *err)
{
    sm_points *p = b->p;
    long line = 0;
    size_t i = 0, n;
    int first = !p->header;
    sm_status st = SM_OK;
    while (st == SM_OK && next_line(text, len, &i, &n, &line) >= 0) {
        if (memchr(text + i, '\0', n))
            st = sm_error_set(err, SM_ERR_FORMAT, "line %ld: NUL byte", line);
        else if (first && is_header(text + i, n)) {
            p->header_line = 1;
            st = set_header(p, text + i, n, line, err);
            if (st == SM_OK)
                st = name_columns(p, line, err);
        } else {
            st = parse_point(b, text + i, n, line, err);
        }
        first = 0;
        i += n;
    }
    return st;
}

/* Appends "\"label\",x,y,z\n" (quotes doubled) to the text t. */
static int append_point(char **t, size_t *len, size_t *cap, const char *label, const double *x)
{
    size_t need = *len + 2 * strlen(label) + 3 * 26 + 8;
    if (need > *cap) {
        size_t ncap = *cap ? *cap : 4096;
        while (ncap < need)
            ncap *= 2;
        char *grown = realloc(*t, ncap);
        if (!grown)
            return -1;
        *t = grown;
        *cap = ncap;
    }
    char *w = *t + *len;
    *w++ = '"';
    for (const char *c = label; *c; c++) {
        if (*c == '"')
            *w++ = '"';
        *w++ = *c == '\n' || *c == '\r' ? ' ' : *c;
    }
    *w++ = '"';
    for (int d = 0; d < 3; d++) {
        *w++ = ',';
        w += sm_decimal_format(x[d], w);
    }
    *w++ = '\n';
    *len = (size_t)(w - *t);
    return 0;
}

/* Slicer's .mrk.json: every markup's control points, as the CSV
 * "label,x,y,z" (their frame LPS, unless all of them say RAS). */
static sm_status mrk_json(const char *text, size_t len, builder *b, sm_error *err)
{
    sm_points *p = b->p;
    json_error_t jerr;
    json_t *root = json_loadb(text, len, JSON_REJECT_DUPLICATES, &jerr);
    if (!root)
        return sm_error_set(err, SM_ERR_FORMAT, "line %d: not JSON: %s", jerr.line, jerr.text);
    json_t *markups = json_object_get(root, "markups");
    sm_status st = SM_OK;
    char *csv = NULL;
    size_t clen = 0, ccap = 0;
    int ras = 0, lps = 0;
    int64_t points = 0;
    if (!json_is_array(markups) || json_array_size(markups) == 0)
        st = sm_error_set(err, SM_ERR_FORMAT, "a markups file (.mrk.json) has a non-empty "
                          "\"markups\" array");
    size_t m;
    json_t *mk;
    json_array_foreach(markups, m, mk) {
        if (st != SM_OK)
            break;
        const char *cs = json_string_value(json_object_get(mk, "coordinateSystem"));
        if (cs && strcmp(cs, "RAS") && strcmp(cs, "LPS")) {
            st = sm_error_set(err, SM_ERR_FORMAT, "markups[%zu].coordinateSystem is LPS or RAS",
                              m);
            break;
        }
        int in_ras = cs && !strcmp(cs, "RAS");
        ras += in_ras;
        lps += !in_ras;
        json_t *cps = json_object_get(mk, "controlPoints");
        if (cps && !json_is_array(cps)) {
            st = sm_error_set(err, SM_ERR_FORMAT, "markups[%zu].controlPoints is an array", m);
            break;
        }
        size_t k;
        json_t *cp;
        json_array_foreach(cps, k, cp) {
            json_t *pos = json_object_get(cp, "position");
            double x[3];
            int ok = json_is_array(pos) && json_array_size(pos) == 3;
            for (int d = 0; ok && d < 3; d++) {
                x[d] = json_number_value(json_array_get(pos, (size_t)d));
                ok = json_is_number(json_array_get(pos, (size_t)d)) && isfinite(x[d]);
            }
            if (!ok) {
                st = sm_error_set(err, SM_ERR_FORMAT, "markups[%zu].controlPoints[%zu].position "
                                  "is three finite numbers", m, k);
                break;
            }
            const char *label = json_string_value(json_object_get(cp, "label"));
            char name[64];
            if (!label || strlen(label) > HEADER_MAX / 4) {
                snprintf(name, sizeof name, "%zu-%zu", m + 1, k + 1);
                label = name;
            }
            if (b->max_points > 0 && ++points > b->max_points) {
                st = sm_error_set(err, SM_ERR_NOMEM, "more than %lld points",
                                  (long long)b->max_points);
                break;
            }
            if (in_ras) /* the file's one frame is decided below */
                x[0] = -x[0], x[1] = -x[1];
            if (append_point(&csv, &clen, &ccap, label, x) != 0) {
                st = sm_error_set(err, SM_ERR_NOMEM, "out of memory");
                break;
            }
        }
    }
    json_decref(root);
    if (st == SM_OK && !csv)
        st = sm_error_set(err, SM_ERR_FORMAT, "no control point in the markups");
    if (st == SM_OK) {
        p->kind = "Slicer .mrk.json";
        p->frame = SM_POINTS_FRAME_LPS; /* converted above */
        st = set_header(p, "label,x,y,z", 11, 0, err);
        if (st == SM_OK)
            st = name_columns(p, 0, err);
        if (st == SM_OK)
            st = parse_lines(csv, clen, b, err);
        if (st == SM_OK && ras && !lps) /* all RAS: keep theirs */
            sm_points_to_frame(p, SM_POINTS_FRAME_RAS);
    }
    free(csv);
    return st;
}

/* A JSON object: '{' then, past blanks, a member's name (a CSV header
 * may start with '{' too). */
static int is_json(const char *text, size_t len)
{
    size_t i = 0;
    while (i < len && (is_space(text[i]) || text[i] == '\r' || text[i] == '\n'))
        i++;
    if (i >= len || text[i] != '{')
        return 0;
    for (i++; i < len && (is_space(text[i]) || text[i] == '\r' || text[i] == '\n'); i++)
        ;
    return i < len && text[i] == '"';
}

static int starts_with(const char *text, size_t len, const char *word)
{
    size_t i = 0, k = strlen(word);
    while (i < len && (is_space(text[i]) || text[i] == '\r' || text[i] == '\n'))
        i++;
    return len - i >= k && memcmp(text + i, word, k) == 0;
}

sm_status sm_points_csv_parse(const char *text, size_t len, int64_t max_points, sm_points *out,
                              sm_error *err)
{
    memset(out, 0, sizeof *out);
    out->inside_col = -1;
    out->kind = "CSV";
    builder b = {out, 0, max_points, 0, 0};
    sm_status st = SM_OK;
    if (is_json(text, len)) {
        st = mrk_json(text, len, &b, err);
    } else {
        if (starts_with(text, len, "# Markups fiducial file"))
            st = fcsv_header(out, text, len, err);
        if (st == SM_OK)
            st = parse_lines(text, len, &b, err);
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
    free(p->lines);
    free(p->line_at);
    memset(p, 0, sizeof *p);
    p->inside_col = -1;
}

void sm_points_to_frame(sm_points *p, sm_points_frame want)
{
    if (p->dim != 3 || p->frame == SM_POINTS_FRAME_UNSTATED || want == SM_POINTS_FRAME_UNSTATED ||
        p->frame == want)
        return;
    for (int64_t i = 0; i < p->n; i++) {
        p->xyz[3 * i] = -p->xyz[3 * i];
        p->xyz[3 * i + 1] = -p->xyz[3 * i + 1];
    }
    p->frame = want;
}

sm_status sm_points_read_file(const char *path, size_t max_bytes, int64_t max_points,
                              sm_points *out, sm_error *err)
{
    memset(out, 0, sizeof *out);
    out->inside_col = -1;
    if (!max_bytes)
        max_bytes = (size_t)64 << 20;
    FILE *f = fopen(path, "rb");
    if (!f)
        return sm_error_set(err, SM_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    size_t cap = 4096, len = 0;
    char *buf = malloc(cap);
    sm_status st = SM_OK;
    for (size_t got; buf && (got = fread(buf + len, 1, cap - len, f)) > 0;) {
        len += got;
        if (len == cap) {
            char *grown = cap < max_bytes ? realloc(buf, cap * 2) : NULL;
            if (!grown) {
                st = cap < max_bytes ? sm_error_set(err, SM_ERR_NOMEM, "%s: out of memory", path)
                                     : sm_error_set(err, SM_ERR_FORMAT, "%s: larger than %zu "
                                                    "bytes", path, max_bytes);
                break;
            }
            buf = grown;
            cap *= 2;
        }
    }
    int bad = ferror(f);
    fclose(f);
    if (!buf)
        return sm_error_set(err, SM_ERR_NOMEM, "%s: out of memory", path);
    if (st == SM_OK && bad)
        st = sm_error_set(err, SM_ERR_IO, "%s: read error", path);
    if (st == SM_OK && (st = sm_points_csv_parse(buf, len, max_points, out, err)) != SM_OK)
        sm_error_prefix(err, "%s", path);
    free(buf);
    return st;
}

/* A growing output text. */
typedef struct text_out {
    char *s;
    size_t len, cap;
} text_out;

static int put(text_out *t, const char *s, size_t n)
{
    if (t->len + n + 32 > t->cap) {
        size_t ncap = t->cap ? t->cap : 4096;
        while (ncap < t->len + n + 32)
            ncap *= 2;
        char *grown = realloc(t->s, ncap);
        if (!grown)
            return -1;
        t->s = grown;
        t->cap = ncap;
    }
    memcpy(t->s + t->len, s, n);
    t->len += n;
    t->s[t->len] = '\0';
    return 0;
}

/* A line of the named columns: its fields in their order, the
 * coordinates replaced by x, the input's inside column left out. */
static int put_columns(text_out *t, const sm_points *p, const char *s, size_t n, const double *x)
{
    field f[COLS_MAX];
    int count = split_fields(s, n, f, COLS_MAX), first = 1;
    for (int c = 0; c < count && c < COLS_MAX; c++) {
        if (c == p->inside_col)
            continue;
        if (!first && put(t, ",", 1) != 0)
            return -1;
        first = 0;
        int d = 0;
        while (d < p->dim && p->col[d] != c)
            d++;
        char num[SM_DECIMAL_LEN];
        size_t k = x && d < p->dim ? sm_decimal_format(x[d], num) : 0;
        if ((k ? put(t, num, k) : put(t, f[c].raw, f[c].raw_n)) != 0)
            return -1;
    }
    return 0;
}

char *sm_points_csv_format(const sm_points *p, const double *out, const uint8_t *inside,
                           int skip_outside, size_t *len)
{
    text_out t = {0};
    int bad = 0;
    field f[4];
    if (p->ncols && p->header)
        bad = put_columns(&t, p, p->header, strlen(p->header), NULL);
    else if (p->header && split_fields(p->header, strlen(p->header), f, 4) == p->dim)
        bad = put(&t, p->header, strlen(p->header));
    else /* none, or one that does not fit the points */
        bad = put(&t, p->dim == 3 ? "x,y,z" : "x,y", p->dim == 3 ? 5 : 3);
    bad = bad || put(&t, ",inside\n", 8);
    for (int64_t i = 0; !bad && i < p->n; i++) {
        if (skip_outside && !inside[i])
            continue;
        const double *x = out + (size_t)i * (size_t)p->dim;
        if (p->ncols) {
            bad = put_columns(&t, p, p->lines + p->line_at[i],
                              (size_t)(p->line_at[i + 1] - p->line_at[i]), x);
        } else {
            char num[3 * (SM_DECIMAL_LEN + 1)], *w = num;
            for (int d = 0; d < p->dim; d++) {
                if (d)
                    *w++ = ',';
                w += sm_decimal_format(x[d], w);
            }
            bad = put(&t, num, (size_t)(w - num));
        }
        bad = bad || put(&t, inside[i] ? ",1\n" : ",0\n", 3);
    }
    if (bad) {
        free(t.s);
        return NULL;
    }
    *len = t.len;
    return t.s;
}

long sm_points_csv_line(const char *text, size_t len, int header, int64_t index)
{
    if (is_json(text, len))
        return 0;
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
    long line = text ? sm_points_csv_line(text, len, p->header_line, i) : 0;
    if (line > 0)
        return sm_error_set(err, SM_ERR_INVALID, "line %ld: point %s %s", line, coords, what);
    return sm_error_set(err, SM_ERR_INVALID, "points[%lld]: point %s %s", (long long)i, coords,
                        what);
}
