/* The files of `shapematch warp` (cmd_warp.c): a whole points file read
 * within a bound (the meshes, surfaces and fields are read by the warp
 * use case, job/sm_job_warp.h). */
#ifndef CLI_WARP_IO_H
#define CLI_WARP_IO_H

#include <stddef.h>

#include "shapematch/sm_error.h"

/* The whole of path into a new malloc'd buffer (*len bytes, plus a NUL
 * not counted).  More than max bytes is SM_ERR_NOMEM; SM_ERR_IO naming
 * the path. */
sm_status warp_read_file(const char *path, size_t max, char **out, size_t *len, sm_error *err);

#endif
