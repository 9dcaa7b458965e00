/* Paths and folders: the one path join and the one `mkdir -p` of the
 * tree (the job runner's result files, the client's outputs and
 * downloads), beside the one atomic write (sm_atomic.h). */
#ifndef SM_PATH_H
#define SM_PATH_H

#include "sm_error.h"

/* dir + "/" + name, malloc'd (NULL when out of memory); no second slash
 * when dir already ends with one. */
char *sm_path_join(const char *dir, const char *name);

/* Creates path and its missing parents (like mkdir -p; mode 0777 before
 * the umask); folders that exist are fine.  SM_ERR_IO naming the path
 * that could not be created (a file of that name, or the system's
 * reason), SM_ERR_NOMEM. */
sm_status sm_mkdir_p(const char *path, sm_error *err);

#endif
