/* P1 linear elasticity: element matrices against closed forms, patch test
 * (affine fields are reproduced exactly), L2 convergence of order 2 on a
 * manufactured solution, symmetry and rigid-motion kernel of the
 * assembled matrix, a brute-force dense comparison of the elimination,
 * refactorization in a forked process, and error handling.  Meshes of the unit square/cube come from Gmsh at
 * test time. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <omp.h>
#include <sys/wait.h>
#include <unistd.h>
#include <cmocka.h>

#include "sm_elasticity.h"
#include "shapematch/sm_mesh.h"
#include "util_gmsh.h"
#include "util_mesh.h"

#define PI 3.14159265358979323846
/* Options of sm__elasticity_new with the automatic factor kind. */
#define OPTS(e, nu, a) \
    (&(sm_elasticity_opts){.young = (e), .poisson = (nu), .alpha = (a)})

static const double YOUNG = 1.0, POISSON = 0.3;

/* ---------------------------------------------------------------------- */
/* meshes                                                                  */
/* ---------------------------------------------------------------------- */

/* Unstructured Gmsh mesh of the unit square / cube with size h, boundary
 * built (and elements oriented) by the mesh module. */
static sm_mesh *unit_mesh(int dim, double h)
{
    sm_mesh *m = NULL;
    char msg[1024];
    sm_status st = util_gmsh_mesh(dim == 2 ? UTIL_GMSH_UNIT_SQUARE : UTIL_GMSH_UNIT_CUBE, dim, h,
                                  &m, msg, sizeof msg);
    if (st != SM_OK)
        fail_msg("gmsh mesh (dim %d, h %g): %s", dim, h, msg);
    assert_int_equal(m->dim, dim);
    sm_error err;
    if (sm_mesh_build_boundary(m, &err) != SM_OK)
        fail_msg("build_boundary: %s", err.msg);
    return m;
}

static sm_mesh *box_mesh(int dim, int n, unsigned shuffle)
{
    const double lo[3] = {0, 0, 0}, hi[3] = {1, 1, 1};
    sm_mesh *m = util_box_mesh(dim, n, lo, hi, shuffle);
    assert_non_null(m);
    return m;
}

static void element_coords(const sm_mesh *m, const double *coords, int32_t e, double *x)
{
    int dim = m->dim, nv = dim + 1;
    for (int i = 0; i < nv; i++)
        for (int r = 0; r < dim; r++)
            x[i * dim + r] = coords[(size_t)m->elems[(size_t)e * nv + i] * dim + r];
}

/* ---------------------------------------------------------------------- */
/* quadrature (barycentric points, weights summing to 1)                   */
/* ---------------------------------------------------------------------- */

typedef struct quadrature {
    int npoints;
    double bary[6][4];
    double weight[6];
} quadrature;

/* Degree 4 on triangles (6 points), degree 3 on tetrahedra (5 points). */
static quadrature make_quadrature(int dim)
{
    quadrature q;
    memset(&q, 0, sizeof q);
    if (dim == 2) {
        const double a = 0.445948490915965, b = 0.091576213509771;
        const double wa = 0.223381589678011, wb = 0.109951743655322;
        const double pa[3][3] = {{a, a, 1 - 2 * a}, {a, 1 - 2 * a, a}, {1 - 2 * a, a, a}};
        const double pb[3][3] = {{b, b, 1 - 2 * b}, {b, 1 - 2 * b, b}, {1 - 2 * b, b, b}};
        q.npoints = 6;
        for (int k = 0; k < 3; k++) {
            memcpy(q.bary[k], pa[k], sizeof pa[k]);
            memcpy(q.bary[3 + k], pb[k], sizeof pb[k]);
            q.weight[k] = wa;
            q.weight[3 + k] = wb;
        }
    } else {
        q.npoints = 5;
        for (int i = 0; i < 4; i++)
            q.bary[0][i] = 0.25;
        q.weight[0] = -0.8;
        for (int k = 0; k < 4; k++) {
            for (int i = 0; i < 4; i++)
                q.bary[1 + k][i] = i == k ? 0.5 : 1.0 / 6.0;
            q.weight[1 + k] = 0.45;
        }
    }
    return q;
}

/* ---------------------------------------------------------------------- */
/* manufactured solution: u smooth, not in P1; f = -div sigma(u)           */
/*   = -mu Lap u - (lambda + mu) grad div u                                */
/* ---------------------------------------------------------------------- */

static void exact_u(int dim, const double *p, double *u)
{
    double x = p[0], y = p[1];
    if (dim == 2) {
        u[0] = sin(PI * x) * sin(PI * y);
        u[1] = exp(x) * sin(2 * y);
    } else {
        double z = p[2];
        u[0] = sin(PI * x) * sin(PI * y) * sin(PI * z);
        u[1] = exp(x + z) * sin(y);
        u[2] = cos(PI * x) * y * y * z;
    }
}

static void exact_f(int dim, const double *p, double lambda, double mu, double *f)
{
    double x = p[0], y = p[1];
    double lap[3], graddiv[3];
    if (dim == 2) {
        double u1 = sin(PI * x) * sin(PI * y), u2 = exp(x) * sin(2 * y);
        lap[0] = -2 * PI * PI * u1;
        lap[1] = -3 * u2;
        graddiv[0] = -PI * PI * u1 + 2 * exp(x) * cos(2 * y);
        graddiv[1] = PI * PI * cos(PI * x) * cos(PI * y) - 4 * u2;
    } else {
        double z = p[2];
        double u1 = sin(PI * x) * sin(PI * y) * sin(PI * z);
        double u2 = exp(x + z) * sin(y);
        double u3 = cos(PI * x) * y * y * z;
        lap[0] = -3 * PI * PI * u1;
        lap[1] = u2;
        lap[2] = -PI * PI * u3 + 2 * cos(PI * x) * z;
        graddiv[0] = -PI * PI * u1 + exp(x + z) * cos(y) - PI * sin(PI * x) * y * y;
        graddiv[1] = PI * PI * cos(PI * x) * cos(PI * y) * sin(PI * z) - u2 + 2 * y * cos(PI * x);
        graddiv[2] = PI * PI * cos(PI * x) * sin(PI * y) * cos(PI * z) + exp(x + z) * cos(y);
    }
    for (int c = 0; c < dim; c++)
        f[c] = -mu * lap[c] - (lambda + mu) * graddiv[c];
}

/* The analytic f agrees with a finite-difference -div sigma(u): guards the
 * convergence test against a wrong right-hand side. */
