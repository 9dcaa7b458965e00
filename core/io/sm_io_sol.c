/* Medit solutions: .sol (ASCII) and .solb (binary, libMeshb versions 1-4),
 * plain or gzip, holding one SolAtVertices field: scalar (type 1), vector
 * (type 2) or symmetric tensor (type 3).  A symmetric tensor's components
 * are stored as Medit and Mmg store them, the lower triangle row by row:
 * xx, xy, yy in 2D and xx, xy, yy, xz, yz, zz in 3D (Mmg's reader swaps
 * the middle two into its own xx, xy, xz, yy, yz, zz order on reading). */
#include "shapematch/sm_io.h"

#include <inttypes.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "sm_alloc.h"
#include "io/sm_medit_common.h"
#include "io/sm_read_input.h"
#include "io/sm_reader.h"
#include "io/sm_stream.h"
#include "io/sm_writer.h"

enum { SOL_SCALAR = 1, SOL_VECTOR = 2, SOL_SYMMETRIC_MATRIX = 3, SOL_MATRIX = 4 };

sm_status sm_sol_alloc(sm_sol **out, int dim, int32_t nverts, int ncomp, sm_error *err)
{
    *out = NULL;
    if (dim != 2 && dim != 3)
        return sm_error_set(err, SM_ERR_INVALID, "solution dimension %d is not 2 or 3", dim);
    if (ncomp != 1 && ncomp != dim && ncomp != dim * (dim + 1) / 2)
        return sm_error_set(err, SM_ERR_INVALID,
                            "solution with %d components per vertex in dimension %d (expected 1, "
                            "%d or %d)",
                            ncomp, dim, dim, dim * (dim + 1) / 2);
    if (nverts < 0 || nverts > SM_MAX_ENTITIES)
        return sm_error_set(err, SM_ERR_NOMEM, "solution vertex count %ld out of range (limit %d)",
                            (long)nverts, SM_MAX_ENTITIES);
    sm_sol *s = calloc(1, sizeof *s);
    if (!s)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    s->dim = dim;
    s->nverts = nverts;
    s->ncomp = ncomp;
    size_t n = (size_t)nverts * (size_t)ncomp;
    /* zeroed as promised; the readers then write every value */
    s->values = sm__alloc_huge(n * sizeof(double));
    if (s->values)
        memset(s->values, 0, n * sizeof(double));
    if (!s->values) {
        free(s);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for a solution of %ld vertices",
                            (long)nverts);
    }
    *out = s;
    return SM_OK;
}

void sm_sol_free(sm_sol *s)
{
    if (!s)
        return;
    free(s->values);
    free(s);
}

typedef struct sol_in {
    sm_reader r;
    sm_error *err;
    int dim;
    int have_version;
    sm_sol *sol;
} sol_in;

/* The number of components of a solution type, or an error message. */
static int type_components(int64_t type, int dim, const char **problem)
{
    *problem = NULL;
    switch (type) {
    case SOL_SCALAR: return 1;
    case SOL_VECTOR: return dim;
    case SOL_SYMMETRIC_MATRIX: return dim * (dim + 1) / 2;
    case SOL_MATRIX: *problem = "matrix"; return 0;
    default: *problem = "unknown type"; return 0;
    }
}

/* ------------------------------------------------------------------ */
/* ASCII                                                               */
/* ------------------------------------------------------------------ */

