/* Internal byte streams shared by the file-format readers and writers
 * (not part of the public API).
 *
 * sm_reader: a buffered input stream over a plain or gzip file (zlib
 * detects compression transparently), with
 *   - an ASCII tokenizer that skips whitespace and '#' comments and keeps
 *     the line number of the last token,
 *   - a binary reader that keeps the byte offset (in the decompressed
 *     stream) and swaps bytes when the file was written on a machine of
 *     the other endianness,
 *   - an upper bound on the bytes left, so that a count read from a file
 *     can be checked before anything is allocated for it.
 * Reading functions return SM_OK or an error code and leave a short
 * description of what was found in r->why ("found 'End'", "unexpected end
 * of file", ...); the format readers add file, line or byte and context.
 *
 * sm_writer: a buffered output stream to a plain or gzip file (chosen by
 * a ".gz" suffix).  Regular files are written to a temporary name in the
 * same directory and renamed on success, so a failed write never leaves
 * a half-written file under the final name.  Errors are sticky and
 * reported (with errno, e.g. ENOSPC) by sm_writer_close.
 *
 * Both set the C numeric locale for the calling thread while open, so
 * "%.17g"/strtod use '.' whatever the application's locale is. */
#ifndef SM_READER_H
#define SM_READER_H

#include <locale.h>
#include <stddef.h>
#include <stdint.h>
#include <zlib.h>

#include "sm_error.h"

#define SM_READER_WHY_LEN 160
#define SM_TOKEN_LEN 128

typedef struct sm_reader {
    const char *path;        /* borrowed, for messages */
    gzFile gz;
    unsigned char *buf;
    size_t cap, pos, len;
    uint64_t buf_offset;     /* stream offset of buf[0] */
    uint64_t file_size;      /* bytes on disk */
    int compressed;          /* 1 when the file is gzip */
    int at_eof;              /* underlying stream exhausted */
    sm_status stream_status; /* sticky I/O or gzip error */
    long line;               /* current line (1-based) */
    long token_line;         /* line of the last token */
    char token[SM_TOKEN_LEN];
    int swap;                /* binary: byte order differs from ours */
    char why[SM_READER_WHY_LEN];
    locale_t c_locale, saved_locale;
} sm_reader;

/* Opens path for reading (plain or gzip).  On failure nothing needs to
 * be closed. */
sm_status sm_reader_open(sm_reader *r, const char *path, sm_error *err);
void sm_reader_close(sm_reader *r);

/* Byte offset of the next unread byte in the (decompressed) stream. */
uint64_t sm_reader_offset(const sm_reader *r);

/* An upper bound on the bytes left in the (decompressed) stream: exact
 * for plain files, the deflate maximum ratio times the compressed size
 * for gzip files. */
uint64_t sm_reader_max_remaining(const sm_reader *r);

/* Copies up to n leading bytes without consuming them; *got tells how
 * many exist (fewer at end of file). */
sm_status sm_reader_peek(sm_reader *r, void *dst, size_t n, size_t *got);

/* ---- ASCII ---- */

/* Next whitespace-separated token into r->token (r->token_line set).
 * Returns SM_OK with *found = 0 at end of file. */
sm_status sm_reader_token(sm_reader *r, int *found);

/* Next token as an integer in [lo, hi] / as a finite real.  A missing
 * token, trailing characters, overflow or a non-finite value are errors
 * (SM_ERR_FORMAT) described in r->why. */
sm_status sm_reader_int(sm_reader *r, int64_t lo, int64_t hi, int64_t *out);
sm_status sm_reader_real(sm_reader *r, double *out);

/* Skips a string argument (Identifier, Geometry): one token, or a
 * double-quoted string possibly containing spaces, on one line. */
sm_status sm_reader_skip_string(sm_reader *r);

/* Writes a printable, truncated copy of s (quoted) into out. */
void sm_quote_token(const char *s, char *out, size_t cap);

/* ---- binary ---- */

/* Reads exactly n bytes (no swapping); a short read is SM_ERR_FORMAT
 * "unexpected end of file". */
sm_status sm_reader_bytes(sm_reader *r, void *dst, size_t n);
sm_status sm_reader_skip(sm_reader *r, uint64_t n);
sm_status sm_reader_i32(sm_reader *r, int32_t *out);
sm_status sm_reader_i64(sm_reader *r, int64_t *out);
sm_status sm_reader_f32(sm_reader *r, float *out);
sm_status sm_reader_f64(sm_reader *r, double *out);
/* An integer of 4 or 8 bytes (as the file version dictates). */
sm_status sm_reader_int_sized(sm_reader *r, int size, int64_t *out);