static void check_exact_f(int dim, double lambda, double mu)
{
    const double p0[3] = {0.31, 0.57, 0.73};
    const double step = 1e-3;
    double f[3], fd[3] = {0, 0, 0};
    exact_f(dim, p0, lambda, mu, f);
    /* sigma at p from central differences of u, then div by differences */
    for (int k = 0; k < dim; k++) {
        double sig[2][3][3];
        for (int s = 0; s < 2; s++) {
            double p[3] = {p0[0], p0[1], p0[2]};
            p[k] += s ? step : -step;
            double grad[3][3];
            for (int j = 0; j < dim; j++) {
                double pp[3] = {p[0], p[1], p[2]}, pm[3] = {p[0], p[1], p[2]}, up[3], um[3];
                pp[j] += step;
                pm[j] -= step;
                exact_u(dim, pp, up);
                exact_u(dim, pm, um);
                for (int i = 0; i < dim; i++)
                    grad[i][j] = (up[i] - um[i]) / (2 * step);
            }
            double tr = 0;
            for (int i = 0; i < dim; i++)
                tr += grad[i][i];
            for (int i = 0; i < dim; i++)
                for (int j = 0; j < dim; j++)
                    sig[s][i][j] = mu * (grad[i][j] + grad[j][i]) + (i == j ? lambda * tr : 0);
        }
        for (int i = 0; i < dim; i++)
            fd[i] -= (sig[1][i][k] - sig[0][i][k]) / (2 * step);
    }
    for (int i = 0; i < dim; i++)
        assert_true(fabs(f[i] - fd[i]) < 1e-4 * (1 + fabs(f[i])));
}

/* ---------------------------------------------------------------------- */
/* small dense linear algebra for brute-force comparisons                  */
/* ---------------------------------------------------------------------- */

/* Solves a x = b in place (partial pivoting); returns 0 on success. */
static int dense_solve(int n, double *a, double *b)
{
    for (int k = 0; k < n; k++) {
        int piv = k;
        for (int i = k + 1; i < n; i++)
            if (fabs(a[(size_t)i * n + k]) > fabs(a[(size_t)piv * n + k]))
                piv = i;
        if (a[(size_t)piv * n + k] == 0.0)
            return -1;
        if (piv != k) {
            for (int j = 0; j < n; j++) {
                double t = a[(size_t)k * n + j];
                a[(size_t)k * n + j] = a[(size_t)piv * n + j];
                a[(size_t)piv * n + j] = t;
            }
            double t = b[k];
            b[k] = b[piv];
            b[piv] = t;
        }
        for (int i = k + 1; i < n; i++) {
            double l = a[(size_t)i * n + k] / a[(size_t)k * n + k];
            for (int j = k; j < n; j++)
                a[(size_t)i * n + j] -= l * a[(size_t)k * n + j];
            b[i] -= l * b[k];
        }
    }
    for (int i = n - 1; i >= 0; i--) {
        double s = b[i];
        for (int j = i + 1; j < n; j++)
            s -= a[(size_t)i * n + j] * b[j];
        b[i] = s / a[(size_t)i * n + i];
    }
    return 0;
}

/* Global (unreduced) matrix K + alpha M of the whole mesh, dense, from the
 * exported element matrix. */
static double *dense_global_matrix(const sm_mesh *m, double lambda, double mu, double alpha)
{
    int dim = m->dim, nv = dim + 1, ne = nv * dim;
    size_t n = (size_t)m->nverts * dim;
    double *a = calloc(n * n, sizeof *a);
    assert_non_null(a);
    double x[12], ke[144], vol;
    for (int32_t e = 0; e < m->nelems; e++) {
        element_coords(m, m->coords, e, x);
        assert_int_equal(sm__elasticity_element_matrix(dim, x, lambda, mu, alpha, ke, &vol, NULL),
                         SM_OK);
        const int32_t *ev = m->elems + (size_t)e * nv;
        for (int i = 0; i < ne; i++)
            for (int j = 0; j < ne; j++) {
                size_t gi = (size_t)ev[i / dim] * dim + i % dim;
                size_t gj = (size_t)ev[j / dim] * dim + j % dim;
                a[gi * n + gj] += ke[i * ne + j];
            }
    }
    return a;
}

/* y = K x over all DOFs (no elimination) via element matrices. */
static void apply_global(const sm_mesh *m, double lambda, double mu, double alpha,
                         const double *xin, double *y, double *max_entry)
{
    int dim = m->dim, nv = dim + 1, ne = nv * dim;
    double x[12], ke[144], vol;
    memset(y, 0, (size_t)m->nverts * dim * sizeof *y);
    *max_entry = 0;
    for (int32_t e = 0; e < m->nelems; e++) {
        element_coords(m, m->coords, e, x);
        assert_int_equal(sm__elasticity_element_matrix(dim, x, lambda, mu, alpha, ke, &vol, NULL),
                         SM_OK);
        const int32_t *ev = m->elems + (size_t)e * nv;
        for (int i = 0; i < ne; i++) {
            size_t gi = (size_t)ev[i / dim] * dim + i % dim;
            for (int j = 0; j < ne; j++) {
                size_t gj = (size_t)ev[j / dim] * dim + j % dim;
                y[gi] += ke[i * ne + j] * xin[gj];
                if (fabs(ke[i * ne + j]) > *max_entry)
                    *max_entry = fabs(ke[i * ne + j]);
            }
        }
    }
}

/* The rigid motions: dim translations, then rotations (1 in 2D, 3 in 3D). */
static int rigid_mode(const sm_mesh *m, int k, double *r)
{
    int dim = m->dim, nmodes = dim == 2 ? 3 : 6;
    if (k >= nmodes)
        return 0;
    for (int32_t v = 0; v < m->nverts; v++) {
        const double *p = m->coords + (size_t)v * dim;
        double *rv = r + (size_t)v * dim;
        for (int c = 0; c < dim; c++)
            rv[c] = k == c ? 1.0 : 0.0;
        if (k >= dim) {
            /* infinitesimal rotation omega x p about the point (0.5,...) */
            double q[3] = {p[0] - 0.5, p[1] - 0.5, dim == 3 ? p[2] - 0.5 : 0.0};
            if (dim == 2) {
                rv[0] = -q[1];
                rv[1] = q[0];
            } else {
                double w[3] = {0, 0, 0};
                w[k - dim] = 1.0;
                double cr[3] = {w[1] * q[2] - w[2] * q[1], w[2] * q[0] - w[0] * q[2],
                                w[0] * q[1] - w[1] * q[0]};
                for (int c = 0; c < 3; c++)
                    rv[c] = cr[c];
            }
        }
    }
    return 1;
}

/* Consistent-mass product (M r)_i = sum_K |K|/((d+1)(d+2)) (r_i + sum_j r_j),
 * computed independently of the library. */
static void mass_apply(const sm_mesh *m, const double *r, double *y)
{
    int dim = m->dim, nv = dim + 1;
    memset(y, 0, (size_t)m->nverts * dim * sizeof *y);
    for (int32_t e = 0; e < m->nelems; e++) {
        double w = fabs(sm_elem_volume(m, m->coords, e)) / ((dim + 1) * (dim + 2));
        const int32_t *ev = m->elems + (size_t)e * nv;
        for (int c = 0; c < dim; c++) {
            double sum = 0;
            for (int j = 0; j < nv; j++)
                sum += r[(size_t)ev[j] * dim + c];
            for (int i = 0; i < nv; i++)
                y[(size_t)ev[i] * dim + c] += w * (r[(size_t)ev[i] * dim + c] + sum);
        }
    }
}

/* ---------------------------------------------------------------------- */
/* element matrix                                                          */
/* ---------------------------------------------------------------------- */

