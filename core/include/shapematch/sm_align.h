/* Pre-alignment: a global transform x -> A x + b that puts the template
 * onto the target before the elastic descent, found from the target's
 * signed distance d alone (no point correspondences), or started from
 * landmark pairs.
 *
 *   1. start: the moments of the template's volume against the target's
 *      inside region (d < 0 on the background): centroids, principal axes
 *      and, for similarity, the volume ratio.  The principal axes fix the
 *      rotation only up to a signed permutation, so every proper one is
 *      tried (24 in 3D, 4 in 2D) and the few with the smallest
 *      sum w d(A x + b)^2 over the template's boundary quadrature points
 *      are refined: a 180-degree flip or a near-symmetric shape does not
 *      trap the start.  Or, with landmarks, Kabsch/Umeyama (below).
 *   2. refinement: Levenberg-Marquardt on sum w rho(d(A x + b)) over the
 *      boundary quadrature points (two Gauss points per edge in 2D, three
 *      per triangle in 3D, w the facet's measure in the template), with
 *      the field's gradient and Huber's rho (its threshold 1.345 times the
 *      residuals' robust spread, 1.4826 median |d|, at each iteration), so
 *      a part of the boundary far from the target (partial overlap) pulls
 *      linearly, not quadratically.  Rigid: translation + rotation
 *      (increments by the exponential map); similarity: + one scale;
 *      affine: the similarity result, then the full matrix, each step
 *      refused when it would leave det A <= 0 or a condition number above
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
    const sm_field *target;           /* d of the target */
    const sm_mesh *background;        /* the field's mesh and its values: */
    const double *distance;           /* the inside region d < 0 for the moments */
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
    int iterations;                   /* refinement iterations (all stages) */
    int candidates;                   /* starts tried (1 with a given start) */
    double seconds;
    int cancelled;                    /* 1: *cancel stopped it; transform and
                                       * rms_after are then where it stood,
                                       * not an alignment */
} sm_align_result;

/* Computes the alignment.  SM_ERR_INVALID for mode NONE, a template with
 * no boundary or volume, a target with no inside region (d >= 0 at every
 * background vertex) without a start, a dimension mismatch; SM_ERR_NOMEM.
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
