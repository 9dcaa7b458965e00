/* Internal input stream shared by the file-format readers (not part of
 * the public API; sm_writer.h is the output side, sm_medit_common.h the
 * Medit helpers built on this).
 *
 * sm_reader: a buffered input stream over a plain or gzip file (plain
 * files are read directly, and the buffers are sized to the input, so a
 * small file is cheap to open; a gzip file of moderate size is inflated
 * whole by libdeflate at the first read and then read in place, others
 * and pipes are streamed through zlib: sm_inflate.h),
 * with
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
 * The reader sets the C numeric locale for the calling thread while open
 * (sm_stream.h), so strtod reads '.' whatever the application's locale. */
#ifndef SM_READER_H
#define SM_READER_H

#include <locale.h>
#include <stddef.h>
#include <stdint.h>
#include <zlib.h>

#include "shapematch/sm_error.h"
#include "shapematch/sm_io.h"

#define SM_READER_WHY_LEN 160
#define SM_TOKEN_LEN 128

/* How a gzip file is inflated (sm_reader.inflate). */
enum { SM_INFLATE_STREAM, SM_INFLATE_WHOLE_PENDING, SM_INFLATE_WHOLE };

typedef struct sm_reader {
    const char *path;        /* borrowed, for messages */
    gzFile gz;               /* gzip input streamed (and pipes); else NULL */
    int fd;                  /* plain regular file read directly, or a gzip
                                one until it is inflated whole; else -1 */
    int inflate;             /* gzip files: SM_INFLATE_* (the first read
                                inflates a pending file whole into buf, or
                                falls back to streaming through gz) */
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
    sm_read_limits *limits;  /* borrowed; NULL: none (sm_io.h) */
    int borrowed;            /* buf is the caller's memory: not freed */
} sm_reader;

/* Opens path for reading (plain or gzip).  On failure nothing needs to
 * be closed. */
sm_status sm__reader_open(sm_reader *r, const char *path, sm_error *err);

/* The same over fd, an open file the reader then owns (closed by
 * sm__reader_close, or here on failure); path names it in messages. */
sm_status sm__reader_open_fd(sm_reader *r, const char *path, int fd, sm_error *err);

/* Opens a reader over size bytes at data, named name in messages: read
 * in place (no copy; data must outlive the reader) exactly as a plain
 * regular file of that content would be.  Gzip data (its magic) is
 * refused with SM_ERR_INVALID: inflating is done for files only.  For the
 * fuzz targets (tests/fuzz/), which hand each input over in memory. */
sm_status sm__reader_open_memory(sm_reader *r, const char *name, const void *data, size_t size,
                                sm_error *err);

/* What a format reader opens: a file (path), or memory (data, size)
 * named path in messages when data is not NULL. */
typedef struct sm_reader_input {
    const char *path;
    const void *data;
    size_t size;
} sm_reader_input;

/* sm__reader_open or sm__reader_open_memory, as in says. */
sm_status sm__reader_open_input(sm_reader *r, const sm_reader_input *in, sm_error *err);
void sm__reader_close(sm_reader *r);

/* Byte offset of the next unread byte in the (decompressed) stream. */
uint64_t sm__reader_offset(const sm_reader *r);

/* An upper bound on the bytes left in the (decompressed) stream: exact
 * for plain files and gzip files inflated whole, the deflate maximum
 * ratio times the compressed size (or the limit on inflated bytes) for
 * gzip files streamed. */
uint64_t sm__reader_max_remaining(const sm_reader *r);

/* Copies up to n leading bytes without consuming them; *got tells how
 * many exist (fewer at end of file). */
sm_status sm__reader_peek(sm_reader *r, void *dst, size_t n, size_t *got);

/* The buffered bytes from the next unread one: refills first when none
 * is buffered, then sets *p and *avail (0 only at the end of the stream
 * or on an error) and returns the stream's sticky error, if any (as
 * sm__reader_peek; sm__reader_bytes would still hand out bytes buffered
 * before the error).  sm__reader_consume(r, k) then consumes k <= *avail
 * of them.  For readers that scan with memchr rather than byte by byte
 * (OBJ lines, skipped .msh sections). */
sm_status sm__reader_window(sm_reader *r, const unsigned char **p, size_t *avail);
void sm__reader_consume(sm_reader *r, size_t k);

/* ---- ASCII ---- */

/* Next whitespace-separated token into r->token (r->token_line set).
 * Returns SM_OK with *found = 0 at end of file. */
sm_status sm__reader_token(sm_reader *r, int *found);

/* Next token as an integer in [lo, hi] / as a finite real (the double
 * strtod gives, bit for bit).  A missing token, trailing characters,
 * overflow or a non-finite value are errors (SM_ERR_FORMAT) described in
 * r->why.  r->token_line is the number's line; r->token is left alone
 * when the number is read in place (the common case). */
sm_status sm__reader_int(sm_reader *r, int64_t lo, int64_t hi, int64_t *out);
sm_status sm__reader_real(sm_reader *r, double *out);

/* Skips a string argument (Identifier, Geometry): one token, or a
 * double-quoted string possibly containing spaces, on one line. */
sm_status sm__reader_skip_string(sm_reader *r);
/* The same string argument copied into buf (without the quotes); one
 * of cap - 1 bytes or more is an error (SM_ERR_FORMAT, r->why). */
sm_status sm__reader_string(sm_reader *r, char *buf, size_t cap);

/* Writes a printable, truncated copy of s (quoted) into out. */
void sm__quote_token(const char *s, char *out, size_t cap);

/* ---- binary ---- */

/* Reads exactly n bytes (no swapping); a short read is SM_ERR_FORMAT
 * "unexpected end of file". */
sm_status sm__reader_bytes(sm_reader *r, void *dst, size_t n);
sm_status sm__reader_skip(sm_reader *r, uint64_t n);
sm_status sm__reader_i32(sm_reader *r, int32_t *out);
sm_status sm__reader_i64(sm_reader *r, int64_t *out);
sm_status sm__reader_f32(sm_reader *r, float *out);
sm_status sm__reader_f64(sm_reader *r, double *out);
/* An integer of 4 or 8 bytes (as the file version dictates). */
sm_status sm__reader_int_sized(sm_reader *r, int size, int64_t *out);

uint32_t sm__bswap32(uint32_t v);
uint64_t sm__bswap64(uint64_t v);

/* ---- errors with position ---- */

/* "path:line: message" (line of the last token). */
sm_status sm__reader_fail_line(sm_reader *r, sm_error *err, sm_status code,
                              const char *fmt, ...) __attribute__((format(printf, 4, 5)));
/* SM_ERR_NOMEM naming the bound when n records (vertices when vertices
 * is 1, else elements or facets) exceed r->limits (sm_io.h), with
 * limits->hit set; SM_OK otherwise.  For readers without a declared
 * count (STL, OBJ): called as the records grow. */
sm_status sm__reader_limit_count(sm_reader *r, sm_error *err, int64_t n, int vertices,
                                const char *what);
/* "path: byte N: message". */
sm_status sm__reader_fail_byte(sm_reader *r, sm_error *err, sm_status code,
                              uint64_t offset, const char *fmt, ...)
    __attribute__((format(printf, 5, 6)));

#endif
