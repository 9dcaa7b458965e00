#include "io/sm_reader.h"

#include <ctype.h>
#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "sm_alloc.h"
#include "io/sm_inflate.h"
#include "io/sm_number.h"
#include "io/sm_stream.h"

#define READ_BUF_SIZE (1u << 16)
#define READ_BUF_MIN 4096u

static void why(sm_reader *r, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void why(sm_reader *r, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(r->why, sizeof r->why, fmt, ap);
    va_end(ap);
}

uint32_t sm__bswap32(uint32_t v)
{
    return (v >> 24) | ((v >> 8) & 0xff00u) | ((v << 8) & 0xff0000u) | (v << 24);
}

uint64_t sm__bswap64(uint64_t v)
{
    return ((uint64_t)sm__bswap32((uint32_t)v) << 32) | sm__bswap32((uint32_t)(v >> 32));
}

/* ------------------------------------------------------------------ */
/* reader                                                              */
/* ------------------------------------------------------------------ */

/* The read buffer: the whole file when it is small (one read finds the
 * end), 64 KiB otherwise; the gzip buffer likewise sized to the input.
 * A small file then costs a small allocation, not 64K + 384K. */
static size_t read_buffer_size(uint64_t file_size)
{
    if (file_size >= READ_BUF_SIZE)
        return READ_BUF_SIZE;
    return file_size + 1 < READ_BUF_MIN ? READ_BUF_MIN : (size_t)file_size + 1;
}

static unsigned zlib_buffer_size(uint64_t file_size)
{
    if (file_size >= SM_STREAM_ZLIB_BUF_SIZE)
        return SM_STREAM_ZLIB_BUF_SIZE;
    return file_size < READ_BUF_MIN ? READ_BUF_MIN : (unsigned)file_size;
}

/* 1 when the regular file behind fd starts with the gzip magic, 0 when
 * it does not, -1 when that cannot be told without reading (pipes). */
static int gzip_magic(int fd, const struct stat *st)
{
    unsigned char m[2];
    if (!S_ISREG(st->st_mode))
        return -1;
    ssize_t n;
    do
        n = pread(fd, m, 2, 0);
    while (n < 0 && errno == EINTR);
    if (n < 0)
        return -1;
    return n == 2 && m[0] == 0x1f && m[1] == 0x8b;
}

/* zlib's stream over fd from its current offset, with a read buffer
 * (for gzip files not inflated whole, and pipes).  On failure fd is
 * closed. */
static int open_zlib(sm_reader *r, int fd)
{
    r->cap = read_buffer_size(r->file_size);
    r->buf = malloc(r->cap);
    r->gz = r->buf ? gzdopen(fd, "rb") : NULL;
    if (!r->gz) {
        close(fd);
        free(r->buf);
        r->buf = NULL;
        r->cap = 0;
        return -1;
    }
    gzbuffer(r->gz, zlib_buffer_size(r->file_size));
    return 0;
}

/* Plain regular files are read with read(2), and gzip regular files up
 * to SM_INFLATE_WHOLE_MAX bytes are inflated whole at the first read
 * (sm_inflate.h; their buffer is then the inflated file), when the limit
 * on inflated bytes is known: zlib's state and buffers are set up only
 * for the other gzip files, and for pipes, whose first bytes cannot be
 * looked at twice. */
static sm_status open_stream(sm_reader *r, int fd, const struct stat *st, sm_error *err)
{
    int magic = gzip_magic(fd, st);
    if (magic == 0) {
        r->cap = read_buffer_size(r->file_size);
        r->buf = malloc(r->cap);
        if (!r->buf) {
            close(fd);
            return sm_error_set(err, SM_ERR_NOMEM, "%s: out of memory", r->path);
        }
        r->fd = fd;
        return SM_OK;
    }
    if (magic == 1 && r->file_size <= SM_INFLATE_WHOLE_MAX) {
        r->fd = fd;
        r->compressed = 1;
        r->inflate = SM_INFLATE_WHOLE_PENDING;
        return SM_OK;
    }
    if (open_zlib(r, fd) != 0)
        return sm_error_set(err, SM_ERR_NOMEM, "%s: out of memory", r->path);
    r->compressed = !gzdirect(r->gz);
    return SM_OK;
}

sm_status sm__reader_open(sm_reader *r, const char *path, sm_error *err)
{
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0) {
        memset(r, 0, sizeof *r);
        r->fd = -1;
        return sm_error_set(err, SM_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    }
    return sm__reader_open_fd(r, path, fd, err);
}

sm_status sm__reader_open_fd(sm_reader *r, const char *path, int fd, sm_error *err)
{
    memset(r, 0, sizeof *r);
    r->path = path;
    r->line = 1;
    r->fd = -1;
    struct stat st;
    if (fstat(fd, &st) != 0) {
        int e = errno;
        close(fd);
        return sm_error_set(err, SM_ERR_IO, "%s: cannot stat: %s", path, strerror(e));
    }
    if (S_ISDIR(st.st_mode)) {
        close(fd);
        return sm_error_set(err, SM_ERR_IO, "%s: is a directory", path);
    }
    /* Pipes and devices have no size: no early bound then. */
    r->file_size = S_ISREG(st.st_mode) ? (uint64_t)st.st_size : UINT64_MAX / 2;
    sm_status s = open_stream(r, fd, &st, err);
    if (s != SM_OK)
        return s;
    sm__stream_use_c_locale(&r->c_locale, &r->saved_locale);
    return SM_OK;
}

sm_status sm__reader_open_memory(sm_reader *r, const char *name, const void *data, size_t size,
                                sm_error *err)
{
    memset(r, 0, sizeof *r);
    r->path = name;
    r->line = 1;
    r->fd = -1;
    const unsigned char *b = size ? data : (const unsigned char *)"";
    if (size >= 2 && b[0] == 0x1f && b[1] == 0x8b)
        return sm_error_set(err, SM_ERR_INVALID, "%s: gzip data is read from files only", name);
    /* The whole input is the buffer and the stream is at its end, so
     * refill() never writes to it. */
    r->buf = (unsigned char *)(uintptr_t)b;
    r->cap = r->len = size;
    r->file_size = size;
    r->at_eof = 1;
    r->borrowed = 1;
    sm__stream_use_c_locale(&r->c_locale, &r->saved_locale);
    return SM_OK;
}

sm_status sm__reader_open_input(sm_reader *r, const sm_reader_input *in, sm_error *err)
{
    if (in->data)
        return sm__reader_open_memory(r, in->path, in->data, in->size, err);
    return sm__reader_open(r, in->path, err);
}

void sm__reader_close(sm_reader *r)
{
    if (r->gz)
        gzclose(r->gz);
    if (r->fd >= 0)
        close(r->fd);
    if (r->inflate == SM_INFLATE_WHOLE)
        sm__free_large(r->buf, r->cap);
    else if (!r->borrowed)
        free(r->buf);
    sm__stream_restore_locale(r->c_locale, r->saved_locale);
    r->gz = NULL;
    r->fd = -1;
    r->buf = NULL;
    r->c_locale = (locale_t)0;
}

uint64_t sm__reader_offset(const sm_reader *r)
{
    return r->buf_offset + r->pos;
}

uint64_t sm__reader_max_remaining(const sm_reader *r)
{
    uint64_t off = sm__reader_offset(r);
    if (r->inflate == SM_INFLATE_WHOLE)
        return r->len - r->pos;
    if (!r->compressed)
        return r->file_size > off ? r->file_size - off : 0;
    if (r->file_size > UINT64_MAX / (2 * SM_DEFLATE_MAX_RATIO))
        return UINT64_MAX / 2;
    /* The whole decompressed size bounds what is left; the slack covers
     * gzip headers and zlib's internal buffering. */
    uint64_t most =
        r->file_size * SM_DEFLATE_MAX_RATIO + 2 * SM_STREAM_ZLIB_BUF_SIZE + READ_BUF_SIZE;
    if (r->limits && r->limits->max_inflated) {
        uint64_t cap = r->limits->max_inflated > off ? r->limits->max_inflated - off : 0;
        if (cap < most)
            most = cap;
    }
    return most;
}

/* The first read of a gzip file SM_INFLATE_WHOLE_PENDING: inflates it
 * whole into buf (then 1, at_eof set) or falls back to zlib's stream
 * from the start of the file (then 0: refill reads on), or fails on a
 * read error or out of memory (1, stream_status set). */
static int start_gzip(sm_reader *r)
{
    int fd = r->fd, io_errno;
    r->fd = -1;
    r->inflate = SM_INFLATE_STREAM;
    /* At most what the file can inflate to (the deflate ratio) and the
     * limit on inflated bytes allow: a lying ISIZE costs no more. */
    uint64_t most = sm__reader_max_remaining(r);
    size_t limit = most < SM_INFLATE_WHOLE_MAX ? (size_t)most : SM_INFLATE_WHOLE_MAX, len;
    size_t bytes;
    unsigned char *out = sm__inflate_file(fd, (size_t)r->file_size, limit, &len, &bytes, &io_errno);
    if (out || io_errno)
        close(fd);
    if (out) {
        r->inflate = SM_INFLATE_WHOLE;
        r->buf = out;
        r->cap = bytes;
        r->len = len;
        r->at_eof = 1;
        return 1;
    }
    if (io_errno) {
        r->stream_status = SM_ERR_IO;
        why(r, "read error: %s", strerror(io_errno));
        return 1;
    }
    if (open_zlib(r, fd) != 0) {
        r->stream_status = SM_ERR_NOMEM;
        why(r, "out of memory");
        return 1;
    }
    return 0;
}

/* refill() of a plain file: read(2) into the free end of the buffer. */
static void refill_plain(sm_reader *r)
{
    ssize_t n;
    do
        n = read(r->fd, r->buf + r->len, r->cap - r->len);
    while (n < 0 && errno == EINTR);
    if (n < 0) {
        r->stream_status = SM_ERR_IO;
        why(r, "read error: %s", strerror(errno));
    } else if (n == 0) {
        r->at_eof = 1;
    } else {
        r->len += (size_t)n;
    }
}

/* Appends more bytes to the buffer; sets at_eof or stream_status. */
static void refill(sm_reader *r)
{
    if (r->at_eof || r->stream_status != SM_OK)
        return;
    if (r->inflate == SM_INFLATE_WHOLE_PENDING && start_gzip(r) != 0)
        return; /* inflated whole, or an error */
    if (r->pos > 0) {
        size_t left = r->len - r->pos;
        memmove(r->buf, r->buf + r->pos, left);
        r->buf_offset += r->pos;
        r->pos = 0;
        r->len = left;
    }
    if (r->len == r->cap)
        return;
    if (r->fd >= 0) {
        refill_plain(r);
        return;
    }
    int n = gzread(r->gz, r->buf + r->len, (unsigned)(r->cap - r->len));
    int errnum = Z_OK;
    if (n < 0) {
        const char *msg = gzerror(r->gz, &errnum);
        if (errnum == Z_ERRNO) {
            r->stream_status = SM_ERR_IO;
            why(r, "read error: %s", strerror(errno));
        } else {
            r->stream_status = SM_ERR_FORMAT;
            why(r, "corrupt gzip data (%s)", sm__stream_zlib_message(msg));
        }
        return;
    }
    if (n == 0) {
        r->at_eof = 1;
        const char *msg = gzerror(r->gz, &errnum);
        if (errnum != Z_OK) {
            r->stream_status = SM_ERR_FORMAT;
            why(r, "truncated or corrupt gzip stream (%s)", sm__stream_zlib_message(msg));
        }
        return;
    }
    r->len += (size_t)n;
    if (r->compressed && r->limits && r->limits->max_inflated &&
        r->buf_offset + r->len > r->limits->max_inflated) {
        r->stream_status = SM_ERR_NOMEM;
        r->limits->hit = SM_LIMIT_INFLATED;
        why(r, "decompresses to more than the limit of %llu bytes",
            (unsigned long long)r->limits->max_inflated);
    }
}

static inline int peek_byte(sm_reader *r)
{
    if (r->pos == r->len) {
        refill(r);
        if (r->pos == r->len)
            return -1;
    }
    return r->buf[r->pos];
}

sm_status sm__reader_peek(sm_reader *r, void *dst, size_t n, size_t *got)
{
    while (r->len - r->pos < n && !r->at_eof && r->stream_status == SM_OK) {
        size_t before = r->len - r->pos;
        refill(r);
        if (r->len - r->pos == before && r->pos == 0 && r->len == r->cap)
            break;
    }
    if (r->stream_status != SM_OK)
        return r->stream_status;
    size_t have = r->len - r->pos;
    *got = have < n ? have : n;
    memcpy(dst, r->buf + r->pos, *got);
    return SM_OK;
}

sm_status sm__reader_window(sm_reader *r, const unsigned char **p, size_t *avail)
{
    if (r->pos == r->len)
        refill(r);
    *p = r->buf + r->pos;
    *avail = r->len - r->pos;
    return r->stream_status;
}

void sm__reader_consume(sm_reader *r, size_t k)
{
    r->pos += k <= r->len - r->pos ? k : r->len - r->pos;
}

static inline int is_space(int c)
{
    return c == ' ' || (unsigned)(c - '\t') <= (unsigned)('\r' - '\t'); /* \t \n \v \f \r */
}

void sm__quote_token(const char *s, char *out, size_t cap)
{
    size_t k = 0;
    if (cap < 8) {
        if (cap)
            out[0] = '\0';
        return;
    }
    out[k++] = '\'';
    for (size_t i = 0; s[i] && k + 5 < cap; i++) {
        unsigned char c = (unsigned char)s[i];
        if (i >= 40) {
            out[k++] = '.';
            out[k++] = '.';
            out[k++] = '.';
            break;
        }
        out[k++] = (c >= 32 && c < 127) ? (char)c : '?';
    }
    out[k++] = '\'';
    out[k] = '\0';
}

/* Length of the token at buf[pos], refilling until its end is in the
 * buffer (or the file ends): the token is then scanned in place rather
 * than byte by byte through peek_byte.  A token longer than the buffer
 * stops at its end (the caller reports it as too long). */
static size_t token_extent(sm_reader *r, int *nul)
{
    for (;;) {
        const unsigned char *b = r->buf;
        size_t i = r->pos, len = r->len;
        unsigned char all = 0xff;
        while (i < len && !is_space(b[i]) && b[i] != '#')
            all &= b[i++] ? 0xff : 0;
        *nul = !all;
        if (i < len || r->at_eof || r->stream_status != SM_OK)
            return i - r->pos;
        size_t before = len - r->pos;
        refill(r);
        if (r->len - r->pos == before)
            return before;
    }
}

sm_status sm__reader_token(sm_reader *r, int *found)
{
    *found = 0;
    int c;
    for (;;) {
        c = peek_byte(r);
        if (c < 0) {
            r->token_line = r->line;
            return r->stream_status;
        }
        if (c == '\n') {
            r->line++;
            r->pos++;
        } else if (is_space(c)) {
            r->pos++;
        } else if (c == '#') {
            while ((c = peek_byte(r)) >= 0 && c != '\n')
                r->pos++;
            if (c < 0)
                return r->stream_status;
        } else {
            break;
        }
    }
    r->token_line = r->line;
    int nul;
    size_t n = token_extent(r, &nul);
    if (r->stream_status != SM_OK)
        return r->stream_status;
    size_t keep = n < sizeof r->token ? n : sizeof r->token - 1;
    memcpy(r->token, r->buf + r->pos, keep);
    r->token[keep] = '\0';
    r->pos += n;
    if (n >= sizeof r->token) {
        char q[64];
        sm__quote_token(r->token, q, sizeof q);
        why(r, "found a token longer than %d characters (%s)", SM_TOKEN_LEN - 1, q);
        return SM_ERR_FORMAT;
    }
    /* An embedded NUL byte would silently shorten the token. */
    if (nul) {
        why(r, "found a NUL byte in a token");
        return SM_ERR_FORMAT;
    }
    *found = 1;
    return SM_OK;
}

static sm_status need_token(sm_reader *r)
{
    int found;
    sm_status st = sm__reader_token(r, &found);
    if (st != SM_OK)
        return st;
    if (!found) {
        why(r, "found end of file");
        return SM_ERR_FORMAT;
    }
    return SM_OK;
}

/* ---- fast paths of sm__reader_int / sm__reader_real ----
 * The common case, a plain number followed by whitespace inside the
 * buffer, is parsed in place (no byte-by-byte tokenizing, no copy into
 * r->token); anything else (comments, the buffer's end, a malformed or
 * out-of-range number, a token too long) falls back to the general
 * path, which gives the same result or the error. */

/* Skips whitespace from buf[pos] without consuming; *line advanced over
 * newlines.  Returns the index of the next byte (len at the end). */
static inline size_t skip_space_at(const sm_reader *r, long *line)
{
    const unsigned char *b = r->buf;
    size_t i = r->pos;
    while (i < r->len && is_space(b[i])) {
        *line += b[i] == '\n';
        i++;
    }
    return i;
}

/* Consumes a number found by a fast path, which ends before buf[end]. */
static inline void commit_number(sm_reader *r, size_t end, long line)
{
    r->pos = end;
    r->line = line;
    r->token_line = line;
}

static inline int fast_int(sm_reader *r, int64_t lo, int64_t hi, int64_t *out)
{
    long line = r->line;
    size_t start = skip_space_at(r, &line);
    const char *b = (const char *)r->buf;
    int64_t x;
    size_t end = start + sm__decimal_to_int(b + start, b + r->len, &x);
    if (end == start || end >= r->len || !is_space(b[end]) || x < lo || x > hi)
        return 0;
    commit_number(r, end, line);
    *out = x;
    return 1;
}

/* sm__decimal_to_double (sm_number.h) for the common forms, strtod in
 * place for the others. */
static inline int fast_real(sm_reader *r, double *out)
{
    long line = r->line;
    size_t start = skip_space_at(r, &line);
    const char *b = (const char *)r->buf;
    double v;
    size_t n = sm__decimal_to_double(b + start, b + r->len, &v);
    size_t end = start + n;
    if (n && n < SM_TOKEN_LEN && end < r->len && is_space(b[end])) {
        commit_number(r, end, line);
        *out = v;
        return 1;
    }
    end = start;
    while (end < r->len && !is_space(b[end]) && b[end] != '#')
        end++;
    if (end == start || end >= r->len || !is_space(b[end]) || end - start >= SM_TOKEN_LEN)
        return 0;
    char *stop;
    v = strtod(b + start, &stop);
    if (stop != b + end || !isfinite(v))
        return 0;
    commit_number(r, end, line);
    *out = v;
    return 1;
}

sm_status sm__reader_int(sm_reader *r, int64_t lo, int64_t hi, int64_t *out)
{
    if (fast_int(r, lo, hi, out))
        return SM_OK;
    sm_status st = need_token(r);
    if (st != SM_OK)
        return st;
    const char *s = r->token;
    int neg = 0;
    if (*s == '+' || *s == '-')
        neg = *s++ == '-';
    if (!isdigit((unsigned char)*s)) {
        char q[64];
        sm__quote_token(r->token, q, sizeof q);
        why(r, "found %s", q);
        return SM_ERR_FORMAT;
    }
    uint64_t v = 0;
    int overflow = 0;
    for (; (unsigned)(*s - '0') < 10u; s++) {
        if (v > (UINT64_MAX - 9) / 10)
            overflow = 1;
        else
            v = v * 10 + (uint64_t)(*s - '0');
    }
    if (*s) {
        char q[64];
        sm__quote_token(r->token, q, sizeof q);
        why(r, "found %s (trailing characters after the number)", q);
        return SM_ERR_FORMAT;
    }
    if (overflow || v > (uint64_t)INT64_MAX) {
        char q[64];
        sm__quote_token(r->token, q, sizeof q);
        why(r, "%s is out of range", q);
        return SM_ERR_FORMAT;
    }
    int64_t x = neg ? -(int64_t)v : (int64_t)v;
    if (x < lo || x > hi) {
        why(r, "%" PRId64 " is out of range [%" PRId64 ", %" PRId64 "]", x, lo, hi);
        return SM_ERR_FORMAT;
    }
    *out = x;
    return SM_OK;
}

sm_status sm__reader_real(sm_reader *r, double *out)
{
    if (fast_real(r, out))
        return SM_OK;
    sm_status st = need_token(r);
    if (st != SM_OK)
        return st;
    char *end;
    double v = strtod(r->token, &end);
    if (end == r->token) {
        char q[64];
        sm__quote_token(r->token, q, sizeof q);
        why(r, "found %s", q);
        return SM_ERR_FORMAT;
    }
    if (*end) {
        char q[64];
        sm__quote_token(r->token, q, sizeof q);
        why(r, "found %s (trailing characters after the number)", q);
        return SM_ERR_FORMAT;
    }
    if (!isfinite(v)) {
        char q[64];
        sm__quote_token(r->token, q, sizeof q);
        why(r, "%s is not a finite number", q);
        return SM_ERR_FORMAT;
    }
    *out = v;
    return SM_OK;
}

/* A string argument into buf (cap bytes, cap 0: skipped). */
static sm_status read_string(sm_reader *r, char *buf, size_t cap)
{
    int c;
    for (;;) {
        c = peek_byte(r);
        if (c < 0)
            break;
        if (c == '\n')
            r->line++;
        if (!is_space(c))
            break;
        r->pos++;
    }
    if (c != '"') {
        sm_status st = need_token(r);
        if (st == SM_OK && cap && strlen(r->token) >= cap) {
            why(r, "found a string longer than %zu bytes", cap - 1);
            return SM_ERR_FORMAT;
        }
        if (st == SM_OK && cap)
            snprintf(buf, cap, "%s", r->token);
        return st;
    }
    r->token_line = r->line;
    r->pos++;
    size_t n = 0;
    while ((c = peek_byte(r)) >= 0 && c != '"' && c != '\n') {
        if (cap && n + 1 >= cap) {
            why(r, "found a string longer than %zu bytes", cap - 1);
            return SM_ERR_FORMAT;
        }
        if (cap)
            buf[n++] = (char)c;
        r->pos++;
    }
    if (cap)
        buf[n] = '\0';
    if (r->stream_status != SM_OK)
        return r->stream_status;
    if (c != '"') {
        why(r, "found an unterminated string");
        return SM_ERR_FORMAT;
    }
    r->pos++;
    return SM_OK;
}

sm_status sm__reader_skip_string(sm_reader *r)
{
    return read_string(r, NULL, 0);
}

sm_status sm__reader_string(sm_reader *r, char *buf, size_t cap)
{
    return cap ? read_string(r, buf, cap) : SM_ERR_INVALID;
}

sm_status sm__reader_bytes(sm_reader *r, void *dst, size_t n)
{
    unsigned char *d = dst;
    while (n > 0) {
        if (r->pos == r->len) {
            refill(r);
            if (r->pos == r->len) {
                if (r->stream_status != SM_OK)
                    return r->stream_status;
                why(r, "unexpected end of file");
                return SM_ERR_FORMAT;
            }
        }
        size_t k = r->len - r->pos;
        if (k > n)
            k = n;
        memcpy(d, r->buf + r->pos, k);
        r->pos += k;
        d += k;
        n -= k;
    }
    return SM_OK;
}

sm_status sm__reader_skip(sm_reader *r, uint64_t n)
{
    while (n > 0) {
        if (r->pos == r->len) {
            refill(r);
            if (r->pos == r->len) {
                if (r->stream_status != SM_OK)
                    return r->stream_status;
                why(r, "unexpected end of file");
                return SM_ERR_FORMAT;
            }
        }
        size_t k = r->len - r->pos;
        if (k > n)
            k = (size_t)n;
        r->pos += k;
        n -= k;
    }
    return SM_OK;
}

/* 4 or 8 bytes in the file's byte order, stored into out unchanged in
 * meaning (integer or IEEE float alike). */
static sm_status read_word32(sm_reader *r, void *out)
{
    uint32_t v;
    sm_status st = sm__reader_bytes(r, &v, 4);
    if (st != SM_OK)
        return st;
    if (r->swap)
        v = sm__bswap32(v);
    memcpy(out, &v, 4);
    return SM_OK;
}

static sm_status read_word64(sm_reader *r, void *out)
{
    uint64_t v;
    sm_status st = sm__reader_bytes(r, &v, 8);
    if (st != SM_OK)
        return st;
    if (r->swap)
        v = sm__bswap64(v);
    memcpy(out, &v, 8);
    return SM_OK;
}

sm_status sm__reader_i32(sm_reader *r, int32_t *out)
{
    return read_word32(r, out);
}

sm_status sm__reader_i64(sm_reader *r, int64_t *out)
{
    return read_word64(r, out);
}

sm_status sm__reader_f32(sm_reader *r, float *out)
{
    return read_word32(r, out);
}

sm_status sm__reader_f64(sm_reader *r, double *out)
{
    return read_word64(r, out);
}

sm_status sm__reader_int_sized(sm_reader *r, int size, int64_t *out)
{
    if (size == 8)
        return sm__reader_i64(r, out);
    int32_t v;
    sm_status st = sm__reader_i32(r, &v);
    if (st == SM_OK)
        *out = v;
    return st;
}

sm_status sm__reader_fail_line(sm_reader *r, sm_error *err, sm_status code,
                              const char *fmt, ...)
{
    char msg[SM_ERROR_MSG_LEN];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    return sm_error_set(err, code, "%s:%ld: %s", r->path, r->token_line, msg);
}

sm_status sm__reader_fail_byte(sm_reader *r, sm_error *err, sm_status code,
                              uint64_t offset, const char *fmt, ...)
{
    char msg[SM_ERROR_MSG_LEN];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    return sm_error_set(err, code, "%s: byte %" PRIu64 ": %s", r->path, offset, msg);
}

sm_status sm__reader_limit_count(sm_reader *r, sm_error *err, int64_t n, int vertices,
                                const char *what)
{
    sm_read_limits *lim = r->limits;
    int64_t most = !lim ? 0 : vertices ? lim->max_vertices : lim->max_elements;
    if (most <= 0 || n <= most)
        return SM_OK;
    lim->hit = vertices ? SM_LIMIT_VERTICES : SM_LIMIT_ELEMENTS;
    return sm_error_set(err, SM_ERR_NOMEM, "%s: more than %lld %s, the limit on %s", r->path,
                        (long long)most, what, vertices ? "vertices" : "elements");
}
