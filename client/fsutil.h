/* File-system helpers of the client: `mkdir -p`, and files written under
 * a temporary name then renamed into place, so that an interrupted or
 * failed run never leaves a torn output under its final name. */
#ifndef CLI_FSUTIL_H
#define CLI_FSUTIL_H

#include <stdio.h>
#include <stddef.h>

/* dir + "/" + name, malloc'd (NULL when out of memory). */
char *fs_join(const char *dir, const char *name);

/* Creates path and its missing parents (like mkdir -p).  Returns 0, or
 * -1 with a message naming the path that could not be created. */
int fs_mkdir_p(const char *path, char *msg, size_t cap);

/* Checks that files can be created in dir (creates and removes a probe
 * file), so that a long run does not discover at the end that its
 * outputs cannot be written. */
int fs_check_writable(const char *dir, char *msg, size_t cap);

/* A stdio stream on a temporary file next to its final path. */
typedef struct fs_atomic {
    FILE *f;
    char *tmp_path;
    char *final_path;
} fs_atomic;

/* Opens "<dir>/.<name>.tmp-<pid>" for writing. */
int fs_atomic_open(fs_atomic *a, const char *path, char *msg, size_t cap);
/* Flushes, syncs, closes and renames to the final path; on any error
 * (including an earlier write error on the stream) removes the
 * temporary file and returns -1 with a message.  Always releases a. */
int fs_atomic_commit(fs_atomic *a, char *msg, size_t cap);
/* Removes the temporary file and releases a. */
void fs_atomic_abort(fs_atomic *a);

/* Temporary name for path that keeps its extension(s): "<dir>/.tmp-<pid>-
 * <name>", for writers that pick the format from the file name. */
char *fs_temp_name(const char *path);
/* fsync(path) then rename(tmp, path) and fsync of the directory. */
int fs_commit_file(const char *tmp, const char *path, char *msg, size_t cap);

#endif
