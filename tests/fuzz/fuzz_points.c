/* The point lists of `shapematch warp`, POST /v1/jobs/{id}/warp and
 * --landmarks (proto/sm_points_csv.c: CSV, Slicer .fcsv and .mrk.json):
 * any input is parsed or refused with a message; an accepted one formats
 * to a CSV that parses back to the same points bit for bit (%.17g), and
 * whose own output is stable (its inside column replaced);
 * sm_points_csv_line names, for every point of a text with lines, a line
 * that holds exactly that point (after the header, when the columns are
 * named), the lines increasing.  Being also the landmarks' reader, each
 * accepted set goes on to the Kabsch/Umeyama start against itself (its
 * checks of degenerate and non-finite sets): the identity. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "shapematch/sm_align.h"
#include "sm_points_csv.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* The point alone (after its header when the columns are named). */
static void check_one(const sm_points *p, int64_t i, const char *at, size_t n)
{
    size_t h = p->ncols ? strlen(p->header) + 1 : 0;
    char *text = malloc(h + n + 1);
    if (!text)
        abort();
    if (h) {
        memcpy(text, p->header, h - 1);
        text[h - 1] = '\n';
    }
    memcpy(text + h, at, n);
    sm_points one;
    sm_error err;
    if (sm_points_csv_parse(text, h + n, 0, &one, &err) != SM_OK || one.n != 1 ||
        (!p->ncols && one.header) ||
        memcmp(one.xyz, p->xyz + (size_t)i * (size_t)p->dim, (size_t)p->dim * sizeof *one.xyz) != 0)
        abort();
    sm_points_release(&one);
    free(text);
}

static void check_lines(const char *data, size_t size, const sm_points *p)
{
    if (sm_points_csv_line(data, size, p->header_line, 0) == 0) { /* .mrk.json */
        if (strcmp(p->kind, "Slicer .mrk.json") != 0)
            abort();
        return;
    }
    long prev = 0;
    const char *at = data;
    long at_line = 1;
    for (int64_t i = 0; i < p->n && i < 2000; i++) {
        long line = sm_points_csv_line(data, size, p->header_line, i);
        if (line <= prev)
            abort();
        prev = line;
        for (; at_line < line; at_line++) {
            const char *nl = memchr(at, '\n', size - (size_t)(at - data));
            if (!nl)
                abort();
            at = nl + 1;
        }
        const char *nl = memchr(at, '\n', size - (size_t)(at - data));
        check_one(p, i, at, nl ? (size_t)(nl - at) : size - (size_t)(at - data));
    }
    if (sm_points_csv_line(data, size, p->header_line, p->n) != 0)
        abort();
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    sm_error err;
    sm_error_clear(&err);
    sm_points p;
    if (sm_points_csv_parse((const char *)data, size, 100000, &p, &err) != SM_OK) {
        if (err.msg[0] == '\0' || p.n != 0 || p.xyz || p.header || p.lines)
            abort();
        return 0;
    }
    if ((p.dim != 2 && p.dim != 3) || p.n < 1)
        abort();
    check_lines((const char *)data, size, &p);
    for (int64_t i = 0; i < p.n * p.dim; i++)
        if (!isfinite(p.xyz[i]))
            abort();
    sm_transform t;
    if (p.n <= SM_LANDMARKS_MAX &&
        sm_align_landmarks(p.dim, (int32_t)p.n, p.xyz, p.xyz, SM_ALIGN_SIMILARITY, &t, &err) == SM_OK)
        for (int i = 0; i < p.dim; i++) /* a set onto itself: the identity */
            if (!(fabs(t.a[i][i] - 1) < 1e-6))
                abort();
    uint8_t *inside = calloc((size_t)p.n, 1);
    if (!inside)
        abort();
    for (int64_t i = 0; i < p.n; i++)
        inside[i] = (uint8_t)(i & 1);
    size_t len, len2;
    char *text = sm_points_csv_format(&p, p.xyz, inside, 0, &len);
    if (!text)
        abort();
    /* the output is an input: the same points; and once read back, its
     * output is stable (the first may differ in blanks and the columns
     * it names) */
    sm_points q, r;
    if (sm_points_csv_parse(text, len, 0, &q, &err) != SM_OK || q.n != p.n || q.dim != p.dim ||
        memcmp(q.xyz, p.xyz, (size_t)p.n * (size_t)p.dim * sizeof *p.xyz) != 0)
        abort();
    char *again = sm_points_csv_format(&q, q.xyz, inside, 0, &len2);
    size_t len3;
    char *third = NULL;
    if (!again || sm_points_csv_parse(again, len2, 0, &r, &err) != SM_OK || r.n != p.n ||
        memcmp(r.xyz, p.xyz, (size_t)p.n * (size_t)p.dim * sizeof *p.xyz) != 0 ||
        !(third = sm_points_csv_format(&r, r.xyz, inside, 0, &len3)) || len3 != len2 ||
        memcmp(third, again, len2) != 0)
        abort();
    free(third);
    free(again);
    free(text);
    sm_points_release(&r);
    free(inside);
    sm_points_release(&q);
    sm_points_release(&p);
    return 0;
}