static double frand(unsigned *state)
{
    *state = *state * 1103515245u + 12345u;
    return ((*state >> 8) & 0xffffff) / (double)0x1000000;
}

/* For an affine field u = A x: u^T Ke u = |K| (2 mu eps:eps + lambda tr(eps)^2),
 * Ke r = 0 for the rigid motions, the mass part integrates |t|^2, Ke is
 * symmetric, and swapping two vertices only permutes Ke. */
static void check_element(int dim, unsigned seed)
{
    unsigned st = seed;
    int nv = dim + 1, ne = nv * dim;
    double x[12], ke[144], ke_swapped[144], vol, vol_swapped;
    double lambda, mu;
    sm__lame(YOUNG, POISSON, &lambda, &mu);
    for (int k = 0; k < nv * dim; k++)
        x[k] = frand(&st);
    assert_int_equal(sm__elasticity_element_matrix(dim, x, lambda, mu, 0.0, ke, &vol, NULL), SM_OK);
    double w = fabs(vol), kmax = 0;
    for (int i = 0; i < ne * ne; i++)
        kmax = fmax(kmax, fabs(ke[i]));
    for (int i = 0; i < ne; i++)
        for (int j = 0; j < ne; j++)
            assert_true(fabs(ke[i * ne + j] - ke[j * ne + i]) <= 1e-14 * kmax);
    for (int trial = 0; trial < 3; trial++) {
        double a[3][3], eps[3][3], u[12], tr = 0, epseps = 0, energy = 0;
        for (int i = 0; i < dim; i++)
            for (int j = 0; j < dim; j++)
                a[i][j] = 2 * frand(&st) - 1;
        for (int i = 0; i < dim; i++)
            for (int j = 0; j < dim; j++)
                eps[i][j] = 0.5 * (a[i][j] + a[j][i]);
        for (int i = 0; i < dim; i++) {
            tr += eps[i][i];
            for (int j = 0; j < dim; j++)
                epseps += eps[i][j] * eps[i][j];
        }
        for (int v = 0; v < nv; v++)
            for (int i = 0; i < dim; i++) {
                u[v * dim + i] = 0.1 * i;
                for (int j = 0; j < dim; j++)
                    u[v * dim + i] += a[i][j] * x[v * dim + j];
            }
        for (int i = 0; i < ne; i++)
            for (int j = 0; j < ne; j++)
                energy += u[i] * ke[i * ne + j] * u[j];
        double expected = w * (2 * mu * epseps + lambda * tr * tr);
        assert_true(fabs(energy - expected) <= 1e-12 * fmax(1.0, fabs(expected)) * (1 + kmax));
    }
    /* rigid rotations in the kernel (translations follow from the energy
     * identity with A = 0, checked here too) */
    int nrot = dim == 2 ? 1 : 3;
    for (int k = 0; k < dim + nrot; k++) {
        double r[12], y;
        for (int v = 0; v < nv; v++) {
            const double *p = x + v * dim;
            for (int c = 0; c < dim; c++)
                r[v * dim + c] = k == c ? 1.0 : 0.0;
            if (k >= dim && dim == 2) {
                r[v * 2] = -p[1];
                r[v * 2 + 1] = p[0];
            } else if (k >= dim) {
                double om[3] = {0, 0, 0};
                om[k - dim] = 1;
                r[v * 3] = om[1] * p[2] - om[2] * p[1];
                r[v * 3 + 1] = om[2] * p[0] - om[0] * p[2];
                r[v * 3 + 2] = om[0] * p[1] - om[1] * p[0];
            }
        }
        for (int i = 0; i < ne; i++) {
            y = 0;
            for (int j = 0; j < ne; j++)
                y += ke[i * ne + j] * r[j];
            assert_true(fabs(y) <= 1e-12 * kmax * 4);
        }
    }
    /* mass term alone: t^T M t = |K| |t|^2 and M_ii = 2|K|/((d+1)(d+2)) */
    double me[144];
    assert_int_equal(sm__elasticity_element_matrix(dim, x, 0.0, 0.0, 2.0, me, &vol, NULL), SM_OK);
    double t[3] = {0.3, -0.7, 0.2}, tt = 0, quad = 0;
    for (int c = 0; c < dim; c++)
        tt += t[c] * t[c];
    for (int i = 0; i < ne; i++)
        for (int j = 0; j < ne; j++)
            quad += t[i % dim] * me[i * ne + j] * t[j % dim];
    assert_true(fabs(quad - 2.0 * w * tt) <= 1e-13 * w);
    assert_true(fabs(me[0] - 2.0 * 2.0 * w / ((dim + 1) * (dim + 2))) <= 1e-14 * w);
    /* swapping vertices 0 and 1 reverses the orientation, permutes Ke */
    double xs[12];
    memcpy(xs, x, sizeof xs);
    for (int r = 0; r < dim; r++) {
        xs[r] = x[dim + r];
        xs[dim + r] = x[r];
    }
    assert_int_equal(sm__elasticity_element_matrix(dim, xs, lambda, mu, 0.5, ke_swapped,
                                                  &vol_swapped, NULL), SM_OK);
    assert_true(fabs(vol_swapped + vol) <= 1e-14 * w);
    assert_int_equal(sm__elasticity_element_matrix(dim, x, lambda, mu, 0.5, ke, &vol, NULL), SM_OK);
    for (int i = 0; i < ne; i++)
        for (int j = 0; j < ne; j++) {
            int pi = (i / dim < 2 ? 1 - i / dim : i / dim) * dim + i % dim;
            int pj = (j / dim < 2 ? 1 - j / dim : j / dim) * dim + j % dim;
            assert_true(fabs(ke[i * ne + j] - ke_swapped[pi * ne + pj]) <= 1e-13 * kmax);
        }
}

static void test_element_matrix(void **state)
{
    (void)state;
    for (unsigned s = 1; s <= 5; s++) {
        check_element(2, s);
        check_element(3, s);
    }
    double lambda, mu;
    sm__lame(2.0, 0.25, &lambda, &mu);
    assert_true(fabs(lambda - 0.8) < 1e-15 && fabs(mu - 0.8) < 1e-15);
    /* degenerate: collinear triangle, flat tetrahedron */
    double tri[6] = {0, 0, 1, 1, 2, 2}, tet[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0};
    double ke[144], vol;
    sm_error err;
    assert_int_equal(sm__elasticity_element_matrix(2, tri, 1, 1, 0, ke, &vol, &err), SM_ERR_NUMERIC);
    assert_non_null(strstr(err.msg, "degenerate"));
    assert_int_equal(sm__elasticity_element_matrix(3, tet, 1, 1, 0, ke, &vol, &err), SM_ERR_NUMERIC);
}

/* ---------------------------------------------------------------------- */
/* (a) patch test                                                          */
/* ---------------------------------------------------------------------- */

