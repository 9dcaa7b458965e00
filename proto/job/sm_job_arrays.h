/* The binding API's inputs in memory (shapematch_job.h: sm_run_mesh,
 * sm_run_surface, a distance array) made into the core's objects, checked
 * as a reader checks a file's contents: sizes in range, reals finite,
 * indices naming a vertex (0-based).  Messages start with name (the part
 * as the caller calls it, "template (array)") and name the entry:
 * "template (array): element 7: vertex index 440 out of range [0, 440)".
 * SM_ERR_FORMAT for contents, SM_ERR_INVALID for a NULL array where
 * entries are counted, SM_ERR_NOMEM; *out NULL on error. */
#ifndef SM_JOB_ARRAYS_H
#define SM_JOB_ARRAYS_H

#include "shapematch/sm_io.h"
#include "shapematch/sm_mesh.h"
#include "shapematch/sm_surface.h"
#include "shapematch_job.h"

sm_status sm_job_mesh_from_arrays(const sm_run_mesh *a, const char *name, sm_mesh **out,
                                  sm_error *err);
sm_status sm_job_surface_from_arrays(const sm_run_surface *a, const char *name,
                                     sm_surface **out, sm_error *err);
/* n scalar values (a distance) for a mesh of dimension dim. */
sm_status sm_job_sol_from_values(const double *values, int32_t n, int dim, const char *name,
                                 sm_sol **out, sm_error *err);

#endif