static sm_status ascii_solution(sol_in *c)
{
    sm_reader *r = &c->r;
    sm_status st;
    int64_t n, nfields, type;
    if ((st = sm__reader_int(r, INT64_MIN, INT64_MAX, &n)) != SM_OK)
        return sm__reader_fail_line(r, c->err, st, "expected the number of SolAtVertices, %s",
                                   r->why);
    if ((st = sm__medit_check_count(r, 0, "SolAtVertices", n, 2, 0, c->err)) != SM_OK)
        return st;
    if ((st = sm__reader_int(r, INT64_MIN, INT64_MAX, &nfields)) != SM_OK)
        return sm__reader_fail_line(r, c->err, st,
                                   "expected the number of solution fields, %s", r->why);
    if (nfields != 1)
        return sm__reader_fail_line(r, c->err, SM_ERR_FORMAT,
                                   "SolAtVertices has %lld fields; exactly one field is supported",
                                   (long long)nfields);
    if ((st = sm__reader_int(r, INT64_MIN, INT64_MAX, &type)) != SM_OK)
        return sm__reader_fail_line(r, c->err, st, "expected the solution type, %s", r->why);
    const char *problem;
    int ncomp = type_components(type, c->dim, &problem);
    if (!ncomp)
        return sm__reader_fail_line(r, c->err, SM_ERR_FORMAT,
                                   "solution type %lld (%s) is not supported (expected 1 scalar, "
                                   "2 vector or 3 symmetric tensor)",
                                   (long long)type, problem);
    if ((st = sm__medit_check_count(r, 0, "SolAtVertices", n, 2 * (uint64_t)ncomp, 0, c->err)) !=
        SM_OK)
        return st;
    if ((st = sm_sol_alloc(&c->sol, c->dim, (int32_t)n, ncomp, c->err)) != SM_OK)
        return st;
    for (int64_t i = 0; i < n; i++)
        for (int j = 0; j < ncomp; j++) {
            st = sm__reader_real(r, &c->sol->values[i * ncomp + j]);
            if (st != SM_OK)
                return sm__reader_fail_line(r, c->err, st,
                                           "expected %d value%s in SolAtVertices record %lld of "
                                           "%lld, %s",
                                           ncomp, ncomp > 1 ? "s" : "", (long long)i + 1,
                                           (long long)n, r->why);
        }
    return SM_OK;
}

static sm_status read_ascii(sol_in *c)
{
    sm_reader *r = &c->r;
    for (;;) {
        int found;
        sm_status st = sm__reader_token(r, &found);
        if (st != SM_OK)
            return sm__reader_fail_line(r, c->err, st, "%s", r->why);
        if (!found || strcasecmp(r->token, "End") == 0)
            return SM_OK;
        int64_t v;
        double x;
        if (strcasecmp(r->token, "MeshVersionFormatted") == 0) {
            if (c->have_version)
                return sm__reader_fail_line(r, c->err, SM_ERR_FORMAT,
                                           "duplicate MeshVersionFormatted");
            if ((st = sm__reader_int(r, INT64_MIN, INT64_MAX, &v)) != SM_OK)
                return sm__reader_fail_line(r, c->err, st,
                                           "expected a version after MeshVersionFormatted, %s",
                                           r->why);
            if (v < 1 || v > 4)
                return sm__reader_fail_line(r, c->err, SM_ERR_FORMAT,
                                           "bad MeshVersionFormatted %lld (expected 1 to 4)",
                                           (long long)v);
            c->have_version = 1;
        } else if (strcasecmp(r->token, "Dimension") == 0) {
            if (c->dim)
                return sm__reader_fail_line(r, c->err, SM_ERR_FORMAT, "duplicate Dimension");
            if ((st = sm__reader_int(r, INT64_MIN, INT64_MAX, &v)) != SM_OK)
                return sm__reader_fail_line(r, c->err, st, "expected a value after Dimension, %s",
                                           r->why);
            if (v != 2 && v != 3)
                return sm__reader_fail_line(r, c->err, SM_ERR_FORMAT,
                                           "Dimension %lld is not supported (expected 2 or 3)",
                                           (long long)v);
            c->dim = (int)v;
        } else if (strcasecmp(r->token, "SolAtVertices") == 0) {
            if (!c->dim)
                return sm__reader_fail_line(r, c->err, SM_ERR_FORMAT,
                                           "SolAtVertices before Dimension (missing Dimension)");
            if (c->sol)
                return sm__reader_fail_line(r, c->err, SM_ERR_FORMAT,
                                           "duplicate SolAtVertices section");
            if ((st = ascii_solution(c)) != SM_OK)
                return st;
        } else if (strcasecmp(r->token, "Time") == 0) {
            if ((st = sm__reader_real(r, &x)) != SM_OK)
                return sm__reader_fail_line(r, c->err, st, "expected a number after Time, %s",
                                           r->why);
        } else if (strcasecmp(r->token, "Iterations") == 0) {
            if ((st = sm__reader_int(r, INT64_MIN, INT64_MAX, &v)) != SM_OK)
                return sm__reader_fail_line(r, c->err, st,
                                           "expected an integer after Iterations, %s", r->why);
        } else {
            char q[64];
            sm__quote_token(r->token, q, sizeof q);
            const char *s = r->token + (r->token[0] == '-' || r->token[0] == '+');
            if ((*s >= '0' && *s <= '9') || *s == '.')
                return sm__reader_fail_line(r, c->err, SM_ERR_FORMAT,
                                           "found the number %s where a keyword was expected "
                                           "(more values than the count and Dimension say?)",
                                           q);
            return sm__reader_fail_line(r, c->err, SM_ERR_FORMAT,
                                       "unexpected keyword %s in a solution file (expected "
                                       "MeshVersionFormatted, Dimension, SolAtVertices, End)",
                                       q);
        }
    }
}

