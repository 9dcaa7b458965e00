/* sdf: exact Euclidean signed distance to an analytic star-shaped shape
 * (examples/tools/shapes.h), evaluated at every vertex of a background
 * mesh and written as a .sol file (SolAtVertices, one scalar, negative
 * inside).
 *
 * How the distance is computed, and why it is exact up to rounding:
 *   1. The boundary is discretised finely: a closed polyline through
 *      points of the analytic curve (2D) or a triangulation of the surface
 *      through points of the analytic surface (3D, a subdivided icosahedron
 *      mapped radially).  Its Hausdorff distance to the true boundary (the
 *      chordal error e) is estimated from the gap between the primitives
 *      and the analytic boundary at their parametric midpoints.
 *   2. For each vertex, the nearest primitive is found with a bounding
 *      volume hierarchy (branch and bound on box distances); the exact
 *      point-segment / point-triangle distance gives d_disc, and
 *      |d_true - d_disc| <= e.
 *   3. Starting from the nearest discrete point, Newton's method on the
 *      analytic parametrisation u -> c + R(u) u finds a stationary point of
 *      the distance.  Its distance d_newton is a distance to a true
 *      boundary point, so d_newton >= d_true; it is accepted when Newton
 *      converged and d_newton <= d_disc + 2e, hence in every case
 *      |d - d_true| <= 3e, and d = d_true up to rounding whenever the
 *      stationary point is the global one (always, in practice: the
 *      fallback count and the Newton-vs-discrete gap are reported).
 *   4. The sign comes from the exact inside test |x - c| < R(u).
 * The --verify-* options measure it: against the closed form on a disk or
 * a ball, against an independent coarser discretisation (the Newton step
 * makes the result independent of it), and the BVH against brute force.
 *
 * The tool is not a library: it reports errors on stderr and exits with
 * status 1 (bad usage or input) or 2 (a verification failed). */
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "shapematch/sm_clock.h"
#include "shapematch/sm_error.h"
#include "shapematch/sm_io.h"
#include "shapematch/sm_mesh.h"

#include "geometry.h"
#include "shapes.h"

/* ---------------------------------------------------------------- utils */

/* ------------------------------------------------------ discretisation */

/* The fine boundary: segments (2 vertices per primitive, 2D) or triangles
 * (3 vertices, 3D); every vertex lies exactly on the analytic boundary.
 * Coordinates always have 3 entries (z = 0 in 2D). */
typedef struct discretization {
    int verts_per_prim;
    int32_t nverts, nprims;
    double *verts; /* nverts * 3: c + R(u) u */
    double *dirs;  /* nverts * 3: the unit direction u of each vertex */
    int32_t *prims;
} discretization;

static void discretization_free(discretization *d)
{
    free(d->verts);
    free(d->dirs);
    free(d->prims);
    memset(d, 0, sizeof *d);
}

static int discretization_alloc(discretization *d, int verts_per_prim,
                                int64_t nverts, int64_t nprims)
{
    memset(d, 0, sizeof *d);
    if (nverts <= 0 || nprims <= 0 || nverts > INT32_MAX / 3 ||
        nprims > INT32_MAX / 3)
        return -1;
    d->verts_per_prim = verts_per_prim;
    d->nverts = (int32_t)nverts;
    d->nprims = (int32_t)nprims;
    d->verts = malloc((size_t)nverts * 3 * sizeof *d->verts);
    d->dirs = malloc((size_t)nverts * 3 * sizeof *d->dirs);
    d->prims = malloc((size_t)nprims * (size_t)verts_per_prim *
                      sizeof *d->prims);
    if (!d->verts || !d->dirs || !d->prims) {
        discretization_free(d);
        return -1;
    }
    return 0;
}

static void set_vertex(discretization *d, const shape *s, int32_t i,
                       const double *u)
{
    memcpy(d->dirs + 3 * (size_t)i, u, 3 * sizeof *u);
    shape_boundary_point(s, u, d->verts + 3 * (size_t)i);
}

/* 2D: a closed polyline through npoints points at equal angles. */
static int discretize_curve(const shape *s, int32_t npoints,
                            discretization *d)
{
    if (discretization_alloc(d, 2, npoints, npoints) != 0)
        return -1;
    for (int32_t i = 0; i < npoints; i++) {
        double theta = 2.0 * M_PI * (double)i / (double)npoints;
        double u[3] = {cos(theta), sin(theta), 0.0};
        set_vertex(d, s, i, u);
        d->prims[2 * i] = i;
        d->prims[2 * i + 1] = (i + 1) % npoints;
    }
    return 0;
}

