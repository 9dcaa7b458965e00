/* NumPy .npy arrays of points (sm_io.h: sm_npy_parse, sm_npy_encode).
 *
 * The format (numpy/lib/format.py, "NEP 1"): the magic "\x93NUMPY", a
 * major and minor version byte, the header's length (2 bytes little-endian
 * in version 1, 4 bytes in versions 2 and 3), then the header: a Python
 * dict literal {'descr': '<f8', 'fortran_order': False, 'shape': (N, 3), }
 * padded with spaces and a '\n'; the data follow, C order.  The header is
 * read as the small language it is (three keys, strings, booleans, a
 * tuple of integers), not searched for substrings: a key twice, an
 * unknown key or anything after the dict is refused. */
#include "shapematch/sm_io.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define NPY_MAGIC "\x93NUMPY"
/* numpy writes headers of a few dozen bytes (64 aligned); bigger ones are
 * not ours to read */
#define NPY_HEADER_MAX 4096

typedef struct npy_header {
    int have_descr, have_order, have_shape;
    int itemsize;       /* 4 or 8 */
    int fortran;
    int ndim;
    int64_t shape[2];
} npy_header;

typedef struct cursor {
    const char *s, *end;
} cursor;

static void skip_blanks(cursor *c)
{
    while (c->s < c->end && (*c->s == ' ' || *c->s == '\t' || *c->s == '\n'))
        c->s++;
}

static int eat(cursor *c, char ch)
{
    skip_blanks(c);
    if (c->s < c->end && *c->s == ch) {
        c->s++;
        return 1;
    }
    return 0;
}

/* A quoted Python string ('...' or "..."), without escapes (numpy's keys
 * and type strings have none): its bytes in *s, *n. */
static int string(cursor *c, const char **s, size_t *n)
{
    skip_blanks(c);
    if (c->s >= c->end || (*c->s != '\'' && *c->s != '"'))
        return 0;
    char q = *c->s++;
    const char *a = c->s;
    while (c->s < c->end && *c->s != q) {
        if (*c->s == '\\')
            return 0;
        c->s++;
    }
    if (c->s >= c->end)
        return 0;
    *s = a;
    *n = (size_t)(c->s - a);
    c->s++;
    return 1;
}

static int word(cursor *c, const char *w)
{
    skip_blanks(c);
    size_t n = strlen(w);
    if ((size_t)(c->end - c->s) < n || memcmp(c->s, w, n) != 0)
        return 0;
    c->s += n;
    return 1;
}

/* A non-negative decimal integer of at most 15 digits (an L suffix, as
 * Python 2's numpy wrote, allowed). */
static int integer(cursor *c, int64_t *v)
{
    skip_blanks(c);
    int64_t x = 0;
    int digits = 0;
    while (c->s < c->end && *c->s >= '0' && *c->s <= '9') {
        if (++digits > 15)
            return 0;
        x = x * 10 + (*c->s++ - '0');
    }
    if (!digits)
        return 0;
    if (c->s < c->end && *c->s == 'L')
        c->s++;
    *v = x;
    return 1;
}

static sm_status bad(sm_error *err, const char *name, const char *what)
{
    return sm_error_set(err, SM_ERR_FORMAT, "%s: %s", name, what);
}