static void patch_test(int dim, double h, double poisson)
{
    sm_mesh *m = unit_mesh(dim, h);
    size_t n = (size_t)m->nverts * dim;
    double *g = malloc(n * sizeof *g), *u = malloc(n * sizeof *u);
    assert_non_null(g);
    assert_non_null(u);
    const double a[3][3] = {{0.3, -0.2, 0.15}, {0.1, 0.25, -0.3}, {-0.05, 0.2, 0.1}};
    const double b[3] = {0.5, -1.0, 2.0};
    double gmax = 0;
    int32_t ninterior = 0;
    for (int32_t v = 0; v < m->nverts; v++) {
        const double *p = m->coords + (size_t)v * dim;
        for (int i = 0; i < dim; i++) {
            double s = b[i];
            for (int j = 0; j < dim; j++)
                s += a[i][j] * p[j];
            g[(size_t)v * dim + i] = s;
            gmax = fmax(gmax, fabs(s));
        }
        ninterior += !m->on_boundary[v];
    }
    assert_true(ninterior > 10);
    sm_elasticity *el = NULL;
    sm_error err;
    if (sm__elasticity_new(m, m->on_boundary, OPTS(YOUNG, poisson, 0.0), &el, &err) != SM_OK)
        fail_msg("%s", err.msg);
    if (sm__elasticity_factorize(el, m->coords, &err) != SM_OK)
        fail_msg("%s", err.msg);
    /* u starts as garbage: every entry must be written */
    for (size_t k = 0; k < n; k++)
        u[k] = 1e300;
    assert_int_equal(sm__elasticity_solve(el, NULL, g, u, &err), SM_OK);
    double maxerr = 0;
    for (size_t k = 0; k < n; k++)
        maxerr = fmax(maxerr, fabs(u[k] - g[k]));
    print_message("# patch %dD h=%g nu=%g: %ld vertices (%ld interior), max rel error %.2e\n", dim,
                  h, poisson, (long)m->nverts, (long)ninterior, maxerr / gmax);
    assert_true(maxerr <= 1e-10 * gmax);
    sm__elasticity_free(el);
    free(g);
    free(u);
    sm_mesh_free(m);
}

static void test_patch_2d(void **state)
{
    (void)state;
    patch_test(2, 0.1, 0.3);
    patch_test(2, 0.1, 0.49);
}

static void test_patch_3d(void **state)
{
    (void)state;
    patch_test(3, 0.15, 0.3);
}

/* ---------------------------------------------------------------------- */
/* (b) convergence on a manufactured solution                              */
/* ---------------------------------------------------------------------- */

/* Solves with f = -div sigma(u_exact), u = u_exact on the boundary;
 * returns the L2 error and in *h_eff the mean edge length. */
static double manufactured_error(int dim, double h, double *h_eff)
{
    sm_mesh *m = unit_mesh(dim, h);
    int nv = dim + 1;
    size_t n = (size_t)m->nverts * dim;
    double lambda, mu;
    sm__lame(YOUNG, POISSON, &lambda, &mu);
    double *load = calloc(n, sizeof *load), *g = malloc(n * sizeof *g), *u = malloc(n * sizeof *u);
    assert_non_null(load);
    assert_non_null(g);
    assert_non_null(u);
    for (int32_t v = 0; v < m->nverts; v++)
        exact_u(dim, m->coords + (size_t)v * dim, g + (size_t)v * dim);
    quadrature q = make_quadrature(dim);
    for (int32_t e = 0; e < m->nelems; e++) {
        double w = fabs(sm_elem_volume(m, m->coords, e));
        const int32_t *ev = m->elems + (size_t)e * nv;
        for (int k = 0; k < q.npoints; k++) {
            double p[3] = {0, 0, 0}, f[3];
            for (int i = 0; i < nv; i++)
                for (int r = 0; r < dim; r++)
                    p[r] += q.bary[k][i] * m->coords[(size_t)ev[i] * dim + r];
            exact_f(dim, p, lambda, mu, f);
            for (int i = 0; i < nv; i++)
                for (int c = 0; c < dim; c++)
                    load[(size_t)ev[i] * dim + c] += w * q.weight[k] * f[c] * q.bary[k][i];
        }
    }
    sm_elasticity *el = NULL;
    sm_error err;
    if (sm__elasticity_new(m, m->on_boundary, OPTS(YOUNG, POISSON, 0.0), &el, &err) != SM_OK)
        fail_msg("%s", err.msg);
    if (sm__elasticity_factorize(el, m->coords, &err) != SM_OK)
        fail_msg("%s", err.msg);
    assert_int_equal(sm__elasticity_solve(el, load, g, u, &err), SM_OK);
    double err2 = 0;
    for (int32_t e = 0; e < m->nelems; e++) {
        double w = fabs(sm_elem_volume(m, m->coords, e));
        const int32_t *ev = m->elems + (size_t)e * nv;
        for (int k = 0; k < q.npoints; k++) {
            double p[3] = {0, 0, 0}, uh[3] = {0, 0, 0}, ue[3];
            for (int i = 0; i < nv; i++)
                for (int r = 0; r < dim; r++) {
                    p[r] += q.bary[k][i] * m->coords[(size_t)ev[i] * dim + r];
                    uh[r] += q.bary[k][i] * u[(size_t)ev[i] * dim + r];
                }
            exact_u(dim, p, ue);
            for (int c = 0; c < dim; c++)
                err2 += w * q.weight[k] * (uh[c] - ue[c]) * (uh[c] - ue[c]);
        }
    }
    /* h: mean edge length (vertex or element counts are biased by the
     * share of boundary vertices on coarse 3D meshes) */
    double edge_sum = 0;
    long nedges = 0;
    for (int32_t e = 0; e < m->nelems; e++)
        for (int i = 0; i < nv; i++)
            for (int j = i + 1; j < nv; j++) {
                double d2 = 0;
                for (int r = 0; r < dim; r++) {
                    double d = m->coords[(size_t)m->elems[(size_t)e * nv + i] * dim + r] -
                               m->coords[(size_t)m->elems[(size_t)e * nv + j] * dim + r];
                    d2 += d * d;
                }
                edge_sum += sqrt(d2);
                nedges++;
            }
    *h_eff = edge_sum / nedges;
    double assembly, factor;
    sm__elasticity_timings(el, &assembly, &factor);
    print_message("# manufactured %dD clmax=%g: %ld vertices, %ld elements, mean edge %.4f, "
                  "L2 error %.4e (assembly %.1f ms, factor %.1f ms)\n",
                  dim, h, (long)m->nverts, (long)m->nelems, *h_eff, sqrt(err2), 1e3 * assembly,
                  1e3 * factor);
    sm__elasticity_free(el);
    free(load);
    free(g);
    free(u);
    sm_mesh_free(m);
    return sqrt(err2);
}

static void convergence_test(int dim, double h0)
{
    double lambda, mu;
    sm__lame(YOUNG, POISSON, &lambda, &mu);
    check_exact_f(dim, lambda, mu);
    double e[3], h[3];
    for (int k = 0; k < 3; k++)
        e[k] = manufactured_error(dim, h0 / (1 << k), &h[k]);
    /* least-squares slope of log e against log h, and each pair */
    double sx = 0, sy = 0, sxx = 0, sxy = 0;
    for (int k = 0; k < 3; k++) {
        double lx = log(h[k]), ly = log(e[k]);
        sx += lx;
        sy += ly;
        sxx += lx * lx;
        sxy += lx * ly;
    }
    double slope = (3 * sxy - sx * sy) / (3 * sxx - sx * sx);
    double r01 = log(e[0] / e[1]) / log(h[0] / h[1]);
    double r12 = log(e[1] / e[2]) / log(h[1] / h[2]);
    print_message("# %dD L2 rates: %.3f, %.3f (fit %.3f)\n", dim, r01, r12, slope);
    assert_true(slope >= 1.8 && slope <= 2.3);
    assert_true(r01 >= 1.8 && r01 <= 2.3);
    assert_true(r12 >= 1.8 && r12 <= 2.3);
}

