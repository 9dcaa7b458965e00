/* The outcome check shared by the multipart fuzz targets (fuzz_parts:
 * the part callbacks driven directly; fuzz_multipart: through a real
 * libmicrohttpd).  finish the request as the daemon does (close the part
 * being received, the required-parts check, the naming of the files by
 * content), then abort() unless the parts layer either keeps a first
 * error that is a status the daemon answers with, with a type and a
 * detail, or accepts a request whose parts are all stored (files on disk
 * under their final names, params within its cap) and whose hash is set. */
#ifndef FUZZ_PARTS_CHECK_H
#define FUZZ_PARTS_CHECK_H

#include "api/smd_parts.h"

/* The targets' upload folder: a new directory under /dev/shm (tmpfs: no
 * disk I/O per part) or /tmp, named after tag, removed at exit; abort()s
 * when it cannot be made.  Returns its path (static storage). */
const char *fuzz_parts_upload_dir(const char *tag);

void fuzz_parts_finish(smd_parts *p);
void fuzz_parts_check(const smd_parts *p);

#endif
