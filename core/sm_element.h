/* The P1 element matrix of linear elasticity (private to the core): the
 * kernel the assembly (sm_elasticity.c) calls for every element, inline
 * so that its small loops unroll for a compile-time dimension, and the
 * exported wrapper sm__elasticity_element_matrix (sm_element.c). */
#ifndef SM_ELEMENT_H
#define SM_ELEMENT_H

#include <math.h>

/* Relative volume below which a simplex counts as degenerate. */
#define DEGENERATE_TOL 1e-12

/* Computes the element matrix of the simplex x[(dim+1)*dim] into ke.
 * Returns 0 on success, -1 when the simplex is degenerate or not finite.
 * Written for a compile-time dim (the callers pass a constant) so the
 * small loops unroll. */
static inline int sm_element_kernel(const int dim, const double *x, double lambda,
                                    double mu, double alpha, double *ke,
                                    double *signed_volume, double *longest_edge)
{
    double grad[4][3];
    double det, vol, lmax2 = 0.0;
    if (dim == 2) {
        double a0 = x[2] - x[0], a1 = x[3] - x[1];
        double b0 = x[4] - x[0], b1 = x[5] - x[1];
        det = a0 * b1 - a1 * b0;
        double inv = 1.0 / det;
        /* rows of J^{-1}, J = [a b] */
        grad[1][0] = b1 * inv;  grad[1][1] = -b0 * inv;
        grad[2][0] = -a1 * inv; grad[2][1] = a0 * inv;
        grad[0][0] = -grad[1][0] - grad[2][0];
        grad[0][1] = -grad[1][1] - grad[2][1];
        vol = 0.5 * det;
        double c0 = b0 - a0, c1 = b1 - a1;
        double la = a0 * a0 + a1 * a1, lb = b0 * b0 + b1 * b1, lc = c0 * c0 + c1 * c1;
        lmax2 = la > lb ? la : lb;
        lmax2 = lmax2 > lc ? lmax2 : lc;
    } else {
        double a[3], b[3], c[3];
        for (int r = 0; r < 3; r++) {
            a[r] = x[3 + r] - x[r];
            b[r] = x[6 + r] - x[r];
            c[r] = x[9 + r] - x[r];
        }
        double bxc[3] = {b[1] * c[2] - b[2] * c[1], b[2] * c[0] - b[0] * c[2],
                         b[0] * c[1] - b[1] * c[0]};
        double cxa[3] = {c[1] * a[2] - c[2] * a[1], c[2] * a[0] - c[0] * a[2],
                         c[0] * a[1] - c[1] * a[0]};
        double axb[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                         a[0] * b[1] - a[1] * b[0]};
        det = a[0] * bxc[0] + a[1] * bxc[1] + a[2] * bxc[2];
        double inv = 1.0 / det;
        for (int r = 0; r < 3; r++) {
            grad[1][r] = bxc[r] * inv;
            grad[2][r] = cxa[r] * inv;
            grad[3][r] = axb[r] * inv;
            grad[0][r] = -grad[1][r] - grad[2][r] - grad[3][r];
        }
        vol = det / 6.0;
        double e[6][3];
        for (int r = 0; r < 3; r++) {
            e[0][r] = a[r];
            e[1][r] = b[r];
            e[2][r] = c[r];
            e[3][r] = b[r] - a[r];
            e[4][r] = c[r] - a[r];
            e[5][r] = c[r] - b[r];
        }
        for (int k = 0; k < 6; k++) {
            double l2 = e[k][0] * e[k][0] + e[k][1] * e[k][1] + e[k][2] * e[k][2];
            lmax2 = l2 > lmax2 ? l2 : lmax2;
        }
    }
    *signed_volume = vol;
    double lmax = sqrt(lmax2);
    *longest_edge = lmax;
    double scale = dim == 2 ? lmax2 : lmax2 * lmax;
    double w = fabs(vol);
    /* The negated comparison also rejects NaN. */
    if (!(w > DEGENERATE_TOL * scale) || !isfinite(w) || !isfinite(scale))
        return -1;

    const int nv = dim + 1, n = nv * dim;
    /* consistent P1 mass: |K| (1 + delta_ij) / ((d+1)(d+2)) */
    const double mass_off = alpha * w / (double)((dim + 1) * (dim + 2));
    const double wl = w * lambda, wm = w * mu;
    /* Blocks j >= i only, mirrored: half the work, and the matrix is
     * exactly (bitwise) symmetric. */
    for (int i = 0; i < nv; i++) {
        for (int j = i; j < nv; j++) {
            double gg = 0.0;
            for (int r = 0; r < dim; r++)
                gg += grad[i][r] * grad[j][r];
            double diag = wm * gg + (i == j ? 2.0 * mass_off : mass_off);
            for (int c = 0; c < dim; c++) {
                for (int d = 0; d < dim; d++) {
                    double v = wm * grad[j][c] * grad[i][d] + wl * grad[i][c] * grad[j][d] +
                               (c == d ? diag : 0.0);
                    ke[(i * dim + c) * n + j * dim + d] = v;
                    ke[(j * dim + d) * n + i * dim + c] = v;
                }
            }
        }
    }
    return 0;
}

#endif
