/* Medit meshes: .mesh (ASCII) and .meshb (libMeshb binary, versions 1-4),
 * plain or gzip; reading (sm_io_medit_write.c has the writer), as a
 * volume mesh or as a surface (sm_io.c's format table), from a
 * reader the dispatcher opened.  The reader collects the sections it needs (Dimension,
 * Vertices, Edges, Triangles, Tetrahedra) into temporary arrays, since
 * whether Triangles are elements or facets is only known at the end
 * (a "Dimension 3" planar file is a 2D mesh), then builds the sm_mesh. */
#include "io/sm_io_formats.h"

#include <inttypes.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "io/sm_medit_common.h"
#include "io/sm_reader.h"
#include "shapematch/sm_io.h"
#include "sm_alloc.h"

/* One block of simplices (or edges) as read from the file. */
typedef struct idx_block {
    int present;
    int64_t count;
    int nidx;            /* vertex indices per record */
    int32_t *idx;        /* count * nidx */
    int32_t *refs;       /* count */
    int zero_based;      /* indices validated and converted already */
    long line;           /* where the section started (ASCII) */
    uint64_t offset;     /* where the section started (binary) */
} idx_block;

typedef struct medit_in {
    sm_reader *r;        /* opened by the dispatcher (sm_io.c) */
    sm_error *err;
    int binary;
    sm_meshb_layout lay;
    int have_version;
    int dim;             /* the file's Dimension, 0 until read */
    int have_vertices;
    int64_t nverts;
    double *coords;      /* nverts * dim */
    int32_t *vert_refs;
    idx_block edges, triangles, tetrahedra;
} medit_in;

static void medit_in_free(medit_in *c)
{
    free(c->coords);
    free(c->vert_refs);
    idx_block *blocks[] = {&c->edges, &c->triangles, &c->tetrahedra};
    for (int i = 0; i < 3; i++) {
        free(blocks[i]->idx);
        free(blocks[i]->refs);
    }
}

/* ------------------------------------------------------------------ */
/* ASCII                                                               */
/* ------------------------------------------------------------------ */

enum kw_kind {
    KIND_VERSION, KIND_DIMENSION, KIND_VERTICES, KIND_BLOCK, KIND_END,
    KIND_SKIP_INTS,      /* count, then nints integers per record */
    KIND_SKIP_VECTORS,   /* count, then Dimension reals per record */
    KIND_SKIP_REAL,      /* one real, no count */
    KIND_SKIP_STRING,    /* one string, no count */
    KIND_UNSUPPORTED,    /* non-simplicial elements */
    KIND_SOLUTION
};

typedef struct keyword {
    const char *name;
    int kind;
    int nints;
} keyword;

static const keyword mesh_keywords[] = {
    {"MeshVersionFormatted", KIND_VERSION, 0},
    {"Dimension", KIND_DIMENSION, 0},
    {"Vertices", KIND_VERTICES, 0},
    {"Edges", KIND_BLOCK, 2},
    {"Triangles", KIND_BLOCK, 3},
    {"Tetrahedra", KIND_BLOCK, 4},
    {"End", KIND_END, 0},
    {"Quadrilaterals", KIND_UNSUPPORTED, 4},
    {"Prisms", KIND_UNSUPPORTED, 6},
    {"Hexahedra", KIND_UNSUPPORTED, 8},
    {"Pyramids", KIND_UNSUPPORTED, 5},
    {"Corners", KIND_SKIP_INTS, 1},
    {"Ridges", KIND_SKIP_INTS, 1},
    {"RequiredVertices", KIND_SKIP_INTS, 1},
    {"RequiredEdges", KIND_SKIP_INTS, 1},
    {"RequiredTriangles", KIND_SKIP_INTS, 1},
    {"RequiredTetrahedra", KIND_SKIP_INTS, 1},
    {"RequiredQuadrilaterals", KIND_SKIP_INTS, 1},
    {"TangentAtEdgeVertices", KIND_SKIP_INTS, 3},
    {"NormalAtVertices", KIND_SKIP_INTS, 2},
    {"NormalAtTriangleVertices", KIND_SKIP_INTS, 3},
    {"NormalAtQuadrilateralVertices", KIND_SKIP_INTS, 4},
    {"TangentAtVertices", KIND_SKIP_INTS, 2},
    {"Normals", KIND_SKIP_VECTORS, 0},
    {"Tangents", KIND_SKIP_VECTORS, 0},
    {"AngleOfCornerBound", KIND_SKIP_REAL, 0},
    {"Identifier", KIND_SKIP_STRING, 0},
    {"Geometry", KIND_SKIP_STRING, 0},
    {"SolAtVertices", KIND_SOLUTION, 0},
};

