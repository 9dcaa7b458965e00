/* Small dense linear algebra of the alignment (see sm_align_internal.h). */
#include "sm_align_internal.h"

#include <math.h>
#include <string.h>

double sm__det(int n, const double a[3][3])
{
    if (n == 1)
        return a[0][0];
    if (n == 2)
        return a[0][0] * a[1][1] - a[0][1] * a[1][0];
    return a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) -
           a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0]) +
           a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
}

void sm__sym_eigen(int n, const double a_in[3][3], double val[3], double vec[3][3])
{
    double a[3][3], v[3][3];
    memset(v, 0, sizeof v);
    for (int i = 0; i < 3; i++) {
        v[i][i] = 1;
        for (int j = 0; j < 3; j++)
            a[i][j] = i < n && j < n ? a_in[i][j] : 0;
    }
    /* cyclic Jacobi: each sweep annihilates every off-diagonal entry in
     * turn; converges quadratically, 50 sweeps is far beyond need */
    for (int sweep = 0; sweep < 50; sweep++) {
        double off = 0, diag = 0;
        for (int p = 0; p < n; p++) {
            diag += a[p][p] * a[p][p];
            for (int q = p + 1; q < n; q++)
                off += a[p][q] * a[p][q];
        }
        if (off <= 1e-32 * diag || off == 0)
            break;
        for (int p = 0; p < n; p++)
            for (int q = p + 1; q < n; q++) {
                if (a[p][q] == 0)
                    continue;
                double theta = (a[q][q] - a[p][p]) / (2 * a[p][q]);
                double t = (theta >= 0 ? 1 : -1) / (fabs(theta) + sqrt(theta * theta + 1));
                double c = 1 / sqrt(t * t + 1), s = t * c;
                for (int k = 0; k < n; k++) { /* a <- a J */
                    double akp = a[k][p], akq = a[k][q];
                    a[k][p] = c * akp - s * akq;
                    a[k][q] = s * akp + c * akq;
                }
                for (int k = 0; k < n; k++) { /* a <- J^T a */
                    double apk = a[p][k], aqk = a[q][k];
                    a[p][k] = c * apk - s * aqk;
                    a[q][k] = s * apk + c * aqk;
                }
                for (int k = 0; k < n; k++) {
                    double vkp = v[k][p], vkq = v[k][q];
                    v[k][p] = c * vkp - s * vkq;
                    v[k][q] = s * vkp + c * vkq;
                }
            }
    }
    int order[3] = {0, 1, 2};
    for (int i = 0; i < n; i++) /* descending: a selection sort of 3 */
        for (int j = i + 1; j < n; j++)
            if (a[order[j]][order[j]] > a[order[i]][order[i]]) {
                int t = order[i];
                order[i] = order[j];
                order[j] = t;
            }
    memset(vec, 0, 9 * sizeof(double));
    for (int i = 0; i < 3; i++)
        val[i] = i < n ? a[order[i]][order[i]] : 0;
    for (int i = 0; i < n; i++)
        for (int k = 0; k < n; k++)
            vec[k][i] = v[k][order[i]];
    if (sm__det(n, (const double(*)[3])vec) < 0) /* a proper rotation */
        for (int k = 0; k < n; k++)
            vec[k][n - 1] = -vec[k][n - 1];
}

/* Completes columns from..n-1 of the n x n matrix u to an orthonormal
 * basis (Gram-Schmidt against the unit vectors). */
static void complete_basis(int n, int from, double u[3][3])
{
    for (int col = from; col < n; col++) {
        double best[3] = {0, 0, 0}, best_norm = -1;
        for (int e = 0; e < n; e++) {
            double w[3] = {0, 0, 0};
            w[e] = 1;
            for (int j = 0; j < col; j++) {
                double dot = 0;
                for (int k = 0; k < n; k++)
                    dot += u[k][j] * w[k];
                for (int k = 0; k < n; k++)
                    w[k] -= dot * u[k][j];
            }
            double nw = 0;
            for (int k = 0; k < n; k++)
                nw += w[k] * w[k];
            if (nw > best_norm) {
                best_norm = nw;
                memcpy(best, w, sizeof best);
            }
        }
        double inv = 1 / sqrt(best_norm);
        for (int k = 0; k < n; k++)
            u[k][col] = best[k] * inv;
    }
}

