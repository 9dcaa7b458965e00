/* Internal output stream shared by the file-format writers (not part of
 * the public API).
 *
 * sm_writer: a buffered output stream to a plain or gzip file (chosen by
 * a ".gz" suffix).  Regular files are written to a temporary name in the
 * same directory and renamed on success, so a failed write never leaves
 * a half-written file under the final name.  Errors are sticky and
 * reported (with errno, e.g. ENOSPC) by sm__writer_close.
 *
 * Numbers are written as text by sm__writer_int and sm__writer_real
 * (sm_number.h: a tenth of vsnprintf's cost, and no locale at all); the
 * writer also sets the C numeric locale for the calling thread while
 * open (sm_stream.h), so that what sm__writer_printf formats writes '.'
 * whatever the application's locale. */
#ifndef SM_WRITER_H
#define SM_WRITER_H

#include <stddef.h>
#include <stdint.h>

#include "shapematch/sm_error.h"

typedef struct sm_writer sm_writer;

/* Opens path for writing; compression when the name ends in ".gz". */
sm_status sm__writer_open(sm_writer **out, const char *path, sm_error *err);
/* Flushes, closes and renames into place; on any error (including one
 * that happened during earlier writes) removes the partial file and
 * returns SM_ERR_IO.  Always frees w. */
sm_status sm__writer_close(sm_writer *w, sm_error *err);

/* Text: headers and keywords. */
void sm__writer_printf(sm_writer *w, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));
/* Text: one number in decimal, then the byte sep (' ' between the numbers
 * of a line, '\n' after the last).  sm__writer_int writes v as "%lld";
 * sm__writer_real writes x as "%.17g" (17 significant digits, which read
 * back to x bit for bit; sm__double_to_decimal). */
void sm__writer_int(sm_writer *w, int64_t v, char sep);
void sm__writer_real(sm_writer *w, double x, char sep);
/* Binary: bytes, and numbers in the machine's byte order. */
void sm__writer_bytes(sm_writer *w, const void *data, size_t n);
void sm__writer_i32(sm_writer *w, int32_t v);
void sm__writer_i64(sm_writer *w, int64_t v);
/* Logical bytes written so far (uncompressed). */
uint64_t sm__writer_offset(const sm_writer *w);

#endif
