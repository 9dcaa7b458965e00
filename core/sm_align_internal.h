/* Private to the alignment (core/sm_align*.c): the small dense linear
 * algebra it needs, written out (cyclic Jacobi) rather than taken from
 * LAPACK, which the core does not link: the matrices are at most 3x3
 * (eigen, SVD) and 12x12 (the normal equations). */
#ifndef SM_ALIGN_INTERNAL_H
#define SM_ALIGN_INTERNAL_H

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

#endif
