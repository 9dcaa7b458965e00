/* VTK XML files: UnstructuredGrid (.vtu) and PolyData (.vtp), one Piece,
 * as VTK, ParaView, meshio and shapematch write them.  DataArrays are read
 * in every encoding VTK writes: format="ascii", format="binary" (base64
 * inline), format="appended" (the AppendedData block, raw or base64), each
 * binary one with its header of UInt32 or UInt64 sizes (header_type) and
 * either byte order, plain or compressed by vtkZLibDataCompressor (a
 * header [blocks, block size, last block size, compressed sizes...], then
 * zlib blocks).  Points (3 components), the Cells' connectivity, offsets
 * and types (.vtu) or the Verts, Lines, Polys and Strips (.vtp; their cells
 * numbered in that order, VTK's), and a CellData array named as
 * sm__cells_ref_name says for the references.
 *
 * The file is read whole (it is XML; bounded by the reader's limits) and
 * scanned for tags, not parsed as general XML: no entities, no CDATA.
 * Hostile input: every size is checked against the bytes there are before
 * anything is allocated for it (a compressed block against zlib's
 * largest ratio), indices against the points, reals finite; errors name
 * the array ("file: VTK XML: Points: ..."). */
#include <ctype.h>
#include <inttypes.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

#include "io/sm_io_cells.h"
#include "io/sm_io_formats.h"

#define ZLIB_MAX_RATIO 1032u /* deflate's largest expansion on inflating */
/* What the compressed arrays of a file may declare altogether: at most
 * this many times the file's bytes (at least XML_INFLATE_FLOOR), and the
 * reader's limit on inflated bytes.  Meshes VTK, meshio and shapematch
 * write compress 2 to 5 times overall (coordinates hardly, a types array
 * of one cell type 600 times, but it is one byte a cell); a file of
 * compressed zeros declares 1000 times its size, which cost 2 KB of
 * memory per byte read before the bound (issue 37). */
#define XML_INFLATE_RATIO 64u
#define XML_INFLATE_FLOOR ((uint64_t)1 << 20)

enum { K_VERTS, K_LINES, K_POLYS, K_STRIPS, K_CELLS, K_NKINDS };

typedef struct xml_array {
    const char *tag, *tag_end; /* the DataArray's attributes */
    const char *text, *text_end;
    int present;
} xml_array;

typedef struct xml_in {
    sm_reader *r;
    sm_error *err;
    sm_msh_data *d;
    char *buf;
    size_t len;
    int polydata, big_endian, header_size, zlib;
    const char *appended;      /* the byte after AppendedData's '_' */
    int appended_base64;
    int64_t npoints, ncells[K_NKINDS];
    xml_array points, conn[K_NKINDS], offsets[K_NKINDS], types, refs;
    const char *what;          /* the array being read, for messages */
    uint64_t declared;         /* compressed arrays' inflated bytes so far */
} xml_in;

static const struct {
    const char *name;
    int size, real, is_signed;
} xml_types[] = {{"Int8", 1, 0, 1},   {"UInt8", 1, 0, 0},   {"Int16", 2, 0, 1},
                 {"UInt16", 2, 0, 0}, {"Int32", 4, 0, 1},   {"UInt32", 4, 0, 0},
                 {"Int64", 8, 0, 1},  {"UInt64", 8, 0, 0},  {"Float32", 4, 1, 1},
                 {"Float64", 8, 1, 1}};

