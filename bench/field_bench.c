/* field_bench: cost of building the target field and of evaluating it.
 *
 *   field_bench DIR [NPOINTS]
 *   field_bench BACKGROUND.mesh[.gz] BACKGROUND.sol[.gz] [NPOINTS]
 *
 * DIR holds background.mesh(.gz) and background.sol(.gz).  Prints the
 * build time of sm_field_new (best of 3) and the cost per sm_field_eval
 * for:
 *   (a) random points of the bounding box, no hint;
 *   (b) points along smooth paths (consecutive points 0.3 h apart, h the
 *       mean edge length), each path with its own hint; the paths are
 *       advanced one step each in turn, in random order, as the descent
 *       samples its template points (every call far from the previous
 *       one in memory); (b2) is the same with sm_field_eval_many, one
 *       call per step over all the paths; (b1) with one path at a time;
 *   (c) the same point repeated with its hint;
 *   (d) points just outside the mesh (0.05 to 0.5 h beyond a boundary
 *       facet), no hint, then (d1) with the hint of the previous call
 *       for the same point.
 * Each figure is the best of 3 passes; the checksum (sum of the values
 * of one pass) lets two builds be compared for identical results. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "bench_util.h"
#include "shapematch/sm_clock.h"
#include "shapematch/sm_field.h"
#include "shapematch/sm_io.h"
#include "shapematch/sm_mesh.h"

/* Declared again, weak: the benchmark also builds and runs against the
 * library from before sm_field_eval_many, for the figures "before". */
void sm_field_eval_many(const sm_field *f, int64_t n, const double *xs, int32_t *hints,
                        double *values) __attribute__((weak));

static double urand(uint64_t *s)
{
    *s ^= *s << 13;
    *s ^= *s >> 7;
    *s ^= *s << 17;
    return (double)(*s >> 11) * (1.0 / 9007199254740992.0);
}

/* Mean edge length over the elements (each edge counted once per element). */
static double mean_edge(const sm_mesh *m)
{
    const int d = m->dim;
    double sum = 0.0;
    int64_t n = 0;
    for (int32_t e = 0; e < m->nelems; e++) {
        const int32_t *ev = m->elems + (size_t)e * (size_t)(d + 1);
        for (int a = 0; a <= d; a++)
            for (int b = a + 1; b <= d; b++) {
                double l2 = 0.0;
                for (int i = 0; i < d; i++) {
                    double t = m->coords[(size_t)ev[a] * d + i] - m->coords[(size_t)ev[b] * d + i];
                    l2 += t * t;
                }
                sum += sqrt(l2);
                n++;
            }
    }
    return sum / (double)n;
}

typedef struct pass_result {
    double ns;       /* best ns per evaluation */
    double checksum; /* sum of the values of the last pass */
} pass_result;

/* n evaluations of pts (dim each) with hints[slot[j]] (slot NULL: no hint). */
static pass_result eval_pass(const sm_field *f, int dim, const double *pts, int64_t n,
                             const int32_t *slot, int32_t *hints, int reps)
{
    pass_result r = {INFINITY, 0.0};
    for (int rep = 0; rep < reps; rep++) {
        double sum = 0.0, t0 = sm_clock_seconds();
        for (int64_t j = 0; j < n; j++)
            sum += sm_field_eval(f, pts + (size_t)j * (size_t)dim, slot ? &hints[slot[j]] : NULL);
        double ns = 1e9 * (sm_clock_seconds() - t0) / (double)n;
        if (ns < r.ns)
            r.ns = ns;
        r.checksum = sum;
    }
    return r;
}

