/* The points CSV of `shapematch warp` and POST /v1/jobs/{id}/warp
 * (proto/sm_points_csv.c): any input is parsed or refused with a message;
 * an accepted one formats and parses back to the same points bit for bit
 * (%.17g), with the same dimension and header (x,y[,z] when it had
 * none); sm_points_csv_line names, for every point, a line that holds
 * exactly that point, the lines increasing. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "sm_points_csv.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* Each point's line (sm_points_csv_line), parsed alone, is that point. */
static void check_lines(const char *data, size_t size, const sm_points *p)
{
    long prev = 0;
    const char *at = data;
    long at_line = 1;
    for (int64_t i = 0; i < p->n && i < 2000; i++) {
        long line = sm_points_csv_line(data, size, p->header != NULL, i);
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
        size_t n = nl ? (size_t)(nl - at) : size - (size_t)(at - data);
        sm_points one;
        sm_error err;
        if (sm_points_csv_parse(at, n, 0, &one, &err) != SM_OK || one.n != 1 || one.header ||
            memcmp(one.xyz, p->xyz + (size_t)i * (size_t)p->dim,
                   (size_t)p->dim * sizeof *one.xyz) != 0)
            abort();
        sm_points_release(&one);
    }
    if (sm_points_csv_line(data, size, p->header != NULL, p->n) != 0)
        abort();
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    sm_error err;
    sm_error_clear(&err);
    sm_points p;
    if (sm_points_csv_parse((const char *)data, size, 100000, &p, &err) != SM_OK) {
        if (err.msg[0] == '\0' || p.n != 0 || p.xyz || p.header)
            abort();
        return 0;
    }
    if ((p.dim != 2 && p.dim != 3) || p.n < 1)
        abort();
    check_lines((const char *)data, size, &p);
    uint8_t *inside = calloc((size_t)p.n, 1);
    size_t len;
    char *text = inside ? sm_points_csv_format(&p, p.xyz, inside, &len) : NULL;
    if (!text)
        abort();
    /* without the inside column (",0" on every point line, ",inside" on
     * the header), the output is an input again */
    char *w = text;
    for (size_t i = 0; i < len; i++) {
        if (text[i] == '\n') {
            size_t cut = i == (size_t)(strchr(text, '\n') - text) ? strlen(",inside") : 2;
            w -= cut;
        }
        *w++ = text[i];
    }
    sm_points q;
    if (sm_points_csv_parse(text, (size_t)(w - text), 0, &q, &err) != SM_OK || q.n != p.n ||
        q.dim != p.dim || memcmp(q.xyz, p.xyz, (size_t)p.n * (size_t)p.dim * sizeof *p.xyz) != 0 ||
        !q.header || strcmp(q.header, p.header ? p.header : p.dim == 3 ? "x,y,z" : "x,y") != 0)
        abort();
    free(text);
    free(inside);
    sm_points_release(&q);
    sm_points_release(&p);
    return 0;
}
