/* STL surfaces, ASCII and binary (see sm_io_formats.h for the detection).
 * Binary: an 80-byte header (ignored, it may start with "solid"), a
 * little-endian uint32 facet count, then 50 bytes per facet (normal,
 * three vertices as float32, a 16-bit attribute).  ASCII: "solid [name]",
 * then per facet "facet normal nx ny nz / outer loop / vertex x y z (x3) /
 * endloop / endfacet", then "endsolid [name]"; several solids may follow
 * each other.  Normals are ignored (orientation comes from the vertex
 * order); vertices are welded afterwards. */
#include <inttypes.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "shapematch/sm_mesh.h"
#include "io/sm_io_formats.h"

#define STL_HEADER 84u
#define STL_RECORD 50u

static int looks_ascii(sm_reader *r)
{
    unsigned char head[512];
    size_t got = 0;
    if (sm__reader_peek(r, head, sizeof head, &got) != SM_OK || got < 6)
        return 0;
    size_t i = 0;
    while (i < got && (head[i] == ' ' || head[i] == '\t' || head[i] == '\r' || head[i] == '\n'))
        i++;
    if (got - i < 5 || memcmp(head + i, "solid", 5) != 0)
        return 0;
    for (size_t k = 0; k < got; k++)
        if (head[k] >= 127 || (head[k] < 32 && head[k] != '\n' && head[k] != '\r' &&
                               head[k] != '\t'))
            return 0;
    return memmem(head, got, "facet", 5) != NULL || memmem(head, got, "endsolid", 8) != NULL;
}

/* The facet count at byte 80 when the plain file is exactly that long. */
static int binary_by_size(sm_reader *r)
{
    unsigned char head[STL_HEADER];
    size_t got = 0;
    if (r->compressed || sm__reader_peek(r, head, sizeof head, &got) != SM_OK || got < STL_HEADER)
        return 0;
    uint64_t n = (uint64_t)head[80] | (uint64_t)head[81] << 8 | (uint64_t)head[82] << 16 |
                 (uint64_t)head[83] << 24;
    return r->file_size == STL_HEADER + STL_RECORD * n;
}

int sm__stl_detect(sm_reader *r)
{
    return binary_by_size(r) || looks_ascii(r);
}

/* ---- binary ---- */