static void test_convergence_2d(void **state)
{
    (void)state;
    convergence_test(2, 0.1);
}

static void test_convergence_3d(void **state)
{
    (void)state;
    convergence_test(3, 0.25);
}

/* ---------------------------------------------------------------------- */
/* (c) matrix structure, symmetry, rigid motions, dense comparison         */
/* ---------------------------------------------------------------------- */

static void check_csr(const sm_elasticity *el, int32_t expected_n)
{
    sm_csr_view a;
    sm__elasticity_matrix(el, &a);
    assert_int_equal(a.n, expected_n);
    assert_int_equal(a.rowptr[0], 0);
    double amax = 0;
    for (int32_t p = 0; p < a.rowptr[a.n]; p++)
        amax = fmax(amax, fabs(a.values[p]));
    assert_true(amax > 0);
    for (int32_t i = 0; i < a.n; i++) {
        int has_diag = 0;
        for (int32_t p = a.rowptr[i]; p < a.rowptr[i + 1]; p++) {
            int32_t j = a.colind[p];
            assert_true(j >= 0 && j < a.n);
            if (p > a.rowptr[i])
                assert_true(a.colind[p - 1] < j);
            if (j == i) {
                has_diag = 1;
                assert_true(a.values[p] > 0);
            }
            /* the transposed entry exists and is equal */
            int32_t lo = a.rowptr[j], hi = a.rowptr[j + 1];
            while (lo < hi) {
                int32_t mid = (lo + hi) / 2;
                if (a.colind[mid] < i)
                    lo = mid + 1;
                else
                    hi = mid;
            }
            assert_true(lo < a.rowptr[j + 1] && a.colind[lo] == i);
            assert_true(fabs(a.values[p] - a.values[lo]) <= 1e-14 * amax);
        }
        assert_true(has_diag);
    }
}

/* Symmetric sorted pattern with positive diagonal on a Gmsh mesh and on
 * a structured one given in mixed orientations; clamped DOFs are absent. */
static void test_symmetry(void **state)
{
    (void)state;
    for (int dim = 2; dim <= 3; dim++) {
        sm_mesh *m = unit_mesh(dim, dim == 2 ? 0.1 : 0.25);
        sm_elasticity *el = NULL;
        sm_error err;
        assert_int_equal(sm__elasticity_new(m, m->on_boundary, OPTS(YOUNG, POISSON, 0.0),
                                           &el, &err), SM_OK);
        assert_int_equal(sm__elasticity_factorize(el, m->coords, &err), SM_OK);
        int32_t nfree = 0;
        for (int32_t v = 0; v < m->nverts; v++) {
            for (int c = 0; c < dim; c++) {
                int32_t k = sm__elasticity_dof(el, v, c);
                if (m->on_boundary[v]) {
                    assert_int_equal(k, -1);
                } else {
                    /* vertex-major, component-minor, contiguous */
                    assert_int_equal(k, nfree);
                    nfree++;
                }
            }
        }
        check_csr(el, nfree);
        sm__elasticity_free(el);
        sm_mesh_free(m);
    }
}

/* K r = 0 for the rigid motions (global element-matrix product); the
 * assembled alpha-system with no clamp satisfies A r = alpha M r (M
 * computed here independently), and solving with that load gives r back. */
static void rigid_test(int dim, double h)
{
    sm_mesh *m = unit_mesh(dim, h);
    size_t n = (size_t)m->nverts * dim;
    double lambda, mu, kmax;
    sm__lame(YOUNG, POISSON, &lambda, &mu);
    double *r = malloc(n * sizeof *r), *y = malloc(n * sizeof *y), *mr = malloc(n * sizeof *mr);
    double *u = malloc(n * sizeof *u);
    assert_non_null(r);
    assert_non_null(y);
    assert_non_null(mr);
    assert_non_null(u);
    const double alpha = 0.05;
    sm_elasticity *el = NULL;
    sm_error err;
    assert_int_equal(sm__elasticity_new(m, NULL, OPTS(YOUNG, POISSON, alpha), &el, &err), SM_OK);
    assert_int_equal(sm__elasticity_factorize(el, m->coords, &err), SM_OK);
    check_csr(el, (int32_t)n);
    sm_csr_view a;
    sm__elasticity_matrix(el, &a);
    double amax = 0;
    for (int32_t p = 0; p < a.rowptr[a.n]; p++)
        amax = fmax(amax, fabs(a.values[p]));
    for (int k = 0; rigid_mode(m, k, r); k++) {
        double rmax = 0, resid = 0;
        for (size_t i = 0; i < n; i++)
            rmax = fmax(rmax, fabs(r[i]));
        apply_global(m, lambda, mu, 0.0, r, y, &kmax);
        for (size_t i = 0; i < n; i++)
            resid = fmax(resid, fabs(y[i]));
        assert_true(resid <= 1e-12 * kmax * rmax);
        /* assembled: (K + alpha M) r - alpha M r = 0; with no clamp the
         * free DOF index is the global one */
        mass_apply(m, r, mr);
        resid = 0;
        for (int32_t i = 0; i < a.n; i++) {
            double s = 0;
            for (int32_t p = a.rowptr[i]; p < a.rowptr[i + 1]; p++)
                s += a.values[p] * r[a.colind[p]];
            resid = fmax(resid, fabs(s - alpha * mr[i]));
        }
        assert_true(resid <= 1e-12 * amax * rmax);
        for (size_t i = 0; i < n; i++)
            mr[i] *= alpha;
        assert_int_equal(sm__elasticity_solve(el, mr, NULL, u, &err), SM_OK);
        double uerr = 0;
        for (size_t i = 0; i < n; i++)
            uerr = fmax(uerr, fabs(u[i] - r[i]));
        assert_true(uerr <= 1e-8 * rmax);
    }
    sm__elasticity_free(el);
    free(r);
    free(y);
    free(mr);
    free(u);
    sm_mesh_free(m);
}

static void test_rigid_motions(void **state)
{
    (void)state;
    rigid_test(2, 0.1);
    rigid_test(3, 0.25);
}

/* The eliminated system against a dense brute force: assemble the full
 * matrix from element matrices, solve the reduced system with the
 * Dirichlet values moved to the right-hand side by dense elimination.
 * Clamps part of the boundary only, uses alpha > 0, random load and
 * values, and elements given in both orientations. */
