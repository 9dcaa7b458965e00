/* Points as CSV, the format `shapematch warp --points` and
 * POST /v1/jobs/{id}/warp read and write (docs/warp.md):
 *
 *   x,y[,z]            an optional header line first (any first line that
 *   0.5,1.25,-3        is not all numbers), then one point per line: 2 or 3
 *   1e-3, 2, 7         comma-separated coordinates, the same count on
 *                      every line; spaces and tabs around a field are
 *                      allowed, CRLF line ends too, blank lines skipped
 *
 * The input is hostile (a daemon's request body): numbers are plain
 * decimals (digits, one '.', an exponent; no "nan", "inf", hex) parsed
 * whole and finite, a NUL byte, a too long field or a wrong field count
 * is an error; every error names its line ("line 7: expected 3
 * coordinates, found 2"), and so does a point refused by sm_points_warp's
 * strict mode.  The output keeps the points' order and adds
 * the `inside` column (1 or 0) after the coordinates, written with %.17g
 * (bitwise round trip); its header is the input's plus ",inside", or
 * "x,y[,z],inside". */
#ifndef SM_POINTS_CSV_H
#define SM_POINTS_CSV_H

#include <stddef.h>
#include <stdint.h>

#include "shapematch/sm_error.h"
#include "shapematch/sm_warp.h"

typedef struct sm_points {
    int dim;          /* 2 or 3 */
    int64_t n;
    double *xyz;      /* n * dim */
    char *header;     /* the header line without its end, or NULL */
} sm_points;

/* Parses len bytes of text (not NUL-terminated).  At most max_points
 * points (0: no bound beyond memory): more is SM_ERR_NOMEM "more than N
 * points".  No point at all is SM_ERR_FORMAT.  On error *out is zeroed
 * and nothing leaks. */
sm_status sm_points_csv_parse(const char *text, size_t len, int64_t max_points, sm_points *out,
                              sm_error *err);
void sm_points_release(sm_points *p);

/* The output text (malloc'd, NUL-terminated, *len without the NUL):
 * header, then one line per point of out (p->n * p->dim coordinates)
 * with inside[i].  NULL when out of memory. */
char *sm_points_csv_format(const sm_points *p, const double *out, const uint8_t *inside,
                           size_t *len);

/* The 1-based line of text (what sm_points_csv_parse read; header: it
 * had one) holding point index (0-based), counting the header and blank
 * lines as an editor does; 0 when there is no such point. */
long sm_points_csv_line(const char *text, size_t len, int header, int64_t index);

/* sm_warp_points on the points p, whose messages name where a point came
 * from: with strict, the first point outside is SM_ERR_INVALID "line L:
 * point (x, y[, z]) is outside the template|deformed mesh (distance D)",
 * L its line in text (len bytes, the CSV p was parsed from), or
 * "points[I]: ..." (0-based, a JSON array's index) when text is NULL.
 * inside (p->n flags) and noutside are required. */
sm_status sm_points_warp(const sm_warp *w, sm_warp_direction dir, int strict, const sm_points *p,
                         const char *text, size_t len, double *out, uint8_t *inside,
                         int64_t *noutside, sm_error *err);

#endif