static sm_status parse_header(const char *h, size_t len, const char *name, npy_header *out,
                              sm_error *err)
{
    cursor c = {h, h + len};
    memset(out, 0, sizeof *out);
    if (!eat(&c, '{'))
        return bad(err, name, "the header is not a Python dict ('{' expected)");
    for (;;) {
        if (eat(&c, '}'))
            break;
        const char *k;
        size_t kn;
        if (!string(&c, &k, &kn) || !eat(&c, ':'))
            return bad(err, name, "the header's dict: a quoted key and ':' expected");
        if (kn == 5 && memcmp(k, "descr", 5) == 0 && !out->have_descr) {
            const char *v;
            size_t vn;
            if (!string(&c, &v, &vn))
                return bad(err, name, "descr: a type string expected (a structured type is "
                           "not a point array)");
            if (vn == 3 && (memcmp(v, "<f8", 3) == 0 || memcmp(v, "<f4", 3) == 0))
                out->itemsize = v[2] - '0';
            else
                return sm_error_set(err, SM_ERR_FORMAT, "%s: descr '%.*s': expected '<f8' "
                                    "(float64) or '<f4' (float32) little-endian; convert with "
                                    "a.astype('<f8')", name, (int)(vn > 16 ? 16 : vn), v);
            out->have_descr = 1;
        } else if (kn == 13 && memcmp(k, "fortran_order", 13) == 0 && !out->have_order) {
            if (word(&c, "False"))
                out->fortran = 0;
            else if (word(&c, "True"))
                out->fortran = 1;
            else
                return bad(err, name, "fortran_order: True or False expected");
            out->have_order = 1;
        } else if (kn == 5 && memcmp(k, "shape", 5) == 0 && !out->have_shape) {
            if (!eat(&c, '('))
                return bad(err, name, "shape: a tuple expected");
            while (!eat(&c, ')')) {
                int64_t v;
                if (out->ndim == 2 || !integer(&c, &v))
                    return bad(err, name, "shape: expected (N, 2) or (N, 3)");
                out->shape[out->ndim++] = v;
                if (!eat(&c, ',') && !(skip_blanks(&c), c.s < c.end && *c.s == ')'))
                    return bad(err, name, "shape: ',' or ')' expected");
            }
            out->have_shape = 1;
        } else {
            return sm_error_set(err, SM_ERR_FORMAT, "%s: the header's key '%.*s' is unknown or "
                                "given twice", name, (int)(kn > 32 ? 32 : kn), k);
        }
        if (!eat(&c, ',')) {
            if (!eat(&c, '}'))
                return bad(err, name, "the header's dict: ',' or '}' expected");
            break;
        }
    }
    skip_blanks(&c);
    if (c.s != c.end)
        return bad(err, name, "bytes after the header's dict");
    if (!out->have_descr || !out->have_order || !out->have_shape)
        return bad(err, name, "the header lacks descr, fortran_order or shape");
    if (out->fortran)
        return bad(err, name, "a Fortran-order array: save np.ascontiguousarray(a)");
    if (out->ndim != 2 || (out->shape[1] != 2 && out->shape[1] != 3)) {
        char got[64];
        if (out->ndim == 2)
            snprintf(got, sizeof got, "(%lld, %lld)", (long long)out->shape[0],
                     (long long)out->shape[1]);
        else
            snprintf(got, sizeof got, out->ndim == 1 ? "(%lld,)" : "()",
                     (long long)out->shape[0]);
        return sm_error_set(err, SM_ERR_FORMAT, "%s: shape %s: expected a 2-D array of shape "
                            "(N, 2) or (N, 3), one point a row", name, got);
    }
    return SM_OK;
}