/* ------------------------------------------------------------------ */
/* binary                                                              */
/* ------------------------------------------------------------------ */

static sm_status binary_solution(sol_in *c, const sm_meshb_layout *lay)
{
    sm_reader *r = &c->r;
    sm_status st;
    uint64_t at = sm__reader_offset(r);
    int64_t n;
    int32_t nfields, type;
    if ((st = sm__reader_int_sized(r, lay->int_size, &n)) != SM_OK)
        return sm__reader_fail_byte(r, c->err, st, at, "SolAtVertices count: %s", r->why);
    if ((st = sm__medit_check_count(r, 1, "SolAtVertices", n, (uint64_t)lay->real_size, at,
                                   c->err)) != SM_OK)
        return st;
    at = sm__reader_offset(r);
    if ((st = sm__reader_i32(r, &nfields)) != SM_OK)
        return sm__reader_fail_byte(r, c->err, st, at, "number of solution fields: %s", r->why);
    if (nfields != 1)
        return sm__reader_fail_byte(r, c->err, SM_ERR_FORMAT, at,
                                   "SolAtVertices has %ld fields; exactly one field is supported",
                                   (long)nfields);
    at = sm__reader_offset(r);
    if ((st = sm__reader_i32(r, &type)) != SM_OK)
        return sm__reader_fail_byte(r, c->err, st, at, "solution type: %s", r->why);
    const char *problem;
    int ncomp = type_components(type, c->dim, &problem);
    if (!ncomp)
        return sm__reader_fail_byte(r, c->err, SM_ERR_FORMAT, at,
                                   "solution type %ld (%s) is not supported (expected 1 scalar, "
                                   "2 vector or 3 symmetric tensor)",
                                   (long)type, problem);
    at = sm__reader_offset(r);
    if ((st = sm__medit_check_count(r, 1, "SolAtVertices", n,
                                   (uint64_t)lay->real_size * (uint64_t)ncomp, at, c->err)) !=
        SM_OK)
        return st;
    if ((st = sm_sol_alloc(&c->sol, c->dim, (int32_t)n, ncomp, c->err)) != SM_OK)
        return st;
    for (int64_t i = 0; i < n; i++)
        for (int j = 0; j < ncomp; j++) {
            double x;
            at = sm__reader_offset(r);
            if (lay->real_size == 4) {
                float f;
                st = sm__reader_f32(r, &f);
                x = f;
            } else {
                st = sm__reader_f64(r, &x);
            }
            if (st != SM_OK)
                return sm__reader_fail_byte(r, c->err, st, at,
                                           "SolAtVertices record %lld of %lld: %s",
                                           (long long)i + 1, (long long)n, r->why);
            if (!isfinite(x))
                return sm__reader_fail_byte(r, c->err, SM_ERR_FORMAT, at,
                                           "SolAtVertices record %lld of %lld: value is not a "
                                           "finite number (%g)",
                                           (long long)i + 1, (long long)n, x);
            c->sol->values[i * ncomp + j] = x;
        }
    return SM_OK;
}

