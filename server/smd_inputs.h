/* A job's inputs, read and checked together: the template mesh, the
 * target (background) mesh, the target's signed distance and the
 * parameters.  The daemon runs this on an upload before accepting it (so
 * that a job known to be bad never gets queued) and the worker runs it
 * again on the job folder, so both apply exactly the same rules:
 *
 *   - each file parses (core readers, hostile-input safe);
 *   - template and target have the same dimension;
 *   - the distance is a scalar field with one finite value per target
 *     vertex;
 *   - the template has a valid topology (sm_mesh_build_boundary on a
 *     copy) and the target mesh supports point location (sm_field_new);
 *   - the parameters decode against that dimension (sm_params_from_json);
 *   - the clamp set is not empty (ball, element or vertex references
 *     that match nothing), does not hold every vertex, and pins rigid
 *     rotations (not a single point, not collinear points in 3D).
 *
 * Messages start with the part they are about ("template: ...",
 * "target_sol: ...", "params.clamp.radius: ..."). */
#ifndef SMD_INPUTS_H
#define SMD_INPUTS_H

#include <stddef.h>
#include <stdint.h>

#include "sm_error.h"
#include "sm_field.h"
#include "sm_io.h"
#include "sm_match.h"
#include "sm_mesh.h"

typedef struct smd_inputs {
    sm_mesh *template_mesh;   /* as read (outputs keep its connectivity) */
    sm_mesh *background;
    sm_sol *distance;
    sm_field *field;          /* d on the background (borrows both) */
    sm_params params;
    int dim;
    int32_t nclamped;         /* template vertices in the clamp set */
} smd_inputs;

/* Reads and checks everything.  params_text need not be NUL-terminated.
 * On failure every member is freed and NULL.  Paths in the core's
 * messages are replaced by the part names. */
sm_status smd_inputs_load(const char *template_path, const char *target_mesh_path,
                          const char *target_sol_path, const char *params_text,
                          size_t params_len, smd_inputs *out, sm_error *err);
void smd_inputs_free(smd_inputs *in);

#endif
