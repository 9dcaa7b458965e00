/* File-system helpers of the client: `mkdir -p` and a writability probe.
 * Files are written atomically through core's sm_atomic.h. */
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

#endif
