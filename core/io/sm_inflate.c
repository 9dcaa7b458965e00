#include "io/sm_inflate.h"

#include <errno.h>
#include <libdeflate.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "sm_alloc.h"

/* The first output buffer is ISIZE bytes, but at least OUTPUT_MIN (an
 * ISIZE of 0 says nothing) and at most FIRST_RATIO times the compressed
 * size plus OUTPUT_MIN: ASCII meshes and solutions compress 2.5 to 10
 * times (examples/3d's background 2.4), so a real file takes one pass,
 * while a small file that claims a large size costs a small buffer (and
 * a file that does inflate that much, doublings). */
#define OUTPUT_MIN ((size_t)4096)
#define FIRST_RATIO 16

/* Buffers of this size or more take whole huge pages (sm__alloc_large
 * maps them): one fault each instead of one per 4 KiB page (for the
 * 1.2 MB of examples/3d's solution, about 0.2 instead of 4 ms here),
 * with at most a huge page resident beyond what is written, for as long
 * as the file is read. */
#define BUFFER_HUGE_MIN ((size_t)256 << 10)

/* The size of a buffer for at least want bytes. */
static size_t buffer_bytes(size_t want)
{
    size_t whole = (want + SM_HUGE_PAGE_BYTES - 1) / SM_HUGE_PAGE_BYTES * SM_HUGE_PAGE_BYTES;
    return want >= BUFFER_HUGE_MIN && whole >= want ? whole : want;
}

/* A new output buffer of at least *cap bytes (at most limit) holding the
 * used bytes of old, which is freed (*bytes: its size, then the new
 * one's).  *cap becomes the usable size, at most limit.  NULL when out of
 * memory. */
static unsigned char *grow_output(unsigned char *old, size_t *bytes, size_t used, size_t limit,
                                  size_t *cap)
{
    size_t size = buffer_bytes(*cap < limit ? *cap : limit);
    unsigned char *out = sm__alloc_large(size);
    if (out && used)
        memcpy(out, old, used);
    sm__free_large(old, *bytes);
    *bytes = out ? size : 0;
    *cap = size < limit ? size : limit;
    return out;
}

/* Inflates member after member of the gzip data in[0, n) into a new
 * buffer, as zlib's gzread reads them: another member follows while the
 * bytes left start with the gzip magic, and anything else after a member
 * is trailing garbage, ignored.  The buffer starts at hint bytes (within
 * the bounds said above) and doubles while a member does not fit, up to
 * limit; a hint above limit is taken at its word (the file is left to
 * zlib's stream at once rather than inflated up to limit in vain: a
 * large file, or one beyond the limit on inflated bytes).  Returns the buffer
 * (its inflated size in *len, its size in *bytes), or NULL when libdeflate does not take the
 * data (sm_inflate.h). */
static unsigned char *inflate_members(const unsigned char *in, size_t n, size_t hint,
                                      size_t limit, size_t *len, size_t *bytes)
{
    if (hint > limit)
        return NULL; /* the last member alone is too large: no work wasted */
    struct libdeflate_decompressor *d = libdeflate_alloc_decompressor();
    size_t cap = hint < OUTPUT_MIN ? OUTPUT_MIN : hint;
    if (n <= (SIZE_MAX - OUTPUT_MIN) / FIRST_RATIO && cap > FIRST_RATIO * n + OUTPUT_MIN)
        cap = FIRST_RATIO * n + OUTPUT_MIN;
    *bytes = 0;
    unsigned char *out = d ? grow_output(NULL, bytes, 0, limit, &cap) : NULL;
    size_t used = 0, at = 0;
    int members = 0;
    while (out && n - at >= 2 && in[at] == 0x1f && in[at + 1] == 0x8b) {
        size_t in_used, out_got;
        enum libdeflate_result res = libdeflate_gzip_decompress_ex(
            d, in + at, n - at, out + used, cap - used, &in_used, &out_got);
        if (res == LIBDEFLATE_SUCCESS) {
            at += in_used;
            used += out_got;
            members++;
            continue;
        }
        if (res != LIBDEFLATE_INSUFFICIENT_SPACE || cap == limit) {
            sm__free_large(out, *bytes);
            out = NULL;
            break;
        }
        cap = cap > limit / 2 ? limit : 2 * cap;
        out = grow_output(out, bytes, used, limit, &cap);
    }
    libdeflate_free_decompressor(d);
    if (out && !members) { /* the file no longer starts with a member */
        sm__free_large(out, *bytes);
        out = NULL;
    }
    *len = used;
    return out;
}

/* The size bytes of the regular file fd, read from its start into a new
 * buffer of *bytes bytes (sm__free_large).  NULL with *io_errno set on a
 * read error; NULL without (0) when out of memory or when the file no
 * longer has that size. */
static unsigned char *read_whole(int fd, size_t size, int *io_errno, size_t *bytes)
{
    *io_errno = 0;
    *bytes = buffer_bytes(size + 1); /* + 1: to see a file that grew */
    unsigned char *buf = sm__alloc_large(*bytes);
    size_t got = 0;
    while (buf && got <= size) {
        ssize_t n = pread(fd, buf + got, size + 1 - got, (off_t)got);
        if (n < 0 && errno == EINTR)
            continue;
        if (n < 0)
            *io_errno = errno;
        if (n <= 0)
            break;
        got += (size_t)n;
    }
    if (buf && (*io_errno || got != size)) {
        sm__free_large(buf, *bytes);
        buf = NULL;
    }
    return buf;
}

/* The gzip trailer's ISIZE: the inflated size mod 2^32 of the last
 * member, if the file is what it says. */
static size_t gzip_isize(const unsigned char *in, size_t n)
{
    if (n < 4)
        return 0;
    const unsigned char *t = in + n - 4;
    return (size_t)t[0] | (size_t)t[1] << 8 | (size_t)t[2] << 16 | (size_t)t[3] << 24;
}

unsigned char *sm__inflate_file(int fd, size_t size, size_t limit, size_t *len, size_t *bytes,
                                int *io_errno)
{
    *len = *bytes = 0;
    size_t in_bytes;
    unsigned char *in = read_whole(fd, size, io_errno, &in_bytes);
    if (!in)
        return NULL;
    unsigned char *out = inflate_members(in, size, gzip_isize(in, size), limit, len, bytes);
    sm__free_large(in, in_bytes);
    return out;
}