static const keyword *find_keyword(const char *tok)
{
    for (size_t i = 0; i < sizeof mesh_keywords / sizeof mesh_keywords[0]; i++)
        if (strcasecmp(tok, mesh_keywords[i].name) == 0)
            return &mesh_keywords[i];
    return NULL;
}

static idx_block *block_of(medit_in *c, int nints)
{
    return nints == 2 ? &c->edges : nints == 3 ? &c->triangles : &c->tetrahedra;
}

static const char *block_name(int nints)
{
    return nints == 2 ? "Edges" : nints == 3 ? "Triangles" : "Tetrahedra";
}

static sm_status alloc_block(medit_in *c, idx_block *b, int nidx, int64_t count)
{
    b->present = 1;
    b->count = count;
    b->nidx = nidx;
    b->idx = sm__alloc_huge((size_t)count * (size_t)nidx * sizeof(int32_t));
    b->refs = sm__alloc_huge((size_t)count * sizeof(int32_t));
    if (!b->idx || !b->refs)
        return sm_error_set(c->err, SM_ERR_NOMEM, "%s: out of memory for %lld records",
                            c->r->path, (long long)count);
    return SM_OK;
}

static sm_status alloc_vertices(medit_in *c, int64_t count)
{
    c->have_vertices = 1;
    c->nverts = count;
    c->coords = sm__alloc_huge((size_t)count * (size_t)c->dim * sizeof(double));
    c->vert_refs = sm__alloc_huge((size_t)count * sizeof(int32_t));
    if (!c->coords || !c->vert_refs)
        return sm_error_set(c->err, SM_ERR_NOMEM, "%s: out of memory for %lld vertices",
                            c->r->path, (long long)count);
    return SM_OK;
}

static sm_status ascii_count(medit_in *c, const char *section, int ntokens, int64_t *n)
{
    sm_reader *r = c->r;
    sm_status st = sm__reader_int(r, INT64_MIN, INT64_MAX, n);
    if (st != SM_OK)
        return sm__reader_fail_line(r, c->err, st, "expected the number of %s, %s", section,
                                   r->why);
    return sm__medit_check_count(r, 0, section, *n, 2 * (uint64_t)ntokens, 0, c->err);
}

static sm_status ascii_vertices(medit_in *c)
{
    sm_reader *r = c->r;
    int64_t n;
    sm_status st = ascii_count(c, "Vertices", c->dim + 1, &n);
    if (st != SM_OK)
        return st;
    if ((st = alloc_vertices(c, n)) != SM_OK)
        return st;
    for (int64_t i = 0; i < n; i++) {
        for (int j = 0; j < c->dim; j++) {
            st = sm__reader_real(r, &c->coords[i * c->dim + j]);
            if (st != SM_OK)
                return sm__reader_fail_line(r, c->err, st,
                                           "expected %d coordinates and a reference in Vertices "
                                           "record %lld of %lld, %s",
                                           c->dim, (long long)i + 1, (long long)n, r->why);
        }
        int64_t ref;
        st = sm__reader_int(r, INT32_MIN, INT32_MAX, &ref);
        if (st != SM_OK)
            return sm__reader_fail_line(r, c->err, st,
                                       "expected %d coordinates and a reference in Vertices "
                                       "record %lld of %lld, %s",
                                       c->dim, (long long)i + 1, (long long)n, r->why);
        c->vert_refs[i] = (int32_t)ref;
    }
    return SM_OK;
}