static sm_status read_binary(sol_in *c)
{
    sm_reader *r = &c->r;
    sm_meshb_layout lay;
    sm_status st = sm__meshb_read_header(r, &lay, c->err);
    if (st != SM_OK)
        return st;
    for (;;) {
        uint64_t start = sm__reader_offset(r);
        int32_t code;
        int64_t next;
        if ((st = sm__meshb_read_keyword(r, &lay, &code, &next, c->err)) != SM_OK)
            return st;
        if (code == -1)
            return sm__reader_fail_byte(r, c->err, SM_ERR_FORMAT, start,
                                       "unexpected end of file (no End keyword; truncated?)");
        if (code == SM_KW_END)
            return SM_OK;
        const char *name = NULL;
        if (code == SM_KW_DIMENSION) {
            if (c->dim)
                return sm__reader_fail_byte(r, c->err, SM_ERR_FORMAT, start, "duplicate Dimension");
            int32_t d;
            uint64_t at = sm__reader_offset(r);
            if ((st = sm__reader_i32(r, &d)) != SM_OK)
                return sm__reader_fail_byte(r, c->err, st, at, "Dimension: %s", r->why);
            if (d != 2 && d != 3)
                return sm__reader_fail_byte(r, c->err, SM_ERR_FORMAT, at,
                                           "Dimension %ld is not supported (expected 2 or 3)",
                                           (long)d);
            c->dim = d;
            name = "Dimension";
        } else if (code == SM_KW_SOL_AT_VERTICES) {
            if (!c->dim)
                return sm__reader_fail_byte(r, c->err, SM_ERR_FORMAT, start,
                                           "SolAtVertices before Dimension (missing Dimension)");
            if (c->sol)
                return sm__reader_fail_byte(r, c->err, SM_ERR_FORMAT, start,
                                           "duplicate SolAtVertices section");
            if ((st = binary_solution(c, &lay)) != SM_OK)
                return st;
            name = "SolAtVertices";
        }
        if (name) {
            if ((st = sm__meshb_check_block_end(r, name, next, c->err)) != SM_OK)
                return st;
        } else if (next != 0) {
            uint64_t here = sm__reader_offset(r);
            if ((st = sm__reader_skip(r, (uint64_t)next - here)) != SM_OK)
                return sm__reader_fail_byte(r, c->err, st, here,
                                           "skipping keyword %ld up to byte %lld: %s", (long)code,
                                           (long long)next, r->why);
        }
        if (next == 0)
            return SM_OK;
    }
}

sm_status sm_sol_read(const char *path, sm_sol **out, sm_error *err)
{
    return sm_sol_read_limited(path, NULL, out, err);
}

sm_status sm_sol_read_limited(const char *path, sm_read_limits *limits, sm_sol **out,
                              sm_error *err)
{
    *out = NULL;
    if (!path)
        return sm_error_set(err, SM_ERR_INVALID, "no solution file name");
    return sm__sol_read_input(&(sm_reader_input){.path = path}, limits, out, err);
}

sm_status sm__sol_read_input(const sm_reader_input *in, sm_read_limits *limits, sm_sol **out,
                             sm_error *err)
{
    const char *path = in->path;
    *out = NULL;
    sol_in c;
    memset(&c, 0, sizeof c);
    c.err = err;
    sm_status st = sm__reader_open_input(&c.r, in, err);
    if (st != SM_OK)
        return st;
    c.r.limits = limits;
    int binary;
    st = sm__medit_detect(&c.r, &binary, err);
    if (st == SM_OK)
        st = binary ? read_binary(&c) : read_ascii(&c);
    if (st == SM_OK && !c.dim)
        st = sm_error_set(err, SM_ERR_FORMAT, "%s: missing Dimension", path);
    if (st == SM_OK && !c.sol)
        st = sm_error_set(err, SM_ERR_FORMAT, "%s: missing SolAtVertices", path);
    sm__reader_close(&c.r);
    if (st != SM_OK) {
        sm_sol_free(c.sol);
        return st;
    }
    *out = c.sol;
    return SM_OK;
}

