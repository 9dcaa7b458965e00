/* Generalized winding number over the facet hierarchy (sm_sdf.h): exact
 * solid angles (3D, the formula of Van Oosterom and Strackee) or angles
 * (2D) for the facets of near boxes, the dipole term of a box far from p.
 * The far-field error of a box is of order (r / d)^2 times its share of
 * the total, so with d > SM_SDF_FAR_RATIO * r the sum stays well within
 * the 1/2 margin that decides the sign away from the surface, and every
 * box near p is summed exactly. */
#include <math.h>

#include "sm_bvh.h"

/* Solid angle of triangle abc seen from p, signed: positive when abc is
 * counter-clockwise seen from outside and p is behind it. */
static double solid_angle(const double *p, const double *a, const double *b, const double *c)
{
    double x[3], y[3], z[3];
    for (int k = 0; k < 3; k++) {
        x[k] = a[k] - p[k];
        y[k] = b[k] - p[k];
        z[k] = c[k] - p[k];
    }
    double lx = sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
    double ly = sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2]);
    double lz = sqrt(z[0] * z[0] + z[1] * z[1] + z[2] * z[2]);
    double det = x[0] * (y[1] * z[2] - y[2] * z[1]) - x[1] * (y[0] * z[2] - y[2] * z[0]) +
                 x[2] * (y[0] * z[1] - y[1] * z[0]);
    double xy = x[0] * y[0] + x[1] * y[1] + x[2] * y[2];
    double xz = x[0] * z[0] + x[1] * z[1] + x[2] * z[2];
    double yz = y[0] * z[0] + y[1] * z[1] + y[2] * z[2];
    double den = lx * ly * lz + xy * lz + xz * ly + yz * lx;
    return 2 * atan2(det, den);
}

static double plane_angle(const double *p, const double *a, const double *b)
{
    double x0 = a[0] - p[0], y0 = a[1] - p[1], x1 = b[0] - p[0], y1 = b[1] - p[1];
    return atan2(x0 * y1 - y0 * x1, x0 * x1 + y0 * y1);
}

static double facet_angle(const sm_surface *s, int32_t f, const double *p)
{
    const int32_t *v = s->facets + (size_t)f * s->dim;
    if (s->dim == 3)
        return solid_angle(p, s->coords + 3 * (size_t)v[0], s->coords + 3 * (size_t)v[1],
                           s->coords + 3 * (size_t)v[2]);
    return plane_angle(p, s->coords + 2 * (size_t)v[0], s->coords + 2 * (size_t)v[1]);
}

double sm__winding_at(const sm_bvh *t, const double *p, int32_t *stack)
{
    const sm_surface *s = t->s;
    int dim = s->dim;
    double sum = 0;
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
        const sm_bvh_node *nd = &t->nodes[stack[--top]];
        double d[3] = {nd->c[0] - p[0], nd->c[1] - p[1], dim == 3 ? nd->c[2] - p[2] : 0};
        double r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        if (r2 > SM_SDF_FAR_RATIO * SM_SDF_FAR_RATIO * nd->r * nd->r) {
            double nd_dot = nd->n[0] * d[0] + nd->n[1] * d[1] + nd->n[2] * d[2];
            sum += dim == 3 ? nd_dot / (r2 * sqrt(r2)) : nd_dot / r2;
        } else if (nd->left < 0) {
            for (int32_t i = nd->first; i < nd->first + nd->count; i++)
                sum += facet_angle(s, t->order[i], p);
        } else {
            stack[top++] = nd->left;
            stack[top++] = nd->right;
        }
    }
    return sum / (dim == 3 ? 4 * M_PI : 2 * M_PI);
}
