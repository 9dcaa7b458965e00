/* Pre-alignment: a global transform x -> A x + b that puts the template
 * onto the target before the elastic descent, found from the target's
 * signed distance d alone (no point correspondences), or started from
 * landmark pairs.
 *
 * The misfit is two-sided, a symmetric chamfer: the mean of rho(d(A x +
 * b)) over the template's boundary quadrature points x (the template's
 * boundary to the target), plus the mean of rho(D(z)) over the target
 * surface's quadrature points z, D the signed distance to the moved
 * template's boundary (the target to the template).  The first side
 * alone is won by any template small enough to fit inside the target (a
 * capsule squeezed into one arm of a bent target); the second is large
 * for it, so similarity and affine scales follow the target's extent.
 * Each mean is weighted by measure (two Gauss points per edge in 2D, the
 * 3-point rule per triangle in 3D), rho is Huber's (its threshold 1.345
 * times each side's robust spread, 1.4826 median |r|, at each iteration),
 * so a part far from the other shape (partial overlap) pulls linearly,
 * not quadratically.
 *
 * The target is a surface (opts.surface: its exact signed distance and
 * hierarchy, sm_sdf.h) or a sampled field (opts.target on a background:
 * its zero level set, by marching simplices, gives the target's points).
 * With a surface every residual is exact: d(y) is the distance to the
 * nearest facet with the winding number's sign, and the refinement is
 * point-to-plane ICP on both sides, so a known map is recovered to
 * rounding, not to the field's interpolation error.  D is exact for
 * rigid and similarity maps (the nearest template point of t^-1 z, moved);
 * for an affine map it is the distance to that point.
 *
 *   1. start: the moments of the template's volume against the target's
 *      (the volume the surface encloses, by the divergence theorem; or
 *      the region d < 0 of the field): centroids, principal axes and, for
 *      similarity, the volume ratio.  The principal axes fix the rotation
 *      only up to a signed permutation, so every proper one is tried (24
 *      in 3D, 4 in 2D) and the few with the smallest two-sided mean square
 *      (on the coarse level below) are refined: a 180-degree flip
 *      or a near-symmetric shape does not trap the start.  This coarse
 *      level is point clouds: 500 points a side with their normals,
 *      symmetric point-to-plane residuals to the nearest point of the
 *      other side (brute force: cheap at any distance, where an exact
 *      nearest-facet search from a far start visits most of a surface).
 *      Or, with landmarks, Kabsch/Umeyama (below).
 *   2. refinement: Levenberg-Marquardt (Gauss-Newton rows: the gradient
 *      of d at the moved point; -grad D at the target point, the nearest
 *      template point held) on the coarse level, then with the exact
 *      residuals on at most 2000 points a side (at most 8 iterations: an
 *      exact fit converges in a few, an inexact one only polishes).  Rigid: translation + rotation (increments by the
 *      exponential map); similarity: + one scale; affine: the similarity
 *      result, then the full matrix, each step refused when it would
 *      leave det A <= 0 or a condition number above
 *      SM_ALIGN_AFFINE_COND_MAX.
 *
 * The 3x3 eigen problems (cyclic Jacobi) and the SVD of Kabsch
 * (one-sided Jacobi on the matrix itself) are written out
 * (core/sm_align_linalg.c): tiny, exact to rounding, and no LAPACK
 * dependency for the core. */
#ifndef SM_ALIGN_H
#define SM_ALIGN_H

#include <stddef.h>
#include <stdint.h>

#include "sm_error.h"
#include "sm_field.h"
#include "sm_mesh.h"
#include "sm_params.h"
#include "sm_sdf.h"

/* sm_align_mode and its names: sm_params.h (the parameter "align"). */

/* Largest condition number (ratio of singular values) of an affine A. */
#define SM_ALIGN_AFFINE_COND_MAX 1e3
/* Most landmarks in one file (each a row of dim numbers). */
#define SM_LANDMARKS_MAX 100000

/* x -> a x + b in dim (2 or 3) dimensions (a[2][*], b[2] unused in 2D). */
typedef struct sm_transform {
    int dim;
    double a[3][3];
    double b[3];
} sm_transform;

void sm_transform_identity(sm_transform *t, int dim);
/* out[i] = a in[i] + b for n points of dim coordinates; in == out allowed. */
void sm_transform_apply(const sm_transform *t, int64_t n, const double *in, double *out);
/* |det a|^(1/dim): the scale of a similarity, a mean scale otherwise. */
double sm_transform_scale(const sm_transform *t);
/* The (dim+1)x(dim+1) homogeneous matrix, row-major, into m. */
void sm_transform_homogeneous(const sm_transform *t, double *m);

typedef struct sm_align_opts {
    sm_align_mode mode;               /* not NONE */
    const sm_mesh *template_mesh;     /* boundary built (sm_mesh_build_boundary) */
    const sm_sdf *surface;            /* the target as a surface (its exact
                                       * distance; the surface outlives the
                                       * call), or NULL and: */
    const sm_field *target;           /* d of the target */
    const sm_mesh *background;        /* the field's mesh and its values: */
    const double *distance;           /* the inside region d < 0 for the
                                       * moments, its zero level set for the
                                       * target's points */
    const sm_transform *start;        /* NULL: the moments' candidates; else
                                       * this start (landmarks) refined */
    int max_iter;                     /* refinement iterations; 0: 100 */
    const volatile int *cancel;       /* may be NULL; nonzero: stop.  Polled
                                       * before each pass over the points
                                       * (a candidate's screening, an
                                       * iteration, a damping trial), so a
                                       * cancel waits for at most one pass */
} sm_align_opts;

typedef struct sm_align_result {
    sm_transform transform;           /* template -> target */
    double scale;                     /* sm_transform_scale */
    double rms_before, rms_after;     /* weighted RMS of d over the boundary
                                       * quadrature points: template as given,
                                       * and moved by transform */
    double target_rms_after;          /* the other side: weighted RMS over
                                       * the target's surface points of their
                                       * distance to the moved template */
    int iterations;                   /* refinement iterations (all stages) */
    int candidates;                   /* starts tried (1 with a given start) */
    double seconds;
    int cancelled;                    /* 1: *cancel stopped it; transform and
                                       * rms_after are then where it stood,
                                       * not an alignment */
} sm_align_result;

/* Computes the alignment.  SM_ERR_INVALID for mode NONE, a template with
 * no boundary or volume, a target with no inside region (d >= 0 at every
 * background vertex, or a surface that encloses no volume) without a
 * start, a dimension mismatch; SM_ERR_NOMEM.
 * Deterministic (its parallel loops are per point).  A cancel is not an
 * error: SM_OK with out->cancelled set (like a cancelled descent). */
sm_status sm_align_run(const sm_align_opts *opts, sm_align_result *out, sm_error *err);

/* Kabsch (rigid) or Umeyama (similarity) least-squares transform taking
 * the n template landmarks src onto the target landmarks dst (n*dim
 * each), exact for noiseless pairs; AFFINE gives the similarity (the
 * refinement then frees the matrix).  SM_ERR_INVALID with a message for
 * users: n < dim, a non-finite coordinate, src or dst degenerate
 * (coincident in 2D, collinear in 3D), NONE. */
sm_status sm_align_landmarks(int dim, int32_t n, const double *src, const double *dst,
                             sm_align_mode mode, sm_transform *out, sm_error *err);

#endif
