/* Interior relaxation: better element quality for free, between the
 * descent's iterations.
 *
 * The descent's energy J + weight * T depends on the boundary only: J's
 * changes are integrals over the regions the boundary facets sweep
 * (sm_shape.h) and T is a distance to the boundary (sm_coverage.h).  So
 * the interior vertices can be moved anywhere that keeps the mesh valid
 * without changing the energy at all, and moving them where elements
 * degenerate (an inner corner of the target compresses the elements
 * behind it) gives the boundary room to move on before the quality floor
 * blocks the step search.
 *
 * sm__relax_run moves each free vertex (neither on the boundary nor
 * marked fixed, e.g. clamped) of the elements below a quality threshold
 * by a few steps of descent on the sum of the inverse qualities of its
 * elements (a barrier: infinite at a flat element), a step being taken
 * only when it lowers that sum and does not lower the worst quality of
 * those elements.  The mesh's worst quality can therefore only rise, no
 * element is inverted, and the boundary and the fixed vertices keep
 * their positions bit for bit. */
#ifndef SM_RELAX_H
#define SM_RELAX_H

#include <stdint.h>

#include "shapematch/sm_error.h"
#include "shapematch/sm_mesh.h"

typedef struct sm_relax sm_relax;

/* m must have its boundary built (sm_mesh_build_boundary); fixed (nverts
 * flags, may be NULL) marks further vertices that may not move.  Both are
 * borrowed for the relaxation's life.  SM_ERR_NOMEM. */
sm_status sm__relax_new(const sm_mesh *m, const uint8_t *fixed, sm_relax **out, sm_error *err);
void sm__relax_free(sm_relax *r);

/* Relaxes the free vertices of every element whose quality at coords is
 * below q_below (sweeps passes over them, the set found again in each
 * pass); coords (nverts * dim) is updated in place.  Returns the number
 * of vertex moves taken. */
int sm__relax_run(sm_relax *r, double *coords, double q_below, int sweeps);

#endif