/* 3D: each of the 20 faces of the icosahedron is split into n^2 triangles
 * by a regular barycentric grid, whose points are projected onto the unit
 * sphere (directions u) and then mapped to c + R(u) u.  Grid points on
 * shared icosahedron edges are duplicated, which is harmless for
 * distance queries. */
static int discretize_surface(const shape *s, int n, discretization *d)
{
    const double g = (1.0 + sqrt(5.0)) / 2.0;
    const double ico_verts[12][3] = {
        {-1, g, 0}, {1, g, 0}, {-1, -g, 0}, {1, -g, 0},
        {0, -1, g}, {0, 1, g}, {0, -1, -g}, {0, 1, -g},
        {g, 0, -1}, {g, 0, 1}, {-g, 0, -1}, {-g, 0, 1}};
    const int ico_faces[20][3] = {
        {0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
        {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
        {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
        {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
    int64_t per_face_verts = (int64_t)(n + 1) * (n + 2) / 2;
    int64_t per_face_tris = (int64_t)n * n;
    if (discretization_alloc(d, 3, 20 * per_face_verts, 20 * per_face_tris) !=
        0)
        return -1;
    int32_t tri = 0;
    for (int f = 0; f < 20; f++) {
        const double *A = ico_verts[ico_faces[f][0]];
        const double *B = ico_verts[ico_faces[f][1]];
        const double *C = ico_verts[ico_faces[f][2]];
        int32_t base = (int32_t)(f * per_face_verts);
        /* grid index of (i, j), i + j <= n: rows of decreasing length */
#define GRID(i, j) (base + (i) * (n + 1) - (i) * ((i)-1) / 2 + (j))
        for (int i = 0; i <= n; i++) {
            for (int j = 0; i + j <= n; j++) {
                double u[3];
                for (int k = 0; k < 3; k++)
                    u[k] = A[k] + (B[k] - A[k]) * i / (double)n +
                           (C[k] - A[k]) * j / (double)n;
                normalize3(u);
                set_vertex(d, s, GRID(i, j), u);
            }
        }
        for (int i = 0; i < n; i++) {
            for (int j = 0; i + j < n; j++) {
                int32_t *t = d->prims + 3 * (size_t)tri++;
                t[0] = GRID(i, j);
                t[1] = GRID(i + 1, j);
                t[2] = GRID(i, j + 1);
                if (i + j + 1 < n) {
                    t = d->prims + 3 * (size_t)tri++;
                    t[0] = GRID(i + 1, j);
                    t[1] = GRID(i + 1, j + 1);
                    t[2] = GRID(i, j + 1);
                }
            }
        }
#undef GRID
    }
    return tri == d->nprims ? 0 : -1;
}

/* Closest point of primitive i to p; returns the squared distance. */
static double prim_closest(const discretization *d, int32_t i,
                           const double *p, double *q)
{
    const int32_t *v = d->prims + (size_t)i * (size_t)d->verts_per_prim;
    if (d->verts_per_prim == 2)
        closest_on_segment(p, d->verts + 3 * (size_t)v[0],
                           d->verts + 3 * (size_t)v[1], q);
    else
        closest_on_triangle(p, d->verts + 3 * (size_t)v[0],
                            d->verts + 3 * (size_t)v[1],
                            d->verts + 3 * (size_t)v[2], q);
    return dist2_3(p, q);
}

/* Chordal error estimate: the largest distance from the analytic boundary
 * point at a primitive's parametric midpoints (the middle of a segment;
 * the centroid and edge midpoints of a triangle) to that primitive. */
static double chordal_error(const shape *s, const discretization *d)
{
    double worst = 0.0;
    for (int32_t i = 0; i < d->nprims; i++) {
        const int32_t *v = d->prims + (size_t)i * (size_t)d->verts_per_prim;
        int nv = d->verts_per_prim;
        /* subsets of the primitive's vertices whose mean direction is
         * sampled: the edges, and (triangles) the whole face */
        const int subsets[4][3] = {{0, 1, -1}, {1, 2, -1}, {2, 0, -1},
                                   {0, 1, 2}};
        int nsubsets = nv == 2 ? 1 : 4;
        for (int k = 0; k < nsubsets; k++) {
            double u[3] = {0, 0, 0}, p[3], q[3];
            for (int l = 0; l < 3 && subsets[k][l] >= 0; l++)
                for (int c = 0; c < 3; c++)
                    u[c] += d->dirs[3 * (size_t)v[subsets[k][l]] + c];
            normalize3(u);
            shape_boundary_point(s, u, p);
            double e = sqrt(prim_closest(d, i, p, q));
            if (e > worst)
                worst = e;
        }
    }
    return worst;
}

/* ------------------------------------------------------------------ BVH */

#define BVH_LEAF_SIZE 4
#define BVH_STACK 256

typedef struct bvh_node {
    double lo[3], hi[3];
    int32_t child; /* index of the left child; right = child + 1 */
    int32_t first, count; /* primitives order[first..first+count) if leaf */
} bvh_node;

typedef struct bvh {
    bvh_node *nodes;
    int32_t nnodes;
    int32_t *order;     /* primitive indices, grouped by leaf */
    double *centroids;  /* nprims * 3 */
    double *boxes;      /* nprims * 6: lo, hi */
    int depth;
} bvh;

static void bvh_free(bvh *b)
{
    free(b->nodes);
    free(b->order);
    free(b->centroids);
    free(b->boxes);
    memset(b, 0, sizeof *b);
}

/* Rearranges order[lo..hi) so that order[mid] has the median centroid
 * coordinate along axis, smaller ones before, larger ones after
 * (quickselect with a deterministic median-of-three pivot). */
static void select_median(int32_t *order, const double *centroids, int axis,
                          int32_t lo, int32_t hi, int32_t mid)
{
    hi--; /* inclusive */
    while (lo < hi) {
        int32_t m = lo + (hi - lo) / 2;
        double a = centroids[3 * (size_t)order[lo] + axis];
        double b = centroids[3 * (size_t)order[m] + axis];
        double c = centroids[3 * (size_t)order[hi] + axis];
        double pivot = a < b ? (b < c ? b : (a < c ? c : a))
                             : (a < c ? a : (b < c ? c : b));
        int32_t i = lo, j = hi;
        while (i <= j) {
            while (centroids[3 * (size_t)order[i] + axis] < pivot)
                i++;
            while (centroids[3 * (size_t)order[j] + axis] > pivot)
                j--;
            if (i <= j) {
                int32_t t = order[i];
                order[i] = order[j];
                order[j] = t;
                i++;
                j--;
            }
        }
        if (mid <= j)
            hi = j;
        else if (mid >= i)
            lo = i;
        else
            return;
    }
}

static void bvh_build_node(bvh *b, int32_t node, int32_t first,
                           int32_t count, int depth)
{
    bvh_node *n = b->nodes + node;
    double clo[3], chi[3];
    for (int k = 0; k < 3; k++) {
        n->lo[k] = clo[k] = INFINITY;
        n->hi[k] = chi[k] = -INFINITY;
    }
    for (int32_t i = first; i < first + count; i++) {
        const double *box = b->boxes + 6 * (size_t)b->order[i];
        const double *c = b->centroids + 3 * (size_t)b->order[i];
        for (int k = 0; k < 3; k++) {
            n->lo[k] = fmin(n->lo[k], box[k]);
            n->hi[k] = fmax(n->hi[k], box[3 + k]);
            clo[k] = fmin(clo[k], c[k]);
            chi[k] = fmax(chi[k], c[k]);
        }
    }
    if (depth > b->depth)
        b->depth = depth;
    if (count <= BVH_LEAF_SIZE) {
        n->child = -1;
        n->first = first;
        n->count = count;
        return;
    }
    int axis = 0;
    for (int k = 1; k < 3; k++)
        if (chi[k] - clo[k] > chi[axis] - clo[axis])
            axis = k;
    int32_t half = count / 2;
    select_median(b->order, b->centroids, axis, first, first + count,
                  first + half);
    int32_t child = b->nnodes;
    b->nnodes += 2;
    n->child = child;
    n->first = 0;
    n->count = 0;
    bvh_build_node(b, child, first, half, depth + 1);
    bvh_build_node(b, child + 1, first + half, count - half, depth + 1);
}

static int bvh_build(bvh *b, const discretization *d)
{
    memset(b, 0, sizeof *b);
    size_t n = (size_t)d->nprims;
    b->nodes = malloc(2 * n * sizeof *b->nodes);
    b->order = malloc(n * sizeof *b->order);
    b->centroids = malloc(3 * n * sizeof *b->centroids);
    b->boxes = malloc(6 * n * sizeof *b->boxes);
    if (!b->nodes || !b->order || !b->centroids || !b->boxes) {
        bvh_free(b);
        return -1;
    }
    for (size_t i = 0; i < n; i++) {
        const int32_t *v = d->prims + i * (size_t)d->verts_per_prim;
        double *box = b->boxes + 6 * i, *c = b->centroids + 3 * i;
        for (int k = 0; k < 3; k++) {
            box[k] = INFINITY;
            box[3 + k] = -INFINITY;
            c[k] = 0.0;
        }
        for (int l = 0; l < d->verts_per_prim; l++) {
            const double *x = d->verts + 3 * (size_t)v[l];
            for (int k = 0; k < 3; k++) {
                box[k] = fmin(box[k], x[k]);
                box[3 + k] = fmax(box[3 + k], x[k]);
                c[k] += x[k] / d->verts_per_prim;
            }
        }
        b->order[i] = (int32_t)i;
    }
    b->nnodes = 1;
    bvh_build_node(b, 0, 0, d->nprims, 0);
    /* a median split keeps the depth near log2(n / leaf size) */
    if (b->depth >= BVH_STACK - 2) {
        bvh_free(b);
        return -1;
    }
    return 0;
}

static double box_dist2(const bvh_node *n, const double *p)
{
    double s = 0.0;
    for (int k = 0; k < 3; k++) {
        double e = 0.0;
        if (p[k] < n->lo[k])
            e = n->lo[k] - p[k];
        else if (p[k] > n->hi[k])
            e = p[k] - n->hi[k];
        s += e * e;
    }
    return s;
}

/* Nearest primitive to p.  *prim holds a starting guess (or -1) whose
 * distance seeds the bound, and receives the answer; q the closest point.
 * Returns the squared distance. */
static double bvh_nearest(const bvh *b, const discretization *d,
                          const double *p, int32_t *prim, double *q)
{
    double best = INFINITY, cand[3];
    int32_t best_prim = -1;
    if (*prim >= 0 && *prim < d->nprims) {
        best = prim_closest(d, *prim, p, q);
        best_prim = *prim;
    }
    int32_t stack[BVH_STACK];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
        const bvh_node *n = b->nodes + stack[--top];
        if (box_dist2(n, p) >= best)
            continue;
        if (n->child < 0) {
            for (int32_t i = n->first; i < n->first + n->count; i++) {
                int32_t pi = b->order[i];
                double d2 = prim_closest(d, pi, p, cand);
                if (d2 < best) {
                    best = d2;
                    best_prim = pi;
                    memcpy(q, cand, sizeof cand);
                }
            }
            continue;
        }
        /* visit the nearer child first: push it last */
        double dl = box_dist2(b->nodes + n->child, p);
        double dr = box_dist2(b->nodes + n->child + 1, p);
        if (dl < dr) {
            stack[top++] = n->child + 1;
            stack[top++] = n->child;
        } else {
            stack[top++] = n->child;
            stack[top++] = n->child + 1;
        }
    }
    *prim = best_prim;
    return best;
}

static double brute_nearest(const discretization *d, const double *p)
{
    double best = INFINITY, q[3];
    for (int32_t i = 0; i < d->nprims; i++) {
        double d2 = prim_closest(d, i, p, q);
        if (d2 < best)
            best = d2;
    }
    return best;
}

/* ------------------------------------------------------ Newton refining */

/* Orthonormal tangent frame at the unit direction u (dim - 1 vectors). */
static void tangent_frame(int dim, const double *u, double t[2][3])
{
    if (dim == 2) {
        t[0][0] = -u[1];
        t[0][1] = u[0];
        t[0][2] = 0.0;
        return;
    }
    /* any vector not parallel to u, then Gram-Schmidt and a cross product */
    double a[3] = {0, 0, 0};
    int k = fabs(u[0]) < fabs(u[1]) ? (fabs(u[0]) < fabs(u[2]) ? 0 : 2)
                                    : (fabs(u[1]) < fabs(u[2]) ? 1 : 2);
    a[k] = 1.0;
    double p = dot3(a, u);
    for (int c = 0; c < 3; c++)
        t[0][c] = a[c] - p * u[c];
    normalize3(t[0]);
    t[1][0] = u[1] * t[0][2] - u[2] * t[0][1];
    t[1][1] = u[2] * t[0][0] - u[0] * t[0][2];
    t[1][2] = u[0] * t[0][1] - u[1] * t[0][0];
}

/* Boundary point at the direction normalize(u0 + a t0 + b t1). */
static void surface_at(const shape *s, const double *u0, double t[2][3],
                       double a, double b, double *x, double *u_out)
{
    double u[3];
    for (int c = 0; c < 3; c++)
        u[c] = u0[c] + a * t[0][c] + b * t[1][c];
    normalize3(u);
    shape_boundary_point(s, u, x);
    if (u_out)
        memcpy(u_out, u, sizeof u);
}

/* Newton's method for the closest boundary point to p from direction u
 * (updated).  Derivatives of the parametrisation by central differences
 * of step h: the stationary point's accuracy depends on the first
 * derivatives only, whose O(h^2) error moves the point tangentially by
 * ~1e-9 and so changes the distance by ~1e-18.  Returns the distance of
 * the final point, and *converged = 1 when the vector from the boundary
 * point to p is normal to the boundary to within 1e-8 radians, or the
 * foot point is within 1e-13 of the stationary point. */
static double newton_closest(const shape *s, const double *p, double *u,
                             int *converged)
{
    const double h = 1e-4;
    const int npar = s->dim - 1;
    double t[2][3] = {{0, 0, 0}, {0, 0, 0}};
    double x[3];
    *converged = 0;
    shape_boundary_point(s, u, x);
    double f = dist2_3(x, p);
    for (int it = 0; it < 60; it++) {
        tangent_frame(s->dim, u, t);
        double S0[3], Sp[2][3], Sm[2][3], Sa[2][3], Saa[2][2][3];
        surface_at(s, u, t, 0, 0, S0, NULL);
        for (int k = 0; k < npar; k++) {
            surface_at(s, u, t, k == 0 ? h : 0, k == 1 ? h : 0, Sp[k], NULL);
            surface_at(s, u, t, k == 0 ? -h : 0, k == 1 ? -h : 0, Sm[k],
                       NULL);
            for (int c = 0; c < 3; c++) {
                Sa[k][c] = (Sp[k][c] - Sm[k][c]) / (2 * h);
                Saa[k][k][c] = (Sp[k][c] - 2 * S0[c] + Sm[k][c]) / (h * h);
            }
        }
        if (npar == 2) {
            double pp[3], pm[3], mp[3], mm[3];
            surface_at(s, u, t, h, h, pp, NULL);
            surface_at(s, u, t, h, -h, pm, NULL);
            surface_at(s, u, t, -h, h, mp, NULL);
            surface_at(s, u, t, -h, -h, mm, NULL);
            for (int c = 0; c < 3; c++)
                Saa[0][1][c] = Saa[1][0][c] =
                    (pp[c] - pm[c] - mp[c] + mm[c]) / (4 * h * h);
        }
        double r[3] = {S0[0] - p[0], S0[1] - p[1], S0[2] - p[2]};
        double rn = sqrt(dot3(r, r));
        double grad[2] = {0, 0}, H[2][2] = {{0, 0}, {0, 0}},
               G[2][2] = {{0, 0}, {0, 0}};
        double misalign = 0.0, offset = 0.0;
        for (int k = 0; k < npar; k++) {
            grad[k] = dot3(r, Sa[k]);
            double san = sqrt(dot3(Sa[k], Sa[k]));
            if (san > 0.0)
                offset = fmax(offset, fabs(grad[k]) / san);
            if (rn > 0.0 && san > 0.0)
                misalign = fmax(misalign, fabs(grad[k]) / (rn * san));
            for (int l = 0; l < npar; l++) {
                G[k][l] = dot3(Sa[k], Sa[l]);
                H[k][l] = G[k][l] + dot3(r, Saa[k][l]);
            }
        }
        /* a tangential offset t of the foot point changes the distance by
         * about t^2 / (2 d) and at most by t: stop when that is below
         * ~1e-16 d or 1e-13 (the rounding of the coordinates is ~1e-17) */
        if (rn == 0.0 || misalign < 1e-8 || offset < 1e-13) {
            *converged = 1;
            return rn;
        }
        /* Newton step if the Hessian is positive definite, else the
         * Gauss-Newton step (the Gram matrix always is) */
        double step[2] = {0, 0};
        double (*M)[2] = H;
        double det = npar == 2 ? H[0][0] * H[1][1] - H[0][1] * H[1][0]
                               : H[0][0];
        if (!(H[0][0] > 0.0 && det > 0.0)) {
            M = G;
            det = npar == 2 ? G[0][0] * G[1][1] - G[0][1] * G[1][0] : G[0][0];
            if (!(det > 0.0))
                return sqrt(f);
        }
        if (npar == 1) {
            step[0] = -grad[0] / M[0][0];
        } else {
            step[0] = -(M[1][1] * grad[0] - M[0][1] * grad[1]) / det;
            step[1] = -(M[0][0] * grad[1] - M[1][0] * grad[0]) / det;
        }
        /* trust region of 0.2 rad, then halve until the distance drops;
         * near the solution the drop (~|r|^2 misalign^2) is below the
         * rounding noise of the squared distance (~1e-16 |r|, coordinates
         * being O(1)), hence the allowance */
        double noise = 1e-12 * f + 1e-15 * rn;
        double len = hypot(step[0], step[1]);
        if (len > 0.2) {
            step[0] *= 0.2 / len;
            step[1] *= 0.2 / len;
        }
        int accepted = 0;
        for (int ls = 0; ls < 50; ls++) {
            double xn[3], un[3];
            surface_at(s, u, t, step[0], step[1], xn, un);
            double fn = dist2_3(xn, p);
            if (fn <= f + noise) {
                memcpy(u, un, sizeof un);
                f = fn;
                accepted = 1;
                break;
            }
            step[0] *= 0.5;
            step[1] *= 0.5;
        }
        if (!accepted)
            return sqrt(f); /* stalled before the stationarity test */
    }
    return sqrt(f);
}

/* ---------------------------------------------------- the computation */

typedef struct sdf_stats {
    int32_t nprims;
    double chordal_error;
    int32_t bvh_nodes;
    int bvh_depth;
    int32_t refined, fallbacks;  /* Newton accepted / discrete distance kept */
    double max_gap, rms_gap;     /* |d_newton - d_discrete| when accepted */
    int32_t brute_checked;
    double brute_max_diff;
    double seconds_setup, seconds_query;
} sdf_stats;

static void vertex_point(const sm_mesh *m, int32_t i, double *p)
{
    p[0] = p[1] = p[2] = 0.0;
    for (int k = 0; k < m->dim; k++)
        p[k] = m->coords[(size_t)i * (size_t)m->dim + (size_t)k];
}

/* Signed distance at every vertex of m into values.  verify_brute > 0
 * also compares the BVH search with a brute-force one at that many
 * vertices.  Returns 0, or -1 when out of memory. */
static int compute_distances(const shape *s, const sm_mesh *m, long resolution,
                             int use_newton, long verify_brute,
                             double *values, sdf_stats *st)
{
    discretization disc;
    bvh tree;
    memset(st, 0, sizeof *st);
    double t0 = sm_clock_seconds();
    int rc = s->dim == 2 ? discretize_curve(s, (int32_t)resolution, &disc)
                         : discretize_surface(s, (int)resolution, &disc);
    if (rc != 0)
        return -1;
    if (bvh_build(&tree, &disc) != 0) {
        discretization_free(&disc);
        return -1;
    }
    st->nprims = disc.nprims;
    st->chordal_error = chordal_error(s, &disc);
    st->bvh_nodes = tree.nnodes;
    st->bvh_depth = tree.depth;
    double t1 = sm_clock_seconds();

    int32_t prim = -1; /* previous answer: consecutive vertices are close */
    double sum_gap2 = 0.0;
    for (int32_t i = 0; i < m->nverts; i++) {
        double p[3], q[3];
        vertex_point(m, i, p);
        double d_disc = sqrt(bvh_nearest(&tree, &disc, p, &prim, q));
        double d = d_disc;
        if (use_newton) {
            double u[3] = {q[0] - s->center[0], q[1] - s->center[1],
                           q[2] - s->center[2]};
            normalize3(u);
            int converged;
            double d_newton = newton_closest(s, p, u, &converged);
            if (converged &&
                d_newton <= d_disc + 2.0 * st->chordal_error + 1e-14) {
                d = d_newton;
                st->refined++;
                double gap = fabs(d_newton - d_disc);
                st->max_gap = fmax(st->max_gap, gap);
                sum_gap2 += gap * gap;
            } else {
                st->fallbacks++;
            }
        }
        values[i] = shape_radial_offset(s, p) < 0.0 ? -d : d;
    }
    st->rms_gap = st->refined ? sqrt(sum_gap2 / st->refined) : 0.0;

    if (verify_brute > 0) {
        int32_t stride = m->nverts / (int32_t)verify_brute;
        if (stride < 1)
            stride = 1;
        for (int32_t i = 0; i < m->nverts && st->brute_checked < verify_brute;
             i += stride) {
            double p[3], q[3];
            vertex_point(m, i, p);
            int32_t guess = -1;
            double a = sqrt(bvh_nearest(&tree, &disc, p, &guess, q));
            double b = sqrt(brute_nearest(&disc, p));
            st->brute_max_diff = fmax(st->brute_max_diff, fabs(a - b));
            st->brute_checked++;
        }
    }
    st->seconds_setup = t1 - t0;
    st->seconds_query = sm_clock_seconds() - t1;
    bvh_free(&tree);
    discretization_free(&disc);
    return 0;
}

static void print_stats(const shape *s, long resolution, int use_newton,
                        const sdf_stats *st)
{
    printf("sdf: %s, resolution %ld: %d %s, chordal error %.3e, BVH %d "
           "nodes depth %d (%.2fs), distances %.2fs\n",
           s->name, resolution, st->nprims,
           s->dim == 2 ? "segments" : "triangles", st->chordal_error,
           st->bvh_nodes, st->bvh_depth, st->seconds_setup,
           st->seconds_query);
    if (use_newton)
        printf("sdf:   Newton refinement: %d vertices refined, %d kept the "
               "discrete distance; |d_newton - d_discrete| max %.3e rms "
               "%.3e\n",
               st->refined, st->fallbacks, st->max_gap, st->rms_gap);
}

/* ----------------------------------------------------------------- main */

static void usage(FILE *out)
{
    fprintf(out,
            "usage: sdf --shape star2d|disk2d|blob3d|ball3d --mesh BACKGROUND\n"
            "           --out SOL [--resolution N] [--no-newton]\n"
            "           [--verify-brute K] [--verify-resolution N]\n"
            "           [--verify-exact TOL]\n"
            "  --resolution N   2D: points of the polyline (default 65536);\n"
            "                   3D: subdivisions of each icosahedron edge\n"
            "                   (20 N^2 triangles, default 256)\n"
            "  --verify-brute K compare the BVH search with a brute-force\n"
            "                   search at K vertices (exit 2 on mismatch)\n"
            "  --verify-resolution N  recompute everything from an\n"
            "                   independent discretisation of resolution N;\n"
            "                   exit 2 if the two differ by more than 1e-10\n"
            "  --verify-exact T disk2d/ball3d only: compare with the closed\n"
            "                   form, exit 2 if the max error exceeds T\n");
}

static int parse_long(const char *s, long lo, long hi, long *out)
{
    char *end;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (errno || end == s || *end || v < lo || v > hi)
        return -1;
    *out = v;
    return 0;
}

static int resolution_ok(const shape *s, long resolution)
{
    if (s->dim == 2)
        return resolution >= 16 && resolution <= 50000000;
    return resolution >= 1 && resolution <= 512;
}

int main(int argc, char **argv)
{
    const char *shape_name = NULL, *mesh_path = NULL, *out_path = NULL;
    long resolution = 0, verify_brute = 0, verify_resolution = 0;
    double verify_exact = -1.0;
    int use_newton = 1;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        const char *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (strcmp(a, "--help") == 0) {
            usage(stdout);
            return 0;
        } else if (strcmp(a, "--no-newton") == 0) {
            use_newton = 0;
            continue;
        }
        if (!v) {
            fprintf(stderr, "sdf: %s needs a value\n", a);
            return 1;
        }
        i++;
        int bad = 0;
        if (strcmp(a, "--shape") == 0) {
            shape_name = v;
        } else if (strcmp(a, "--mesh") == 0) {
            mesh_path = v;
        } else if (strcmp(a, "--out") == 0) {
            out_path = v;
        } else if (strcmp(a, "--resolution") == 0) {
            bad = parse_long(v, 1, 100000000, &resolution);
        } else if (strcmp(a, "--verify-brute") == 0) {
            bad = parse_long(v, 0, 1000000, &verify_brute);
        } else if (strcmp(a, "--verify-resolution") == 0) {
            bad = parse_long(v, 1, 100000000, &verify_resolution);
        } else if (strcmp(a, "--verify-exact") == 0) {
            char *end;
            verify_exact = strtod(v, &end);
            bad = *end || end == v || !(verify_exact >= 0.0);
        } else {
            fprintf(stderr, "sdf: unknown argument '%s'\n", a);
            usage(stderr);
            return 1;
        }
        if (bad) {
            fprintf(stderr, "sdf: bad value '%s' for %s\n", v, a);
            return 1;
        }
    }
    shape s;
    if (!shape_name || !mesh_path || !out_path) {
        usage(stderr);
        return 1;
    }
    if (shape_from_name(shape_name, &s) != 0) {
        fprintf(stderr, "sdf: unknown shape '%s'\n", shape_name);
        return 1;
    }
    if (resolution == 0)
        resolution = s.dim == 2 ? 65536 : 256;
    if (!resolution_ok(&s, resolution) ||
        (verify_resolution && !resolution_ok(&s, verify_resolution))) {
        fprintf(stderr, "sdf: resolution out of range for %s\n", s.name);
        return 1;
    }
    if (verify_exact >= 0.0 && isnan(shape_exact_distance(&s, s.center))) {
        fprintf(stderr, "sdf: --verify-exact needs disk2d or ball3d\n");
        return 1;
    }

    int status = 1;
    sm_error err;
    sm_error_clear(&err);
    sm_mesh *m = NULL;
    sm_sol *sol = NULL;
    double *check = NULL;
    double t0 = sm_clock_seconds();
    sdf_stats st;

    if (sm_mesh_read(mesh_path, &m, &err) != SM_OK) {
        fprintf(stderr, "sdf: %s\n", err.msg);
        goto done;
    }
    if (m->dim != s.dim) {
        fprintf(stderr, "sdf: %s is a %dD mesh, shape %s is %dD\n", mesh_path,
                m->dim, s.name, s.dim);
        goto done;
    }
    if (sm_sol_alloc(&sol, m->dim, m->nverts, 1, &err) != SM_OK) {
        fprintf(stderr, "sdf: %s\n", err.msg);
        goto done;
    }
    printf("sdf: %s: %d vertices (read in %.2fs)\n", mesh_path, m->nverts,
           sm_clock_seconds() - t0);
    if (compute_distances(&s, m, resolution, use_newton, verify_brute,
                          sol->values, &st) != 0) {
        fprintf(stderr, "sdf: out of memory for the boundary discretisation\n");
        goto done;
    }
    print_stats(&s, resolution, use_newton, &st);
    status = 0;
    if (verify_brute > 0) {
        printf("sdf: verify-brute: %d vertices, max |bvh - brute| = %.3e\n",
               st.brute_checked, st.brute_max_diff);
        if (st.brute_max_diff > 1e-14) {
            fprintf(stderr, "sdf: verify-brute FAILED\n");
            status = 2;
        }
    }
    if (verify_resolution > 0) {
        sdf_stats st2;
        check = malloc((size_t)m->nverts * sizeof *check);
        if (!check || compute_distances(&s, m, verify_resolution, use_newton,
                                        0, check, &st2) != 0) {
            fprintf(stderr, "sdf: out of memory for the verification\n");
            status = 1;
            goto done;
        }
        print_stats(&s, verify_resolution, use_newton, &st2);
        double worst = 0.0;
        int32_t worst_i = 0;
        for (int32_t i = 0; i < m->nverts; i++) {
            double e = fabs(sol->values[i] - check[i]);
            if (e > worst) {
                worst = e;
                worst_i = i;
            }
        }
        printf("sdf: verify-resolution: max |d(%ld) - d(%ld)| = %.3e "
               "(vertex %d)\n",
               resolution, verify_resolution, worst, worst_i + 1);
        if (!(worst <= 1e-10)) {
            fprintf(stderr, "sdf: verify-resolution FAILED\n");
            status = 2;
        }
    }
    if (verify_exact >= 0.0) {
        double worst = 0.0;
        int32_t worst_i = 0;
        for (int32_t i = 0; i < m->nverts; i++) {
            double p[3];
            vertex_point(m, i, p);
            double e = fabs(sol->values[i] - shape_exact_distance(&s, p));
            if (e > worst) {
                worst = e;
                worst_i = i;
            }
        }
        printf("sdf: verify-exact: max |d - d_exact| = %.3e (vertex %d)\n",
               worst, worst_i + 1);
        if (!(worst <= verify_exact)) {
            fprintf(stderr, "sdf: verify-exact FAILED (tolerance %.1e)\n",
                    verify_exact);
            status = 2;
        }
    }
    if (sm_sol_write(out_path, sol, &err) != SM_OK) {
        fprintf(stderr, "sdf: %s\n", err.msg);
        status = 1;
        goto done;
    }
    printf("sdf: wrote %s (%.2fs in all)\n", out_path, sm_clock_seconds() - t0);

done:
    free(check);
    sm_sol_free(sol);
    sm_mesh_free(m);
    return status;
}
