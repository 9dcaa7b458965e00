/* Point lists: the points of `shapematch warp --points` and POST
 * /v1/jobs/{id}/warp, and the landmarks of --landmarks and the
 * template_landmarks/target_landmarks parts (docs/warp.md).  One reader
 * for three kinds of file, told apart by their content:
 *
 *   CSV        x,y[,z]            an optional header line first (a first
 *              0.5,1.25,-3        line whose first field is no number), then one
 *              1e-3, 2, 7         point per line; '#' lines are comments;
 *                                 spaces and tabs around a field, CRLF line
 *                                 ends and blank lines are allowed.  With a
 *              label,x,y,z        header naming columns x and y (and z, any
 *              "F-1",1,2,3        case), those are the coordinates and the
 *                                 other columns (an id, a label: what 3D
 *                                 Slicer and most landmark tools write) pass
 *                                 through; fields may be "quoted".  Without
 *                                 such names every field is a coordinate (2
 *                                 or 3).
 *   Slicer     .fcsv: "# Markups fiducial file", "# CoordinateSystem = LPS|
 *   markups    RAS|0|1" (0: RAS), "# columns = id,x,y,z,...", then CSV;
 *              .mrk.json: {"markups": [{"coordinateSystem": "LPS",
 *              "controlPoints": [{"label": "F-1", "position": [x, y, z]},
 *              ...]}, ...]} (jansson), read as the CSV "label,x,y,z".
 *
 * The input is hostile (a daemon's request body): numbers are plain
 * decimals (digits, one '.', an exponent; no "nan", "inf", hex) parsed
 * whole and finite, a NUL byte, a too long field or a wrong field count
 * is an error; every error names its line ("line 7: expected 3
 * coordinates, found 2"), and so does a point refused by sm_points_warp's
 * strict mode.  The output keeps the points' order and every input column
 * in its place, the coordinates replaced (written with %.17g: bitwise
 * round trip), and adds the `inside` column (1 or 0) at the end; its
 * header is the input's plus ",inside" (or "x,y[,z],inside" when it had
 * none, or one of another field count).  An input
 * column named inside (a warp's own output fed back) is dropped for the
 * new one, so an output reads as an input. */
#ifndef SM_POINTS_CSV_H
#define SM_POINTS_CSV_H

#include <stddef.h>
#include <stdint.h>

#include "shapematch/sm_error.h"
#include "shapematch/sm_warp.h"

/* The frame a file states its points in (Slicer's markups do). */
typedef enum sm_points_frame {
    SM_POINTS_FRAME_UNSTATED = 0,
    SM_POINTS_FRAME_LPS,
    SM_POINTS_FRAME_RAS
} sm_points_frame;

typedef struct sm_points {
    int dim;          /* 2 or 3 */
    int64_t n;
    double *xyz;      /* n * dim */
    char *header;     /* the header (a CSV's first line, an .fcsv's
                       * columns) without its end, or NULL */
    int header_line;  /* 1: the header is a line before the points (not a
                       * comment): sm_points_csv_line's header */
    sm_points_frame frame;
    const char *kind; /* "CSV", "Slicer .fcsv", "Slicer .mrk.json" */
    /* with columns besides the coordinates: each point's line as read
     * (lines + line_at[i] .. line_at[i + 1]), to write them back */
    int ncols, col[3], inside_col; /* inside_col -1: none */
    char *lines;
    int64_t *line_at;
} sm_points;

/* Parses len bytes of text (not NUL-terminated).  At most max_points
 * points (0: no bound beyond memory): more is SM_ERR_NOMEM "more than N
 * points".  No point at all is SM_ERR_FORMAT.  On error *out is zeroed
 * and nothing leaks. */
sm_status sm_points_csv_parse(const char *text, size_t len, int64_t max_points, sm_points *out,
                              sm_error *err);
void sm_points_release(sm_points *p);

/* Puts the points in frame want (LPS or RAS: x and y negated between
 * them, 3D only) when the file stated the other; nothing otherwise. */
void sm_points_to_frame(sm_points *p, sm_points_frame want);

/* A point list's file (at most max_bytes; 0: 64 MiB) parsed as above,
 * messages prefixed with the path: the landmarks' reader. */
sm_status sm_points_read_file(const char *path, size_t max_bytes, int64_t max_points,
                              sm_points *out, sm_error *err);

/* The output text (malloc'd, NUL-terminated, *len without the NUL):
 * header, then one line per point of out (p->n * p->dim coordinates)
 * with inside[i]; with skip_outside, the points whose inside is 0 are
 * left out.  NULL when out of memory. */
char *sm_points_csv_format(const sm_points *p, const double *out, const uint8_t *inside,
                           int skip_outside, size_t *len);

/* The 1-based line of text (what sm_points_csv_parse read; header: its
 * header_line) holding point index (0-based), counting the header, blank
 * and comment lines as an editor does; 0 when there is no such point (or
 * the text is an .mrk.json, which has no lines of points). */
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