uint32_t sm_bswap32(uint32_t v);
uint64_t sm_bswap64(uint64_t v);

/* ---- errors with position ---- */

/* "path:line: message" (line of the last token). */
sm_status sm_reader_fail_line(sm_reader *r, sm_error *err, sm_status code,
                              const char *fmt, ...) __attribute__((format(printf, 4, 5)));
/* "path: byte N: message". */
sm_status sm_reader_fail_byte(sm_reader *r, sm_error *err, sm_status code,
                              uint64_t offset, const char *fmt, ...)
    __attribute__((format(printf, 5, 6)));

/* ---- Medit helpers shared by the mesh and solution readers ---- */

/* libMeshb keyword codes. */
enum {
    SM_KW_VERSION = 1, SM_KW_DIMENSION = 3, SM_KW_VERTICES = 4, SM_KW_EDGES = 5,
    SM_KW_TRIANGLES = 6, SM_KW_QUADRILATERALS = 7, SM_KW_TETRAHEDRA = 8,
    SM_KW_PRISMS = 9, SM_KW_HEXAHEDRA = 10, SM_KW_CORNERS = 13, SM_KW_RIDGES = 14,
    SM_KW_REQUIRED_VERTICES = 15, SM_KW_REQUIRED_EDGES = 16,
    SM_KW_REQUIRED_TRIANGLES = 17, SM_KW_NORMAL_AT_VERTICES = 20,
    SM_KW_PYRAMIDS = 49, SM_KW_END = 54, SM_KW_TANGENTS = 59, SM_KW_NORMALS = 60,
    SM_KW_TANGENT_AT_VERTICES = 61, SM_KW_SOL_AT_VERTICES = 62
};

/* Binary layout by file version: v1 float32 reals, int32 ints, int32
 * positions; v2 float64 reals; v3 also int64 positions; v4 also int64
 * integers (counts and record fields; the Dimension value and the
 * solution type table stay int32). */
typedef struct sm_meshb_layout {
    int version, int_size, real_size, pos_size;
} sm_meshb_layout;

/* Peeks at the first bytes: binary when they are the 32-bit code 1 in
 * either byte order.  An empty file is an error. */
sm_status sm_medit_detect(sm_reader *r, int *binary, sm_error *err);
/* Reads the code and version words, sets r->swap and the layout. */
sm_status sm_meshb_read_header(sm_reader *r, sm_meshb_layout *lay, sm_error *err);
/* Reads a keyword code and the position of the next keyword (0 when
 * there is none) and checks that position points forward and inside
 * the file.  At a clean end of file, *code = -1. */
sm_status sm_meshb_read_keyword(sm_reader *r, const sm_meshb_layout *lay,
                                int32_t *code, int64_t *next, sm_error *err);
/* After a block was read: the next keyword must start where it ends. */
sm_status sm_meshb_check_block_end(sm_reader *r, const char *section, int64_t next,
                                   sm_error *err);
/* Validates a record count before any allocation: not negative, not above
 * SM_MAX_ENTITIES, and not more records than the bytes left in the file
 * can hold (min_record_bytes each). */
sm_status sm_medit_check_count(sm_reader *r, int binary, const char *section, int64_t n,
                               uint64_t min_record_bytes, uint64_t where, sm_error *err);

/* ---- writer ---- */

typedef struct sm_writer sm_writer;

/* Opens path for writing; compression when the name ends in ".gz". */
sm_status sm_writer_open(sm_writer **out, const char *path, sm_error *err);
/* Flushes, closes and renames into place; on any error (including one
 * that happened during earlier writes) removes the partial file and
 * returns SM_ERR_IO.  Always frees w. */
sm_status sm_writer_close(sm_writer *w, sm_error *err);
/* Discards everything written (error paths of the callers). */
void sm_writer_abort(sm_writer *w);

void sm_writer_printf(sm_writer *w, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));
void sm_writer_bytes(sm_writer *w, const void *data, size_t n);
void sm_writer_i32(sm_writer *w, int32_t v);
void sm_writer_i64(sm_writer *w, int64_t v);
void sm_writer_f64(sm_writer *w, double v);
/* Logical bytes written so far (uncompressed). */
uint64_t sm_writer_offset(const sm_writer *w);

/* True when path ends in suffix (ASCII case-insensitive). */
int sm_path_has_suffix(const char *path, const char *suffix);

#endif
