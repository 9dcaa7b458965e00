/* VTK legacy files (.vtk: "# vtk DataFile Version x.y", a title, ASCII or
 * BINARY (big-endian), "DATASET UNSTRUCTURED_GRID" or "POLYDATA"), as
 * Gmsh, meshio, ParaView and VTK write them: POINTS, then CELLS and
 * CELL_TYPES (unstructured grids) or VERTICES, LINES, POLYGONS and
 * TRIANGLE_STRIPS (poly data), in the layout of versions before 5 ("n
 * size" then per cell its count and points) or of 5.x (OFFSETS and
 * CONNECTIVITY arrays).  CELL_DATA attributes (SCALARS, FIELD arrays) named
 * as sm__cells_ref_name says give the references; every other attribute,
 * POINT_DATA, field data and METADATA are read and dropped.  Poly data
 * cells are numbered in file order (VTK writes vertices, lines, polygons,
 * strips, its own order).  Hostile input: counts checked against the
 * bytes left before allocation, indices against the points, reals
 * finite; errors give "file:line" (ASCII) or "file: byte N" (binary). */
#include <inttypes.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "io/sm_io_cells.h"
#include "io/sm_io_formats.h"

#define VTK_LINE_MAX 512

typedef struct vtk_in {
    sm_reader *r;
    sm_error *err;
    sm_msh_data *d;
    int binary, polydata, major;
    uint64_t where;        /* binary: offset of the block being read */
    int64_t ncells;        /* cells numbered so far */
    int64_t *offsets;      /* unstructured grid: CELLS until CELL_TYPES */
    int64_t *conn;
    int64_t noffsets, nconn, ugrid_cells;
    int32_t *refs;         /* the reference array, ncelldata of them */
    int64_t ncelldata;
    int section;           /* 0 none, 1 CELL_DATA, 2 POINT_DATA */
    int64_t nsection;      /* its tuple count */
} vtk_in;

static const struct {
    const char *name;
    int size, real;
} vtk_types[] = {{"bit", 0, 0}, {"unsigned_char", 1, 0}, {"char", 1, 0},
                 {"unsigned_short", 2, 0}, {"short", 2, 0}, {"unsigned_int", 4, 0},
                 {"int", 4, 0}, {"unsigned_long", 8, 0}, {"long", 8, 0}, {"float", 4, 1},
                 {"double", 8, 1}, {"vtktypeint64", 8, 0}, {"vtktypeuint64", 8, 0},
                 {"vtkIdType", 4, 0}};

int sm__vtk_detect(sm_reader *r)
{
    char head[24];
    size_t got = 0;
    return sm__reader_peek(r, head, sizeof head, &got) == SM_OK && got >= 22 &&
           memcmp(head, "# vtk DataFile Version", 22) == 0;
}