void sm__svd(int n, const double a[3][3], double u[3][3], double s[3], double v[3][3])
{
    /* one-sided Jacobi (Hestenes): rotate pairs of columns of w = a v
     * until they are orthogonal; then s_i = |w_i| and u_i = w_i / s_i.
     * Working on a itself, not on a^T a, keeps the small singular
     * values' digits (squaring would lose half of them). */
    double w[3][3] = {{0}}, vv[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    /* scaled to a largest entry of 1, and s scaled back at the end: the
     * column products below square the entries twice, which overflows
     * from entries of ~1e77 (landmarks 1e59 apart: fuzz_landmarks) and
     * underflows below ~1e-77; u and v do not depend on the scale */
    double m = 0;
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++)
            m = fmax(m, fabs(a[i][j]));
    if (!(m > 0) || !isfinite(m))
        m = 1;
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++)
            w[i][j] = a[i][j] / m;
    for (int sweep = 0; sweep < 60; sweep++) {
        int rotated = 0;
        for (int p = 0; p < n; p++)
            for (int q = p + 1; q < n; q++) {
                double alpha = 0, beta = 0, gamma = 0;
                for (int k = 0; k < n; k++) {
                    alpha += w[k][p] * w[k][p];
                    beta += w[k][q] * w[k][q];
                    gamma += w[k][p] * w[k][q];
                }
                if (!(fabs(gamma) > 1e-15 * sqrt(alpha * beta)))
                    continue;
                rotated = 1;
                double zeta = (beta - alpha) / (2 * gamma);
                double t = (zeta >= 0 ? 1 : -1) / (fabs(zeta) + sqrt(1 + zeta * zeta));
                double c = 1 / sqrt(1 + t * t), sn = c * t;
                for (int k = 0; k < n; k++) {
                    double wp = w[k][p], wq = w[k][q];
                    w[k][p] = c * wp - sn * wq;
                    w[k][q] = sn * wp + c * wq;
                    double vp = vv[k][p], vq = vv[k][q];
                    vv[k][p] = c * vp - sn * vq;
                    vv[k][q] = sn * vp + c * vq;
                }
            }
        if (!rotated)
            break;
    }
    double norm[3] = {0, 0, 0};
    int order[3] = {0, 1, 2};
    for (int j = 0; j < n; j++) {
        for (int k = 0; k < n; k++)
            norm[j] += w[k][j] * w[k][j];
        norm[j] = sqrt(norm[j]);
    }
    for (int i = 0; i < n; i++) /* descending */
        for (int j = i + 1; j < n; j++)
            if (norm[order[j]] > norm[order[i]]) {
                int t = order[i];
                order[i] = order[j];
                order[j] = t;
            }
    memset(u, 0, 9 * sizeof(double));
    memset(v, 0, 9 * sizeof(double));
    int rank = 0;
    for (int i = 0; i < 3; i++)
        s[i] = i < n ? norm[order[i]] : 0;
    for (int i = 0; i < n; i++) {
        for (int k = 0; k < n; k++)
            v[k][i] = vv[k][order[i]];
        if (rank == i && s[i] > 1e-300 && s[i] > 1e-15 * s[0]) {
            for (int k = 0; k < n; k++)
                u[k][i] = w[k][order[i]] / s[i];
            rank++;
        }
    }
    for (int i = rank; i < n; i++)
        s[i] = 0;
    for (int i = 0; i < n; i++)
        s[i] *= m;
    complete_basis(n, rank, u);
}

int sm__solve_dense(int n, double *m, double *r, double *x)
{
    for (int col = 0; col < n; col++) {
        int piv = col;
        for (int i = col + 1; i < n; i++)
            if (fabs(m[i * n + col]) > fabs(m[piv * n + col]))
                piv = i;
        if (!(fabs(m[piv * n + col]) > 0))
            return -1;
        if (piv != col) {
            for (int j = 0; j < n; j++) {
                double t = m[col * n + j];
                m[col * n + j] = m[piv * n + j];
                m[piv * n + j] = t;
            }
            double t = r[col];
            r[col] = r[piv];
            r[piv] = t;
        }
        for (int i = col + 1; i < n; i++) {
            double f = m[i * n + col] / m[col * n + col];
            for (int j = col; j < n; j++)
                m[i * n + j] -= f * m[col * n + j];
            r[i] -= f * r[col];
        }
    }
    for (int i = n - 1; i >= 0; i--) {
        double acc = r[i];
        for (int j = i + 1; j < n; j++)
            acc -= m[i * n + j] * x[j];
        x[i] = acc / m[i * n + i];
        if (!isfinite(x[i]))
            return -1;
    }
    return 0;
}