static sm_status ascii_block(medit_in *c, int nidx)
{
    sm_reader *r = c->r;
    const char *name = block_name(nidx);
    idx_block *b = block_of(c, nidx);
    b->line = r->token_line;
    int64_t n;
    sm_status st = ascii_count(c, name, nidx + 1, &n);
    if (st != SM_OK)
        return st;
    if ((st = alloc_block(c, b, nidx, n)) != SM_OK)
        return st;
    /* Indices can be checked at once when Vertices came first (as every
     * writer does); otherwise at the end. */
    b->zero_based = c->have_vertices;
    int64_t hi = c->have_vertices ? c->nverts : INT32_MAX;
    for (int64_t i = 0; i < n; i++) {
        for (int j = 0; j <= nidx; j++) {
            int64_t v;
            st = sm__reader_int(r, INT64_MIN, INT64_MAX, &v);
            if (st != SM_OK)
                return sm__reader_fail_line(r, c->err, st,
                                           "expected %d vertex indices and a reference in %s "
                                           "record %lld of %lld, %s",
                                           nidx, name, (long long)i + 1, (long long)n, r->why);
            if (j == nidx) {
                if (v < INT32_MIN || v > INT32_MAX)
                    return sm__reader_fail_line(r, c->err, SM_ERR_FORMAT,
                                               "reference %lld out of the 32-bit range in %s "
                                               "record %lld of %lld",
                                               (long long)v, name, (long long)i + 1,
                                               (long long)n);
                b->refs[i] = (int32_t)v;
            } else {
                if (v < 1 || v > hi)
                    return sm__reader_fail_line(r, c->err, SM_ERR_FORMAT,
                                               "vertex index %lld out of range [1, %lld] in %s "
                                               "record %lld of %lld",
                                               (long long)v, (long long)hi, name,
                                               (long long)i + 1, (long long)n);
                b->idx[i * nidx + j] = (int32_t)(b->zero_based ? v - 1 : v);
            }
        }
    }
    return SM_OK;
}

static sm_status ascii_skip(medit_in *c, const keyword *kw)
{
    sm_reader *r = c->r;
    sm_status st;
    if (kw->kind == KIND_SKIP_STRING) {
        st = sm__reader_skip_string(r);
        if (st != SM_OK)
            return sm__reader_fail_line(r, c->err, st, "expected a string after %s, %s", kw->name,
                                       r->why);
        return SM_OK;
    }
    if (kw->kind == KIND_SKIP_REAL) {
        double x;
        st = sm__reader_real(r, &x);
        if (st != SM_OK)
            return sm__reader_fail_line(r, c->err, st, "expected a number after %s, %s", kw->name,
                                       r->why);
        return SM_OK;
    }
    int vectors = kw->kind == KIND_SKIP_VECTORS;
    if (vectors && !c->dim)
        return sm__reader_fail_line(r, c->err, SM_ERR_FORMAT, "%s before Dimension", kw->name);
    int per = vectors ? c->dim : kw->nints;
    int64_t n;
    if ((st = ascii_count(c, kw->name, per, &n)) != SM_OK)
        return st;
    for (int64_t i = 0; i < n; i++) {
        for (int j = 0; j < per; j++) {
            double x;
            int64_t v;
            st = vectors ? sm__reader_real(r, &x) : sm__reader_int(r, INT64_MIN, INT64_MAX, &v);
            if (st != SM_OK)
                return sm__reader_fail_line(r, c->err, st,
                                           "expected %d %s in %s record %lld of %lld, %s", per,
                                           vectors ? "numbers" : "integers", kw->name,
                                           (long long)i + 1, (long long)n, r->why);
        }
    }
    return SM_OK;
}

static int looks_numeric(const char *tok)
{
    const char *s = tok;
    if (*s == '+' || *s == '-')
        s++;
    if (*s == '.')
        s++;
    return *s >= '0' && *s <= '9';
}

