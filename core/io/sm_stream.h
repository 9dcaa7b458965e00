/* What the byte streams of the file formats (sm_reader.h, sm_writer.h)
 * share (internal, not part of the public API): the C numeric locale for
 * the calling thread while a stream is open, so that "%.17g" and strtod
 * use '.' whatever the application's locale is; zlib's messages without
 * the "<fd:N>" name it gives to gzdopen'ed files; the gzip buffer size;
 * and the suffix test that picks compression (".gz") and formats. */
#ifndef SM_STREAM_H
#define SM_STREAM_H

#include <locale.h>

/* zlib's buffer for gzip streams, in each direction. */
#define SM_STREAM_ZLIB_BUF_SIZE (1u << 17)

/* Switches the calling thread to the C numeric locale: *c_locale is the
 * locale created (or (locale_t)0 when that failed, then nothing changed)
 * and *saved the one to restore with sm__stream_restore_locale. */
void sm__stream_use_c_locale(locale_t *c_locale, locale_t *saved);
void sm__stream_restore_locale(locale_t c_locale, locale_t saved);

/* msg (may be NULL) without zlib's "<fd:N>: " prefix; the callers add
 * the real path themselves. */
const char *sm__stream_zlib_message(const char *msg);

/* True when path ends in suffix (ASCII case-insensitive). */
int sm__path_has_suffix(const char *path, const char *suffix);

#endif
