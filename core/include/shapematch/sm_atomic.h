/* Files written whole or not at all: the one atomic-write implementation
 * of the tree (the job runner's results, the daemon's spool files, the
 * client's downloads).
 *
 * A file is written under a temporary name in the folder of its final
 * path, then renamed over it: rename(2) within one folder is atomic, so
 * a reader sees the old file or the new one, never a torn one, and a
 * failed or interrupted write leaves no half-written file under the final
 * name.  The temporary name is "<dir>/.tmp-<pid>-<k>-<name>": hidden, so
 * listings skip it, and it keeps the final name's extension, so writers
 * that choose the format from the name (sm_mesh_write_coords, sm_sol_write,
 * sm_vtu_write) can write it.
 *
 * SM_ATOMIC_FSYNC also makes the result durable: the file is fsync'ed
 * before the rename and the folder after it, so after a crash the file
 * exists complete or not at all (what a job store needs; a local run's
 * outputs can skip the cost).
 *
 * Errors are SM_ERR_IO (SM_ERR_NOMEM) with a message naming the final
 * path; errno is left as the failing call set it, for callers that report
 * errno. */
#ifndef SM_ATOMIC_H
#define SM_ATOMIC_H

#include <stddef.h>
#include <stdio.h>

#include "sm_error.h"

#define SM_ATOMIC_FSYNC 1u

typedef struct sm_atomic {
    FILE *f;            /* sm_atomic_open: the temporary file, open for
                         * writing; NULL after sm_atomic_reserve */
    char *tmp_path;
    char *final_path;
} sm_atomic;

/* Creates the temporary file next to path and opens it for writing
 * (a->f).  Write to a->f, then commit or abort. */
sm_status sm_atomic_open(sm_atomic *a, const char *path, sm_error *err);
/* Creates the temporary file (empty) and closes it, for a writer that
 * takes a path: write a->tmp_path, then commit or abort. */
sm_status sm_atomic_reserve(sm_atomic *a, const char *path, sm_error *err);
/* Flushes and closes a->f (write errors on the stream count), fsyncs with
 * SM_ATOMIC_FSYNC, renames onto the final path and fsyncs its folder.  On
 * any error the temporary file is removed.  Always releases a. */
sm_status sm_atomic_commit(sm_atomic *a, unsigned flags, sm_error *err);
/* Removes the temporary file and releases a (a zeroed a is fine). */
void sm_atomic_abort(sm_atomic *a);

/* len bytes of data to path, atomically. */
sm_status sm_atomic_write_file(const char *path, const void *data, size_t len,
                               unsigned flags, sm_error *err);

/* fsync of a folder: makes creations and renames in it durable. */
sm_status sm_fsync_dir(const char *dir, sm_error *err);

#endif