static sm_status read_ascii(medit_in *c)
{
    sm_reader *r = c->r;
    for (;;) {
        int found;
        sm_status st = sm__reader_token(r, &found);
        if (st != SM_OK)
            return sm__reader_fail_line(r, c->err, st, "%s", r->why);
        if (!found)
            return SM_OK;
        const keyword *kw = find_keyword(r->token);
        if (!kw) {
            char q[64];
            sm__quote_token(r->token, q, sizeof q);
            if (looks_numeric(r->token))
                return sm__reader_fail_line(r, c->err, SM_ERR_FORMAT,
                                           "found the number %s where a keyword was expected "
                                           "(more records than the section count says?)",
                                           q);
            if (!c->have_version && !c->dim && !c->have_vertices)
                return sm__reader_fail_line(r, c->err, SM_ERR_FORMAT,
                                           "unknown format: the file starts with %s; meshes "
                                           "are read as " SM_MESH_FORMATS, q);
            return sm__reader_fail_line(r, c->err, SM_ERR_FORMAT, "unknown keyword %s", q);
        }
        int64_t v;
        switch (kw->kind) {
        case KIND_VERSION:
            if (c->have_version)
                return sm__reader_fail_line(r, c->err, SM_ERR_FORMAT,
                                           "duplicate MeshVersionFormatted");
            st = sm__reader_int(r, INT64_MIN, INT64_MAX, &v);
            if (st != SM_OK)
                return sm__reader_fail_line(r, c->err, st,
                                           "expected a version after MeshVersionFormatted, %s",
                                           r->why);
            if (v < 1 || v > 4)
                return sm__reader_fail_line(r, c->err, SM_ERR_FORMAT,
                                           "bad MeshVersionFormatted %lld (expected 1 to 4)",
                                           (long long)v);
            c->have_version = 1;
            break;
        case KIND_DIMENSION:
            if (c->dim)
                return sm__reader_fail_line(r, c->err, SM_ERR_FORMAT, "duplicate Dimension");
            st = sm__reader_int(r, INT64_MIN, INT64_MAX, &v);
            if (st != SM_OK)
                return sm__reader_fail_line(r, c->err, st, "expected a value after Dimension, %s",
                                           r->why);
            if (v != 2 && v != 3)
                return sm__reader_fail_line(r, c->err, SM_ERR_FORMAT,
                                           "Dimension %lld is not supported (expected 2 or 3)",
                                           (long long)v);
            c->dim = (int)v;
            break;
        case KIND_VERTICES:
            if (!c->dim)
                return sm__reader_fail_line(r, c->err, SM_ERR_FORMAT,
                                           "Vertices before Dimension (missing Dimension)");
            if (c->have_vertices)
                return sm__reader_fail_line(r, c->err, SM_ERR_FORMAT, "duplicate Vertices section");
            if ((st = ascii_vertices(c)) != SM_OK)
                return st;
            break;
        case KIND_BLOCK:
            if (!c->dim)
                return sm__reader_fail_line(r, c->err, SM_ERR_FORMAT,
                                           "%s before Dimension (missing Dimension)", kw->name);
            if (block_of(c, kw->nints)->present)
                return sm__reader_fail_line(r, c->err, SM_ERR_FORMAT, "duplicate %s section",
                                           kw->name);
            if (kw->nints == 4 && c->dim == 2)
                return sm__reader_fail_line(r, c->err, SM_ERR_FORMAT,
                                           "Tetrahedra in a Dimension 2 mesh");
            if ((st = ascii_block(c, kw->nints)) != SM_OK)
                return st;
            break;
        case KIND_END:
            return SM_OK;
        case KIND_UNSUPPORTED:
            return sm__reader_fail_line(r, c->err, SM_ERR_FORMAT,
                                       "%s are not supported, shapematch needs simplices "
                                       "(triangles or tetrahedra)",
                                       kw->name);
        case KIND_SOLUTION:
            return sm__reader_fail_line(r, c->err, SM_ERR_FORMAT,
                                       "SolAtVertices in a mesh file (is this a .sol file?)");
        default:
            if ((st = ascii_skip(c, kw)) != SM_OK)
                return st;
            break;
        }
    }
}

/* ------------------------------------------------------------------ */
/* binary                                                              */
/* ------------------------------------------------------------------ */

static int64_t decode_int(const medit_in *c, const unsigned char *p)
{
    if (c->lay.int_size == 8) {
        uint64_t u;
        memcpy(&u, p, 8);
        if (c->r->swap)
            u = sm__bswap64(u);
        return (int64_t)u;
    }
    uint32_t u;
    memcpy(&u, p, 4);
    if (c->r->swap)
        u = sm__bswap32(u);
    return (int32_t)u;
}

static double decode_real(const medit_in *c, const unsigned char *p)
{
    if (c->lay.real_size == 4) {
        uint32_t u;
        float f;
        memcpy(&u, p, 4);
        if (c->r->swap)
            u = sm__bswap32(u);
        memcpy(&f, &u, 4);
        return f;
    }
    uint64_t u;
    double d;
    memcpy(&u, p, 8);
    if (c->r->swap)
        u = sm__bswap64(u);
    memcpy(&d, &u, 8);
    return d;
}