int main(int argc, char **argv)
{
    char mpath[4096], spath[4096];
    const char *mesh_path, *sol_path;
    int arg = 1;
    if (argc >= 2 && access(argv[1], R_OK) == 0 &&
        bench_first_existing(argv[1], "background.mesh", mpath, sizeof mpath) &&
        bench_first_existing(argv[1], "background.sol", spath, sizeof spath)) {
        mesh_path = mpath;
        sol_path = spath;
        arg = 2;
    } else if (argc >= 3) {
        mesh_path = argv[1];
        sol_path = argv[2];
        arg = 3;
    } else {
        fprintf(stderr, "usage: %s DIR|BACKGROUND.mesh BACKGROUND.sol [NPOINTS]\n", argv[0]);
        return 1;
    }
    int64_t npts = argc > arg ? atoll(argv[arg]) : 1000000;
    if (npts < 1000)
        npts = 1000;

    sm_error err;
    sm_mesh *bg = NULL;
    sm_sol *sol = NULL;
    if (sm_mesh_read(mesh_path, &bg, &err) != SM_OK || sm_sol_read(sol_path, &sol, &err) != SM_OK) {
        fprintf(stderr, "%s\n", err.msg);
        return 1;
    }
    if (sol->nverts != bg->nverts || sol->ncomp != 1) {
        fprintf(stderr, "%s: expected %d scalar values\n", sol_path, bg->nverts);
        return 1;
    }
    const int d = bg->dim;
    const double h = mean_edge(bg);
    double lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
    sm_mesh_bbox(bg, bg->coords, lo, hi);
    printf("background %s: %dD, %d vertices, %d elements, mean edge h = %.4g\n", mesh_path, d,
           bg->nverts, bg->nelems, h);

    /* build */
    sm_field *f = NULL;
    double tb[3];
    for (int rep = 0; rep < 3; rep++) {
        sm_field_free(f);
        f = NULL;
        double t0 = sm_clock_seconds();
        if (sm_field_new(bg, sol->values, &f, &err) != SM_OK) {
            fprintf(stderr, "%s\n", err.msg);
            return 1;
        }
        tb[rep] = sm_clock_seconds() - t0;
    }
    double tbest = fmin(tb[0], fmin(tb[1], tb[2]));
    sm_field_stats st;
    sm_field_get_stats(f, &st);
    printf("  build               %8.3f s   (runs %.3f %.3f %.3f), %.1f MiB, grid %dx%dx%d, "
           "%lld cell entries (lists built on first need)\n",
           tbest, tb[0], tb[1], tb[2], st.bytes / 1048576.0, st.grid[0], st.grid[1], st.grid[2],
           (long long)st.elem_entries);

    uint64_t s = 0x9e3779b97f4a7c15ULL;
    double *pts = malloc(sizeof(double) * (size_t)npts * (size_t)d);
    int32_t *slot = malloc(sizeof(int32_t) * (size_t)npts);
    int32_t *hints = malloc(sizeof(int32_t) * (size_t)npts);
    if (!pts || !slot || !hints) {
        fprintf(stderr, "out of memory\n");
        return 1;
    }

    /* (a) random points of the bounding box, no hint */
    int64_t inside = 0;
    for (int64_t j = 0; j < npts; j++) {
        double *x = pts + (size_t)j * d;
        for (int i = 0; i < d; i++)
            x[i] = lo[i] + (hi[i] - lo[i]) * urand(&s);
        inside += sm_field_locate(f, x, -1, NULL) >= 0;
    }
    pass_result ra = eval_pass(f, d, pts, npts, NULL, hints, 3);
    printf("  (a)  random, no hint      %8.1f ns/eval  (%lld points, %.1f%% inside)  checksum %.15g\n",
           ra.ns, (long long)npts, 100.0 * (double)inside / (double)npts, ra.checksum);

    /* (b) smooth paths with hints: npaths paths of nsteps points, a
     * direction turning slowly, reflected on the bounding box. */
    int32_t nsteps = 50, npaths = (int32_t)(npts / nsteps);
    int32_t *order = malloc(sizeof(int32_t) * (size_t)npaths);
    double *pos = malloc(sizeof(double) * 3 * (size_t)npaths);
    double *dir = malloc(sizeof(double) * 3 * (size_t)npaths);
    if (!order || !pos || !dir) {
        fprintf(stderr, "out of memory\n");
        return 1;
    }
    for (int32_t p = 0; p < npaths; p++) {
        order[p] = p;
        double n2 = 0.0;
        for (int i = 0; i < d; i++) {
            pos[3 * p + i] = lo[i] + (hi[i] - lo[i]) * (0.05 + 0.9 * urand(&s));
            dir[3 * p + i] = 2.0 * urand(&s) - 1.0;
            n2 += dir[3 * p + i] * dir[3 * p + i];
        }
        for (int i = 0; i < d; i++)
            dir[3 * p + i] /= sqrt(n2) + 1e-300;
    }
    for (int32_t p = npaths - 1; p > 0; p--) { /* random order of the paths */
        int32_t q = (int32_t)(urand(&s) * (p + 1)), t = order[p];
        order[p] = order[q];
        order[q] = t;
    }
    for (int32_t step = 0; step < nsteps; step++)
        for (int32_t k = 0; k < npaths; k++) {
            int32_t p = order[k];
            double *x = pos + 3 * p, *u = dir + 3 * p, n2 = 0.0;
            for (int i = 0; i < d; i++) {
                u[i] += 0.2 * (2.0 * urand(&s) - 1.0);
                n2 += u[i] * u[i];
            }
            for (int i = 0; i < d; i++) {
                u[i] /= sqrt(n2) + 1e-300;
                x[i] += 0.3 * h * u[i];
                if (x[i] < lo[i] || x[i] > hi[i]) {
                    u[i] = -u[i];
                    x[i] += 2 * 0.3 * h * u[i];
                }
            }
            int64_t j = (int64_t)step * npaths + k;
            memcpy(pts + (size_t)j * d, x, sizeof(double) * (size_t)d);
            slot[j] = p;
        }
    int64_t nb = (int64_t)nsteps * npaths;
    pass_result rb = {INFINITY, 0.0};
    for (int rep = 0; rep < 3; rep++) {
        for (int32_t p = 0; p < npaths; p++)
            hints[p] = -1;
        /* the first step of every path finds its hint without one */
        for (int32_t k = 0; k < npaths; k++)
            sm_field_eval(f, pts + (size_t)k * d, &hints[slot[k]]);
        pass_result r = eval_pass(f, d, pts + (size_t)npaths * d, nb - npaths, slot + npaths, hints, 1);
        if (r.ns < rb.ns)
            rb.ns = r.ns;
        rb.checksum = r.checksum;
    }
    printf("  (b)  paths, hint          %8.1f ns/eval  (%d paths x %d steps of 0.3 h, interleaved)"
           "  checksum %.15g\n",
           rb.ns, npaths, nsteps - 1, rb.checksum);
    /* (b2) the same with sm_field_eval_many: each step evaluates all the
     * paths in one call, as a descent can evaluate all its points */
    pass_result rb2 = {INFINITY, 0.0};
    if (!sm_field_eval_many) {
        printf("  (b2) paths, hint, batched      n/a     (no sm_field_eval_many in this library)\n");
    } else {
        int32_t *hk = malloc(sizeof(int32_t) * (size_t)npaths);
        double *vals = malloc(sizeof(double) * (size_t)npaths);
        if (!hk || !vals) {
            fprintf(stderr, "out of memory\n");
            return 1;
        }
        for (int rep = 0; rep < 3; rep++) {
            for (int32_t k = 0; k < npaths; k++)
                hk[k] = -1;
            sm_field_eval_many(f, npaths, pts, hk, vals);
            double sum = 0.0, t0 = sm_clock_seconds();
            for (int32_t step = 1; step < nsteps; step++) {
                sm_field_eval_many(f, npaths, pts + (size_t)step * (size_t)npaths * d, hk, vals);
                for (int32_t k = 0; k < npaths; k++)
                    sum += vals[k];
            }
            double ns = 1e9 * (sm_clock_seconds() - t0) / (double)(nb - npaths);
            if (ns < rb2.ns)
                rb2.ns = ns;
            rb2.checksum = sum;
        }
        printf("  (b2) paths, hint, batched %8.1f ns/eval  (sm_field_eval_many, one call per step)"
               "  checksum %.15g\n",
               rb2.ns, rb2.checksum);
        free(hk);
        free(vals);
    }
    /* (b1) the same points, one path after the other */
    {
        double *seq = malloc(sizeof(double) * (size_t)nb * (size_t)d);
        int32_t *sslot = malloc(sizeof(int32_t) * (size_t)nb);
        if (!seq || !sslot) {
            fprintf(stderr, "out of memory\n");
            return 1;
        }
        int64_t j = 0;
        for (int32_t k = 0; k < npaths; k++)
            for (int32_t step = 1; step < nsteps; step++, j++) {
                int64_t src = (int64_t)step * npaths + k;
                memcpy(seq + (size_t)j * d, pts + (size_t)src * d, sizeof(double) * (size_t)d);
                sslot[j] = slot[src];
            }
        pass_result r1 = {INFINITY, 0.0};
        for (int rep = 0; rep < 3; rep++) {
            for (int32_t k = 0; k < npaths; k++)
                sm_field_eval(f, pts + (size_t)k * d, &hints[slot[k]]);
            pass_result r = eval_pass(f, d, seq, j, sslot, hints, 1);
            if (r.ns < r1.ns)
                r1.ns = r.ns;
            r1.checksum = r.checksum;
        }
        printf("  (b1) paths, hint, 1 by 1  %8.1f ns/eval  checksum %.15g\n", r1.ns, r1.checksum);
        free(seq);
        free(sslot);
    }

    /* (c) the same point repeated with its hint */
    double rc_ns = INFINITY, rd_ns = INFINITY, rd1_ns = INFINITY;
    {
        const int npoint = 1000, repeat = 1000;
        double csum = 0.0, best = INFINITY;
        for (int rep = 0; rep < 3; rep++) {
            double t = 0.0;
            csum = 0.0;
            uint64_t s2 = 12345;
            for (int k = 0; k < npoint; k++) {
                double x[3] = {0, 0, 0};
                for (int i = 0; i < d; i++)
                    x[i] = lo[i] + (hi[i] - lo[i]) * urand(&s2);
                int32_t hint = -1;
                sm_field_eval(f, x, &hint);
                double t0 = sm_clock_seconds();
                for (int r = 0; r < repeat; r++) {
                    /* the compiler must not hoist the call */
                    __asm__ volatile("" : : "g"(x) : "memory");
                    csum += sm_field_eval(f, x, &hint);
                }
                t += sm_clock_seconds() - t0;
            }
            double ns = 1e9 * t / ((double)npoint * repeat);
            if (ns < best)
                best = ns;
        }
        printf("  (c)  same point, hint     %8.1f ns/eval  (%d points x %d)  checksum %.15g\n", best,
               npoint, repeat, csum);
        rc_ns = best;
    }

    /* (d) just outside: beyond boundary facets (sm_mesh_build_boundary on
     * a copy, so the field's mesh is untouched) */
    {
        sm_mesh *cp = NULL;
        if (sm_mesh_clone(bg, &cp, &err) != SM_OK || sm_mesh_build_boundary(cp, &err) != SM_OK) {
            fprintf(stderr, "boundary: %s\n", err.msg);
            return 1;
        }
        int64_t nd = npts / 10;
        for (int64_t j = 0; j < nd; j++) {
            int32_t b = (int32_t)(urand(&s) * cp->nbfacets);
            const int32_t *fv = cp->bfacets + (size_t)b * (size_t)d;
            double n[3] = {0, 0, 0}, w[3], ws = 0.0, x[3] = {0, 0, 0};
            sm_bfacet_normal(cp, cp->coords, b, n);
            for (int k = 0; k < d; k++) {
                w[k] = urand(&s) + 1e-3;
                ws += w[k];
            }
            double off = (0.05 + 0.45 * urand(&s)) * h;
            for (int i = 0; i < d; i++) {
                for (int k = 0; k < d; k++)
                    x[i] += w[k] / ws * cp->coords[(size_t)fv[k] * d + i];
                x[i] += off * n[i];
            }
            memcpy(pts + (size_t)j * d, x, sizeof(double) * (size_t)d);
            slot[j] = (int32_t)j;
            hints[j] = -1;
        }
        pass_result rd = eval_pass(f, d, pts, nd, NULL, hints, 3);
        printf("  (d)  just outside         %8.1f ns/eval  (%lld points)  checksum %.15g\n", rd.ns,
               (long long)nd, rd.checksum);
        for (int64_t j = 0; j < nd; j++)
            sm_field_eval(f, pts + (size_t)j * d, &hints[j]);
        pass_result rd1 = eval_pass(f, d, pts, nd, slot, hints, 3);
        printf("  (d1) just outside, hint   %8.1f ns/eval  checksum %.15g\n", rd1.ns, rd1.checksum);
        rd_ns = rd.ns;
        rd1_ns = rd1.ns;
        sm_mesh_free(cp);
    }
    /* the grid's element lists are built on first need (a walk that
     * failed: the outside points above): the field's memory now */
    sm_field_get_stats(f, &st);
    printf("  field with its grid lists (built when a walk first failed): %.1f MiB\n",
           st.bytes / 1048576.0);
    /* machine-readable line for scripts */
    printf("RESULT build=%.4f a=%.1f b=%.1f b2=%.1f c=%.1f d=%.1f d1=%.1f\n", tbest, ra.ns, rb.ns,
           rb2.ns, rc_ns, rd_ns, rd1_ns);

    free(order);
    free(pos);
    free(dir);
    free(pts);
    free(slot);
    free(hints);
    sm_field_free(f);
    sm_sol_free(sol);
    sm_mesh_free(bg);
    return 0;
}