sm_status sm_npy_parse(const void *bytes, size_t len, int64_t max_rows, const char *name,
                       double **values, int64_t *rows, int *cols, sm_error *err)
{
    *values = NULL;
    *rows = 0;
    *cols = 0;
    const unsigned char *b = bytes;
    if (len < 10 || memcmp(b, NPY_MAGIC, 6) != 0)
        return bad(err, name, "not a NumPy .npy file (no \\x93NUMPY magic)");
    int major = b[6];
    size_t at = major == 1 ? 10 : 12;
    if (major < 1 || major > 3 || len < at)
        return sm_error_set(err, SM_ERR_FORMAT, "%s: .npy version %d.%d: expected 1.0, 2.0 or "
                            "3.0", name, major, b[7]);
    size_t hlen = major == 1 ? (size_t)b[8] | (size_t)b[9] << 8
                             : (size_t)b[8] | (size_t)b[9] << 8 | (size_t)b[10] << 16 |
                                   (size_t)b[11] << 24;
    if (hlen > NPY_HEADER_MAX || hlen > len - at)
        return sm_error_set(err, SM_ERR_FORMAT, "%s: a header of %zu bytes %s", name, hlen,
                            hlen > NPY_HEADER_MAX ? "(a .npy header of points is under 4 KiB)"
                                                  : "runs past the end of the file");
    if (memchr(b + at, '\0', hlen))
        return bad(err, name, "a NUL byte in the header");
    npy_header h;
    sm_status st = parse_header((const char *)b + at, hlen, name, &h, err);
    if (st != SM_OK)
        return st;
    at += hlen;
    int64_t n = h.shape[0];
    int dim = (int)h.shape[1];
    size_t data = len - at, row_bytes = (size_t)dim * (size_t)h.itemsize;
    if ((uint64_t)n > data / row_bytes || data != (size_t)n * row_bytes)
        return sm_error_set(err, SM_ERR_FORMAT, "%s: shape (%lld, %d) of %d-byte values needs "
                            "%.0f bytes of data, the file has %zu", name, (long long)n, dim,
                            h.itemsize, (double)n * (double)row_bytes, data);
    if (n == 0)
        return bad(err, name, "no point (shape (0, ...))");
    if (max_rows > 0 && n > max_rows)
        return sm_error_set(err, SM_ERR_NOMEM, "%s: more than %lld points", name,
                            (long long)max_rows);
    double *v = malloc((size_t)n * (size_t)dim * sizeof *v);
    if (!v)
        return sm_error_set(err, SM_ERR_NOMEM, "%s: out of memory for %lld points", name,
                            (long long)n);
    const unsigned char *p = b + at;
    size_t count = (size_t)n * (size_t)dim;
    for (size_t i = 0; i < count; i++) {
        /* little-endian bytes to the host's value, whatever its order */
        if (h.itemsize == 8) {
            uint64_t u = 0;
            for (int k = 7; k >= 0; k--)
                u = u << 8 | p[8 * i + (size_t)k];
            memcpy(&v[i], &u, sizeof u);
        } else {
            uint32_t u = 0;
            float f;
            for (int k = 3; k >= 0; k--)
                u = u << 8 | p[4 * i + (size_t)k];
            memcpy(&f, &u, sizeof u);
            v[i] = f;
        }
        if (!(v[i] - v[i] == 0)) { /* NaN or infinite */
            free(v);
            return sm_error_set(err, SM_ERR_FORMAT, "%s: point %zu, coordinate %zu is not "
                                "finite", name, i / (size_t)dim, i % (size_t)dim);
        }
    }
    *values = v;
    *rows = n;
    *cols = dim;
    return SM_OK;
}

sm_status sm_npy_encode(const double *values, int64_t rows, int cols, char **out, size_t *len,
                        sm_error *err)
{
    *out = NULL;
    *len = 0;
    if (rows < 0 || cols < 1 || cols > 9)
        return sm_error_set(err, SM_ERR_INVALID, ".npy: shape (%lld, %d) not written",
                            (long long)rows, cols);
    char dict[128];
    int dn = snprintf(dict, sizeof dict, "{'descr': '<f8', 'fortran_order': False, "
                      "'shape': (%lld, %d), }", (long long)rows, cols);
    /* magic, version 1.0, length; the header padded with spaces to a
     * multiple of 64 bytes in all, ending in '\n', as numpy writes it */
    size_t head = 10 + (size_t)dn + 1;
    size_t padded = (head + 63) / 64 * 64;
    size_t count = (size_t)rows * (size_t)cols;
    size_t total = padded + count * 8;
    char *b = malloc(total ? total : 1);
    if (!b)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for a .npy of %lld points",
                            (long long)rows);
    memcpy(b, NPY_MAGIC, 6);
    b[6] = 1;
    b[7] = 0;
    size_t hlen = padded - 10;
    b[8] = (char)(hlen & 0xff);
    b[9] = (char)(hlen >> 8);
    memcpy(b + 10, dict, (size_t)dn);
    memset(b + 10 + dn, ' ', padded - 10 - (size_t)dn - 1);
    b[padded - 1] = '\n';
    unsigned char *p = (unsigned char *)b + padded;
    for (size_t i = 0; i < count; i++) {
        uint64_t u;
        memcpy(&u, &values[i], sizeof u);
        for (int k = 0; k < 8; k++)
            p[8 * i + (size_t)k] = (unsigned char)(u >> (8 * k));
    }
    *out = b;
    *len = total;
    return SM_OK;
}
