/* Analytic star-shaped shapes of the bundled examples.
 *
 * Every shape is star-shaped with respect to its center c: its boundary is
 * { c + R(u) u : |u| = 1 } for a smooth positive radius function R, and its
 * interior is { x : |x - c| < R((x - c)/|x - c|) }.  That gives an exact
 * inside/outside test (the sign of the distance) and a parametrisation of
 * the boundary for the fine polyline/triangulation and the Newton
 * refinement of the closest point.
 *
 * The same formulas appear in the .geo files (MathEval size fields) of
 * examples/2d and examples/3d; keep them in sync. */
#ifndef EXAMPLES_SHAPES_H
#define EXAMPLES_SHAPES_H

#include <math.h>
#include <string.h>

typedef enum shape_kind {
    SHAPE_STAR2D = 0, /* 2D target: five-lobed star */
    SHAPE_DISK2D = 1, /* 2D template: disk (closed-form distance) */
    SHAPE_BLOB3D = 2, /* 3D target: bumpy ellipsoid */
    SHAPE_BALL3D = 3  /* 3D template: ball (closed-form distance) */
} shape_kind;

typedef struct shape {
    shape_kind kind;
    const char *name;
    int dim;
    double center[3];
} shape;

/* 2D target: R(theta) = 0.25 (1 + 0.2 cos 5 theta). */
#define STAR2D_MEAN_RADIUS 0.25
#define STAR2D_AMPLITUDE 0.2
/* 2D template: disk of radius 0.25. */
#define DISK2D_RADIUS 0.25
/* 3D target: ellipsoid of semi-axes (0.34, 0.26, 0.22) modulated by
 * 1 + 0.12 (ux^3 - 3 ux uy^2) + 0.08 P3(uz), P3(t) = (5t^3 - 3t)/2:
 * three lobes around the z axis, a bulge at the top and a dent below. */
#define BLOB3D_AXIS_X 0.34
#define BLOB3D_AXIS_Y 0.26
#define BLOB3D_AXIS_Z 0.22
#define BLOB3D_LOBES 0.12
#define BLOB3D_P3 0.08
/* 3D template: ball of radius 0.3. */
#define BALL3D_RADIUS 0.3

/* Fills s from a name; returns 0 on success, -1 for an unknown name. */
static inline int shape_from_name(const char *name, shape *s)
{
    static const struct { const char *name; shape_kind kind; int dim; } table[] = {
        {"star2d", SHAPE_STAR2D, 2},
        {"disk2d", SHAPE_DISK2D, 2},
        {"blob3d", SHAPE_BLOB3D, 3},
        {"ball3d", SHAPE_BALL3D, 3},
    };
    for (size_t i = 0; i < sizeof table / sizeof table[0]; i++) {
        if (strcmp(name, table[i].name) == 0) {
            s->kind = table[i].kind;
            s->name = table[i].name;
            s->dim = table[i].dim;
            s->center[0] = 0.5;
            s->center[1] = 0.5;
            s->center[2] = table[i].dim == 3 ? 0.5 : 0.0;
            return 0;
        }
    }
    return -1;
}

/* R(u) for a unit direction u (3 entries, u[2] = 0 in 2D). */
static inline double shape_radius(const shape *s, const double *u)
{
    switch (s->kind) {
    case SHAPE_STAR2D: {
        /* cos 5θ as a polynomial in (cos θ, sin θ), as in the .geo file */
        double x = u[0], y = u[1];
        double cos5 = x * x * x * x * x - 10.0 * x * x * x * y * y +
                      5.0 * x * y * y * y * y;
        return STAR2D_MEAN_RADIUS * (1.0 + STAR2D_AMPLITUDE * cos5);
    }
    case SHAPE_DISK2D:
        return DISK2D_RADIUS;
    case SHAPE_BLOB3D: {
        double x = u[0], y = u[1], z = u[2];
        double ex = x / BLOB3D_AXIS_X, ey = y / BLOB3D_AXIS_Y,
               ez = z / BLOB3D_AXIS_Z;
        double ellipsoid = 1.0 / sqrt(ex * ex + ey * ey + ez * ez);
        double lobes = x * x * x - 3.0 * x * y * y;
        double p3 = 0.5 * (5.0 * z * z * z - 3.0 * z);
        return ellipsoid * (1.0 + BLOB3D_LOBES * lobes + BLOB3D_P3 * p3);
    }
    case SHAPE_BALL3D:
        return BALL3D_RADIUS;
    }
    return 0.0;
}

/* Boundary point for direction u: c + R(u) u (3 entries). */
static inline void shape_boundary_point(const shape *s, const double *u,
                                        double *p)
{
    double r = shape_radius(s, u);
    for (int k = 0; k < 3; k++)
        p[k] = s->center[k] + r * u[k];
}

/* Signed radial offset |x - c| - R(u): negative exactly inside the shape.
 * Only its sign is used as the sign of the distance (its magnitude is
 * not the Euclidean distance). */
static inline double shape_radial_offset(const shape *s, const double *x)
{
    double v[3] = {0, 0, 0}, r2 = 0.0;
    for (int k = 0; k < s->dim; k++) {
        v[k] = x[k] - s->center[k];
        r2 += v[k] * v[k];
    }
    if (r2 == 0.0)
        return -shape_radius(s, (const double[3]){1.0, 0.0, 0.0});
    double r = sqrt(r2);
    for (int k = 0; k < 3; k++)
        v[k] /= r;
    return r - shape_radius(s, v);
}

/* Closed-form signed distance, only for the disk and the ball (used to
 * verify the distance tool); NAN for the other shapes. */
static inline double shape_exact_distance(const shape *s, const double *x)
{
    if (s->kind != SHAPE_DISK2D && s->kind != SHAPE_BALL3D)
        return NAN;
    double r2 = 0.0;
    for (int k = 0; k < s->dim; k++)
        r2 += (x[k] - s->center[k]) * (x[k] - s->center[k]);
    return sqrt(r2) - shape_radius(s, (const double[3]){1.0, 0.0, 0.0});
}

#endif
