/* PLY surfaces (Stanford polygon files: scanners, MeshLab, Open3D), ASCII
 * and binary in either byte order.  The header ("ply", "format ...",
 * "element NAME COUNT", "property TYPE NAME", "property list CTYPE ITYPE
 * NAME", comment and obj_info lines, "end_header") declares the elements
 * in file order; the "vertex" element's x, y, z properties give the
 * points, the "face" element's vertex_indices (or vertex_index) list the
 * polygons, fan-triangulated; a file without faces whose "edge" element
 * (vertex1, vertex2) joins vertices all at z = 0 is a 2D curve of those
 * segments (sm__msh_surface); every other element and property is read
 * and dropped.  Hostile input: each element's count is checked against
 * the bytes left before anything is allocated for it (at least two bytes
 * a value in ASCII, the declared sizes in binary), a polygon has at most
 * SM_CELL_MAX_NODES vertices, indices must name a vertex, reals be finite.
 * Errors give "file:line" in ASCII and "file: byte N" in binary data. */
#include <inttypes.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "io/sm_io_cells.h"
#include "io/sm_io_formats.h"

#define PLY_MAX_ELEMS 32
#define PLY_MAX_PROPS 64
#define PLY_MAX_HEADER_LINES 10000
#define PLY_LINE 512

enum { PLY_ASCII, PLY_LE, PLY_BE };
enum { T_NONE, T_I8, T_U8, T_I16, T_U16, T_I32, T_U32, T_F32, T_F64 };

typedef struct ply_prop {
    int type;       /* of the value, or of the list's items */
    int count_type; /* T_NONE for a scalar, the list count's type */
} ply_prop;

typedef struct ply_elem {
    char name[64];
    int64_t count;
    int nprops;
    ply_prop props[PLY_MAX_PROPS];
    int x, y, z;    /* vertex: the properties' positions, -1 if absent */
    int indices;    /* face: the index list's position, -1 if absent */
    int v1, v2;     /* edge: vertex1's and vertex2's positions, -1 if absent */
} ply_elem;

typedef struct ply_in {
    sm_reader *r;
    sm_error *err;
    sm_msh_data *d;
    int format;
    int nelems;
    ply_elem elems[PLY_MAX_ELEMS];
    uint64_t where;   /* binary: offset of the value being read */
    int64_t *poly;    /* SM_CELL_MAX_NODES */
    int have_vertices;
} ply_in;

static const struct {
    const char *name;
    int type, size;
} ply_types[] = {{"char", T_I8, 1},    {"int8", T_I8, 1},     {"uchar", T_U8, 1},
                 {"uint8", T_U8, 1},   {"short", T_I16, 2},   {"int16", T_I16, 2},
                 {"ushort", T_U16, 2}, {"uint16", T_U16, 2},  {"int", T_I32, 4},
                 {"int32", T_I32, 4},  {"uint", T_U32, 4},    {"uint32", T_U32, 4},
                 {"float", T_F32, 4},  {"float32", T_F32, 4}, {"double", T_F64, 8},
                 {"float64", T_F64, 8}};

static int type_of(const char *name)
{
    for (size_t k = 0; k < sizeof ply_types / sizeof ply_types[0]; k++)
        if (name && strcmp(name, ply_types[k].name) == 0)
            return ply_types[k].type;
    return T_NONE;
}

static int size_of(int type)
{
    for (size_t k = 0; k < sizeof ply_types / sizeof ply_types[0]; k++)
        if (ply_types[k].type == type)
            return ply_types[k].size;
    return 0;
}

int sm__ply_detect(sm_reader *r)
{
    char head[4];
    size_t got = 0;
    return sm__reader_peek(r, head, sizeof head, &got) == SM_OK && got == sizeof head &&
           memcmp(head, "ply", 3) == 0 && (head[3] == '\n' || head[3] == '\r');
}