static sm_status fail(vtk_in *c, sm_status st, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
static sm_status fail(vtk_in *c, sm_status st, const char *fmt, ...)
{
    char msg[SM_ERROR_MSG_LEN];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    if (st == SM_ERR_IO)
        return sm_error_set(c->err, st, "%s: %s", c->r->path, msg);
    if (c->binary && c->where)
        return sm__reader_fail_byte(c->r, c->err, st, c->where, "VTK: %s", msg);
    return sm__reader_fail_line(c->r, c->err, st, "VTK: %s", msg);
}

static sm_status word(vtk_in *c, const char *what, char *out, size_t cap)
{
    int found;
    sm_status st = sm__reader_token(c->r, &found);
    c->where = 0;
    if (st != SM_OK)
        return fail(c, st, "expected %s, %s", what, c->r->why);
    if (!found)
        return fail(c, SM_ERR_FORMAT, "expected %s, found the end of the file", what);
    snprintf(out, cap, "%s", c->r->token);
    return SM_OK;
}

static sm_status number(vtk_in *c, const char *what, int64_t hi, int64_t *out)
{
    c->where = 0;
    sm_status st = sm__reader_int(c->r, 0, hi, out);
    return st == SM_OK ? SM_OK : fail(c, st, "expected %s, %s", what, c->r->why);
}

/* The size of a data type name (0 when unknown), *real for float types. */
static int type_size(const char *name, int *real)
{
    for (size_t k = 0; k < sizeof vtk_types / sizeof vtk_types[0]; k++)
        if (strcmp(name, vtk_types[k].name) == 0) {
            *real = vtk_types[k].real;
            return vtk_types[k].size;
        }
    return 0;
}

/* n values of type into dbl or (integers, within int64 and exact) into
 * i64, or dropped when both are NULL.  Binary: big-endian, from the byte
 * after the current line. */
static sm_status values(vtk_in *c, int64_t n, const char *type, double *dbl, int64_t *i64)
{
    int real = 0, size = type_size(type, &real);
    sm_reader *r = c->r;
    if (!size)
        return fail(c, SM_ERR_FORMAT, "data type '%.40s' is not read", type);
    uint64_t least = c->binary ? (uint64_t)size : 2;
    if (n < 0 || (uint64_t)n > sm__reader_max_remaining(r) / least)
        return fail(c, SM_ERR_FORMAT, "%" PRId64 " values do not fit in the file", n);
    sm_status st;
    if (c->binary) {
        char rest[VTK_LINE_MAX];
        if ((st = sm__reader_line(r, rest, sizeof rest)) != SM_OK)
            return fail(c, st, "%s", r->why);
        c->where = sm__reader_offset(r);
        if (!dbl && !i64) {
            st = sm__reader_skip(r, (uint64_t)n * (uint64_t)size);
            return st == SM_OK ? SM_OK : fail(c, st, "%s", r->why);
        }
    }
    for (int64_t i = 0; i < n; i++) {
        double v;
        if (!c->binary) {
            if ((st = sm__reader_real(r, &v)) != SM_OK)
                return fail(c, st, "value %" PRId64 " of %" PRId64 ": %s", i + 1, n, r->why);
        } else {
            unsigned char b[8];
            c->where = sm__reader_offset(r);
            if ((st = sm__reader_bytes(r, b, (size_t)size)) != SM_OK)
                return fail(c, st, "value %" PRId64 " of %" PRId64 ": %s", i + 1, n, r->why);
            uint64_t u = 0;
            for (int k = 0; k < size; k++)
                u = u << 8 | b[k];
            int is_signed = strncmp(type, "unsigned", 8) != 0 && strcmp(type, "vtktypeuint64");
            if (real && size == 4) {
                uint32_t u32 = (uint32_t)u;
                float f;
                memcpy(&f, &u32, sizeof f);
                v = f;
            } else if (real) {
                memcpy(&v, &u, sizeof v);
            } else if (is_signed) {
                int shift = 64 - 8 * size; /* sign extension */
                v = (double)((int64_t)(u << shift) >> shift);
            } else {
                v = (double)u;
            }
            if (!isfinite(v))
                return fail(c, SM_ERR_FORMAT, "value %" PRId64 " is not a finite number", i + 1);
        }
        if (dbl)
            dbl[i] = v;
        if (i64) {
            if (v != floor(v) || fabs(v) > 9.0e15)
                return fail(c, SM_ERR_FORMAT, "value %" PRId64 " (%g) is not an integer", i + 1,
                            v);
            i64[i] = (int64_t)v;
        }
    }
    return SM_OK;
}

/* Room for n values of type: checked against the bytes left (as values()
 * does) before anything is allocated for them; NULL with err set if not. */
static int64_t *alloc_i64(vtk_in *c, int64_t n, const char *type)
{
    int real = 0, size = type_size(type, &real);
    uint64_t least = c->binary ? (uint64_t)(size ? size : 1) : 2;
    if (n < 0 || (uint64_t)n > sm__reader_max_remaining(c->r) / least) {
        fail(c, SM_ERR_FORMAT, "%" PRId64 " values do not fit in the file", n);
        return NULL;
    }
    int64_t *p = malloc(((size_t)n + 1) * sizeof *p);
    if (!p)
        sm_error_set(c->err, SM_ERR_NOMEM, "%s: out of memory", c->r->path);
    return p;
}

/* A cell array in either layout into offsets (ncells + 1) and conn. */
static sm_status read_cell_array(vtk_in *c, int64_t a, int64_t b, int64_t **off, int64_t **conn,
                                 int64_t *ncells)
{
    char w[64];
    sm_status st;
    if (c->major >= 5) { /* a offsets, b connectivity entries */
        if (a < 1)
            return fail(c, SM_ERR_FORMAT, "a cell array needs at least one offset");
        if ((st = word(c, "OFFSETS", w, sizeof w)) != SM_OK || strcmp(w, "OFFSETS") != 0)
            return st != SM_OK ? st : fail(c, SM_ERR_FORMAT, "expected OFFSETS");
        if ((st = word(c, "a data type", w, sizeof w)) != SM_OK)
            return st;
        if (!(*off = alloc_i64(c, a, w)) || (st = values(c, a, w, NULL, *off)) != SM_OK)
            return *off ? st : c->err->code;
        if ((st = word(c, "CONNECTIVITY", w, sizeof w)) != SM_OK || strcmp(w, "CONNECTIVITY"))
            return st != SM_OK ? st : fail(c, SM_ERR_FORMAT, "expected CONNECTIVITY");
        if ((st = word(c, "a data type", w, sizeof w)) != SM_OK)
            return st;
        if (!(*conn = alloc_i64(c, b, w)) || (st = values(c, b, w, NULL, *conn)) != SM_OK)
            return *conn ? st : c->err->code;
        *ncells = a - 1;
        if ((*off)[0] != 0 || (*off)[a - 1] != b)
            return fail(c, SM_ERR_FORMAT, "offsets do not span the connectivity");
        for (int64_t i = 0; i < a - 1; i++)
            if ((*off)[i + 1] < (*off)[i])
                return fail(c, SM_ERR_FORMAT, "offsets decrease at cell %" PRId64, i + 1);
        return SM_OK;
    }
    /* a cells, b integers: each cell its count, then its points */
    if (a > b) /* each cell takes at least its count */
        return fail(c, SM_ERR_FORMAT, "%" PRId64 " cells in %" PRId64 " integers", a, b);
    int64_t *all = alloc_i64(c, b, "int");
    if (!all || (st = values(c, b, "int", NULL, all)) != SM_OK) {
        free(all);
        return all ? st : c->err->code;
    }
    if (!(*off = malloc(((size_t)a + 1) * sizeof **off))) { /* a <= b, all held */
        free(all);
        return sm_error_set(c->err, SM_ERR_NOMEM, "%s: out of memory", c->r->path);
    }
    int64_t at = 0, m = 0;
    for (int64_t i = 0; i < a; i++) {
        (*off)[i] = m;
        if (at >= b || all[at] < 0 || all[at] > b - at - 1) {
            free(all);
            return fail(c, SM_ERR_FORMAT, "cell %" PRId64 " runs past the %" PRId64 " integers "
                        "declared", i + 1, b);
        }
        int64_t k = all[at++];
        memmove(all + m, all + at, (size_t)k * sizeof *all);
        at += k;
        m += k;
    }
    (*off)[a] = m;
    *conn = all;
    *ncells = a;
    return SM_OK;
}

static sm_status add_cells(vtk_in *c, const int64_t *off, const int64_t *conn, int64_t n,
                           const int64_t *types, int type)
{
    for (int64_t i = 0; i < n; i++) {
        int64_t t = types ? types[i] : type;
        sm_status st = sm__cells_add_vtk(c->r, c->d, t > 255 ? 255 : (int)t, off[i + 1] - off[i],
                                         conn + off[i], c->ncells++);
        if (st != SM_OK)
            return fail(c, st, "%s", c->r->why);
    }
    return SM_OK;
}

static sm_status read_points(vtk_in *c)
{
    char type[64];
    int64_t n;
    sm_status st;
    if ((st = number(c, "the point count", SM_MAX_ENTITIES, &n)) != SM_OK ||
        (st = word(c, "a data type", type, sizeof type)) != SM_OK)
        return st;
    if (c->d->coords)
        return fail(c, SM_ERR_FORMAT, "two POINTS sections");
    int real, size = type_size(type, &real);
    if (!size)
        return fail(c, SM_ERR_FORMAT, "data type '%.40s' is not read", type);
    uint64_t least = 3 * (c->binary ? (uint64_t)size : 2); /* per point */
    if ((uint64_t)n > sm__reader_max_remaining(c->r) / least)
        return fail(c, SM_ERR_FORMAT, "%" PRId64 " points do not fit in the file", n);
    if ((st = sm__cells_points(c->r, c->d, n, c->err)) != SM_OK)
        return fail(c, st, "%s", c->r->why);
    return values(c, 3 * n, type, c->d->coords, NULL);
}

/* CELLS, VERTICES, LINES, POLYGONS, TRIANGLE_STRIPS (type: the cell type
 * of poly data sections, 0 for CELLS). */
static sm_status read_cells(vtk_in *c, int type)
{
    int64_t a, b, *off = NULL, *conn = NULL, n = 0;
    sm_status st;
    if (!c->d->coords)
        return fail(c, SM_ERR_FORMAT, "cells before POINTS");
    if ((st = number(c, "a cell count", INT64_MAX / 16, &a)) != SM_OK ||
        (st = number(c, "a size", INT64_MAX / 16, &b)) != SM_OK)
        return st;
    if ((st = read_cell_array(c, a, b, &off, &conn, &n)) == SM_OK) {
        if (type) {
            st = add_cells(c, off, conn, n, NULL, type);
        } else if (c->offsets) {
            st = fail(c, SM_ERR_FORMAT, "two CELLS sections");
        } else {
            c->offsets = off;
            c->conn = conn;
            c->ugrid_cells = n;
            off = conn = NULL;
        }
    }
    free(off);
    free(conn);
    return st;
}

static sm_status read_cell_types(vtk_in *c)
{
    int64_t n;
    sm_status st = number(c, "the cell count", INT64_MAX / 16, &n);
    if (st != SM_OK)
        return st;
    if (!c->offsets || n != c->ugrid_cells)
        return fail(c, SM_ERR_FORMAT, "CELL_TYPES %" PRId64 " without CELLS of as many cells",
                    n);
    int64_t *types = alloc_i64(c, n, "unsigned_char");
    if (!types)
        return c->err->code;
    if ((st = values(c, n, "int", NULL, types)) == SM_OK)
        st = add_cells(c, c->offsets, c->conn, n, types, 0);
    free(types);
    return st;
}

/* One data array of n tuples of k components, kept as the references
 * when it is a cell array of that name with one component. */
static sm_status data_array(vtk_in *c, const char *name, int64_t k, int64_t n, const char *type)
{
    int keep = c->section == 1 && k == 1 && sm__cells_ref_name(name) && !c->refs;
    if (k < 1 || n < 0 || n > INT64_MAX / 16 / k)
        return fail(c, SM_ERR_FORMAT, "array '%.40s': bad size", name);
    if (!keep)
        return values(c, n * k, type, NULL, NULL);
    int64_t *v = alloc_i64(c, n, type);
    sm_status st = v ? values(c, n, type, NULL, v) : c->err->code;
    if (st == SM_OK && !(c->refs = malloc(((size_t)n + 1) * sizeof *c->refs)))
        st = sm_error_set(c->err, SM_ERR_NOMEM, "%s: out of memory", c->r->path);
    for (int64_t i = 0; st == SM_OK && i < n; i++) {
        if (v[i] < INT32_MIN || v[i] > INT32_MAX)
            st = fail(c, SM_ERR_FORMAT, "reference %" PRId64 " out of the int32 range", v[i]);
        else
            c->refs[i] = (int32_t)v[i];
    }
    c->ncelldata = n;
    free(v);
    return st;
}

static sm_status read_field(vtk_in *c)
{
    char name[128], type[64];
    int64_t narrays;
    sm_status st;
    if ((st = word(c, "a field name", name, sizeof name)) != SM_OK ||
        (st = number(c, "the array count", 1 << 20, &narrays)) != SM_OK)
        return st;
    for (int64_t a = 0; a < narrays; a++) {
        int64_t k, n;
        if ((st = word(c, "an array name", name, sizeof name)) != SM_OK ||
            (st = number(c, "the component count", 1 << 20, &k)) != SM_OK ||
            (st = number(c, "the tuple count", INT64_MAX / 16, &n)) != SM_OK ||
            (st = word(c, "a data type", type, sizeof type)) != SM_OK ||
            (st = data_array(c, name, k, n, type)) != SM_OK)
            return st;
    }
    return SM_OK;
}

/* An attribute of CELL_DATA or POINT_DATA (or FIELD anywhere). */
static sm_status read_attribute(vtk_in *c, const char *kw)
{
    char name[128], type[64], w[64];
    int64_t k = 1, n = c->nsection;
    sm_status st;
    if (strcmp(kw, "FIELD") == 0)
        return read_field(c);
    if (!c->section)
        return fail(c, SM_ERR_FORMAT, "%s outside CELL_DATA and POINT_DATA", kw);
    if ((st = word(c, "a name", name, sizeof name)) != SM_OK)
        return st;
    if (strcmp(kw, "SCALARS") == 0) {
        if ((st = word(c, "a data type", type, sizeof type)) != SM_OK ||
            (st = word(c, "LOOKUP_TABLE", w, sizeof w)) != SM_OK)
            return st;
        if (strcmp(w, "LOOKUP_TABLE") != 0) { /* the optional component count */
            char *end;
            k = strtoll(w, &end, 10);
            if (*end || k < 1 || k > 4 || (st = word(c, "LOOKUP_TABLE", w, sizeof w)) != SM_OK)
                return st != SM_OK ? st : fail(c, SM_ERR_FORMAT, "bad SCALARS line");
        }
        if (strcmp(w, "LOOKUP_TABLE") != 0 || (st = word(c, "a table", w, sizeof w)) != SM_OK)
            return st != SM_OK ? st : fail(c, SM_ERR_FORMAT, "expected LOOKUP_TABLE");
        return data_array(c, name, k, n, type);
    }
    if (strcmp(kw, "LOOKUP_TABLE") == 0) {
        if ((st = number(c, "the table size", INT64_MAX / 16, &n)) != SM_OK)
            return st;
        return data_array(c, "", 4, n, c->binary ? "unsigned_char" : "float");
    }
    if (strcmp(kw, "COLOR_SCALARS") == 0) {
        if ((st = number(c, "the component count", 16, &k)) != SM_OK)
            return st;
        return data_array(c, "", k, n, c->binary ? "unsigned_char" : "float");
    }
    if (strcmp(kw, "TEXTURE_COORDINATES") == 0 &&
        (st = number(c, "the dimension", 3, &k)) != SM_OK)
        return st;
    if ((st = word(c, "a data type", type, sizeof type)) != SM_OK)
        return st;
    k = strcmp(kw, "TENSORS") == 0 ? 9 : strcmp(kw, "TEXTURE_COORDINATES") == 0 ? k : 3;
    return data_array(c, "", k, n, type);
}

/* METADATA blocks end at an empty line. */
static sm_status skip_metadata(vtk_in *c)
{
    char line[VTK_LINE_MAX];
    for (int blank_seen = 0, k = 0; !blank_seen; k++) {
        uint64_t at = sm__reader_offset(c->r);
        sm_status st = sm__reader_line(c->r, line, sizeof line);
        if (st != SM_OK)
            return fail(c, st, "%s", c->r->why);
        if (sm__reader_offset(c->r) == at)
            break;
        blank_seen = k > 0 && line[strspn(line, " \t")] == '\0';
    }
    return SM_OK;
}

static sm_status read_header(vtk_in *c)
{
    char line[VTK_LINE_MAX], w[64];
    sm_reader *r = c->r;
    sm_status st;
    int minor = 0;
    if ((st = sm__reader_line(r, line, sizeof line)) != SM_OK)
        return fail(c, st, "%s", r->why);
    if (sscanf(line, "# vtk DataFile Version %d.%d", &c->major, &minor) < 1)
        return fail(c, SM_ERR_FORMAT, "bad version line");
    if ((st = sm__reader_line(r, line, sizeof line)) != SM_OK) /* the title */
        return fail(c, st, "%s", r->why);
    if ((st = word(c, "ASCII or BINARY", w, sizeof w)) != SM_OK)
        return st;
    if (strcmp(w, "ASCII") != 0 && strcmp(w, "BINARY") != 0)
        return fail(c, SM_ERR_FORMAT, "expected ASCII or BINARY");
    c->binary = w[0] == 'B';
    if ((st = word(c, "DATASET", w, sizeof w)) != SM_OK || strcmp(w, "DATASET") != 0 ||
        (st = word(c, "a dataset type", w, sizeof w)) != SM_OK)
        return st != SM_OK ? st : fail(c, SM_ERR_FORMAT, "expected DATASET");
    if (strcmp(w, "UNSTRUCTURED_GRID") != 0 && strcmp(w, "POLYDATA") != 0)
        return fail(c, SM_ERR_FORMAT, "dataset %.40s is not read (UNSTRUCTURED_GRID and "
                    "POLYDATA are)", w);
    c->polydata = w[0] == 'P';
    return SM_OK;
}

static sm_status read_section(vtk_in *c, const char *kw)
{
    static const struct {
        const char *kw;
        int type;
    } polys[] = {{"VERTICES", SM_VTK_POLY_VERTEX}, {"LINES", SM_VTK_POLY_LINE},
                 {"POLYGONS", SM_VTK_POLYGON}, {"TRIANGLE_STRIPS", SM_VTK_TRIANGLE_STRIP}};
    if (strcmp(kw, "POINTS") == 0)
        return read_points(c);
    if (strcmp(kw, "CELLS") == 0 && !c->polydata)
        return read_cells(c, 0);
    if (strcmp(kw, "CELL_TYPES") == 0 && !c->polydata)
        return read_cell_types(c);
    for (size_t k = 0; c->polydata && k < sizeof polys / sizeof polys[0]; k++)
        if (strcmp(kw, polys[k].kw) == 0)
            return read_cells(c, polys[k].type);
    if (strcmp(kw, "CELL_DATA") == 0 || strcmp(kw, "POINT_DATA") == 0) {
        c->section = kw[0] == 'C' ? 1 : 2;
        return number(c, "a count", INT64_MAX / 16, &c->nsection);
    }
    if (strcmp(kw, "METADATA") == 0)
        return skip_metadata(c);
    static const char *const attrs[] = {"SCALARS", "VECTORS", "NORMALS", "TENSORS",
                                        "TEXTURE_COORDINATES", "COLOR_SCALARS",
                                        "LOOKUP_TABLE", "FIELD"};
    for (size_t k = 0; k < sizeof attrs / sizeof attrs[0]; k++)
        if (strcmp(kw, attrs[k]) == 0)
            return read_attribute(c, kw);
    char q[64];
    sm__quote_token(kw, q, sizeof q);
    return fail(c, SM_ERR_FORMAT, "unknown keyword %s", q);
}

sm_status sm__vtk_parse(sm_reader *r, sm_msh_data *d, sm_error *err)
{
    sm__cells_init(d);
    vtk_in c;
    memset(&c, 0, sizeof c);
    c.r = r;
    c.err = err;
    c.d = d;
    sm_status st = read_header(&c);
    char kw[SM_TOKEN_LEN];
    while (st == SM_OK) {
        int found;
        if ((st = sm__reader_token(r, &found)) != SM_OK) {
            st = fail(&c, st, "%s", r->why);
            break;
        }
        if (!found)
            break;
        snprintf(kw, sizeof kw, "%s", r->token);
        st = read_section(&c, kw);
    }
    if (st == SM_OK && !d->coords)
        st = sm_error_set(err, SM_ERR_FORMAT, "%s: VTK file without POINTS", r->path);
    if (st == SM_OK && c.offsets && c.ncells == 0 && c.ugrid_cells > 0)
        st = sm_error_set(err, SM_ERR_FORMAT, "%s: VTK CELLS without CELL_TYPES", r->path);
    if (st == SM_OK)
        sm__cells_finish(d, c.refs && c.ncelldata == c.ncells ? c.refs : NULL, c.ncells);
    free(c.offsets);
    free(c.conn);
    free(c.refs);
    return st;
}