static sm_status binary_count(medit_in *c, const char *section, uint64_t record_bytes,
                              int64_t *n)
{
    sm_reader *r = c->r;
    uint64_t at = sm__reader_offset(r);
    sm_status st = sm__reader_int_sized(r, c->lay.int_size, n);
    if (st != SM_OK)
        return sm__reader_fail_byte(r, c->err, st, at, "%s count: %s", section, r->why);
    return sm__medit_check_count(r, 1, section, *n, record_bytes, at, c->err);
}

static sm_status binary_vertices(medit_in *c)
{
    sm_reader *r = c->r;
    size_t rec = (size_t)c->dim * (size_t)c->lay.real_size + (size_t)c->lay.int_size;
    int64_t n;
    sm_status st = binary_count(c, "Vertices", rec, &n);
    if (st != SM_OK)
        return st;
    if ((st = alloc_vertices(c, n)) != SM_OK)
        return st;
    unsigned char buf[3 * 8 + 8];
    for (int64_t i = 0; i < n; i++) {
        uint64_t at = sm__reader_offset(r);
        st = sm__reader_bytes(r, buf, rec);
        if (st != SM_OK)
            return sm__reader_fail_byte(r, c->err, st, at, "Vertices record %lld of %lld: %s",
                                       (long long)i + 1, (long long)n, r->why);
        for (int j = 0; j < c->dim; j++) {
            double x = decode_real(c, buf + (size_t)j * (size_t)c->lay.real_size);
            if (!isfinite(x))
                return sm__reader_fail_byte(r, c->err, SM_ERR_FORMAT, at,
                                           "Vertices record %lld of %lld: coordinate %d is not a "
                                           "finite number (%g)",
                                           (long long)i + 1, (long long)n, j + 1, x);
            c->coords[i * c->dim + j] = x;
        }
        int64_t ref = decode_int(c, buf + (size_t)c->dim * (size_t)c->lay.real_size);
        if (ref < INT32_MIN || ref > INT32_MAX)
            return sm__reader_fail_byte(r, c->err, SM_ERR_FORMAT, at,
                                       "Vertices record %lld of %lld: reference %lld out of the "
                                       "32-bit range",
                                       (long long)i + 1, (long long)n, (long long)ref);
        c->vert_refs[i] = (int32_t)ref;
    }
    return SM_OK;
}

static sm_status binary_block(medit_in *c, int nidx)
{
    sm_reader *r = c->r;
    const char *name = block_name(nidx);
    idx_block *b = block_of(c, nidx);
    b->offset = sm__reader_offset(r);
    size_t isz = (size_t)c->lay.int_size;
    size_t rec = (size_t)(nidx + 1) * isz;
    int64_t n;
    sm_status st = binary_count(c, name, rec, &n);
    if (st != SM_OK)
        return st;
    if ((st = alloc_block(c, b, nidx, n)) != SM_OK)
        return st;
    b->zero_based = c->have_vertices;
    int64_t hi = c->have_vertices ? c->nverts : INT32_MAX;
    unsigned char buf[5 * 8];
    for (int64_t i = 0; i < n; i++) {
        uint64_t at = sm__reader_offset(r);
        st = sm__reader_bytes(r, buf, rec);
        if (st != SM_OK)
            return sm__reader_fail_byte(r, c->err, st, at, "%s record %lld of %lld: %s", name,
                                       (long long)i + 1, (long long)n, r->why);
        for (int j = 0; j < nidx; j++) {
            int64_t v = decode_int(c, buf + (size_t)j * isz);
            if (v < 1 || v > hi)
                return sm__reader_fail_byte(r, c->err, SM_ERR_FORMAT, at,
                                           "%s record %lld of %lld: vertex index %lld out of "
                                           "range [1, %lld]",
                                           name, (long long)i + 1, (long long)n, (long long)v,
                                           (long long)hi);
            b->idx[i * nidx + j] = (int32_t)(b->zero_based ? v - 1 : v);
        }
        int64_t ref = decode_int(c, buf + (size_t)nidx * isz);
        if (ref < INT32_MIN || ref > INT32_MAX)
            return sm__reader_fail_byte(r, c->err, SM_ERR_FORMAT, at,
                                       "%s record %lld of %lld: reference %lld out of the 32-bit "
                                       "range",
                                       name, (long long)i + 1, (long long)n, (long long)ref);
        b->refs[i] = (int32_t)ref;
    }
    return SM_OK;
}