static float le_f32(const unsigned char *p)
{
    uint32_t u = (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 |
                 (uint32_t)p[3] << 24;
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}

static sm_status read_binary(sm_reader *r, sm_surface **out, sm_error *err)
{
    unsigned char head[STL_HEADER];
    sm_status st = sm__reader_bytes(r, head, sizeof head);
    if (st != SM_OK)
        return sm__reader_fail_byte(r, err, SM_ERR_FORMAT, 0, "binary STL header: %s", r->why);
    uint64_t n = (uint64_t)head[80] | (uint64_t)head[81] << 8 | (uint64_t)head[82] << 16 |
                 (uint64_t)head[83] << 24;
    if (n == 0)
        return sm__reader_fail_byte(r, err, SM_ERR_FORMAT, 80, "binary STL with 0 facets");
    if (n > SM_MAX_ENTITIES / 3 || n * STL_RECORD > sm__reader_max_remaining(r))
        return sm__reader_fail_byte(r, err, SM_ERR_FORMAT, 80,
                                   "binary STL facet count %" PRIu64 " does not fit in the "
                                   "file (%" PRIu64 " bytes left, %u per facet)",
                                   n, sm__reader_max_remaining(r), STL_RECORD);
    if ((st = sm__reader_limit_count(r, err, (int64_t)n, 0, "facets")) != SM_OK)
        return st;
    sm_surface *s;
    if ((st = sm_surface_alloc(&s, 3, (int32_t)(3 * n), (int32_t)n, err)) != SM_OK)
        return st;
    for (uint64_t f = 0; f < n; f++) {
        unsigned char rec[STL_RECORD];
        uint64_t at = sm__reader_offset(r);
        if (sm__reader_bytes(r, rec, sizeof rec) != SM_OK) {
            sm_surface_free(s);
            return sm__reader_fail_byte(r, err, SM_ERR_FORMAT, at,
                                       "binary STL facet %" PRIu64 " of %" PRIu64 ": %s",
                                       f + 1, n, r->why);
        }
        for (int k = 0; k < 9; k++) {
            double v = le_f32(rec + 12 + 4 * k);
            if (!isfinite(v)) {
                sm_surface_free(s);
                return sm__reader_fail_byte(r, err, SM_ERR_FORMAT, at + 12 + 4 * (uint64_t)k,
                                           "binary STL facet %" PRIu64 ": coordinate is not "
                                           "a finite number", f + 1);
            }
            s->coords[9 * f + (uint64_t)k] = v;
        }
        for (int k = 0; k < 3; k++)
            s->facets[3 * f + (uint64_t)k] = (int32_t)(3 * f + (uint64_t)k);
    }
    unsigned char extra;
    size_t got = 0;
    if (sm__reader_peek(r, &extra, 1, &got) == SM_OK && got) {
        uint64_t at = sm__reader_offset(r);
        sm_surface_free(s);
        return sm__reader_fail_byte(r, err, SM_ERR_FORMAT, at,
                                   "binary STL has bytes after its %" PRIu64 " facets (wrong "
                                   "facet count?)", n);
    }
    *out = s;
    return SM_OK;
}

/* ---- ASCII ---- */

typedef struct stl_grow {
    double *x;     /* 9 per facet */
    int64_t n, cap;
} stl_grow;

static sm_status expect_word(sm_reader *r, const char *want, sm_error *err)
{
    int found;
    sm_status st = sm__reader_token(r, &found);
    if (st != SM_OK)
        return sm__reader_fail_line(r, err, st, "expected '%s', %s", want, r->why);
    if (!found || strcmp(r->token, want) != 0) {
        char q[64];
        sm__quote_token(found ? r->token : "end of file", q, sizeof q);
        return sm__reader_fail_line(r, err, SM_ERR_FORMAT, "expected '%s', found %s", want, q);
    }
    return SM_OK;
}

static sm_status read_facet(sm_reader *r, stl_grow *g, sm_error *err)
{
    sm_status st = expect_word(r, "normal", err);
    double v;
    for (int k = 0; st == SM_OK && k < 3; k++)
        if ((st = sm__reader_real(r, &v)) != SM_OK)
            return sm__reader_fail_line(r, err, st, "expected a facet normal, %s", r->why);
    if (st != SM_OK || (st = expect_word(r, "outer", err)) != SM_OK ||
        (st = expect_word(r, "loop", err)) != SM_OK ||
        (st = sm__reader_limit_count(r, err, g->n + 1, 0, "facets")) != SM_OK)
        return st;
    if (g->n == g->cap) {
        int64_t cap = g->cap ? 2 * g->cap : 64; /* small inputs, small buffers */
        if (cap > SM_MAX_ENTITIES / 3)
            return sm__reader_fail_line(r, err, SM_ERR_FORMAT, "too many facets");
        double *x = realloc(g->x, (size_t)cap * 9 * sizeof *x);
        if (!x)
            return sm_error_set(err, SM_ERR_NOMEM, "%s: out of memory", r->path);
        g->x = x;
        g->cap = cap;
    }
    for (int k = 0; k < 3; k++) {
        if ((st = expect_word(r, "vertex", err)) != SM_OK)
            return st;
        for (int j = 0; j < 3; j++)
            if ((st = sm__reader_real(r, &g->x[9 * g->n + 3 * k + j])) != SM_OK)
                return sm__reader_fail_line(r, err, st, "expected a vertex coordinate, %s",
                                           r->why);
    }
    g->n++;
    if ((st = expect_word(r, "endloop", err)) != SM_OK)
        return st;
    return expect_word(r, "endfacet", err);
}

/* Skips the rest of the "solid" / "endsolid" line (the optional name). */
static sm_status skip_line(sm_reader *r)
{
    unsigned char c;
    while (sm__reader_bytes(r, &c, 1) == SM_OK) {
        if (c == '\n') {
            r->line++;
            break;
        }
    }
    return r->stream_status;
}

static sm_status read_ascii_facets(sm_reader *r, stl_grow *g, sm_error *err)
{
    int in_solid = 0;
    for (;;) {
        int found;
        sm_status st = sm__reader_token(r, &found);
        if (st != SM_OK)
            return sm__reader_fail_line(r, err, st, "%s", r->why);
        if (!found)
            break;
        if (strcmp(r->token, "solid") == 0 && !in_solid) {
            in_solid = 1;
            st = skip_line(r);
        } else if (strcmp(r->token, "endsolid") == 0 && in_solid) {
            in_solid = 0;
            st = skip_line(r);
        } else if (strcmp(r->token, "facet") == 0 && in_solid) {
            st = read_facet(r, g, err);
        } else {
            char q[64];
            sm__quote_token(r->token, q, sizeof q);
            return sm__reader_fail_line(r, err, SM_ERR_FORMAT, "expected '%s', found %s",
                                       in_solid ? "facet' or 'endsolid" : "solid", q);
        }
        if (st != SM_OK)
            return st;
    }
    if (in_solid)
        return sm__reader_fail_line(r, err, SM_ERR_FORMAT, "missing 'endsolid' (truncated file?)");
    if (g->n == 0)
        return sm_error_set(err, SM_ERR_FORMAT, "%s: ASCII STL without facets", r->path);
    return SM_OK;
}

static sm_status read_ascii(sm_reader *r, sm_surface **out, sm_error *err)
{
    stl_grow g = {NULL, 0, 0};
    sm_status st = read_ascii_facets(r, &g, err);
    sm_surface *s = NULL;
    if (st == SM_OK && (st = sm_surface_alloc(&s, 3, (int32_t)(3 * g.n), (int32_t)g.n, err)) ==
                           SM_OK) {
        memcpy(s->coords, g.x, (size_t)g.n * 9 * sizeof(double));
        for (int32_t i = 0; i < 3 * (int32_t)g.n; i++)
            s->facets[i] = i;
        *out = s;
    }
    free(g.x);
    return st;
}

sm_status sm__stl_read(sm_reader *r, sm_surface **out, sm_error *err)
{
    *out = NULL;
    sm_status st = looks_ascii(r) && !binary_by_size(r) ? read_ascii(r, out, err)
                                                         : read_binary(r, out, err);
    if (st == SM_OK && (st = sm__surface_weld(*out, err)) != SM_OK) {
        sm_surface_free(*out);
        *out = NULL;
    }
    return st;
}
