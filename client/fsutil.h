/* File-system helpers of the client: an output folder made and probed.
 * Paths are joined and folders made by core's sm_path.h, files written
 * atomically through its sm_atomic.h. */
#ifndef CLI_FSUTIL_H
#define CLI_FSUTIL_H

#include <stdio.h>
#include <stddef.h>

/* An output folder: creates dir and its missing parents (sm_mkdir_p),
 * then fs_check_writable.  0, or -1 with a message naming the path. */
int fs_output_dir(const char *dir, char *msg, size_t cap);

/* Checks that files can be created in dir (creates and removes a probe
 * file), so that a long run does not discover at the end that its
 * outputs cannot be written. */
int fs_check_writable(const char *dir, char *msg, size_t cap);

#endif