static sm_status fail(ply_in *c, sm_status st, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
static sm_status fail(ply_in *c, sm_status st, const char *fmt, ...)
{
    char msg[SM_ERROR_MSG_LEN];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    if (st == SM_ERR_IO)
        return sm_error_set(c->err, st, "%s: %s", c->r->path, msg);
    if (c->format == PLY_ASCII)
        return sm__reader_fail_line(c->r, c->err, st, "PLY: %s", msg);
    return sm__reader_fail_byte(c->r, c->err, st, c->where, "PLY: %s", msg);
}

/* ---- header ---- */

static sm_status header_property(ply_in *c, char *save)
{
    if (c->nelems == 0)
        return sm__reader_fail_line(c->r, c->err, SM_ERR_FORMAT, "PLY: property before any "
                                    "element");
    ply_elem *e = &c->elems[c->nelems - 1];
    if (e->nprops == PLY_MAX_PROPS)
        return sm__reader_fail_line(c->r, c->err, SM_ERR_FORMAT, "PLY: more than %d "
                                    "properties in element '%s'", PLY_MAX_PROPS, e->name);
    ply_prop *p = &e->props[e->nprops];
    const char *w = strtok_r(NULL, " \t", &save);
    if (w && strcmp(w, "list") == 0) {
        p->count_type = type_of(strtok_r(NULL, " \t", &save));
        w = strtok_r(NULL, " \t", &save);
        if (p->count_type == T_NONE || p->count_type == T_F32 || p->count_type == T_F64)
            return sm__reader_fail_line(c->r, c->err, SM_ERR_FORMAT, "PLY: bad list count "
                                        "type in element '%s'", e->name);
    }
    p->type = type_of(w);
    const char *name = strtok_r(NULL, " \t", &save);
    if (p->type == T_NONE || !name)
        return sm__reader_fail_line(c->r, c->err, SM_ERR_FORMAT, "PLY: bad property in "
                                    "element '%s' (type and name expected)", e->name);
    int pos = e->nprops++;
    if (p->count_type == T_NONE) {
        if (strcmp(name, "x") == 0)
            e->x = pos;
        else if (strcmp(name, "y") == 0)
            e->y = pos;
        else if (strcmp(name, "z") == 0)
            e->z = pos;
        else if (strcmp(name, "vertex1") == 0)
            e->v1 = pos;
        else if (strcmp(name, "vertex2") == 0)
            e->v2 = pos;
    } else if (strcmp(name, "vertex_indices") == 0 || strcmp(name, "vertex_index") == 0) {
        if (p->type == T_F32 || p->type == T_F64)
            return sm__reader_fail_line(c->r, c->err, SM_ERR_FORMAT, "PLY: face indices of a "
                                        "real type");
        e->indices = pos;
    }
    return SM_OK;
}

static sm_status header_element(ply_in *c, char *save)
{
    if (c->nelems == PLY_MAX_ELEMS)
        return sm__reader_fail_line(c->r, c->err, SM_ERR_FORMAT, "PLY: more than %d elements",
                                    PLY_MAX_ELEMS);
    ply_elem *e = &c->elems[c->nelems];
    memset(e, 0, sizeof *e);
    e->x = e->y = e->z = e->indices = e->v1 = e->v2 = -1;
    const char *name = strtok_r(NULL, " \t", &save);
    const char *count = strtok_r(NULL, " \t", &save);
    char *end = NULL;
    long long n = count ? strtoll(count, &end, 10) : -1;
    if (!name || !count || *end || n < 0 || n > INT64_MAX / 16)
        return sm__reader_fail_line(c->r, c->err, SM_ERR_FORMAT, "PLY: bad element line "
                                    "(name and count expected)");
    snprintf(e->name, sizeof e->name, "%s", name);
    e->count = n;
    c->nelems++;
    return SM_OK;
}

static sm_status read_header(ply_in *c)
{
    char line[PLY_LINE];
    sm_reader *r = c->r;
    int have_format = 0;
    for (long k = 0;; k++) {
        if (k == PLY_MAX_HEADER_LINES)
            return sm__reader_fail_line(r, c->err, SM_ERR_FORMAT, "PLY header longer than %d "
                                        "lines", PLY_MAX_HEADER_LINES);
        uint64_t at = sm__reader_offset(r);
        sm_status st = sm__reader_line(r, line, sizeof line);
        if (st != SM_OK)
            return fail(c, st, "%s", r->why);
        r->token_line = r->line - 1;
        if (sm__reader_offset(r) == at)
            return sm__reader_fail_line(r, c->err, SM_ERR_FORMAT, "PLY header without "
                                        "end_header (truncated file?)");
        char *save = NULL;
        const char *w = strtok_r(line, " \t", &save);
        if (k == 0 || !w || strcmp(w, "comment") == 0 || strcmp(w, "obj_info") == 0)
            continue;
        if (strcmp(w, "format") == 0) {
            const char *f = strtok_r(NULL, " \t", &save);
            const char *v = strtok_r(NULL, " \t", &save);
            c->format = !f ? -1 : strcmp(f, "ascii") == 0 ? PLY_ASCII
                          : strcmp(f, "binary_little_endian") == 0 ? PLY_LE
                          : strcmp(f, "binary_big_endian") == 0 ? PLY_BE : -1;
            if (c->format < 0 || !v || strcmp(v, "1.0") != 0)
                return sm__reader_fail_line(r, c->err, SM_ERR_FORMAT, "PLY: unknown format "
                                            "line (ascii, binary_little_endian or "
                                            "binary_big_endian 1.0 are read)");
            have_format = 1;
        } else if (strcmp(w, "element") == 0) {
            if ((st = header_element(c, save)) != SM_OK)
                return st;
        } else if (strcmp(w, "property") == 0) {
            if ((st = header_property(c, save)) != SM_OK)
                return st;
        } else if (strcmp(w, "end_header") == 0) {
            break;
        } else {
            char q[64];
            sm__quote_token(w, q, sizeof q);
            return sm__reader_fail_line(r, c->err, SM_ERR_FORMAT, "PLY: unknown header "
                                        "line %s", q);
        }
    }
    if (!have_format)
        return sm__reader_fail_line(r, c->err, SM_ERR_FORMAT, "PLY header without a format "
                                    "line");
    return SM_OK;
}

/* ---- values ---- */

static sm_status value(ply_in *c, int type, double *out)
{
    sm_reader *r = c->r;
    if (c->format == PLY_ASCII) {
        sm_status st = sm__reader_real(r, out);
        return st == SM_OK ? SM_OK : fail(c, st, "expected a number, %s", r->why);
    }
    unsigned char b[8];
    int n = size_of(type);
    c->where = sm__reader_offset(r);
    if (sm__reader_bytes(r, b, (size_t)n) != SM_OK)
        return fail(c, r->stream_status == SM_ERR_IO ? SM_ERR_IO : SM_ERR_FORMAT, "%s",
                    r->why);
    uint64_t u = 0;
    for (int k = 0; k < n; k++)
        u |= (uint64_t)b[c->format == PLY_LE ? k : n - 1 - k] << (8 * k);
    switch (type) {
    case T_I8: *out = (int8_t)u; break;
    case T_U8: *out = (uint8_t)u; break;
    case T_I16: *out = (int16_t)u; break;
    case T_U16: *out = (uint16_t)u; break;
    case T_I32: *out = (int32_t)u; break;
    case T_U32: *out = (uint32_t)u; break;
    case T_F32: {
        uint32_t v = (uint32_t)u;
        float f;
        memcpy(&f, &v, sizeof f);
        *out = f;
        break;
    }
    default: memcpy(out, &u, sizeof *out); break;
    }
    if (!isfinite(*out))
        return fail(c, SM_ERR_FORMAT, "a value is not a finite number");
    return SM_OK;
}

/* An integer value: a list count, a vertex index. */
static sm_status integer(ply_in *c, int type, int64_t lo, int64_t hi, const char *what,
                         int64_t *out)
{
    double v;
    sm_status st = value(c, type, &v);
    if (st != SM_OK)
        return st;
    if (v != floor(v) || v < (double)lo || v > (double)hi)
        return fail(c, SM_ERR_FORMAT, "%s %g is not an integer in [%" PRId64 ", %" PRId64 "]",
                    what, v, lo, hi);
    *out = (int64_t)v;
    return SM_OK;
}

/* The element's count against the bytes left: every value takes at least
 * two bytes in ASCII (a digit and a separator), its size in binary. */
static sm_status check_count(ply_in *c, const ply_elem *e)
{
    uint64_t least = 0;
    for (int k = 0; k < e->nprops; k++) {
        const ply_prop *p = &e->props[k];
        least += c->format == PLY_ASCII ? 2 : (uint64_t)size_of(p->count_type ? p->count_type
                                                                               : p->type);
    }
    uint64_t left = sm__reader_max_remaining(c->r);
    c->where = sm__reader_offset(c->r);
    if (least && (uint64_t)e->count > left / least)
        return fail(c, SM_ERR_FORMAT, "element '%s': count %" PRId64 " does not fit in the "
                    "bytes left (%" PRIu64 ")", e->name, e->count, left);
    return SM_OK;
}

static sm_status read_record(ply_in *c, const ply_elem *e, int64_t i, int is_vertex,
                             int is_face, int is_edge)
{
    double xyz[3] = {0, 0, 0};
    int64_t ends[2] = {-1, -1};
    int64_t nidx = -1;
    for (int k = 0; k < e->nprops; k++) {
        const ply_prop *p = &e->props[k];
        sm_status st;
        if (p->count_type == T_NONE) {
            double v;
            if (is_edge && (k == e->v1 || k == e->v2)) {
                if ((st = integer(c, p->type, INT32_MIN, INT32_MAX, "vertex index",
                                  &ends[k == e->v2])) != SM_OK)
                    return st;
                continue;
            }
            if ((st = value(c, p->type, &v)) != SM_OK)
                return st;
            for (int j = 0; j < 3; j++)
                if (k == (j == 0 ? e->x : j == 1 ? e->y : e->z))
                    xyz[j] = v;
            continue;
        }
        int64_t n;
        if ((st = integer(c, p->count_type, 0, SM_CELL_MAX_NODES, "list length", &n)) != SM_OK)
            return st;
        int64_t *dst = is_face && k == e->indices ? c->poly : NULL;
        for (int64_t j = 0; j < n; j++) {
            double v;
            if (dst)
                st = integer(c, p->type, INT32_MIN, INT32_MAX, "vertex index", &dst[j]);
            else
                st = value(c, p->type, &v);
            if (st != SM_OK)
                return st;
        }
        if (dst)
            nidx = n;
    }
    if (is_vertex)
        memcpy(c->d->coords + 3 * i, xyz, sizeof xyz);
    if (is_face) {
        sm_status st = sm__cells_add_polygon(c->r, c->d, nidx, c->poly, i);
        if (st != SM_OK)
            return fail(c, st, "%s", c->r->why);
    }
    if (is_edge) {
        sm_status st = sm__cells_add_vtk(c->r, c->d, SM_VTK_LINE, 2, ends, i);
        if (st != SM_OK)
            return fail(c, st, "edge %" PRId64 ": %s", i + 1, c->r->why);
    }
    return SM_OK;
}

static sm_status read_element(ply_in *c, const ply_elem *e)
{
    int is_vertex = strcmp(e->name, "vertex") == 0;
    int is_face = strcmp(e->name, "face") == 0;
    int is_edge = strcmp(e->name, "edge") == 0;
    sm_status st = check_count(c, e);
    if (st != SM_OK)
        return st;
    if (is_vertex) {
        if (e->x < 0 || e->y < 0 || e->z < 0)
            return fail(c, SM_ERR_FORMAT, "the vertex element has no x, y and z properties");
        if (c->have_vertices)
            return fail(c, SM_ERR_FORMAT, "two vertex elements");
        if ((st = sm__cells_points(c->r, c->d, e->count, c->err)) != SM_OK)
            return fail(c, st, "%s", c->r->why);
        c->have_vertices = 1;
    }
    if (is_face) {
        if (e->indices < 0)
            return fail(c, SM_ERR_FORMAT, "the face element has no vertex_indices list");
        if (!c->have_vertices)
            return fail(c, SM_ERR_FORMAT, "faces before the vertex element");
    }
    if (is_edge) {
        if (e->v1 < 0 || e->v2 < 0 || e->props[e->v1].type == T_F32 ||
            e->props[e->v1].type == T_F64 || e->props[e->v2].type == T_F32 ||
            e->props[e->v2].type == T_F64)
            return fail(c, SM_ERR_FORMAT, "the edge element has no integer vertex1 and vertex2 "
                        "properties");
        if (!c->have_vertices)
            return fail(c, SM_ERR_FORMAT, "edges before the vertex element");
    }
    if (e->nprops == 0)
        return SM_OK;
    for (int64_t i = 0; i < e->count && st == SM_OK; i++)
        st = read_record(c, e, i, is_vertex, is_face, is_edge);
    return st;
}

sm_status sm__ply_read(sm_reader *r, sm_surface **out, sm_error *err)
{
    *out = NULL;
    sm_msh_data d;
    sm__cells_init(&d);
    ply_in c;
    memset(&c, 0, sizeof c);
    c.r = r;
    c.err = err;
    c.d = &d;
    c.format = PLY_ASCII;
    sm_status st = read_header(&c);
    if (st == SM_OK && !(c.poly = malloc(SM_CELL_MAX_NODES * sizeof *c.poly)))
        st = sm_error_set(err, SM_ERR_NOMEM, "%s: out of memory", r->path);
    for (int k = 0; st == SM_OK && k < c.nelems; k++)
        st = read_element(&c, &c.elems[k]);
    if (st == SM_OK && d.triangles.count == 0 && d.lines.count == 0)
        st = sm_error_set(err, SM_ERR_FORMAT, "%s: PLY without faces or edges (%lld vertices "
                          "and nothing joining them)", r->path, (long long)d.nnodes);
    if (st == SM_OK) {
        sm__cells_finish(&d, NULL, 0);
        st = sm__msh_surface(r->path, &d, out, err);
    }
    if (st == SM_OK && (st = sm__surface_weld(*out, err)) != SM_OK) {
        sm_surface_free(*out);
        *out = NULL;
    }
    free(c.poly);
    sm__msh_data_free(&d);
    return st;
}
