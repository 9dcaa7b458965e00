/* gzip files inflated whole by libdeflate (internal, not part of the
 * public API; the reader's fast path, sm_reader.h).
 *
 * libdeflate inflates a whole gzip file about 2.3 times as fast as
 * zlib's stream (examples/3d's 12 MB background: 18 against 42 ms of
 * CPU), but it wants the whole compressed file in memory and an output
 * buffer large enough.  So the file is read into memory and inflated
 * member by member into a buffer sized by the gzip trailer's ISIZE,
 * doubled while too small, up to a bound; the compressed copy is freed
 * before the caller gets the inflated file.  ISIZE is only a hint (the
 * size mod 2^32 of the last member alone, and a hostile file can say
 * anything): the bound is what holds.
 *
 * What this does not take (more than the bound, corrupt or truncated
 * data, a file that changed while it was read, out of memory), the
 * caller reads again from the start through zlib's stream, which gives
 * the result, the limit error or the corruption message, at the place in
 * the file, that it always gave: an error costs at most one inflation of
 * at most the bound more. */
#ifndef SM_INFLATE_H
#define SM_INFLATE_H

#include <stddef.h>

/* The largest gzip file, compressed and inflated, inflated whole: the
 * paper-size background of examples/3d inflates to 12 MB.  Both copies
 * are held for a moment, so larger files are streamed through zlib's
 * bounded buffers instead. */
#define SM_INFLATE_WHOLE_MAX ((size_t)64 << 20)

/* Deflate cannot expand data by more than about 1032:1: the compressed
 * size bounds the inflated one before anything is inflated. */
#define SM_DEFLATE_MAX_RATIO 1032u

/* The gzip regular file fd of size bytes inflated whole, read from its
 * start (with pread: fd's offset is left alone) into a new buffer of
 * *bytes bytes (free with sm__free_large(p, *bytes), sm_alloc.h) holding
 * at most limit inflated bytes, *len of them.  Members
 * are read as zlib's gzread reads them: another member follows while the
 * bytes left start with the gzip magic, anything else after a member is
 * trailing garbage, ignored.  NULL with *io_errno set on a read error;
 * NULL with *io_errno 0 when the file is not taken (see above). */
unsigned char *sm__inflate_file(int fd, size_t size, size_t limit, size_t *len, size_t *bytes,
                                int *io_errno);

#endif
