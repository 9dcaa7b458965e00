/* check: sanity checks of a bundled example — a template mesh, a
 * background mesh and the target's signed distance on it.
 *
 * Prints the sizes, the element qualities and a list of checks, each
 * "[ok]" or "[FAILED]", and exits with status 2 if any check failed (1 for
 * bad usage or unreadable input).  The output has no timings, so it is
 * reproducible and generate.sh keeps it next to the example (check.txt).
 *
 * What is checked, and why it can fail:
 *   template    references as documented (outer boundary facets 1, clamp
 *               facets 10 strictly inside, clamp elements 2 exactly those
 *               inside the clamp ball), boundary vertices on the analytic
 *               template boundary, no inverted element, minimum quality,
 *               clamp ball inside the template;
 *   distance    one value per background vertex, the sign agrees with the
 *               analytic inside test at every vertex, the values are
 *               1-Lipschitz along every background edge (an exact
 *               distance is; an implicit function usually is not),
 *               |grad d| = 1 on the elements near the target (P1
 *               gradients), d ~ 0 on the analytic target boundary and of
 *               the right sign just inside/outside, positive at the box
 *               corners, clamp ball inside the target (d(c) < -r). */
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "shapematch/sm_error.h"
#include "shapematch/sm_field.h"
#include "shapematch/sm_io.h"
#include "shapematch/sm_mesh.h"

#include "geometry.h"
#include "shapes.h"

#define MAX_REFS 32

typedef struct report {
    int checks, failures;
} report;