/* The Dimension keyword at byte start (its value follows). */
static sm_status binary_dimension(medit_in *c, uint64_t start)
{
    sm_reader *r = c->r;
    if (c->dim)
        return sm__reader_fail_byte(r, c->err, SM_ERR_FORMAT, start, "duplicate Dimension");
    int32_t d;
    uint64_t at = sm__reader_offset(r);
    sm_status st = sm__reader_i32(r, &d);
    if (st != SM_OK)
        return sm__reader_fail_byte(r, c->err, st, at, "Dimension: %s", r->why);
    if (d != 2 && d != 3)
        return sm__reader_fail_byte(r, c->err, SM_ERR_FORMAT, at,
                                   "Dimension %ld is not supported (expected 2 or 3)",
                                   (long)d);
    c->dim = d;
    return SM_OK;
}

/* An Edges, Triangles or Tetrahedra section (nidx vertices a record) at
 * byte start: after Dimension, once, no tetrahedra in 2D. */
static sm_status binary_section(medit_in *c, int nidx, uint64_t start)
{
    sm_reader *r = c->r;
    const char *name = block_name(nidx);
    if (!c->dim)
        return sm__reader_fail_byte(r, c->err, SM_ERR_FORMAT, start,
                                   "%s before Dimension (missing Dimension)", name);
    if (block_of(c, nidx)->present)
        return sm__reader_fail_byte(r, c->err, SM_ERR_FORMAT, start,
                                   "duplicate %s section", name);
    if (nidx == 4 && c->dim == 2)
        return sm__reader_fail_byte(r, c->err, SM_ERR_FORMAT, start,
                                   "Tetrahedra in a Dimension 2 mesh");
    return binary_block(c, nidx);
}

/* The error for a section of non-simplicial elements at byte start. */
static sm_status binary_unsupported(medit_in *c, int32_t code, uint64_t start)
{
    const char *what = code == SM_KW_QUADRILATERALS ? "Quadrilaterals"
                       : code == SM_KW_PRISMS       ? "Prisms"
                       : code == SM_KW_HEXAHEDRA    ? "Hexahedra"
                                                    : "Pyramids";
    return sm__reader_fail_byte(c->r, c->err, SM_ERR_FORMAT, start,
                               "%s are not supported, shapematch needs simplices "
                               "(triangles or tetrahedra)",
                               what);
}

static sm_status read_binary(medit_in *c)
{
    sm_reader *r = c->r;
    sm_status st = sm__meshb_read_header(r, &c->lay, c->err);
    if (st != SM_OK)
        return st;
    for (;;) {
        uint64_t start = sm__reader_offset(r);
        int32_t code;
        int64_t next;
        if ((st = sm__meshb_read_keyword(r, &c->lay, &code, &next, c->err)) != SM_OK)
            return st;
        if (code == -1)
            return sm__reader_fail_byte(r, c->err, SM_ERR_FORMAT, start,
                                       "unexpected end of file (no End keyword; truncated?)");
        int known = 1;
        const char *name = "";
        switch (code) {
        case SM_KW_DIMENSION:
            if ((st = binary_dimension(c, start)) != SM_OK)
                return st;
            name = "Dimension";
            break;
        case SM_KW_VERTICES:
            if (!c->dim)
                return sm__reader_fail_byte(r, c->err, SM_ERR_FORMAT, start,
                                           "Vertices before Dimension (missing Dimension)");
            if (c->have_vertices)
                return sm__reader_fail_byte(r, c->err, SM_ERR_FORMAT, start,
                                           "duplicate Vertices section");
            if ((st = binary_vertices(c)) != SM_OK)
                return st;
            name = "Vertices";
            break;
        case SM_KW_EDGES:
        case SM_KW_TRIANGLES:
        case SM_KW_TETRAHEDRA: {
            int nidx = code == SM_KW_EDGES ? 2 : code == SM_KW_TRIANGLES ? 3 : 4;
            name = block_name(nidx);
            if ((st = binary_section(c, nidx, start)) != SM_OK)
                return st;
            break;
        }
        case SM_KW_QUADRILATERALS:
        case SM_KW_PRISMS:
        case SM_KW_HEXAHEDRA:
        case SM_KW_PYRAMIDS:
            return binary_unsupported(c, code, start);
        case SM_KW_END:
            return SM_OK;
        default:
            known = 0;
            break;
        }
        if (known) {
            if ((st = sm__meshb_check_block_end(r, name, next, c->err)) != SM_OK)
                return st;
        } else if (next != 0) {
            /* Unknown or unused keyword: its successor's position lets us
             * skip it without knowing its layout. */
            uint64_t here = sm__reader_offset(r);
            if ((st = sm__reader_skip(r, (uint64_t)next - here)) != SM_OK)
                return sm__reader_fail_byte(r, c->err, st, here,
                                           "skipping keyword %ld up to byte %lld: %s", (long)code,
                                           (long long)next, r->why);
        }
        if (next == 0)
            return SM_OK; /* libMeshb: the last keyword has no successor */
    }
}

