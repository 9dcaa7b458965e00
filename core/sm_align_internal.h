/* Private to the alignment (core/sm_align*.c): the small dense linear
 * algebra it needs, written out (cyclic Jacobi) rather than taken from
 * LAPACK, which the core does not link: the matrices are at most 3x3
 * (eigen, SVD) and 12x12 (the normal equations). */
#ifndef SM_ALIGN_INTERNAL_H
#define SM_ALIGN_INTERNAL_H

#include <stdint.h>

#include "shapematch/sm_error.h"
#include "shapematch/sm_mesh.h"
#include "shapematch/sm_surface.h"

/* Eigen decomposition of the symmetric n x n (n <= 3) matrix a (row-major
 * 3x3 storage, the leading n x n used): eigenvalues in val, descending;
 * eigenvectors in the columns of vec (a proper rotation: det +1).
 * Cyclic Jacobi to rounding. */
void sm__sym_eigen(int n, const double a[3][3], double val[3], double vec[3][3]);

/* SVD a = u diag(s) v^T of the n x n (n <= 3) matrix a, s descending,
 * u and v orthogonal (columns of u for zero singular values completed to
 * an orthonormal basis); one-sided Jacobi on a itself. */
void sm__svd(int n, const double a[3][3], double u[3][3], double s[3], double v[3][3]);

/* Determinant of the leading n x n block. */
double sm__det(int n, const double a[3][3]);

/* Solves the SPD-ish system m x = r (n <= 12, m row-major n x n) by
 * Gaussian elimination with partial pivoting; 0 on success, -1 when
 * singular.  m and r are overwritten. */
int sm__solve_dense(int n, double *m, double *r, double *x);

/* ------------------------------------------- sm_align_points.c */

/* Weighted points on one side of the misfit, and per point work: y the
 * moved point (template side) or the moved closest template point
 * (target side), u the target point pulled back into the template's
 * frame, r the residual, g its direction (the gradient of the signed
 * distance the residual is), hints the field's element hints. */
typedef struct sm__align_pts {
    int dim;
    int64_t n;
    double *x, *w;
    double wsum;
    double *y, *u, *r, *g;
    double *nrm; /* the unit outward normal at each point */
    int32_t *hints, *nearest;
} sm__align_pts;

void sm__align_pts_free(sm__align_pts *p);
/* Room for n points (x, w filled by the caller, then sm__align_pts_done). */
sm_status sm__align_pts_alloc(sm__align_pts *p, int dim, int64_t n, sm_error *err);
/* wsum, and the hints reset. */
void sm__align_pts_done(sm__align_pts *p);
/* Every k-th point of from (k >= 1, so that at most cap remain; weights
 * kept: the misfit is a weighted mean). */
sm_status sm__align_pts_sample(const sm__align_pts *from, int64_t cap, sm__align_pts *to,
                               sm_error *err);

/* Quadrature points of facets (2 Gauss points per segment, the 3-point
 * rule per triangle, weights the facet's measure shared): of the
 * template's boundary (its outward facets) or of a target surface. */
sm_status sm__align_mesh_boundary_pts(const sm_mesh *m, sm__align_pts *p, sm_error *err);
sm_status sm__align_surface_pts(const sm_surface *s, sm__align_pts *p, sm_error *err);
/* The zero level set of the P1 field values on bg (marching simplices:
 * each cut piece, a segment or a triangle, by its centroid weighted by
 * its measure). */
sm_status sm__align_level_set_pts(const sm_mesh *bg, const double *values, sm__align_pts *p,
                                  sm_error *err);

typedef struct sm__moments {
    double volume;
    double centroid[3];
    double cov[3][3]; /* second central moment / volume */
} sm__moments;

/* The volume moments of the mesh's elements (values NULL), or of the
 * region values < 0 (an element partly inside counts by the fraction
 * sum(d-)/sum|d| of its vertex values); -1 when it has no volume. */
int sm__align_mesh_moments(const sm_mesh *m, const double *values, sm__moments *out);
/* The moments of the volume a closed outward surface encloses (the
 * divergence theorem: signed simplices on its facets and one apex); -1
 * when it encloses none. */
int sm__align_surface_moments(const sm_surface *s, sm__moments *out);

#endif