static void dense_test(int dim, int n_cells)
{
    sm_mesh *m = box_mesh(dim, n_cells, 7);
    int32_t negative = 0;
    for (int32_t e = 0; e < m->nelems; e++)
        negative += sm_elem_volume(m, m->coords, e) < 0;
    assert_true(negative > 0); /* mixed orientations, on purpose */
    size_t n = (size_t)m->nverts * dim;
    double lambda, mu;
    const double poisson = 0.35, young = 3.0, alpha = 0.2;
    sm__lame(young, poisson, &lambda, &mu);
    uint8_t *clamped = calloc((size_t)m->nverts, 1);
    double *load = malloc(n * sizeof *load), *g = malloc(n * sizeof *g), *u = malloc(n * sizeof *u);
    assert_non_null(clamped);
    assert_non_null(load);
    assert_non_null(g);
    assert_non_null(u);
    unsigned st = 42;
    for (int32_t v = 0; v < m->nverts; v++) {
        /* the face x = 0 plus one extra vertex */
        clamped[v] = m->coords[(size_t)v * dim] < 1e-12 || v == m->nverts - 1;
        for (int c = 0; c < dim; c++) {
            load[(size_t)v * dim + c] = 2 * frand(&st) - 1;
            g[(size_t)v * dim + c] = 2 * frand(&st) - 1;
        }
    }
    sm_elasticity *el = NULL;
    sm_error err;
    assert_int_equal(sm__elasticity_new(m, clamped, OPTS(young, poisson, alpha), &el, &err), SM_OK);
    assert_int_equal(sm__elasticity_factorize(el, m->coords, &err), SM_OK);
    assert_int_equal(sm__elasticity_solve(el, load, g, u, &err), SM_OK);

    double *full = dense_global_matrix(m, lambda, mu, alpha);
    /* reduced matrix and right-hand side */
    int32_t *free_of = malloc(n * sizeof *free_of);
    assert_non_null(free_of);
    int nf = 0;
    for (size_t i = 0; i < n; i++)
        free_of[i] = clamped[i / dim] ? -1 : nf++;
    double *ared = calloc((size_t)nf * nf, sizeof *ared), *b = calloc((size_t)nf, sizeof *b);
    assert_non_null(ared);
    assert_non_null(b);
    for (size_t i = 0; i < n; i++) {
        if (free_of[i] < 0)
            continue;
        b[free_of[i]] = load[i];
        for (size_t j = 0; j < n; j++) {
            if (free_of[j] >= 0)
                ared[(size_t)free_of[i] * nf + free_of[j]] = full[i * n + j];
            else
                b[free_of[i]] -= full[i * n + j] * g[j];
        }
    }
    /* the CSR equals the dense reduced matrix entry by entry */
    sm_csr_view a;
    sm__elasticity_matrix(el, &a);
    assert_int_equal(a.n, nf);
    double amax = 0;
    for (int i = 0; i < nf * nf; i++)
        amax = fmax(amax, fabs(ared[i]));
    double *from_csr = calloc((size_t)nf * nf, sizeof *from_csr);
    assert_non_null(from_csr);
    for (int32_t i = 0; i < a.n; i++)
        for (int32_t p = a.rowptr[i]; p < a.rowptr[i + 1]; p++)
            from_csr[(size_t)i * nf + a.colind[p]] = a.values[p];
    for (int i = 0; i < nf * nf; i++)
        assert_true(fabs(from_csr[i] - ared[i]) <= 1e-13 * amax);
    assert_int_equal(dense_solve(nf, ared, b), 0);
    double umax = 0, diff = 0;
    for (size_t i = 0; i < n; i++) {
        double expected = free_of[i] >= 0 ? b[free_of[i]] : g[i];
        umax = fmax(umax, fabs(expected));
        diff = fmax(diff, fabs(u[i] - expected));
    }
    assert_true(diff <= 1e-9 * umax);
    sm__elasticity_free(el);
    free(full);
    free(free_of);
    free(ared);
    free(b);
    free(from_csr);
    free(clamped);
    free(load);
    free(g);
    free(u);
    sm_mesh_free(m);
}

static void test_dense_comparison(void **state)
{
    (void)state;
    dense_test(2, 5);
    dense_test(3, 3);
}

/* Forced simplicial and supernodal factors give the same solution; the
 * info and timings are filled; refactorizing on moved vertices reuses the
 * analysis and matches a fresh object. */
static void test_factor_kinds(void **state)
{
    (void)state;
    sm_mesh *m = unit_mesh(3, 0.2);
    size_t n = (size_t)m->nverts * 3;
    double *load = malloc(n * sizeof *load), *u1 = malloc(n * sizeof *u1);
    double *u2 = malloc(n * sizeof *u2), *moved = malloc(n * sizeof *moved);
    assert_non_null(load);
    assert_non_null(u1);
    assert_non_null(u2);
    assert_non_null(moved);
    unsigned st = 3;
    for (size_t i = 0; i < n; i++) {
        load[i] = frand(&st) - 0.5;
        moved[i] = m->coords[i] + 0.01 * (frand(&st) - 0.5);
    }
    sm_elasticity *simp = NULL, *super = NULL;
    sm_error err;
    assert_int_equal(sm__elasticity_new(m, m->on_boundary,
                                       &(sm_elasticity_opts){.young = YOUNG, .poisson = POISSON,
                                                              .alpha = 0, .factor = SM_FACTOR_SIMPLICIAL},
                                       &simp, &err), SM_OK);
    assert_int_equal(sm__elasticity_new(m, m->on_boundary,
                                       &(sm_elasticity_opts){.young = YOUNG, .poisson = POISSON,
                                                              .alpha = 0, .factor = SM_FACTOR_SUPERNODAL},
                                       &super, &err), SM_OK);
    for (int pass = 0; pass < 2; pass++) {
        const double *coords = pass ? moved : m->coords;
        assert_int_equal(sm__elasticity_factorize(simp, coords, &err), SM_OK);
        assert_int_equal(sm__elasticity_factorize(super, coords, &err), SM_OK);
        assert_int_equal(sm__elasticity_solve(simp, load, NULL, u1, &err), SM_OK);
        assert_int_equal(sm__elasticity_solve(super, load, NULL, u2, &err), SM_OK);
        double umax = 0, diff = 0;
        for (size_t i = 0; i < n; i++) {
            umax = fmax(umax, fabs(u1[i]));
            diff = fmax(diff, fabs(u1[i] - u2[i]));
        }
        assert_true(umax > 0);
        assert_true(diff <= 1e-10 * umax);
    }
    /* a fresh object on the moved coordinates agrees with the refactorized one */
    sm_elasticity *fresh = NULL;
    assert_int_equal(sm__elasticity_new(m, m->on_boundary, OPTS(YOUNG, POISSON, 0),
                                       &fresh, &err), SM_OK);
    assert_int_equal(sm__elasticity_factorize(fresh, moved, &err), SM_OK);
    assert_int_equal(sm__elasticity_solve(fresh, load, NULL, u2, &err), SM_OK);
    for (size_t i = 0; i < n; i++)
        assert_true(fabs(u1[i] - u2[i]) <= 1e-10 * (1 + fabs(u1[i])));

    sm_elasticity_info i1, i2;
    sm__elasticity_get_info(simp, &i1);
    sm__elasticity_get_info(super, &i2);
    assert_int_equal(i1.supernodal, 0);
    assert_int_equal(i2.supernodal, 1);
    assert_int_equal(i1.nfree, i2.nfree);
    assert_true(i1.nnz > i1.nfree && i1.nnz_factor >= (i1.nnz + i1.nfree) / 2.0);
    assert_true(i1.nnz_coupling > 0);
    double assembly = -1, factor = -1;
    sm__elasticity_timings(super, &assembly, &factor);
    assert_true(assembly >= 0 && factor > 0);
    sm__elasticity_free(simp);
    sm__elasticity_free(super);
    sm__elasticity_free(fresh);
    free(load);
    free(u1);
    free(u2);
    free(moved);
    sm_mesh_free(m);
}