/* ------------------------------------------------------------------ */
/* assembling the mesh                                                 */
/* ------------------------------------------------------------------ */

/* Converts indices read before Vertices (1-based, unchecked). */
static sm_status finish_block(medit_in *c, idx_block *b, const char *name)
{
    if (!b->present || b->zero_based)
        return SM_OK;
    for (int64_t i = 0; i < b->count; i++) {
        for (int j = 0; j < b->nidx; j++) {
            int32_t v = b->idx[i * b->nidx + j];
            if (v < 1 || v > c->nverts) {
                if (c->binary)
                    return sm__reader_fail_byte(c->r, c->err, SM_ERR_FORMAT, b->offset,
                                               "%s record %lld of %lld: vertex index %ld out of "
                                               "range [1, %lld]",
                                               name, (long long)i + 1, (long long)b->count,
                                               (long)v, (long long)c->nverts);
                return sm_error_set(c->err, SM_ERR_FORMAT,
                                    "%s:%ld: vertex index %ld out of range [1, %lld] in %s record "
                                    "%lld of %lld",
                                    c->r->path, b->line, (long)v, (long long)c->nverts, name,
                                    (long long)i + 1, (long long)b->count);
            }
            b->idx[i * b->nidx + j] = v - 1;
        }
    }
    b->zero_based = 1;
    return SM_OK;
}

/* What every Medit reading needs before its blocks are used: a Dimension,
 * Vertices, and each listed block's indices checked and made 0-based. */
static sm_status finish_blocks(medit_in *c, int with_tetrahedra)
{
    const char *path = c->r->path;
    if (!c->dim)
        return sm_error_set(c->err, SM_ERR_FORMAT, "%s: missing Dimension", path);
    if (!c->have_vertices)
        return sm_error_set(c->err, SM_ERR_FORMAT, "%s: missing Vertices", path);
    sm_status st;
    if ((st = finish_block(c, &c->edges, "Edges")) != SM_OK ||
        (st = finish_block(c, &c->triangles, "Triangles")) != SM_OK)
        return st;
    return with_tetrahedra ? finish_block(c, &c->tetrahedra, "Tetrahedra") : SM_OK;
}

