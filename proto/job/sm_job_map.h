/* The map of a result set (sm_job_results.h), read back for
 * `shapematch warp`, the daemon's warp route and their benchmark
 * (core's sm_warp.h uses it; docs/warp.md has the conventions).
 *
 * A result folder holds the deformed mesh (result.mesh, else
 * result.meshb, either possibly .gz) and the displacement at its vertices
 * (displacement.sol, else .solb, possibly .gz): the template is the
 * deformed mesh's elements with coordinates result - displacement. */
#ifndef SM_JOB_MAP_H
#define SM_JOB_MAP_H

#include "shapematch/sm_error.h"
#include "shapematch/sm_mesh.h"

/* Reads dir's result: *tmpl the template (topology, references, the
 * template coordinates; free with sm_mesh_free) and *deformed the
 * deformed coordinates (tmpl->nverts * dim, malloc'd).  SM_ERR_IO when a
 * file is missing (naming what a result folder holds) or unreadable,
 * SM_ERR_FORMAT for a malformed file or a displacement that does not
 * match the mesh, SM_ERR_NOMEM; on error both are NULL. */
sm_status sm_job_map_read(const char *dir, sm_mesh **tmpl, double **deformed, sm_error *err);

#endif