/* ------------------------------------------------------------------ */
/* writing                                                             */
/* ------------------------------------------------------------------ */

sm_status sm_sol_write(const char *path, const sm_sol *s, sm_error *err)
{
    if (!path)
        return sm_error_set(err, SM_ERR_INVALID, "no solution file name");
    const int ntensor = s ? s->dim * (s->dim + 1) / 2 : 0;
    if (!s || (s->dim != 2 && s->dim != 3) ||
        (s->ncomp != 1 && s->ncomp != s->dim && s->ncomp != ntensor) ||
        s->nverts < 0 || (s->nverts > 0 && !s->values))
        return sm_error_set(err, SM_ERR_INVALID, "sm_sol_write: invalid solution");
    size_t n = (size_t)s->nverts * (size_t)s->ncomp;
    for (size_t i = 0; i < n; i++)
        if (!isfinite(s->values[i]))
            return sm_error_set(err, SM_ERR_INVALID,
                                "sm_sol_write: vertex %zu has a non-finite value",
                                i / (size_t)s->ncomp + 1);
    size_t len = strlen(path);
    size_t stem = sm__path_has_suffix(path, ".gz") ? len - 3 : len;
    int binary;
    if (stem >= 5 && strncasecmp(path + stem - 5, ".solb", 5) == 0)
        binary = 1;
    else if (stem >= 4 && strncasecmp(path + stem - 4, ".sol", 4) == 0)
        binary = 0;
    else
        return sm_error_set(err, SM_ERR_INVALID,
                            "%s: cannot tell the solution format from the name (expected .sol "
                            "or .solb, optionally followed by .gz)",
                            path);
    /* 2D: 2 components are a vector, 3 a tensor; 3D: 3 and 6 */
    int type = s->ncomp == 1 ? SOL_SCALAR : s->ncomp == s->dim ? SOL_VECTOR : SOL_SYMMETRIC_MATRIX;
    sm_writer *w;
    sm_status st = sm__writer_open(&w, path, err);
    if (st != SM_OK)
        return st;
    if (binary) {
        uint64_t bytes = (uint64_t)n * 8;
        int version = bytes + 64 < INT32_MAX ? 2 : 3;
        sm__writer_i32(w, 1);
        sm__writer_i32(w, version);
        uint64_t off = sm__writer_offset(w);
        sm__writer_i32(w, SM_KW_DIMENSION);
        if (version == 2)
            sm__writer_i32(w, (int32_t)(off + 12));
        else
            sm__writer_i64(w, (int64_t)(off + 16));
        sm__writer_i32(w, s->dim);
        off = sm__writer_offset(w);
        sm__writer_i32(w, SM_KW_SOL_AT_VERTICES);
        if (version == 2)
            sm__writer_i32(w, (int32_t)(off + 8 + 12 + bytes));
        else
            sm__writer_i64(w, (int64_t)(off + 12 + 12 + bytes));
        sm__writer_i32(w, s->nverts);
        sm__writer_i32(w, 1);
        sm__writer_i32(w, type);
        sm__writer_bytes(w, s->values, (size_t)bytes);
        sm__writer_i32(w, SM_KW_END);
        if (version == 2)
            sm__writer_i32(w, 0);
        else
            sm__writer_i64(w, 0);
    } else {
        sm__writer_printf(w,
                         "MeshVersionFormatted 2\n\nDimension %d\n\nSolAtVertices\n%ld\n1 %d\n\n",
                         s->dim, (long)s->nverts, type);
        for (int32_t i = 0; i < s->nverts; i++) {
            const double *v = s->values + (size_t)i * (size_t)s->ncomp;
            for (int c = 0; c < s->ncomp; c++)
                sm__writer_real(w, v[c], c + 1 < s->ncomp ? ' ' : '\n');
        }
        sm__writer_printf(w, "\nEnd\n");
    }
    return sm__writer_close(w, err);
}