static void expect(report *r, int ok, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

static void expect(report *r, int ok, const char *fmt, ...)
{
    va_list ap;
    printf("  [%s] ", ok ? "ok" : "FAILED");
    va_start(ap, fmt);
    vprintf(fmt, ap);
    va_end(ap);
    printf("\n");
    r->checks++;
    if (!ok)
        r->failures++;
}

/* Counts per reference (the first MAX_REFS distinct ones). */
typedef struct ref_histogram {
    int n;
    int32_t ref[MAX_REFS];
    int32_t count[MAX_REFS];
} ref_histogram;

static void histogram(const int32_t *refs, int32_t n, ref_histogram *h)
{
    h->n = 0;
    for (int32_t i = 0; i < n; i++) {
        int k = 0;
        while (k < h->n && h->ref[k] != refs[i])
            k++;
        if (k == h->n) {
            if (h->n == MAX_REFS)
                continue;
            h->ref[h->n] = refs[i];
            h->count[h->n++] = 0;
        }
        h->count[k]++;
    }
    /* sorted by reference, for a stable output */
    for (int i = 1; i < h->n; i++)
        for (int j = i; j > 0 && h->ref[j - 1] > h->ref[j]; j--) {
            int32_t t = h->ref[j];
            h->ref[j] = h->ref[j - 1];
            h->ref[j - 1] = t;
            t = h->count[j];
            h->count[j] = h->count[j - 1];
            h->count[j - 1] = t;
        }
}

static int32_t histogram_count(const ref_histogram *h, int32_t ref)
{
    for (int i = 0; i < h->n; i++)
        if (h->ref[i] == ref)
            return h->count[i];
    return 0;
}

static void print_histogram(const char *what, const ref_histogram *h)
{
    printf("  %-22s", what);
    if (h->n == 0)
        printf(" none");
    for (int i = 0; i < h->n; i++)
        printf(" %d (ref %d)%s", h->count[i], h->ref[i],
               i + 1 < h->n ? "," : "");
    printf("\n");
}

static void point_of(const sm_mesh *m, int32_t v, double *p)
{
    p[0] = p[1] = p[2] = 0.0;
    for (int k = 0; k < m->dim; k++)
        p[k] = m->coords[(size_t)v * (size_t)m->dim + (size_t)k];
}

static void centroid_of(const sm_mesh *m, int32_t e, double *c)
{
    int nv = m->dim + 1;
    c[0] = c[1] = c[2] = 0.0;
    for (int l = 0; l < nv; l++) {
        double p[3];
        point_of(m, m->elems[(size_t)e * (size_t)nv + (size_t)l], p);
        for (int k = 0; k < 3; k++)
            c[k] += p[k] / nv;
    }
}

/* Distance from p to facet f (dim vertices) of the list facets. */
static double facet_distance(const sm_mesh *m, const int32_t *facet,
                             const double *p)
{
    double a[3], b[3], c[3], q[3];
    point_of(m, facet[0], a);
    point_of(m, facet[1], b);
    if (m->dim == 2) {
        closest_on_segment(p, a, b, q);
    } else {
        point_of(m, facet[2], c);
        closest_on_triangle(p, a, b, c, q);
    }
    return sqrt(dist2_3(p, q));
}

static double distance_to(const double *p, const double *center, int dim)
{
    double s = 0.0;
    for (int k = 0; k < dim; k++)
        s += (p[k] - center[k]) * (p[k] - center[k]);
    return sqrt(s);
}

typedef struct clamp {
    double center[3];
    double radius;
} clamp;

/* ------------------------------------------------------------ template */

static void check_template(report *r, const sm_mesh *t, const shape *ts,
                           const clamp *cl)
{
    ref_histogram he, hf, hb;
    histogram(t->elem_refs, t->nelems, &he);
    histogram(t->facet_refs, t->nfacets, &hf);
    histogram(t->bfacet_refs, t->nbfacets, &hb);
    const char *elem_name = t->dim == 2 ? "triangles" : "tetrahedra";
    const char *facet_name = t->dim == 2 ? "edges" : "triangles";
    printf("  vertices               %d\n", t->nverts);
    printf("  %-22s %d\n", elem_name, t->nelems);
    char what[64];
    snprintf(what, sizeof what, "%s by reference", elem_name);
    print_histogram(what, &he);
    snprintf(what, sizeof what, "file %s", facet_name);
    print_histogram(what, &hf);
    snprintf(what, sizeof what, "boundary %s", facet_name);
    print_histogram(what, &hb);
    if (t->dim == 2)
        /* conforming: interior edges are shared by two triangles */
        printf("  mesh edges (all)       %lld\n",
               ((long long)3 * t->nelems + t->nbfacets) / 2);
    sm_quality_stats q;
    sm_mesh_quality(t, t->coords, &q);
    printf("  element quality        min %.3f, mean %.3f\n", q.min, q.mean);

    expect(r, q.ninverted == 0 && q.min >= 0.3,
           "no inverted element, min quality %.3f >= 0.3", q.min);
    expect(r, t->nbfacets > 0 && histogram_count(&hb, 1) == t->nbfacets,
           "every boundary facet has reference 1 (%d of %d)",
           histogram_count(&hb, 1), t->nbfacets);

    /* clamp facets: present, none on the boundary, all on the clamp sphere */
    int32_t nclamp_facets = 0;
    double clamp_facet_dev = 0.0;
    for (int32_t f = 0; f < t->nfacets; f++) {
        if (t->facet_refs[f] != 10)
            continue;
        nclamp_facets++;
        for (int l = 0; l < t->dim; l++) {
            double p[3];
            point_of(t, t->facets[(size_t)f * (size_t)t->dim + (size_t)l], p);
            clamp_facet_dev = fmax(clamp_facet_dev,
                                   fabs(distance_to(p, cl->center, t->dim) -
                                        cl->radius));
        }
    }
    expect(r, nclamp_facets > 0 && histogram_count(&hb, 10) == 0,
           "%d clamp %s (reference 10) kept inside the mesh, none on the "
           "boundary",
           nclamp_facets, facet_name);
    expect(r, clamp_facet_dev < 1e-9,
           "clamp %s lie on the clamp sphere (max deviation %.1e)",
           facet_name, clamp_facet_dev);

    /* clamp elements: reference 2 exactly for the elements inside */
    int32_t mismatched = 0, inside = 0;
    for (int32_t e = 0; e < t->nelems; e++) {
        double c[3];
        centroid_of(t, e, c);
        int in = distance_to(c, cl->center, t->dim) < cl->radius;
        inside += in;
        if (in != (t->elem_refs[e] == 2))
            mismatched++;
    }
    expect(r, mismatched == 0 && inside > 0,
           "reference 2 marks exactly the %d elements inside the clamp ball "
           "(%d mismatches)",
           inside, mismatched);

    /* boundary vertices on the analytic template boundary */
    double on_dev = 0.0;
    for (int32_t v = 0; v < t->nverts; v++) {
        if (!t->on_boundary[v])
            continue;
        double p[3];
        point_of(t, v, p);
        on_dev = fmax(on_dev, fabs(shape_radial_offset(ts, p)));
    }
    expect(r, on_dev < 1e-9,
           "boundary vertices lie on the %s boundary (max |r - R| %.1e)",
           ts->name, on_dev);

    double margin = INFINITY;
    for (int32_t f = 0; f < t->nbfacets; f++)
        margin = fmin(margin,
                      facet_distance(t, t->bfacets + (size_t)f * (size_t)t->dim,
                                     cl->center) -
                          cl->radius);
    expect(r, margin > 0.0,
           "clamp ball inside the template (gap to the boundary %.4f)",
           margin);
}

/* ---------------------------------------------------- background field */

/* P1 gradient of the values on element e; returns its norm. */
static double p1_gradient_norm(const sm_mesh *m, const double *values,
                               int32_t e)
{
    int dim = m->dim, nv = dim + 1;
    const int32_t *ev = m->elems + (size_t)e * (size_t)nv;
    double x0[3], A[3][3], rhs[3];
    point_of(m, ev[0], x0);
    for (int l = 1; l < nv; l++) {
        double x[3];
        point_of(m, ev[l], x);
        for (int k = 0; k < dim; k++)
            A[l - 1][k] = x[k] - x0[k];
        rhs[l - 1] = values[ev[l]] - values[ev[0]];
    }
    double g[3] = {0, 0, 0};
    if (dim == 2) {
        double det = A[0][0] * A[1][1] - A[0][1] * A[1][0];
        g[0] = (rhs[0] * A[1][1] - rhs[1] * A[0][1]) / det;
        g[1] = (A[0][0] * rhs[1] - A[1][0] * rhs[0]) / det;
    } else {
        /* Cramer's rule on A g = rhs */
        double det = A[0][0] * (A[1][1] * A[2][2] - A[1][2] * A[2][1]) -
                     A[0][1] * (A[1][0] * A[2][2] - A[1][2] * A[2][0]) +
                     A[0][2] * (A[1][0] * A[2][1] - A[1][1] * A[2][0]);
        for (int c = 0; c < 3; c++) {
            double B[3][3];
            memcpy(B, A, sizeof B);
            for (int l = 0; l < 3; l++)
                B[l][c] = rhs[l];
            g[c] = (B[0][0] * (B[1][1] * B[2][2] - B[1][2] * B[2][1]) -
                    B[0][1] * (B[1][0] * B[2][2] - B[1][2] * B[2][0]) +
                    B[0][2] * (B[1][0] * B[2][1] - B[1][1] * B[2][0])) /
                   det;
        }
    }
    return sqrt(dot3(g, g));
}

static int compare_doubles(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Unit direction number i of n, spread over the circle or the sphere
 * (a Fibonacci spiral). */
static void direction(int dim, int i, int n, double *u)
{
    if (dim == 2) {
        double theta = 2.0 * M_PI * (i + 0.5) / n;
        u[0] = cos(theta);
        u[1] = sin(theta);
        u[2] = 0.0;
        return;
    }
    double z = 1.0 - 2.0 * (i + 0.5) / n;
    double rho = sqrt(1.0 - z * z);
    double phi = M_PI * (3.0 - sqrt(5.0)) * i;
    u[0] = rho * cos(phi);
    u[1] = rho * sin(phi);
    u[2] = z;
}

static void check_distance(report *r, const sm_mesh *b, const sm_sol *sol,
                           const sm_field *field, const shape *target,
                           const clamp *cl, double band)
{
    int dim = b->dim, nv = dim + 1;
    const double *d = sol->values;
    sm_quality_stats q;
    sm_mesh_quality(b, b->coords, &q);
    double lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
    sm_mesh_bbox(b, b->coords, lo, hi);
    double dmin = INFINITY, dmax = -INFINITY;
    for (int32_t v = 0; v < b->nverts; v++) {
        dmin = fmin(dmin, d[v]);
        dmax = fmax(dmax, d[v]);
    }
    printf("  vertices               %d\n", b->nverts);
    printf("  %-22s %d\n", dim == 2 ? "triangles" : "tetrahedra", b->nelems);
    printf("  element quality        min %.3f, mean %.3f\n", q.min, q.mean);
    printf("  distance range         [%.4f, %.4f]\n", dmin, dmax);

    double box_dev = 0.0;
    for (int k = 0; k < dim; k++)
        box_dev = fmax(box_dev, fmax(fabs(lo[k]), fabs(hi[k] - 1.0)));
    expect(r, box_dev < 1e-12 && q.ninverted == 0,
           "background covers [0,1]^%d (bounding box deviation %.1e), no "
           "inverted element",
           dim, box_dev);
    expect(r, sol->nverts == b->nverts && sol->ncomp == 1,
           "one scalar value per background vertex (%d values, %d "
           "component)",
           sol->nverts, sol->ncomp);

    /* sign against the analytic inside test */
    int32_t sign_errors = 0, ninside = 0;
    for (int32_t v = 0; v < b->nverts; v++) {
        double p[3];
        point_of(b, v, p);
        int in = shape_radial_offset(target, p) < 0.0;
        ninside += in;
        if (fabs(d[v]) > 1e-12 && in != (d[v] < 0.0))
            sign_errors++;
    }
    expect(r, sign_errors == 0,
           "sign agrees with the inside test of %s at every vertex (%d "
           "inside, %d disagreements)",
           target->name, ninside, sign_errors);

    /* 1-Lipschitz along every element edge; |grad d| = 1 near the target */
    int32_t lipschitz_violations = 0, nband = 0, nband_1pct = 0;
    double worst_ratio = 0.0, gsum = 0.0;
    double *gnorms = malloc((size_t)(b->nelems > 0 ? b->nelems : 1) *
                            sizeof *gnorms);
    if (!gnorms) {
        expect(r, 0, "out of memory for the gradient statistics");
        return;
    }
    double hsum = 0.0;
    int32_t hcount = 0;
    for (int32_t e = 0; e < b->nelems; e++) {
        const int32_t *ev = b->elems + (size_t)e * (size_t)nv;
        int in_band = 1;
        for (int i = 0; i < nv; i++) {
            if (fabs(d[ev[i]]) >= band)
                in_band = 0;
            for (int j = i + 1; j < nv; j++) {
                double pi[3], pj[3];
                point_of(b, ev[i], pi);
                point_of(b, ev[j], pj);
                double len = sqrt(dist2_3(pi, pj));
                double diff = fabs(d[ev[i]] - d[ev[j]]);
                worst_ratio = fmax(worst_ratio, diff / len);
                if (diff > len * (1.0 + 1e-9) + 1e-15)
                    lipschitz_violations++;
                if (in_band && j == i + 1) {
                    hsum += len;
                    hcount++;
                }
            }
        }
        if (!in_band)
            continue;
        double g = p1_gradient_norm(b, d, e);
        gnorms[nband++] = g;
        gsum += g;
        if (fabs(g - 1.0) <= 0.01)
            nband_1pct++;
    }
    expect(r, lipschitz_violations == 0,
           "1-Lipschitz on every element edge (max |d_i - d_j| / |x_i - "
           "x_j| = %.6f)",
           worst_ratio);
    printf("  elements with |d| < %g at all vertices: %d, edge length "
           "there %.4f (mean)\n",
           band, nband, hcount ? hsum / hcount : 0.0);
    /* The P1 gradient of the exact distance differs from a unit vector by
     * O(h kappa) on an element of size h where the boundary curvature is
     * kappa (the normals fan out across the element), so only the bulk
     * of the distribution is held to a tight bound.  A distance that is
     * not Euclidean (a radial offset r - R(u), a level-set function)
     * shifts the mean and the percentiles by several percent. */
    qsort(gnorms, (size_t)nband, sizeof *gnorms, compare_doubles);
    double gmean = nband ? gsum / nband : 0.0;
    double p01 = nband ? gnorms[(size_t)(0.01 * (nband - 1))] : 0.0;
    double p50 = nband ? gnorms[(size_t)(0.50 * (nband - 1))] : 0.0;
    double p99 = nband ? gnorms[(size_t)(0.99 * (nband - 1))] : 0.0;
    printf("  |grad d| there         min %.4f, 1%% %.4f, median %.5f, "
           "99%% %.4f, max %.4f, mean %.5f; %.2f%% within 1%% of 1\n",
           nband ? gnorms[0] : 0.0, p01, p50, p99,
           nband ? gnorms[nband - 1] : 0.0, gmean,
           nband ? 100.0 * nband_1pct / nband : 0.0);
    expect(r, nband > 0 && fabs(gmean - 1.0) < 1e-3 &&
                  fabs(p50 - 1.0) < 1e-3 && p01 > 0.95 && p99 < 1.05,
           "|grad d| = 1 near the target: mean and median within 1e-3, "
           "1%% and 99%% percentiles within 5%%");
    expect(r, nband > 0 && gnorms[0] > 0.8 && gnorms[nband - 1] < 1.2,
           "|grad d| within 20%% of 1 on every element near the target");
    free(gnorms);

    /* interpolated values at known points */
    int32_t hint = -1;
    double corner_min = INFINITY;
    for (int c = 0; c < (1 << dim); c++) {
        double p[3] = {0, 0, 0};
        for (int k = 0; k < dim; k++)
            p[k] = (c >> k) & 1 ? 1.0 : 0.0;
        corner_min = fmin(corner_min, sm_field_eval(field, p, &hint));
    }
    expect(r, corner_min > 0.0, "d > 0 at the box corners (min %.4f)",
           corner_min);

    const int ndirs = dim == 2 ? 64 : 200;
    const double offset = 0.01;
    double on_max = 0.0, in_max = -INFINITY, out_min = INFINITY;
    for (int i = 0; i < ndirs; i++) {
        double u[3], p[3], pin[3], pout[3];
        direction(dim, i, ndirs, u);
        shape_boundary_point(target, u, p);
        for (int k = 0; k < 3; k++) {
            pin[k] = p[k] - offset * u[k];
            pout[k] = p[k] + offset * u[k];
        }
        on_max = fmax(on_max, fabs(sm_field_eval(field, p, &hint)));
        in_max = fmax(in_max, sm_field_eval(field, pin, &hint));
        out_min = fmin(out_min, sm_field_eval(field, pout, &hint));
    }
    expect(r, on_max < 5e-4,
           "|d| < 5e-4 on the target boundary (%d points; max %.2e, P1 "
           "interpolation error)",
           ndirs, on_max);
    expect(r, in_max < 0.0 && out_min > 0.0,
           "d < 0 at %g inside, d > 0 at %g outside along the radius (max "
           "inside %.4f, min outside %.4f)",
           offset, offset, in_max, out_min);

    double dc = sm_field_eval(field, cl->center, &hint);
    expect(r, dc < -cl->radius,
           "clamp ball inside the target: d(center) = %.4f < -%.3f "
           "(gap %.4f)",
           dc, cl->radius, -dc - cl->radius);
}

/* ----------------------------------------------------------------- main */

static void usage(FILE *out)
{
    fprintf(out,
            "usage: check --template MESH --template-shape disk2d|ball3d\n"
            "             --background MESH --sol SOL --target-shape "
            "star2d|blob3d\n"
            "             --clamp X,Y[,Z],R [--band B]\n"
            "  --band B  |grad d| is checked on the background elements\n"
            "            where |d| < B at every vertex (default 0.02)\n");
}

static int parse_clamp(const char *s, int dim, clamp *cl)
{
    double v[4];
    int n = 0;
    const char *p = s;
    while (n < 4) {
        char *end;
        errno = 0;
        v[n] = strtod(p, &end);
        if (end == p || errno || !isfinite(v[n]))
            return -1;
        n++;
        if (*end == '\0')
            break;
        if (*end != ',')
            return -1;
        p = end + 1;
    }
    if (n != dim + 1 || !(v[dim] > 0.0))
        return -1;
    memset(cl, 0, sizeof *cl);
    for (int k = 0; k < dim; k++)
        cl->center[k] = v[k];
    cl->radius = v[dim];
    return 0;
}

int main(int argc, char **argv)
{
    const char *template_path = NULL, *background_path = NULL,
               *sol_path = NULL, *template_shape = NULL,
               *target_shape = NULL, *clamp_arg = NULL;
    double band = 0.02;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (strcmp(a, "--help") == 0) {
            usage(stdout);
            return 0;
        }
        if (i + 1 >= argc) {
            fprintf(stderr, "check: %s needs a value\n", a);
            return 1;
        }
        const char *v = argv[++i];
        if (strcmp(a, "--template") == 0)
            template_path = v;
        else if (strcmp(a, "--template-shape") == 0)
            template_shape = v;
        else if (strcmp(a, "--background") == 0)
            background_path = v;
        else if (strcmp(a, "--sol") == 0)
            sol_path = v;
        else if (strcmp(a, "--target-shape") == 0)
            target_shape = v;
        else if (strcmp(a, "--clamp") == 0)
            clamp_arg = v;
        else if (strcmp(a, "--band") == 0) {
            char *end;
            band = strtod(v, &end);
            if (*end || end == v || !(band > 0.0)) {
                fprintf(stderr, "check: bad --band '%s'\n", v);
                return 1;
            }
        } else {
            fprintf(stderr, "check: unknown argument '%s'\n", a);
            usage(stderr);
            return 1;
        }
    }
    shape ts, target;
    clamp cl;
    if (!template_path || !background_path || !sol_path || !template_shape ||
        !target_shape || !clamp_arg) {
        usage(stderr);
        return 1;
    }
    if (shape_from_name(template_shape, &ts) != 0 ||
        shape_from_name(target_shape, &target) != 0 || ts.dim != target.dim) {
        fprintf(stderr, "check: bad shapes '%s', '%s'\n", template_shape,
                target_shape);
        return 1;
    }
    if (parse_clamp(clamp_arg, ts.dim, &cl) != 0) {
        fprintf(stderr, "check: bad --clamp '%s' (expected %s)\n", clamp_arg,
                ts.dim == 2 ? "X,Y,R" : "X,Y,Z,R");
        return 1;
    }

    int status = 1;
    sm_error err;
    sm_error_clear(&err);
    sm_mesh *t = NULL, *b = NULL;
    sm_sol *sol = NULL;
    sm_field *field = NULL;
    report r = {0, 0};

    if (sm_mesh_read(template_path, &t, &err) != SM_OK ||
        sm_mesh_build_boundary(t, &err) != SM_OK ||
        sm_mesh_read(background_path, &b, &err) != SM_OK ||
        sm_mesh_build_boundary(b, &err) != SM_OK ||
        sm_sol_read(sol_path, &sol, &err) != SM_OK) {
        fprintf(stderr, "check: %s\n", err.msg);
        goto done;
    }
    if (t->dim != ts.dim || b->dim != ts.dim || sol->nverts != b->nverts ||
        sol->ncomp != 1) {
        fprintf(stderr,
                "check: dimensions or sizes disagree (template %dD, "
                "background %dD with %d vertices, sol %d values x %d)\n",
                t->dim, b->dim, b->nverts, sol->nverts, sol->ncomp);
        goto done;
    }
    if (sm_field_new(b, sol->values, &field, &err) != SM_OK) {
        fprintf(stderr, "check: %s\n", err.msg);
        goto done;
    }

    printf("template %s (%s, clamp ball radius %g)\n", template_path,
           ts.name, cl.radius);
    check_template(&r, t, &ts, &cl);
    printf("target %s: background %s, distance %s\n", target.name,
           background_path, sol_path);
    check_distance(&r, b, sol, field, &target, &cl, band);
    printf("%d checks, %d failed\n", r.checks, r.failures);
    status = r.failures ? 2 : 0;

done:
    sm_field_free(field);
    sm_sol_free(sol);
    sm_mesh_free(b);
    sm_mesh_free(t);
    return status;
}