/* A process forked after the factorization (a batch's target) gives the
 * shared pages of the values back before refactorizing
 * (unshare_values): its solution on moved vertices equals, bit for bit,
 * the parent's own refactorization on them, and the parent's factor is
 * untouched by the child's (its solution before and after the child ran
 * identical). */
static void test_forked_refactor(void **state)
{
    (void)state;
    sm_mesh *m = unit_mesh(3, 0.15);
    size_t n = (size_t)m->nverts * 3;
    double *load = malloc(n * sizeof *load), *moved = malloc(n * sizeof *moved);
    double *u0 = malloc(n * sizeof *u0), *u = malloc(n * sizeof *u);
    double *uc = malloc(n * sizeof *uc);
    assert_true(load && moved && u0 && u && uc);
    unsigned st = 5;
    for (size_t i = 0; i < n; i++) {
        load[i] = frand(&st) - 0.5;
        moved[i] = m->coords[i] + 0.01 * (frand(&st) - 0.5);
    }
    sm_elasticity *el = NULL;
    sm_error err;
    assert_int_equal(sm__elasticity_new(m, m->on_boundary,
                                       &(sm_elasticity_opts){.young = YOUNG, .poisson = POISSON,
                                                              .alpha = 0, .factor = SM_FACTOR_SUPERNODAL},
                                       &el, &err), SM_OK);
    assert_int_equal(sm__elasticity_factorize(el, m->coords, &err), SM_OK);
    assert_int_equal(sm__elasticity_solve(el, load, NULL, u0, &err), SM_OK);
    sm_elasticity_info info;
    sm__elasticity_get_info(el, &info);
    assert_int_equal(info.supernodal, 1);
    assert_true(info.nnz_factor * sizeof(double) > 16 * 4096.0); /* whole pages to give back */
    int fd[2];
    assert_int_equal(pipe(fd), 0);
    fflush(NULL);
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        /* no OpenMP team here: the earlier tests' threads are the
         * parent's (a batch's parent starts none, sm_job_threads_single) */
        omp_set_max_active_levels(0);
        close(fd[0]);
        int ok = sm__elasticity_factorize(el, moved, &err) == SM_OK &&
                 sm__elasticity_solve(el, load, NULL, uc, &err) == SM_OK;
        size_t bytes = n * sizeof *uc;
        ok = ok && write(fd[1], uc, bytes) == (ssize_t)bytes;
        _exit(ok ? 0 : 1);
    }
    close(fd[1]);
    size_t got = 0, bytes = n * sizeof *uc;
    while (got < bytes) {
        ssize_t r = read(fd[0], (char *)uc + got, bytes - got);
        if (r <= 0)
            break;
        got += (size_t)r;
    }
    close(fd[0]);
    int wst = 0;
    assert_int_equal(waitpid(pid, &wst, 0), pid);
    assert_true(WIFEXITED(wst) && WEXITSTATUS(wst) == 0);
    assert_int_equal(got, bytes);
    assert_int_equal(sm__elasticity_solve(el, load, NULL, u, &err), SM_OK);
    assert_memory_equal(u, u0, bytes);
    assert_int_equal(sm__elasticity_factorize(el, moved, &err), SM_OK);
    assert_int_equal(sm__elasticity_solve(el, load, NULL, u, &err), SM_OK);
    assert_memory_equal(u, uc, bytes);
    assert_memory_not_equal(u, u0, bytes);
    sm__elasticity_free(el);
    free(load);
    free(moved);
    free(u0);
    free(u);
    free(uc);
    sm_mesh_free(m);
}

/* ---------------------------------------------------------------------- */
/* (d) errors and edge cases                                               */
/* ---------------------------------------------------------------------- */

