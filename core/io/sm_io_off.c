/* OFF surfaces (Geomview's Object File Format: "OFF" or a variant with
 * colours, normals or texture coordinates per vertex, COFF, NOFF, CNOFF,
 * STOFF..., then "nv nf ne", nv vertex lines "x y z ...", nf face lines
 * "n i1 ... in [colour]") and PLY2 (what Gmsh writes as ply2: "nv", "nf",
 * the vertices, then faces "3 i j k"; no keyword, recognised by its first
 * three lines).  Polygons are fan-triangulated; indices are 0-based; what
 * follows the values read on a vertex or face line (colours, normals) is
 * skipped.  Counts are checked against the bytes left before allocation
 * (a vertex line takes at least 6 bytes, a face line 8); '#' starts a
 * comment.  Errors give "file:line". */
#include <ctype.h>
#include <inttypes.h>
#include <stdlib.h>
#include <string.h>

#include "io/sm_io_cells.h"
#include "io/sm_io_formats.h"

/* The header keyword: [ST][C][N]OFF (4OFF and nOFF, other dimensions,
 * are not surfaces in 3D). */
static int off_keyword(const char *w, size_t n)
{
    if (n >= 2 && w[0] == 'S' && w[1] == 'T') {
        w += 2;
        n -= 2;
    }
    if (n >= 1 && *w == 'C') {
        w++;
        n--;
    }
    if (n >= 1 && *w == 'N') {
        w++;
        n--;
    }
    return n == 3 && memcmp(w, "OFF", 3) == 0;
}

/* Counts the numbers on the line starting at p (up to a newline or end). */
static int numbers_on_line(const char **pp, const char *end)
{
    const char *p = *pp;
    int n = 0;
    for (;;) {
        while (p < end && (*p == ' ' || *p == '\t' || *p == '\r'))
            p++;
        if (p == end || *p == '\n')
            break;
        char *e;
        strtod(p, &e); /* the peeked text is NUL-terminated */
        if (e == p || (e < end && !isspace((unsigned char)*e)))
            return -1;
        p = e;
        n++;
    }
    *pp = p < end ? p + 1 : p;
    return n;
}

int sm__off_detect(sm_reader *r, int *ply2)
{
    char head[512];
    size_t got = 0;
    *ply2 = 0;
    if (sm__reader_peek(r, head, sizeof head - 1, &got) != SM_OK || !got)
        return 0;
    head[got] = '\0';
    const char *p = head, *end = head + got;
    while (p < end && isspace((unsigned char)*p))
        p++;
    size_t n = strcspn(p, " \t\r\n#");
    if (off_keyword(p, n))
        return 1;
    /* PLY2: one count, one count, then three coordinates */
    const char *q = head;
    if (numbers_on_line(&q, end) != 1 || numbers_on_line(&q, end) != 1 ||
        numbers_on_line(&q, end) != 3)
        return 0;
    *ply2 = 1;
    return 1;
}

/* Skips what is left of the current line (colours, normals). */
static sm_status skip_rest(sm_reader *r)
{
    char rest[16];
    return sm__reader_line(r, rest, sizeof rest);
}

static sm_status count(sm_reader *r, sm_error *err, const char *what, uint64_t least,
                       int64_t *n)
{
    sm_status st = sm__reader_int(r, 0, SM_MAX_ENTITIES, n);
    if (st != SM_OK)
        return sm__reader_fail_line(r, err, st, "expected the %s count, %s", what, r->why);
    if ((uint64_t)*n > sm__reader_max_remaining(r) / least)
        return sm__reader_fail_line(r, err, SM_ERR_FORMAT, "%s count %" PRId64 " does not fit "
                                    "in the file", what, *n);
    return SM_OK;
}

static sm_status read_faces(sm_reader *r, sm_msh_data *d, int64_t nf, int64_t *poly,
                            sm_error *err)
{
    for (int64_t f = 0; f < nf; f++) {
        int64_t n;
        sm_status st = sm__reader_int(r, 0, SM_CELL_MAX_NODES, &n);
        if (st != SM_OK)
            return sm__reader_fail_line(r, err, st, "face %" PRId64 ": expected its vertex "
                                        "count (at most %d), %s", f + 1, SM_CELL_MAX_NODES,
                                        r->why);
        for (int64_t k = 0; k < n; k++)
            if ((st = sm__reader_int(r, INT32_MIN, INT32_MAX, &poly[k])) != SM_OK)
                return sm__reader_fail_line(r, err, st, "face %" PRId64 ": expected a vertex "
                                            "index, %s", f + 1, r->why);
        if ((st = sm__cells_add_polygon(r, d, n, poly, f)) != SM_OK)
            return sm__reader_fail_line(r, err, st, "%s", r->why);
        if ((st = skip_rest(r)) != SM_OK)
            return sm__reader_fail_line(r, err, st, "%s", r->why);
    }
    return SM_OK;
}

static sm_status read_off(sm_reader *r, sm_msh_data *d, int ply2, int64_t *poly, sm_error *err)
{
    int found;
    sm_status st;
    int64_t nv, nf, ne;
    if (!ply2 && (st = sm__reader_token(r, &found)) != SM_OK)
        return sm__reader_fail_line(r, err, st, "%s", r->why);
    if ((st = count(r, err, "vertex", 6, &nv)) != SM_OK ||
        (st = count(r, err, "face", 8, &nf)) != SM_OK)
        return st;
    if (!ply2 && (st = sm__reader_int(r, 0, INT64_MAX, &ne)) != SM_OK)
        return sm__reader_fail_line(r, err, st, "expected the edge count, %s", r->why);
    if ((st = sm__cells_points(r, d, nv, err)) != SM_OK)
        return sm__reader_fail_line(r, err, st, "%s", r->why);
    for (int64_t i = 0; i < nv; i++) {
        for (int k = 0; k < 3; k++)
            if ((st = sm__reader_real(r, &d->coords[3 * i + k])) != SM_OK)
                return sm__reader_fail_line(r, err, st, "vertex %" PRId64 ": expected a "
                                            "coordinate, %s", i + 1, r->why);
        if (!ply2 && (st = skip_rest(r)) != SM_OK)
            return sm__reader_fail_line(r, err, st, "%s", r->why);
    }
    if ((st = read_faces(r, d, nf, poly, err)) != SM_OK)
        return st;
    if (d->triangles.count == 0)
        return sm_error_set(err, SM_ERR_FORMAT, "%s: %s without faces", r->path,
                            ply2 ? "PLY2" : "OFF");
    return SM_OK;
}

sm_status sm__off_read(sm_reader *r, sm_surface **out, sm_error *err)
{
    *out = NULL;
    int ply2;
    sm__off_detect(r, &ply2);
    sm_msh_data d;
    sm__cells_init(&d);
    int64_t *poly = malloc(SM_CELL_MAX_NODES * sizeof *poly);
    sm_status st = poly ? read_off(r, &d, ply2, poly, err)
                        : sm_error_set(err, SM_ERR_NOMEM, "%s: out of memory", r->path);
    if (st == SM_OK) {
        sm__cells_finish(&d, NULL, 0);
        st = sm__msh_surface(r->path, &d, out, err);
    }
    if (st == SM_OK && (st = sm__surface_weld(*out, err)) != SM_OK) {
        sm_surface_free(*out);
        *out = NULL;
    }
    free(poly);
    sm__msh_data_free(&d);
    return st;
}