static sm_status fail(xml_in *c, sm_status st, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
static sm_status fail(xml_in *c, sm_status st, const char *fmt, ...)
{
    char msg[SM_ERROR_MSG_LEN];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    return sm_error_set(c->err, st, "%s: VTK XML: %s%s%s", c->r->path, c->what ? c->what : "",
                        c->what ? ": " : "", msg);
}

int sm__vtkxml_detect(sm_reader *r)
{
    char head[512];
    size_t got = 0;
    if (sm__reader_peek(r, head, sizeof head - 1, &got) != SM_OK)
        return 0;
    head[got] = '\0';
    return memmem(head, got, "<VTKFile", 8) != NULL;
}

/* ---- tags ---- */

/* The value of attribute name within [tag, end) into out ("" if absent). */
static int attr(const char *tag, const char *end, const char *name, char *out, size_t cap)
{
    size_t n = strlen(name);
    out[0] = '\0';
    for (const char *p = tag; p + n + 2 < end; p++) {
        if (!isspace((unsigned char)p[-1]) || memcmp(p, name, n) != 0)
            continue;
        const char *q = p + n;
        while (q < end && isspace((unsigned char)*q))
            q++;
        if (q >= end || *q != '=')
            continue;
        q++;
        while (q < end && isspace((unsigned char)*q))
            q++;
        if (q >= end || (*q != '"' && *q != '\''))
            return 0;
        const char *v = q + 1, *e = memchr(v, *q, (size_t)(end - v));
        if (!e)
            return 0;
        size_t k = (size_t)(e - v) < cap - 1 ? (size_t)(e - v) : cap - 1;
        memcpy(out, v, k);
        out[k] = '\0';
        return 1;
    }
    return 0;
}

static int64_t attr_int(const char *tag, const char *end, const char *name, int64_t dflt)
{
    char v[32];
    if (!attr(tag, end, name, v, sizeof v))
        return dflt;
    char *e;
    long long x = strtoll(v, &e, 10);
    return e == v || *e || x < 0 ? -1 : x;
}

static int is_name(const char *p, const char *end, const char *name)
{
    size_t n = strlen(name);
    return (size_t)(end - p) > n && memcmp(p, name, n) == 0 &&
           (isspace((unsigned char)p[n]) || p[n] == '>' || p[n] == '/');
}

/* ---- base64 and blocks ---- */

static int b64_value(int ch)
{
    if (ch >= 'A' && ch <= 'Z')
        return ch - 'A';
    if (ch >= 'a' && ch <= 'z')
        return ch - 'a' + 26;
    if (ch >= '0' && ch <= '9')
        return ch - '0' + 52;
    return ch == '+' ? 62 : ch == '/' ? 63 : -1;
}

/* Decodes the first want bytes of the base64 text [p, end) into out;
 * whitespace is skipped and '=' padding may end a quantum in the middle
 * (VTK encodes a compressed array's header and data separately). */
static int b64_prefix(const char *p, const char *end, unsigned char *out, size_t want)
{
    size_t n = 0;
    uint32_t acc = 0;
    int bits = 0;
    for (; p < end && n < want; p++) {
        if (*p == '=') {
            acc = 0;
            bits = 0;
            continue;
        }
        int v = b64_value((unsigned char)*p);
        if (v < 0) {
            if (isspace((unsigned char)*p))
                continue;
            break;
        }
        acc = acc << 6 | (uint32_t)v;
        bits += 6;
        if (bits >= 8) {
            bits -= 8;
            out[n++] = (unsigned char)(acc >> bits);
            acc &= (1u << bits) - 1;
        }
    }
    return n == want;
}

/* Where an array's binary bytes are: the text of an inline one, or the
 * appended data from its offset. */
typedef struct src {
    const char *p, *end;
    int base64;
} src;

/* The first want bytes of s: into tmp (base64) or in place (raw). */
static const unsigned char *src_bytes(xml_in *c, const src *s, size_t want,
                                      unsigned char **tmp)
{
    free(*tmp);
    *tmp = NULL;
    if (!s->base64) {
        if (want > (size_t)(s->end - s->p)) {
            fail(c, SM_ERR_FORMAT, "%zu bytes needed, %zu left in the file", want,
                 (size_t)(s->end - s->p));
            return NULL;
        }
        return (const unsigned char *)s->p;
    }
    if (want > (size_t)(s->end - s->p) / 4 * 3 + 3) {
        fail(c, SM_ERR_FORMAT, "%zu bytes needed, fewer are encoded", want);
        return NULL;
    }
    if (!(*tmp = malloc(want + 1))) {
        fail(c, SM_ERR_NOMEM, "out of memory");
        return NULL;
    }
    if (!b64_prefix(s->p, s->end, *tmp, want)) {
        fail(c, SM_ERR_FORMAT, "%zu bytes needed, fewer are encoded", want);
        return NULL;
    }
    return *tmp;
}

static uint64_t get_uint(const xml_in *c, const unsigned char *p, int size)
{
    uint64_t u = 0;
    for (int k = 0; k < size; k++)
        u |= (uint64_t)p[c->big_endian ? size - 1 - k : k] << (8 * k);
    return u;
}

/* A compressed array's header [blocks, block size, last block size,
 * compressed size of each] checked against want bytes of data and the
 * bytes there are: *nb blocks of *bs bytes (the last *last, 0 for bs),
 * their compressed sizes in *cs (malloc'd), *csum of them, the header
 * *hbytes long.  SM_OK or an error with *cs NULL. */
static sm_status zlib_header(xml_in *c, const src *s, size_t want, size_t *nb, uint64_t *bs,
                             uint64_t *last, uint64_t **cs, uint64_t *csum, size_t *hbytes)
{
    unsigned char *tmp = NULL;
    const unsigned char *h;
    size_t hs = (size_t)c->header_size;
    sm_status st = SM_OK;
    *cs = NULL;
    *csum = 0;
    if (!(h = src_bytes(c, s, hs, &tmp)))
        goto bad;
    uint64_t n0 = get_uint(c, h, (int)hs);
    if (n0 > (uint64_t)(s->end - s->p) / hs) {
        st = fail(c, SM_ERR_FORMAT, "%" PRIu64 " compressed blocks do not fit", n0);
        goto done;
    }
    *nb = (size_t)n0;
    *hbytes = (3 + *nb) * hs;
    if (!(h = src_bytes(c, s, *hbytes, &tmp)))
        goto bad;
    *bs = get_uint(c, h + hs, (int)hs);
    *last = get_uint(c, h + 2 * hs, (int)hs);
    uint64_t total = *nb == 0 ? 0 : (uint64_t)(*nb - 1) * *bs + (*last ? *last : *bs);
    if (!(*cs = malloc((*nb + 1) * sizeof **cs))) {
        st = fail(c, SM_ERR_NOMEM, "out of memory");
        goto done;
    }
    for (size_t b = 0; b < *nb; b++) {
        (*cs)[b] = get_uint(c, h + (3 + b) * hs, (int)hs);
        *csum += (*cs)[b] < (uint64_t)(s->end - s->p) ? (*cs)[b] : (uint64_t)(s->end - s->p) + 1;
    }
    /* the compressed blocks are there (base64: 4 characters per 3 bytes) */
    uint64_t present = (uint64_t)(s->end - s->p);
    if (s->base64)
        present = present / 4 * 3 + 3;
    if ((*nb && *bs == 0) || *last > *bs || (*nb > 1 && *bs > want) || total != want ||
        *csum > present || *hbytes + *csum > present ||
        total > (*csum + 64 * *nb) * ZLIB_MAX_RATIO)
        st = fail(c, SM_ERR_FORMAT, "compressed blocks of %" PRIu64 " bytes, %zu expected, "
                  "or sizes that do not fit", total, want);
    goto done;
bad:
    st = c->err->code != SM_OK ? c->err->code : SM_ERR_FORMAT;
done:
    free(tmp);
    if (st != SM_OK) {
        free(*cs);
        *cs = NULL;
    }
    return st;
}

/* The uncompressed data bytes (exactly want of them) of a binary array
 * into *out (malloc'd). */
static sm_status binary_data(xml_in *c, const src *s, size_t want, unsigned char **out)
{
    unsigned char *tmp = NULL;
    const unsigned char *h;
    size_t hs = (size_t)c->header_size;
    uint64_t *cs = NULL;
    sm_status st = SM_OK;
    *out = NULL;
    if (!c->zlib) {
        if (!(h = src_bytes(c, s, hs, &tmp)))
            goto bad;
        uint64_t n0 = get_uint(c, h, (int)hs);
        if (n0 != want) {
            st = fail(c, SM_ERR_FORMAT, "%" PRIu64 " bytes, %zu expected", n0, want);
            goto done;
        }
        if (!(h = src_bytes(c, s, hs + want, &tmp)))
            goto bad;
        if (!(*out = malloc(want + 1))) {
            st = fail(c, SM_ERR_NOMEM, "out of memory");
            goto done;
        }
        memcpy(*out, h + hs, want);
        goto done;
    }
    size_t nb, hbytes;
    uint64_t bs, last, csum;
    if ((st = zlib_header(c, s, want, &nb, &bs, &last, &cs, &csum, &hbytes)) != SM_OK)
        goto done;
    if (!(h = src_bytes(c, s, hbytes + (size_t)csum, &tmp)))
        goto bad;
    if (!(*out = malloc(want + 1))) {
        st = fail(c, SM_ERR_NOMEM, "out of memory");
        goto done;
    }
    const unsigned char *z = h + hbytes;
    for (size_t b = 0, at = 0; b < nb && st == SM_OK; b++) {
        uLongf expect = (uLongf)(b + 1 < nb || !last ? bs : last), got = expect;
        if (uncompress(*out + at, &got, z, (uLong)cs[b]) != Z_OK || got != expect)
            st = fail(c, SM_ERR_FORMAT, "compressed block %zu of %zu does not inflate to %lu "
                      "bytes", b + 1, nb, (unsigned long)expect);
        z += cs[b];
        at += expect;
    }
    goto done;
bad:
    st = c->err->code != SM_OK ? c->err->code : SM_ERR_FORMAT;
done:
    free(tmp);
    free(cs);
    if (st != SM_OK) {
        free(*out);
        *out = NULL;
    }
    return st;
}

/* ---- arrays ---- */

static double typed_value(const xml_in *c, const unsigned char *p, int t)
{
    uint64_t u = get_uint(c, p, xml_types[t].size);
    int size = xml_types[t].size;
    if (xml_types[t].real && size == 4) {
        uint32_t v = (uint32_t)u;
        float f;
        memcpy(&f, &v, sizeof f);
        return f;
    }
    if (xml_types[t].real) {
        double d;
        memcpy(&d, &u, sizeof d);
        return d;
    }
    if (xml_types[t].is_signed) {
        int shift = 64 - 8 * size;
        return (double)((int64_t)(u << shift) >> shift);
    }
    return (double)u;
}

/* Where array a's n values are: *t its type (xml_types), and either
 * *ascii set (its text) or *s its binary bytes.  Checks the count
 * against the bytes there are (at zlib's largest ratio: the exact
 * checks follow, on the array's header). */
static sm_status array_source(xml_in *c, const xml_array *a, int64_t n, int *t, int *ascii,
                              src *s)
{
    char type[32], format[32];
    attr(a->tag, a->tag_end, "type", type, sizeof type);
    attr(a->tag, a->tag_end, "format", format, sizeof format);
    *t = -1;
    for (int k = 0; k < (int)(sizeof xml_types / sizeof xml_types[0]); k++)
        if (strcmp(type, xml_types[k].name) == 0)
            *t = k;
    if (*t < 0)
        return fail(c, SM_ERR_FORMAT, "data type '%s' is not read", type);
    *ascii = strcmp(format, "ascii") == 0;
    if (*ascii) {
        if ((uint64_t)n > (uint64_t)(a->text_end - a->text) / 2 + 1)
            return fail(c, SM_ERR_FORMAT, "%" PRId64 " values do not fit in the text", n);
        return SM_OK;
    }
    *s = (src){a->text, a->text_end, 1};
    if (strcmp(format, "appended") == 0) {
        int64_t off = attr_int(a->tag, a->tag_end, "offset", -1);
        if (!c->appended || off < 0 || (uint64_t)off > (uint64_t)(c->buf + c->len - c->appended))
            return fail(c, SM_ERR_FORMAT, "no appended data at its offset");
        *s = (src){c->appended + off, c->buf + c->len, c->appended_base64};
    } else if (strcmp(format, "binary") != 0) {
        return fail(c, SM_ERR_FORMAT, "format '%s' is not read", format);
    }
    if ((uint64_t)n > (uint64_t)(c->buf + c->len - s->p) * ZLIB_MAX_RATIO /
                          (uint64_t)xml_types[*t].size)
        return fail(c, SM_ERR_FORMAT, "%" PRId64 " values do not fit in the file", n);
    return SM_OK;
}

/* Before anything is allocated for array a's n values: a compressed
 * array's block header is read and checked against the bytes there are,
 * and what the file's compressed arrays declare altogether is bounded
 * (XML_INFLATE_RATIO, the reader's limit on inflated bytes). */
static sm_status check_declared(xml_in *c, const xml_array *a, int64_t n)
{
    if (!a->present || n == 0 || !c->zlib)
        return SM_OK;
    int t, ascii;
    src s;
    sm_status st = array_source(c, a, n, &t, &ascii, &s);
    if (st != SM_OK || ascii)
        return st;
    size_t nb, hbytes;
    uint64_t bs, last, csum, *cs = NULL;
    size_t want = (size_t)n * (size_t)xml_types[t].size;
    if ((st = zlib_header(c, &s, want, &nb, &bs, &last, &cs, &csum, &hbytes)) != SM_OK)
        return st;
    free(cs);
    c->declared += want;
    uint64_t ratio = (uint64_t)c->len * XML_INFLATE_RATIO;
    uint64_t most = ratio > XML_INFLATE_FLOOR ? ratio : XML_INFLATE_FLOOR;
    const sm_read_limits *lim = c->r->limits;
    if (lim && lim->max_inflated && lim->max_inflated < most) {
        if (c->declared > lim->max_inflated) {
            c->r->limits->hit = SM_LIMIT_INFLATED;
            return fail(c, SM_ERR_NOMEM, "its compressed arrays inflate to more than %" PRIu64
                        " bytes", lim->max_inflated);
        }
    } else if (c->declared > most) {
        return fail(c, SM_ERR_NOMEM, "its compressed arrays declare %" PRIu64 " bytes, more "
                    "than %u times the file's %zu (a bound of the VTK XML reader)", c->declared,
                    XML_INFLATE_RATIO, c->len);
    }
    return SM_OK;
}

/* n values of array a into dbl or (exact integers) into i64. */
static sm_status read_array(xml_in *c, const xml_array *a, int64_t n, double *dbl, int64_t *i64)
{
    if (!a->present)
        return n == 0 ? SM_OK : fail(c, SM_ERR_FORMAT, "missing");
    int t, ascii;
    src s;
    sm_status st = array_source(c, a, n, &t, &ascii, &s);
    if (st != SM_OK)
        return st;
    unsigned char *bytes = NULL;
    const char *p = a->text;
    if (!ascii && (st = binary_data(c, &s, (size_t)n * (size_t)xml_types[t].size, &bytes)) != SM_OK)
        return st;
    for (int64_t i = 0; i < n && st == SM_OK; i++) {
        double v;
        if (bytes) {
            v = typed_value(c, bytes + (size_t)i * (size_t)xml_types[t].size, t);
        } else {
            char *e;
            while (p < a->text_end && isspace((unsigned char)*p))
                p++;
            v = p < a->text_end ? strtod(p, &e) : 0.0;
            if (p >= a->text_end || e == p || e > a->text_end) {
                st = fail(c, SM_ERR_FORMAT, "value %" PRId64 " of %" PRId64 " missing or not "
                          "a number", i + 1, n);
                break;
            }
            p = e;
        }
        if (!isfinite(v) || (i64 && (v != floor(v) || fabs(v) > 9.0e15)))
            st = fail(c, SM_ERR_FORMAT, "value %" PRId64 " is not a finite%s number", i + 1,
                      i64 ? " integer" : "");
        else if (dbl)
            dbl[i] = v;
        else
            i64[i] = (int64_t)v;
    }
    free(bytes);
    return st;
}

/* ---- the document ---- */

static sm_status slurp(xml_in *c)
{
    sm_reader *r = c->r;
    size_t cap = 0;
    for (;;) {
        const unsigned char *b;
        size_t avail;
        sm_status st = sm__reader_window(r, &b, &avail);
        if (st != SM_OK)
            return sm_error_set(c->err, st, "%s: %s", r->path, r->why);
        if (!avail)
            break;
        if (c->len + avail + 1 > cap) {
            size_t want = c->len + avail + 1, n = cap ? cap : 4096;
            while (n < want)
                n *= 2;
            char *p = realloc(c->buf, n);
            if (!p)
                return sm_error_set(c->err, SM_ERR_NOMEM, "%s: out of memory", r->path);
            c->buf = p;
            cap = n;
        }
        memcpy(c->buf + c->len, b, avail);
        c->len += avail;
        sm__reader_consume(r, avail);
    }
    if (!c->buf && !(c->buf = malloc(1)))
        return sm_error_set(c->err, SM_ERR_NOMEM, "%s: out of memory", r->path);
    c->buf[c->len] = '\0';
    return SM_OK;
}

static sm_status file_attributes(xml_in *c, const char *tag, const char *end)
{
    char v[64];
    attr(tag, end, "type", v, sizeof v);
    if (strcmp(v, "UnstructuredGrid") != 0 && strcmp(v, "PolyData") != 0)
        return fail(c, SM_ERR_FORMAT, "file type '%s' is not read (UnstructuredGrid .vtu and "
                    "PolyData .vtp are)", v);
    c->polydata = v[0] == 'P';
    attr(tag, end, "byte_order", v, sizeof v);
    c->big_endian = strcmp(v, "BigEndian") == 0;
    attr(tag, end, "header_type", v, sizeof v);
    c->header_size = strcmp(v, "UInt64") == 0 ? 8 : 4;
    if (v[0] && strcmp(v, "UInt64") != 0 && strcmp(v, "UInt32") != 0)
        return fail(c, SM_ERR_FORMAT, "header_type '%s' is not read", v);
    attr(tag, end, "compressor", v, sizeof v);
    c->zlib = v[0] != '\0';
    if (v[0] && strcmp(v, "vtkZLibDataCompressor") != 0)
        return fail(c, SM_ERR_FORMAT, "compressor '%s' is not read (vtkZLibDataCompressor is)",
                    v);
    return SM_OK;
}

static const char *const kind_tags[K_NKINDS] = {"Verts", "Lines", "Polys", "Strips", "Cells"};

static sm_status piece_attributes(xml_in *c, const char *tag, const char *end)
{
    static const char *const counts[K_NKINDS] = {"NumberOfVerts", "NumberOfLines",
                                                 "NumberOfPolys", "NumberOfStrips",
                                                 "NumberOfCells"};
    if ((c->npoints = attr_int(tag, end, "NumberOfPoints", -1)) < 0)
        return fail(c, SM_ERR_FORMAT, "Piece without a NumberOfPoints");
    for (int k = 0; k < K_NKINDS; k++)
        if ((c->ncells[k] = attr_int(tag, end, counts[k], 0)) < 0 ||
            c->ncells[k] > SM_MAX_ENTITIES)
            return fail(c, SM_ERR_FORMAT, "Piece with a bad %s", counts[k]);
    return SM_OK;
}

/* Files a DataArray of parent (a tag name) under its role. */
static void file_array(xml_in *c, const char *parent, const xml_array *a)
{
    char name[64];
    attr(a->tag, a->tag_end, "Name", name, sizeof name);
    if (strcmp(parent, "Points") == 0 && !c->points.present)
        c->points = *a;
    if (strcmp(parent, "CellData") == 0 && sm__cells_ref_name(name) && !c->refs.present &&
        attr_int(a->tag, a->tag_end, "NumberOfComponents", 1) == 1)
        c->refs = *a;
    for (int k = 0; k < K_NKINDS; k++) {
        if (strcmp(parent, kind_tags[k]) != 0)
            continue;
        if (strcmp(name, "connectivity") == 0)
            c->conn[k] = *a;
        else if (strcmp(name, "offsets") == 0)
            c->offsets[k] = *a;
        else if (strcmp(name, "types") == 0 && k == K_CELLS)
            c->types = *a;
    }
}

/* The tags up to AppendedData (whose raw bytes may hold anything). */
static sm_status scan(xml_in *c)
{
    const char *p = c->buf, *end = c->buf + c->len;
    char parent[32] = "";
    int pieces = 0, have_file = 0;
    while ((p = memchr(p, '<', (size_t)(end - p))) != NULL) {
        const char *tag = p + 1;
        if (tag < end && (*tag == '?' || *tag == '!')) { /* declarations, comments */
            const char *q = strstr(tag, tag[0] == '!' && tag[1] == '-' ? "-->" : ">");
            if (!q)
                return fail(c, SM_ERR_FORMAT, "unterminated declaration or comment");
            p = q + 1;
            continue;
        }
        const char *close = memchr(tag, '>', (size_t)(end - tag));
        if (!close)
            return fail(c, SM_ERR_FORMAT, "unterminated tag");
        p = close + 1;
        if (*tag == '/') { /* the end of the parent (not of a DataArray) */
            if (parent[0] && is_name(tag + 1, close + 1, parent))
                parent[0] = '\0';
            continue;
        }
        sm_status st = SM_OK;
        if (is_name(tag, close, "VTKFile")) {
            have_file = 1;
            st = file_attributes(c, tag, close);
        } else if (is_name(tag, close, "Piece")) {
            if (++pieces > 1)
                return fail(c, SM_ERR_FORMAT, "more than one Piece (one is read)");
            st = piece_attributes(c, tag, close);
        } else if (is_name(tag, close, "DataArray")) {
            const char *text_end = memchr(p, '<', (size_t)(end - p));
            xml_array a = {tag, close, p, text_end ? text_end : end, 1};
            file_array(c, parent, &a);
        } else if (is_name(tag, close, "AppendedData")) {
            char enc[32];
            attr(tag, close, "encoding", enc, sizeof enc);
            c->appended_base64 = strcmp(enc, "raw") != 0;
            const char *u = memchr(p, '_', (size_t)(end - p));
            if (!u)
                return fail(c, SM_ERR_FORMAT, "AppendedData without its '_'");
            c->appended = u + 1;
            break;
        } else {
            size_t n = strcspn(tag, " \t\r\n/>");
            snprintf(parent, sizeof parent, "%.*s", (int)(n < 31 ? n : 31), tag);
        }
        if (st != SM_OK)
            return st;
    }
    if (!have_file || pieces == 0)
        return fail(c, SM_ERR_FORMAT, "no VTKFile with a Piece");
    return SM_OK;
}

/* At most this many values fit in the file (compressed data inflates). */
static uint64_t bytes_bound(const xml_in *c)
{
    return (uint64_t)c->len * (c->zlib ? ZLIB_MAX_RATIO : 1u);
}

/* One kind of cells (.vtu Cells, .vtp Verts/Lines/Polys/Strips). */
static sm_status read_kind(xml_in *c, int k, int64_t *cell)
{
    static const int kind_type[K_NKINDS] = {SM_VTK_POLY_VERTEX, SM_VTK_POLY_LINE,
                                            SM_VTK_POLYGON, SM_VTK_TRIANGLE_STRIP, 0};
    int64_t n = c->ncells[k], *off = NULL, *conn = NULL, *types = NULL;
    if (n == 0)
        return SM_OK;
    c->what = kind_tags[k];
    if ((uint64_t)n > bytes_bound(c))
        return fail(c, SM_ERR_FORMAT, "%" PRId64 " cells do not fit in the file", n);
    if (!c->conn[k].present || !c->offsets[k].present || (k == K_CELLS && !c->types.present))
        return fail(c, SM_ERR_FORMAT, "connectivity, offsets%s missing",
                    k == K_CELLS ? " or types" : "");
    sm_status st = check_declared(c, &c->offsets[k], n);
    if (st == SM_OK && k == K_CELLS)
        st = check_declared(c, &c->types, n);
    if (st != SM_OK)
        return st;
    if (!(off = malloc(((size_t)n + 1) * sizeof *off)) ||
        (k == K_CELLS && !(types = malloc((size_t)n * sizeof *types))))
        st = fail(c, SM_ERR_NOMEM, "out of memory");
    if (st == SM_OK) {
        off[0] = 0;
        st = read_array(c, &c->offsets[k], n, NULL, off + 1);
    }
    for (int64_t i = 0; st == SM_OK && i < n; i++)
        if (off[i + 1] < off[i])
            st = fail(c, SM_ERR_FORMAT, "offsets decrease at cell %" PRId64, i + 1);
    if (st == SM_OK && types)
        st = read_array(c, &c->types, n, NULL, types);
    if (st == SM_OK && (uint64_t)off[n] > bytes_bound(c))
        st = fail(c, SM_ERR_FORMAT, "%" PRId64 " connectivity entries do not fit in the file",
                  off[n]);
    if (st == SM_OK)
        st = check_declared(c, &c->conn[k], off[n]);
    if (st == SM_OK && !(conn = malloc(((size_t)off[n] + 1) * sizeof *conn)))
        st = fail(c, SM_ERR_NOMEM, "out of memory");
    if (st == SM_OK)
        st = read_array(c, &c->conn[k], off[n], NULL, conn);
    for (int64_t i = 0; st == SM_OK && i < n; i++) {
        int64_t t = types ? types[i] : kind_type[k];
        st = sm__cells_add_vtk(c->r, c->d, t > 255 ? 255 : (int)t, off[i + 1] - off[i],
                               conn + off[i], (*cell)++);
        if (st != SM_OK)
            st = fail(c, st, "%s", c->r->why);
    }
    free(off);
    free(conn);
    free(types);
    return st;
}

static sm_status read_pieces(xml_in *c)
{
    sm_status st = scan(c);
    if (st != SM_OK)
        return st;
    c->what = "Points";
    if (c->npoints > 0 && !c->points.present)
        return fail(c, SM_ERR_FORMAT, "missing");
    if (c->npoints > 0 &&
        attr_int(c->points.tag, c->points.tag_end, "NumberOfComponents", 1) != 3)
        return fail(c, SM_ERR_FORMAT, "NumberOfComponents is not 3");
    if ((uint64_t)c->npoints > bytes_bound(c) / 3)
        return fail(c, SM_ERR_FORMAT, "%" PRId64 " points do not fit in the file", c->npoints);
    if ((st = check_declared(c, &c->points, 3 * c->npoints)) != SM_OK)
        return st;
    if ((st = sm__cells_points(c->r, c->d, c->npoints, c->err)) != SM_OK)
        return fail(c, st, "%s", c->r->why);
    if ((st = read_array(c, &c->points, 3 * c->npoints, c->d->coords, NULL)) != SM_OK)
        return st;
    int64_t ncells = 0;
    static const int order[K_NKINDS] = {K_CELLS, K_VERTS, K_LINES, K_POLYS, K_STRIPS};
    for (int k = 0; k < K_NKINDS && st == SM_OK; k++)
        if (order[k] == K_CELLS ? !c->polydata : c->polydata)
            st = read_kind(c, order[k], &ncells);
    int32_t *refs = NULL;
    c->what = "CellData";
    if (st == SM_OK && c->refs.present && ncells > 0)
        st = check_declared(c, &c->refs, ncells);
    if (st == SM_OK && c->refs.present && ncells > 0) {
        int64_t *v = malloc((size_t)ncells * sizeof *v);
        refs = malloc((size_t)ncells * sizeof *refs);
        st = !v || !refs ? fail(c, SM_ERR_NOMEM, "out of memory")
                         : read_array(c, &c->refs, ncells, NULL, v);
        for (int64_t i = 0; st == SM_OK && i < ncells; i++) {
            if (v[i] < INT32_MIN || v[i] > INT32_MAX)
                st = fail(c, SM_ERR_FORMAT, "reference %" PRId64 " out of the int32 range",
                          v[i]);
            else
                refs[i] = (int32_t)v[i];
        }
        free(v);
    }
    if (st == SM_OK)
        sm__cells_finish(c->d, refs, ncells);
    free(refs);
    return st;
}

sm_status sm__vtkxml_parse(sm_reader *r, sm_msh_data *d, sm_error *err)
{
    sm__cells_init(d);
    xml_in c;
    memset(&c, 0, sizeof c);
    c.r = r;
    c.err = err;
    c.d = d;
    c.header_size = 4;
    sm_status st = slurp(&c);
    if (st == SM_OK)
        st = read_pieces(&c);
    free(c.buf);
    return st;
}