static void test_errors(void **state)
{
    (void)state;
    sm_mesh *m = box_mesh(2, 4, 0);
    sm_elasticity *el = NULL;
    sm_error err;
    uint8_t *clamped = calloc((size_t)m->nverts, 1);
    assert_non_null(clamped);
    clamped[0] = clamped[1] = 1;

    /* no clamp and alpha = 0: singular, refused with a message */
    assert_int_equal(sm__elasticity_new(m, NULL, OPTS(YOUNG, POISSON, 0.0),
                                       &el, &err), SM_ERR_INVALID);
    assert_null(el);
    assert_non_null(strstr(err.msg, "alpha"));
    assert_int_equal(sm__elasticity_new(m, clamped, OPTS(YOUNG, POISSON, -1.0),
                                       &el, &err), SM_ERR_INVALID);
    /* material parameters */
    assert_int_equal(sm__elasticity_new(m, clamped, OPTS(0.0, POISSON, 0.0),
                                       &el, &err), SM_ERR_INVALID);
    assert_int_equal(sm__elasticity_new(m, clamped, OPTS(YOUNG, 0.5, 0.0),
                                       &el, &err), SM_ERR_INVALID);
    assert_int_equal(sm__elasticity_new(m, clamped, OPTS(NAN, POISSON, 0.0),
                                       &el, &err), SM_ERR_INVALID);
    /* options */
    assert_int_equal(sm__elasticity_new(m, clamped, NULL, &el, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "options"));
    assert_int_equal(sm__elasticity_new(m, clamped,
                                       &(sm_elasticity_opts){.young = YOUNG, .poisson = POISSON,
                                                              .factor = (sm_factor_kind)7},
                                       &el, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "factor kind"));
    /* topology */
    int32_t saved = m->elems[4];
    m->elems[4] = m->nverts;
    assert_int_equal(sm__elasticity_new(m, clamped, OPTS(YOUNG, POISSON, 0.0),
                                       &el, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "element 2 "));
    m->elems[4] = m->elems[3];
    assert_int_equal(sm__elasticity_new(m, clamped, OPTS(YOUNG, POISSON, 0.0),
                                       &el, &err), SM_ERR_INVALID);
    m->elems[4] = saved;

    assert_int_equal(sm__elasticity_new(m, clamped, OPTS(YOUNG, POISSON, 0.0), &el, &err), SM_OK);
    size_t n = (size_t)m->nverts * 2;
    double *u = malloc(n * sizeof *u), *coords = malloc(n * sizeof *coords);
    assert_non_null(u);
    assert_non_null(coords);
    /* solve before factorize */
    assert_int_equal(sm__elasticity_solve(el, NULL, NULL, u, &err), SM_ERR_INVALID);
    /* degenerate element: move vertex onto the segment of two others */
    memcpy(coords, m->coords, n * sizeof *coords);
    const int32_t *ev = m->elems + 3 * 3;
    for (int r = 0; r < 2; r++)
        coords[(size_t)ev[2] * 2 + r] =
            0.5 * (coords[(size_t)ev[0] * 2 + r] + coords[(size_t)ev[1] * 2 + r]);
    assert_int_equal(sm__elasticity_factorize(el, coords, &err), SM_ERR_NUMERIC);
    assert_non_null(strstr(err.msg, "element"));
    assert_non_null(strstr(err.msg, "degenerate"));
    /* a failed factorize invalidates the previous one */
    assert_int_equal(sm__elasticity_solve(el, NULL, NULL, u, &err), SM_ERR_INVALID);
    coords[0] = NAN;
    assert_int_equal(sm__elasticity_factorize(el, coords, &err), SM_ERR_NUMERIC);
    /* recovers on valid coordinates */
    assert_int_equal(sm__elasticity_factorize(el, m->coords, &err), SM_OK);
    assert_int_equal(sm__elasticity_solve(el, NULL, NULL, u, &err), SM_OK);
    for (size_t k = 0; k < n; k++)
        assert_true(u[k] == 0.0);
    sm__elasticity_free(el);

    /* everything clamped: no system, the Dirichlet values come back */
    memset(clamped, 1, (size_t)m->nverts);
    assert_int_equal(sm__elasticity_new(m, clamped, OPTS(YOUNG, POISSON, 0.0), &el, &err), SM_OK);
    assert_int_equal(sm__elasticity_factorize(el, m->coords, &err), SM_OK);
    assert_int_equal(sm__elasticity_solve(el, NULL, m->coords, u, &err), SM_OK);
    for (size_t k = 0; k < n; k++)
        assert_true(u[k] == m->coords[k]);
    sm__elasticity_free(el);

    /* a clamp that leaves a rotation free (one vertex) with alpha = 0:
     * singular.  Round-off makes the last pivot a tiny number of either
     * sign; every factor kind must report it, never return garbage. */
    memset(clamped, 0, (size_t)m->nverts);
    clamped[5] = 1;
    for (int kind = SM_FACTOR_AUTO; kind <= SM_FACTOR_SUPERNODAL; kind++) {
        assert_int_equal(sm__elasticity_new(m, clamped,
                                           &(sm_elasticity_opts){.young = YOUNG, .poisson = POISSON,
                                                                  .alpha = 0.0,
                                                                  .factor = (sm_factor_kind)kind},
                                           &el, &err), SM_OK);
        assert_int_equal(sm__elasticity_factorize(el, m->coords, &err), SM_ERR_NUMERIC);
        assert_non_null(strstr(err.msg, "CHOLMOD"));
        assert_non_null(strstr(err.msg, "rigid motion"));
        assert_int_equal(sm__elasticity_solve(el, NULL, NULL, u, &err), SM_ERR_INVALID);
        sm__elasticity_free(el);
    }

    /* no element at all: nothing to solve, not an error */
    sm_mesh *empty = NULL;
    assert_int_equal(sm_mesh_alloc(&empty, 3, 2, 0, 0, &err), SM_OK);
    assert_int_equal(sm__elasticity_new(empty, NULL, OPTS(YOUNG, POISSON, 0.0), &el, &err), SM_OK);
    assert_int_equal(sm__elasticity_factorize(el, empty->coords, &err), SM_OK);
    u[0] = 1;
    assert_int_equal(sm__elasticity_solve(el, NULL, NULL, u, &err), SM_OK);
    for (int k = 0; k < 6; k++)
        assert_true(u[k] == 0.0);
    sm__elasticity_free(el);
    sm_mesh_free(empty);

    free(u);
    free(coords);
    free(clamped);
    sm_mesh_free(m);
}

/* Vertices used by no element carry no unknown (displacement 0 or the
 * Dirichlet value); the others are solved as if the vertex did not exist. */
static void test_unused_vertex(void **state)
{
    (void)state;
    sm_mesh *base = box_mesh(2, 3, 0);
    sm_mesh *m = NULL;
    sm_error err;
    assert_int_equal(sm_mesh_alloc(&m, 2, base->nverts + 1, base->nelems, 0, &err), SM_OK);
    /* the extra vertex first, so every index shifts */
    m->coords[0] = 5;
    m->coords[1] = 5;
    memcpy(m->coords + 2, base->coords, (size_t)base->nverts * 2 * sizeof(double));
    for (int32_t k = 0; k < base->nelems * 3; k++)
        m->elems[k] = base->elems[k] + 1;
    uint8_t *cl_base = calloc((size_t)base->nverts, 1), *cl = calloc((size_t)m->nverts, 1);
    assert_non_null(cl_base);
    assert_non_null(cl);
    for (int32_t v = 0; v < base->nverts; v++)
        cl_base[v] = cl[v + 1] = base->coords[(size_t)v * 2] < 1e-12;
    size_t nb = (size_t)base->nverts * 2, n = nb + 2;
    double *load = malloc(n * sizeof *load), *u = malloc(n * sizeof *u), *ub = malloc(nb * sizeof *ub);
    assert_non_null(load);
    assert_non_null(u);
    assert_non_null(ub);
    for (size_t k = 0; k < n; k++)
        load[k] = 0.1 * (double)(k % 5) - 0.2;
    sm_elasticity *el = NULL, *elb = NULL;
    assert_int_equal(sm__elasticity_new(m, cl, OPTS(YOUNG, POISSON, 0.0), &el, &err), SM_OK);
    assert_int_equal(sm__elasticity_new(base, cl_base, OPTS(YOUNG, POISSON, 0.0),
                                       &elb, &err), SM_OK);
    assert_int_equal(sm__elasticity_dof(el, 0, 0), -1);
    assert_int_equal(sm__elasticity_factorize(el, m->coords, &err), SM_OK);
    assert_int_equal(sm__elasticity_factorize(elb, base->coords, &err), SM_OK);
    assert_int_equal(sm__elasticity_solve(el, load, NULL, u, &err), SM_OK);
    assert_int_equal(sm__elasticity_solve(elb, load + 2, NULL, ub, &err), SM_OK);
    assert_true(u[0] == 0.0 && u[1] == 0.0);
    for (size_t k = 0; k < nb; k++)
        assert_true(fabs(u[k + 2] - ub[k]) <= 1e-12 * (1 + fabs(ub[k])));
    sm__elasticity_free(el);
    sm__elasticity_free(elb);
    free(cl_base);
    free(cl);
    free(load);
    free(u);
    free(ub);
    sm_mesh_free(m);
    sm_mesh_free(base);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_element_matrix),
        cmocka_unit_test(test_patch_2d),
        cmocka_unit_test(test_patch_3d),
        cmocka_unit_test(test_convergence_2d),
        cmocka_unit_test(test_convergence_3d),
        cmocka_unit_test(test_symmetry),
        cmocka_unit_test(test_rigid_motions),
        cmocka_unit_test(test_dense_comparison),
        cmocka_unit_test(test_factor_kinds),
        cmocka_unit_test(test_forked_refactor),
        cmocka_unit_test(test_errors),
        cmocka_unit_test(test_unused_vertex),
    };
    return cmocka_run_group_tests_name("elasticity", tests, NULL, NULL);
}
