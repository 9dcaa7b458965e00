/* The clamp set omega of the paper: which template vertices are held
 * fixed, and whether that makes the elasticity problem well posed. */
#ifndef SM_CLAMP_H
#define SM_CLAMP_H

#include <stdint.h>

#include "sm_error.h"
#include "sm_mesh.h"
#include "sm_params.h"

/* Flags (clamped[v] = 1) the vertices held by the clamp of p: inside the
 * ball (a relative tolerance keeps vertices placed exactly on its
 * sphere), vertices of elements with the listed references, or vertices
 * with the listed references; none for SM_CLAMP_NONE.  Returns how many. */
int32_t sm_clamp_mark(const sm_mesh *m, const sm_params *p, uint8_t *clamped);

/* Affine rank of the clamped vertices, capped at 2: 0 for one point (or
 * none), 1 for points on a line, 2 otherwise.  A clamp of rank < dim-1
 * leaves a rigid rotation free. */
int sm_clamp_rank(const sm_mesh *m, const uint8_t *clamped);

/* Checks the clamp of p on m: it must hold a vertex, not every vertex,
 * and leave no rigid rotation free.  SM_ERR_INVALID otherwise, with a
 * message that callers prefix with the option or field name ("the clamp
 * set is empty: no template vertex lies in the ball").  *nclamped (may be
 * NULL) receives the number of clamped vertices.  SM_CLAMP_NONE is always
 * fine (the alpha term makes the problem well posed). */
sm_status sm_clamp_check(const sm_mesh *m, const sm_params *p, int32_t *nclamped,
                         sm_error *err);

/* The clamp of every connected part of m (vertices joined by elements;
 * vertices of no element are ignored): a template in several pieces is
 * well posed only when each piece is held like a whole template (a
 * vertex and no rigid rotation free, as sm_clamp_check).  SM_OK for one
 * part (sm_clamp_check covers it) and for SM_CLAMP_NONE; SM_ERR_INVALID
 * naming a vertex of the first loose part otherwise.  O(vertices +
 * elements). */
sm_status sm_clamp_check_parts(const sm_mesh *m, const sm_params *p, sm_error *err);

/* The default clamp (params kind auto): a ball centred at the template's
 * deepest interior point (of its vertices and element centroids, the
 * farthest from its boundary facets: sm_sdf's exact distance), of radius
 * a quarter of that depth (the inradius), or of the distance to the
 * (dim+2)-th nearest vertex when that is larger.  m needs its boundary
 * (sm_mesh_build_boundary).  center has 3 entries (the third 0 in 2D). */
sm_status sm_clamp_default_ball(const sm_mesh *m, double center[3], double *radius,
                                double *inradius, sm_error *err);
/* p's clamp of kind auto made the default ball on m (grown by half until
 * sm_clamp_check holds, at most 8 times); *inradius (may be NULL) the
 * depth of its centre.  Any other kind: nothing. */
sm_status sm_clamp_resolve(const sm_mesh *m, sm_params *p, double *inradius, sm_error *err);

#endif