static sm_status build_mesh(medit_in *c, sm_mesh **out)
{
    const char *path = c->r->path;
    sm_status st;
    if ((st = finish_blocks(c, 1)) != SM_OK)
        return st;

    int mesh_dim;
    idx_block *elems, *facets;
    if (c->dim == 3 && c->tetrahedra.count > 0) {
        mesh_dim = 3;
        elems = &c->tetrahedra;
        facets = &c->triangles;
    } else if (c->triangles.count > 0) {
        if (c->dim == 3) {
            for (int64_t i = 0; i < c->nverts; i++)
                if (c->coords[3 * i + 2] != 0.0)
                    return sm_error_set(c->err, SM_ERR_FORMAT,
                                        "%s: Triangles without Tetrahedra in 3D and vertex %lld "
                                        "has z = %g: a surface mesh is not supported, "
                                        "shapematch needs a volume mesh (tetrahedra in 3D, or a "
                                        "planar triangle mesh)",
                                        path, (long long)i + 1, c->coords[3 * i + 2]);
        }
        mesh_dim = 2;
        elems = &c->triangles;
        facets = &c->edges;
    } else {
        return sm_error_set(c->err, SM_ERR_FORMAT,
                            "%s: no elements (Triangles in 2D or Tetrahedra in 3D)", path);
    }

    /* The mesh takes the arrays read rather than copies of them: for the
     * 344k-tetrahedron background of examples/3d, 8.5 MB less to write,
     * and to fault in (first touches are most of a copy's cost on a
     * virtual machine).  sm_mesh_alloc's arrays for no records are
     * replaced; a missing facet block keeps its empty one. */
    sm_mesh *m;
    st = sm_mesh_alloc(&m, mesh_dim, 0, 0, 0, c->err);
    if (st != SM_OK)
        return st;
    if (mesh_dim != c->dim) /* planar Dimension 3 file: z dropped in place */
        for (int64_t i = 0; i < c->nverts; i++) {
            c->coords[2 * i] = c->coords[3 * i];
            c->coords[2 * i + 1] = c->coords[3 * i + 1];
        }
    m->nverts = (int32_t)c->nverts;
    free(m->coords);
    free(m->vert_refs);
    m->coords = c->coords;
    m->vert_refs = c->vert_refs;
    c->coords = NULL;
    c->vert_refs = NULL;
    m->nelems = (int32_t)elems->count;
    free(m->elems);
    free(m->elem_refs);
    m->elems = elems->idx;
    m->elem_refs = elems->refs;
    elems->idx = elems->refs = NULL;
    if (facets->present) {
        m->nfacets = (int32_t)facets->count;
        free(m->facets);
        free(m->facet_refs);
        m->facets = facets->idx;
        m->facet_refs = facets->refs;
        facets->idx = facets->refs = NULL;
    }
    *out = m;
    return SM_OK;
}

sm_status sm__medit_mesh_read(sm_reader *r, sm_mesh **out, sm_error *err)
{
    *out = NULL;
    medit_in c;
    memset(&c, 0, sizeof c);
    c.err = err;
    c.r = r;
    sm_status st = sm__medit_detect(c.r, &c.binary, err);
    if (st == SM_OK)
        st = c.binary ? read_binary(&c) : read_ascii(&c);
    if (st == SM_OK)
        st = build_mesh(&c, out);
    medit_in_free(&c);
    return st;
}

/* ------------------------------------------------------------------ */
/* surfaces (sm_surface_read's Medit reader)                           */
/* ------------------------------------------------------------------ */

static sm_status build_surface(medit_in *c, sm_surface **out)
{
    const char *path = c->r->path;
    sm_status st;
    if ((st = finish_blocks(c, 0)) != SM_OK)
        return st;
    int planar = 1;
    for (int64_t i = 0; c->dim == 3 && i < c->nverts; i++)
        planar = planar && c->coords[3 * i + 2] == 0.0;
    int dim = c->dim == 3 && c->triangles.count > 0 ? 3 : 2;
    idx_block *b = dim == 3 ? &c->triangles : &c->edges;
    if (b->count == 0 || (dim == 2 && !planar))
        return sm_error_set(c->err, SM_ERR_FORMAT,
                            "%s: no surface: Triangles in 3D, or Edges in 2D (a Dimension 3 "
                            "file with all z = 0) are needed", path);
    sm_surface *s;
    if ((st = sm_surface_alloc(&s, dim, (int32_t)c->nverts, (int32_t)b->count, c->err)) != SM_OK)
        return st;
    for (int64_t i = 0; i < c->nverts; i++)
        for (int k = 0; k < dim; k++)
            s->coords[dim * i + k] = c->coords[c->dim * i + k];
    memcpy(s->facets, b->idx, (size_t)b->count * (size_t)dim * sizeof(int32_t));
    memcpy(s->facet_refs, b->refs, (size_t)b->count * sizeof(int32_t));
    *out = s;
    return SM_OK;
}

sm_status sm__medit_surface_read(sm_reader *r, sm_surface **out, sm_error *err)
{
    *out = NULL;
    medit_in c;
    memset(&c, 0, sizeof c);
    c.err = err;
    c.r = r;
    sm_status st = sm__medit_detect(c.r, &c.binary, err);
    if (st == SM_OK)
        st = c.binary ? read_binary(&c) : read_ascii(&c);
    if (st == SM_OK)
        st = build_surface(&c, out);
    medit_in_free(&c);
    return st;
}
