/* Two-sided distances between a match's boundary and its target, the
 * missed part of the target, the topology of both, and the descent's
 * target-side term (sm_coverage.h, sm_coverage_internal.h). */
#include "shapematch/sm_coverage.h"

#include <float.h>
#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

#include "sm_bvh.h"
#include "sm_coverage_internal.h"
#include "sm_field_internal.h"

/* Subdivisions of one facet at most (per side): a target facet a
 * thousand times the spacing is sampled like a thousand smaller ones. */
#define MAX_SPLIT 1000
/* Fewer points than this are searched on one thread: the start of a
 * parallel region costs more than their searches. */
#define PARALLEL_MIN 20000
/* The descent's searches start from the last answer but still descend
 * the boundary's hierarchy: 1.5-4 us a sample (3D example: 4.6k
 * samples, 3-10 ms a trial), so a few thousand are worth a second thread.
 * Each sample's answer is its own, so the result does not depend on the
 * thread count. */
#define CORRESPOND_PARALLEL_MIN 2000
/* At most this many target samples (once each facet gets one): five
 * times the 3D example's; the final measure of 1M costs seconds */
#define MAX_TARGET_SAMPLES 1000000
/* The descent's samples: one per cell of THIN_CELL times the spacing
 * (so of the template boundary's mean edge), about one per two boundary
 * facets in 3D (3D example: 4.3k samples for 8.9k facets, where one per
 * spacing cell, 17k, made the term 72 ms of a 150 ms iteration). */
#define THIN_CELL 4.0
/* Iterations between two builds of the descent's boundary hierarchy
 * (refitted in between: a build was 18% of a 3D example iteration). */
#define REBUILD_EVERY 20

struct sm_coverage {
    int dim;
    sm_distance_method method;
    const sm_mesh *m;
    const sm_surface *target;  /* the given surface or own */
    sm_surface *own;           /* the extracted level set */
    sm_bvh target_bvh;         /* built by the first sm_coverage_measure
                                * (the descent does not search the target) */
    int target_bvh_built;
    double spacing;            /* the samples': a quarter of the template
                                * boundary's mean edge */
    double dead;               /* the term's dead zone: half that edge */
    double tspacing;           /* the target's: the same, or a quarter of
                                * the target's own mean edge when larger,
                                * or coarser still (MAX_TARGET_SAMPLES) */
    /* the target's samples: counted and thinned at the set-up, made
     * again by sm_coverage_measure (the same points: 19 MB of the 3D
     * example's that the descent does not read) */
    int64_t nt;
    double *ty, *tw;           /* nt * dim, nt; NULL before the measure */
    double tmeasure;
    double *tdist;             /* nt: the last sm_coverage_measure's */
    /* the boundary's samples of the last sm_coverage_measure */
    int64_t nr;
    double *rpts, *rw, *rdist; /* nr * dim, nr, nr */
    double rmeasure;
    /* the boundary measured: the active facets of m */
    int32_t nactive;
    int32_t *afacets;          /* nactive * dim vertex ids */
    /* the descent's samples: the target's merged per cell of a grid of
     * the spacing (thin_samples), and their correspondences
     * (sm__coverage_correspond) */
    int64_t nd;
    double *dy, *dw;           /* nd * dim, nd */
    int32_t *cfacet;           /* nd: index into afacets; also the hint */
    double *cbary;             /* nd * dim */
    double *cdist;             /* nd */
    /* the boundary's vertex graph (CSR over the mesh's vertex ids), for
     * spreading the term's load (sm__coverage_spread) */
    int32_t *adj_start, *adj;
    double *spread_tmp;        /* nverts * dim */
    /* the descent's hierarchy over the boundary: built once, refitted
     * to the moved vertices, built again every REBUILD_EVERY iterations
     * (a refitted tree's boxes grow loose as the mesh deforms) */
    sm_surface view;
    sm_bvh bvh;
    int bvh_age;               /* -1: not built */
    sm_coverage_topology topo;
};

const char *sm_distance_method_name(sm_distance_method m)
{
    switch (m) {
    case SM_DISTANCE_SURFACE: return "surface";
    case SM_DISTANCE_LEVEL_SET: return "level-set";
    case SM_DISTANCE_NONE: break;
    }
    return NULL;
}

/* ---- the zero level set of the field: marching simplices ---- */

typedef struct cut_edge {
    uint64_t key;   /* (lo << 32) | hi background vertex ids */
    int64_t id;     /* running index: the cut's vertex id after merging */
} cut_edge;

static int cmp_cut(const void *a, const void *b)
{
    uint64_t x = ((const cut_edge *)a)->key, y = ((const cut_edge *)b)->key;
    return x < y ? -1 : x > y;
}

static uint64_t edge_key(int32_t a, int32_t b)
{
    return a < b ? ((uint64_t)a << 32) | (uint64_t)b : ((uint64_t)b << 32) | (uint64_t)a;
}

/* The level set's facets of element e as background edges: 0, 1 or 2
 * facets (a tetrahedron with two negative vertices gives a quad, cut in
 * two triangles).  Returns the number of facets written to edges
 * (facets * dim edge pairs). */
static int elem_cuts(const sm_field *f, int32_t e, int32_t edges[2][3][2])
{
    const int D = f->dim;
    const int32_t *v = f->bg->elems + (size_t)e * (size_t)(D + 1);
    int neg[4], nneg = 0, pos[4], npos = 0;
    for (int k = 0; k <= D; k++) {
        if (f->values[v[k]] < 0)
            neg[nneg++] = v[k];
        else
            pos[npos++] = v[k];
    }
    if (nneg == 0 || npos == 0)
        return 0;
    if (D == 2) { /* one vertex alone on its side: the two edges from it */
        const int32_t lone = nneg == 1 ? neg[0] : pos[0];
        const int32_t *other = nneg == 1 ? pos : neg;
        edges[0][0][0] = lone, edges[0][0][1] = other[0];
        edges[0][1][0] = lone, edges[0][1][1] = other[1];
        return 1;
    }
    if (nneg == 1 || npos == 1) {
        const int32_t lone = nneg == 1 ? neg[0] : pos[0];
        const int32_t *other = nneg == 1 ? pos : neg;
        for (int j = 0; j < 3; j++)
            edges[0][j][0] = lone, edges[0][j][1] = other[j];
        return 1;
    }
    /* 2 and 2: the quad n0p0, n0p1, n1p1, n1p0 */
    int32_t q[4][2] = {{neg[0], pos[0]}, {neg[0], pos[1]}, {neg[1], pos[1]}, {neg[1], pos[0]}};
    for (int j = 0; j < 2; j++) {
        edges[0][j][0] = q[j][0], edges[0][j][1] = q[j][1];
        edges[1][j][0] = q[j + 2][0], edges[1][j][1] = q[j + 2][1];
    }
    edges[0][2][0] = q[2][0], edges[0][2][1] = q[2][1];
    edges[1][2][0] = q[0][0], edges[1][2][1] = q[0][1];
    return 2;
}

/* The zero level set of d as a surface whose vertices are the cut
 * background edges (shared between elements, so that its topology can be
 * counted). */
static sm_status extract_level_set(const sm_field *f, sm_surface **out, sm_error *err)
{
    const int D = f->dim;
    int64_t nfac = 0;
    for (int32_t e = 0; e < f->nelems; e++) {
        int32_t edges[2][3][2];
        if (f->valid[e])
            nfac += elem_cuts(f, e, edges);
    }
    if (nfac == 0)
        return sm_error_set(err, SM_ERR_INVALID,
                            "the target distance does not change sign on its background mesh: "
                            "it has no zero level set");
    if (nfac > SM_MAX_ENTITIES)
        return sm_error_set(err, SM_ERR_NOMEM, "the zero level set has too many facets (%lld)",
                            (long long)nfac);
    cut_edge *cuts = malloc((size_t)nfac * (size_t)D * sizeof *cuts);
    if (!cuts)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the zero level set");
    int64_t n = 0;
    for (int32_t e = 0; e < f->nelems; e++) {
        int32_t edges[2][3][2];
        int k = f->valid[e] ? elem_cuts(f, e, edges) : 0;
        for (int i = 0; i < k; i++)
            for (int j = 0; j < D; j++) {
                cuts[n].key = edge_key(edges[i][j][0], edges[i][j][1]);
                cuts[n].id = n;
                n++;
            }
    }
    /* merge: sort by key, give each distinct edge a vertex id */
    cut_edge *sorted = malloc((size_t)n * sizeof *sorted);
    int32_t *vid = malloc((size_t)n * sizeof *vid);
    if (!sorted || !vid) {
        free(cuts), free(sorted), free(vid);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the zero level set");
    }
    memcpy(sorted, cuts, (size_t)n * sizeof *sorted);
    qsort(sorted, (size_t)n, sizeof *sorted, cmp_cut);
    int32_t nv = 0;
    for (int64_t i = 0; i < n; i++) {
        if (i > 0 && sorted[i].key != sorted[i - 1].key)
            nv++;
        vid[sorted[i].id] = nv;
    }
    nv++;
    sm_surface *s;
    sm_status st = sm_surface_alloc(&s, D, nv, (int32_t)nfac, err);
    if (st == SM_OK) {
        for (int64_t i = 0; i < n; i++) {
            int32_t a = (int32_t)(sorted[i].key >> 32), b = (int32_t)(sorted[i].key & 0xffffffffu);
            double va = f->values[a], vb = f->values[b];
            double t = va / (va - vb);
            double *x = s->coords + (size_t)vid[sorted[i].id] * (size_t)D;
            for (int k = 0; k < D; k++)
                x[k] = f->bg->coords[(size_t)a * D + k] +
                       t * (f->bg->coords[(size_t)b * D + k] - f->bg->coords[(size_t)a * D + k]);
        }
        for (int64_t i = 0; i < n; i++)
            s->facets[i] = vid[i];
        *out = s;
    }
    free(cuts), free(sorted), free(vid);
    return st;
}

/* ---- sampling ---- */

static double facet_measure(int dim, const double *a, const double *b, const double *c)
{
    if (dim == 2)
        return hypot(b[0] - a[0], b[1] - a[1]);
    double u[3], w[3];
    for (int k = 0; k < 3; k++)
        u[k] = b[k] - a[k], w[k] = c[k] - a[k];
    double n0 = u[1] * w[2] - u[2] * w[1], n1 = u[2] * w[0] - u[0] * w[2],
           n2 = u[0] * w[1] - u[1] * w[0];
    return 0.5 * sqrt(n0 * n0 + n1 * n1 + n2 * n2);
}

/* One square root for the longest (the root of the largest square is
 * the largest root: it rounds monotonically). */
static double longest_edge(int dim, const double *const x[3])
{
    double l2 = 0;
    for (int i = 0; i < dim; i++)
        for (int j = i + 1; j < dim; j++) {
            double s = 0;
            for (int k = 0; k < dim; k++)
                s += (x[i][k] - x[j][k]) * (x[i][k] - x[j][k]);
            l2 = s > l2 ? s : l2;
        }
    return sqrt(l2);
}

static int splits(int dim, const double *const x[3], double spacing)
{
    double k = ceil(longest_edge(dim, x) / spacing);
    return k < 1 || !isfinite(k) ? 1 : k > MAX_SPLIT ? MAX_SPLIT : (int)k;
}

/* Samples of facets (nfacets * dim vertex ids into coords): the centroids
 * of the k^(dim-1) equal parts of each facet, weighted by their measure,
 * or with gauss set each part's points of a Gauss rule (2 per segment,
 * the 3 of the degree-2 rule per triangle).  The distance from a chord
 * to a curved target is a parabola through 0, so its square varies
 * fast: the centroids sampled the 2D example's RMS 8% low (1.48e-4
 * against 1.61e-4 by 64 samples per edge, tests/cli/chord_check.py),
 * the Gauss points within 1%.  With pts NULL only counts.  Returns the
 * number of samples. */
static int64_t sample_facets(int dim, const double *coords, const int32_t *facets, int32_t nfacets,
                             double spacing, int gauss, double *pts, double *w)
{
    static const double seg_gauss[2] = {0.5 - 0.28867513459481288225, 0.5 + 0.28867513459481288225};
    static const double tri_gauss[3][3] = {{2.0 / 3, 1.0 / 6, 1.0 / 6},
                                           {1.0 / 6, 2.0 / 3, 1.0 / 6},
                                           {1.0 / 6, 1.0 / 6, 2.0 / 3}};
    const int per = gauss ? dim : 1;
    int64_t n = 0;
    for (int32_t f = 0; f < nfacets; f++) {
        const double *x[3] = {NULL, NULL, NULL};
        for (int i = 0; i < dim; i++)
            x[i] = coords + (size_t)facets[(size_t)f * dim + i] * (size_t)dim;
        int k = splits(dim, x, spacing);
        if (!pts) {
            n += per * (dim == 2 ? k : (int64_t)k * k);
            continue;
        }
        double meas = facet_measure(dim, x[0], x[1], x[2]);
        if (dim == 2) {
            for (int i = 0; i < k; i++)
                for (int g = 0; g < per; g++, n++) {
                    double t = (i + (gauss ? seg_gauss[g] : 0.5)) / k;
                    for (int c = 0; c < 2; c++)
                        pts[n * 2 + c] = x[0][c] + t * (x[1][c] - x[0][c]);
                    w[n] = meas / k / per;
                }
            continue;
        }
        /* the k^2 triangles of the lattice of step 1/k: upward (i, j),
         * (i+1, j), (i, j+1) and downward (i+1, j), (i, j+1), (i+1, j+1),
         * in lattice coordinates (along x1 - x0, along x2 - x0) */
        for (int up = 0; up < 2; up++)
            for (int i = 0; i < k; i++)
                for (int j = 0; i + j < k - up; j++) {
                    const double corner[2][3][2] = {{{i, j}, {i + 1, j}, {i, j + 1}},
                                                    {{i + 1, j}, {i, j + 1}, {i + 1, j + 1}}};
                    for (int g = 0; g < per; g++, n++) {
                        double bb = 0, bc = 0;
                        for (int a = 0; a < 3; a++) {
                            double l = gauss ? tri_gauss[g][a] : 1.0 / 3;
                            bb += l * corner[up][a][0];
                            bc += l * corner[up][a][1];
                        }
                        bb /= k, bc /= k;
                        for (int c = 0; c < 3; c++)
                            pts[n * 3 + c] = x[0][c] + bb * (x[1][c] - x[0][c]) +
                                             bc * (x[2][c] - x[0][c]);
                        w[n] = meas / ((double)k * k) / per;
                    }
                }
    }
    return n;
}

/* ---- distances to a hierarchy ---- */

/* Distance from each of the points pts[from..to) to the facets of t, on
 * the calling thread; NAN when out of memory for the search's stack. */
static void nearest_range(const sm_bvh *t, int dim, int64_t from, int64_t to, const double *pts,
                          double *dist)
{
    sm_bvh_entry *stack = malloc((size_t)(2 * t->depth + 2) * sizeof *stack);
    for (int64_t i = from; i < to; i++) {
        if (!stack) {
            dist[i] = NAN;
            continue;
        }
        double p[3] = {0, 0, 0};
        memcpy(p, pts + i * dim, (size_t)dim * sizeof *p);
        int32_t hint = -1;
        dist[i] = sm__bvh_nearest(t, p, &hint, stack);
    }
    free(stack);
}

/* The same for pts[0..n) as tasks for the threads of the enclosing
 * parallel region (each point's answer is its own: any thread, any
 * order, the same bits), SEARCH_TASKS a thread of at least SEARCH_GRAIN
 * points: few enough that libgomp queues them (beyond 64 a thread it
 * runs a taskloop's tasks on the thread that made them, one after the
 * other), enough to even out.  Returns at once: the caller waits
 * (taskwait) before reading dist. */
#define SEARCH_GRAIN 512
#define SEARCH_TASKS 8
static void nearest_tasks(const sm_bvh *t, int dim, int64_t n, const double *pts, double *dist)
{
    int64_t want = (n + SEARCH_GRAIN - 1) / SEARCH_GRAIN;
    if (want > SEARCH_TASKS * (int64_t)omp_get_num_threads())
        want = SEARCH_TASKS * (int64_t)omp_get_num_threads();
    /* an unsigned counter: clang's expansion of the taskloop compares
     * the counter with its unsigned grain (-Wsign-compare on a signed one) */
    uint64_t tasks = (uint64_t)want;
#pragma omp taskloop grainsize(1) nogroup
    for (uint64_t k = 0; k < tasks; k++)
        nearest_range(t, dim, n * (int64_t)k / want, n * (int64_t)(k + 1) / want, pts, dist);
}

/* The max of the distance over facets is often inside a facet (a chord's
 * middle), between samples: the facets whose samples come within
 * REFINE_NEAR of the largest distance so far are sampled again REFINE
 * times finer per side, and the max taken over those too.  (An
 * ellipsoid's target side had its max 7% low at a quarter edge.) */
#define REFINE_NEAR 0.8
#define REFINE 4

static double refine_max(int dim, const double *coords, const int32_t *facets, int32_t nfacets,
                         double spacing, int gauss, const double *d, double mx, const sm_bvh *t)
{
    int64_t at = 0;
    double *pts = NULL, *w = NULL, *fd = NULL;
    int64_t cap = 0;
    for (int32_t f = 0; f < nfacets; f++) {
        const double *x[3] = {NULL, NULL, NULL};
        for (int i = 0; i < dim; i++)
            x[i] = coords + (size_t)facets[(size_t)f * dim + i] * (size_t)dim;
        int k = splits(dim, x, spacing);
        int64_t n = (gauss ? dim : 1) * (dim == 2 ? k : (int64_t)k * k);
        double fmx = 0;
        for (int64_t i = 0; i < n; i++)
            fmx = d[at + i] > fmx ? d[at + i] : fmx;
        at += n;
        if (fmx < REFINE_NEAR * mx)
            continue;
        const int32_t *one = facets + (size_t)f * dim;
        int64_t nf = sample_facets(dim, coords, one, 1, spacing / REFINE, 0, NULL, NULL);
        if (nf > cap) {
            free(pts), free(w), free(fd);
            cap = nf;
            pts = malloc((size_t)nf * dim * sizeof *pts);
            w = malloc((size_t)nf * sizeof *w);
            fd = malloc((size_t)nf * sizeof *fd);
            if (!pts || !w || !fd)
                break; /* the samples' max stands */
        }
        sample_facets(dim, coords, one, 1, spacing / REFINE, 0, pts, w);
        nearest_range(t, dim, 0, nf, pts, fd);
        for (int64_t i = 0; i < nf; i++)
            mx = fd[i] > mx ? fd[i] : mx;
    }
    free(pts), free(w), free(fd);
    return mx;
}

typedef struct wd {
    double d, w;
} wd;

/* The smallest d of s[0..n) with at least the weight `want` at or below
 * it: a quickselect by weight (expected O(n), where a sort made the
 * per-iteration figures cost a third of the descent's sampling). */
static double weighted_quantile(wd *s, int64_t n, double want)
{
    int64_t lo = 0, hi = n; /* the answer is in s[lo..hi); want counts from lo */
    while (hi - lo > 1) {
        double pivot = s[lo + (hi - lo) / 2].d;
        /* three-way partition: < pivot, == pivot, > pivot */
        int64_t lt = lo, i = lo, gt = hi;
        double wl = 0, we = 0;
        while (i < gt) {
            if (s[i].d < pivot) {
                wl += s[i].w;
                wd t = s[lt];
                s[lt++] = s[i];
                s[i++] = t;
            } else if (s[i].d > pivot) {
                wd t = s[--gt];
                s[gt] = s[i];
                s[i] = t;
            } else {
                we += s[i++].w;
            }
        }
        if (want <= wl && lt > lo) {
            hi = lt;
        } else if (want <= wl + we || gt == hi) {
            return pivot;
        } else {
            want -= wl + we;
            lo = gt;
        }
    }
    return hi > lo ? s[lo].d : 0;
}

/* rms, mean, max over weighted distances, and the p99 by weight; extra
 * (n_extra unweighted distances, may be 0) count toward the max only.
 * p99 is NAN when out of memory. */
static void side_figures(int64_t n, const double *d, const double *w, int64_t n_extra,
                         const double *extra, sm_distance_side *out)
{
    double sw = 0, swd = 0, swd2 = 0, mx = 0;
    for (int64_t i = 0; i < n; i++) {
        sw += w[i];
        swd += w[i] * d[i];
        swd2 += w[i] * d[i] * d[i];
        mx = d[i] > mx ? d[i] : mx; /* not fmax: a library call */
    }
    for (int64_t i = 0; i < n_extra; i++)
        mx = extra[i] > mx ? extra[i] : mx;
    out->rms = sw > 0 ? sqrt(swd2 / sw) : 0;
    out->mean = sw > 0 ? swd / sw : 0;
    out->max = mx;
    out->p99 = NAN;
    wd *s = malloc((size_t)(n ? n : 1) * sizeof *s);
    if (!s)
        return;
    for (int64_t i = 0; i < n; i++)
        s[i] = (wd){d[i], w[i]};
    out->p99 = weighted_quantile(s, n, 0.99 * sw);
    free(s);
}

/* The boundary at coords as a surface (coords borrowed: the hierarchy
 * built on it reads them until the next build). */
static sm_surface boundary_view(const sm_coverage *c, const double *coords)
{
    return (sm_surface){.dim = c->dim, .nverts = c->m->nverts, .coords = (double *)coords,
                        .nfacets = c->nactive, .facets = c->afacets, .facet_refs = NULL};
}

/* ---- topology ---- */

static int64_t uf_find(int64_t *parent, int64_t i)
{
    while (parent[i] != i) {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    return i;
}

static int cmp_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

/* Pieces, Euler characteristic and closedness of a surface given by
 * facets over nverts vertex ids (only the ids used count).  Returns 0
 * when out of memory. */
/* The distinct edges among m edge keys (edge_key: the smaller vertex
 * id, below nverts, in the high half), and whether each is there exactly
 * twice (a closed surface): the keys bucketed by their smaller vertex (a
 * counting sort, where sorting the 250k keys of the 3D example's target
 * took 0.04 s), each bucket of a few ordered by insertion.  Returns 0
 * when out of memory. */
static int count_edges(int32_t nverts, int64_t m, const uint64_t *edges, int64_t *nedges,
                       int *closed)
{
    int64_t *start = calloc((size_t)nverts + 2, sizeof *start);
    int32_t *other = malloc((size_t)(m ? m : 1) * sizeof *other);
    if (!start || !other) {
        free(start), free(other);
        return 0;
    }
    for (int64_t i = 0; i < m; i++)
        start[(edges[i] >> 32) + 2]++;
    for (int32_t v = 0; v < nverts; v++)
        start[v + 2] += start[v + 1];
    for (int64_t i = 0; i < m; i++) /* start[v + 1]: the next free place of bucket v */
        other[start[(edges[i] >> 32) + 1]++] = (int32_t)(edges[i] & 0xffffffffu);
    *nedges = 0;
    for (int32_t v = 0; v < nverts; v++) {
        int32_t *b = other + start[v];
        int64_t n = start[v + 1] - start[v];
        for (int64_t i = 1; i < n; i++)
            for (int64_t j = i; j > 0 && b[j - 1] > b[j]; j--) {
                int32_t t = b[j];
                b[j] = b[j - 1];
                b[j - 1] = t;
            }
        for (int64_t i = 0, j; i < n; i = j) {
            for (j = i; j < n && b[j] == b[i]; j++)
                ;
            ++*nedges;
            if (j - i != 2)
                *closed = 0;
        }
    }
    free(start), free(other);
    return 1;
}

static int surface_topology(int dim, int32_t nverts, const int32_t *facets, int32_t nfacets,
                            int64_t *pieces, int64_t *chi, int *closed)
{
    int64_t *parent = malloc((size_t)(nverts ? nverts : 1) * sizeof *parent);
    uint8_t *used = calloc((size_t)(nverts ? nverts : 1), 1);
    int64_t ne = (int64_t)nfacets * (dim == 3 ? 3 : 1);
    uint64_t *edges = malloc((size_t)(ne ? ne : 1) * sizeof *edges);
    if (!parent || !used || !edges) {
        free(parent), free(used), free(edges);
        return 0;
    }
    for (int32_t v = 0; v < nverts; v++)
        parent[v] = v;
    int64_t m = 0;
    for (int32_t f = 0; f < nfacets; f++) {
        const int32_t *v = facets + (size_t)f * dim;
        for (int j = 0; j < dim; j++)
            used[v[j]] = 1;
        for (int j = 1; j < dim; j++) {
            int64_t a = uf_find(parent, v[0]), b = uf_find(parent, v[j]);
            if (a != b)
                parent[a] = b;
        }
        if (dim == 3)
            for (int j = 0; j < 3; j++)
                edges[m++] = edge_key(v[j], v[(j + 1) % 3]);
    }
    int64_t nv = 0, np = 0;
    for (int32_t v = 0; v < nverts; v++)
        if (used[v]) {
            nv++;
            np += uf_find(parent, v) == v;
        }
    *closed = 1;
    int64_t nedges = 0;
    if (dim == 3) {
        if (!count_edges(nverts, m, edges, &nedges, closed)) {
            free(parent), free(used), free(edges);
            return 0;
        }
        *chi = nv - nedges + nfacets;
    } else {
        /* a closed curve: every vertex in exactly two segments */
        int32_t *deg = calloc((size_t)(nverts ? nverts : 1), sizeof *deg);
        if (!deg) {
            free(parent), free(used), free(edges);
            return 0;
        }
        for (int64_t i = 0; i < (int64_t)nfacets * 2; i++)
            deg[facets[i]]++;
        for (int32_t v = 0; v < nverts; v++)
            if (used[v] && deg[v] != 2)
                *closed = 0;
        free(deg);
        *chi = 0;
    }
    *pieces = np;
    free(parent), free(used), free(edges);
    return 1;
}

static void find_topology(sm_coverage *c)
{
    sm_coverage_topology *t = &c->topo;
    memset(t, 0, sizeof *t);
    int closed_t = 0, closed_m = 0;
    const sm_mesh *m = c->m;
    if (!surface_topology(c->dim, c->target->nverts, c->target->facets, c->target->nfacets,
                          &t->target_pieces, &t->target_chi, &closed_t) ||
        !surface_topology(c->dim, m->nverts, m->bfacets, m->nbfacets, &t->template_pieces,
                          &t->template_chi, &closed_m))
        return;
    t->known = closed_t && closed_m;
    if (c->dim == 3) {
        t->target_genus = t->target_pieces - t->target_chi / 2;
        t->template_genus = t->template_pieces - t->template_chi / 2;
    }
}

/* ---- the coverage ---- */

static sm_status check_boundary(sm_coverage *c, const sm_mesh *m, const int32_t *free_refs,
                                int nfree, sm_error *err)
{
    const int dim = m->dim;
    c->afacets = malloc(((size_t)m->nbfacets * dim + 1) * sizeof *c->afacets);
    if (!c->afacets)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    double len = 0;
    int64_t nedges = 0;
    for (int32_t f = 0; f < m->nbfacets; f++) {
        int is_free = 0;
        for (int i = 0; i < nfree; i++)
            is_free |= m->bfacet_refs && m->bfacet_refs[f] == free_refs[i];
        if (is_free)
            continue;
        const int32_t *v = m->bfacets + (size_t)f * dim;
        memcpy(c->afacets + (size_t)c->nactive * dim, v, (size_t)dim * sizeof *v);
        c->nactive++;
        for (int i = 0; i < dim; i++)
            for (int j = i + 1; j < dim; j++) {
                double s = 0;
                for (int k = 0; k < dim; k++) {
                    double e = m->coords[(size_t)v[i] * dim + k] - m->coords[(size_t)v[j] * dim + k];
                    s += e * e;
                }
                len += sqrt(s);
                nedges++;
            }
    }
    if (c->nactive == 0)
        return sm_error_set(err, SM_ERR_INVALID, "no boundary facet carries the load (all are "
                            "in the free boundary)");
    c->spacing = 0.25 * len / (double)nedges;
    c->dead = 2 * c->spacing;
    if (!(c->spacing > 0))
        return sm_error_set(err, SM_ERR_INVALID, "the template's boundary has zero size");
    return SM_OK;
}

/* One cell of the thinning grid: its key, the weight and weighted sum of
 * its samples, then their centroid and the sample nearest it. */
typedef struct thin_cell {
    uint64_t key;
    double w, g[3], centre[3], best[3], bd;
} thin_cell;

/* The cells in the order met (their indices stay), and an open-addressed
 * index of them by key (nslots a power of two; -1: empty). */
typedef struct thin_table {
    thin_cell *cells;
    int64_t n, cap;
    int32_t *slots;
    int64_t nslots;
} thin_table;

static uint64_t thin_hash(uint64_t key, int64_t nslots)
{
    return (key * 0x9E3779B97F4A7C15ull) >> 20 & (uint64_t)(nslots - 1);
}

/* The index of the cell of key (added when new), or -1 when out of
 * memory. */
static int64_t thin_cell_of(thin_table *t, uint64_t key)
{
    if (2 * (t->n + 1) > t->nslots) {
        int64_t nslots = t->nslots ? 2 * t->nslots : 1024;
        int32_t *slots = malloc((size_t)nslots * sizeof *slots);
        if (!slots)
            return -1;
        for (int64_t h = 0; h < nslots; h++)
            slots[h] = -1;
        for (int64_t i = 0; i < t->n; i++) {
            uint64_t h = thin_hash(t->cells[i].key, nslots);
            while (slots[h] >= 0)
                h = (h + 1) & (uint64_t)(nslots - 1);
            slots[h] = (int32_t)i;
        }
        free(t->slots);
        t->slots = slots;
        t->nslots = nslots;
    }
    uint64_t h = thin_hash(key, t->nslots);
    while (t->slots[h] >= 0 && t->cells[t->slots[h]].key != key)
        h = (h + 1) & (uint64_t)(t->nslots - 1);
    if (t->slots[h] >= 0)
        return t->slots[h];
    if (t->n == t->cap) {
        int64_t cap = t->cap ? 2 * t->cap : 512;
        thin_cell *cells = realloc(t->cells, (size_t)cap * sizeof *cells);
        if (!cells)
            return -1;
        t->cells = cells;
        t->cap = cap;
    }
    t->cells[t->n] = (thin_cell){.key = key, .bd = DBL_MAX};
    t->slots[h] = (int32_t)t->n;
    return t->n++;
}

static int cmp_thin_cell(const void *a, const void *b)
{
    const thin_cell *x = a, *y = b;
    return x->key < y->key ? -1 : x->key > y->key;
}

/* The target's samples of facet f at tspacing into *pts, *w (grown to
 * fit, *cap entries): the same points and weights as sample_facets over
 * all facets gives for f.  Returns their number, -1 when out of memory. */
static int64_t facet_target_samples(const sm_coverage *c, int32_t f, double **pts, double **w,
                                    int64_t *cap)
{
    const sm_surface *s = c->target;
    const int32_t *one = s->facets + (size_t)f * c->dim;
    int64_t n = sample_facets(c->dim, s->coords, one, 1, c->tspacing, 0, NULL, NULL);
    if (n > *cap) {
        free(*pts), free(*w);
        *pts = malloc((size_t)n * c->dim * sizeof **pts);
        *w = malloc((size_t)n * sizeof **w);
        *cap = *pts && *w ? n : 0;
        if (!*cap)
            return -1;
    }
    return sample_facets(c->dim, s->coords, one, 1, c->tspacing, 0, *pts, *w);
}

/* The descent's samples: the target's samples merged per cell of a grid
 * of the spacing, each cell's the sample nearest the cell's centroid
 * (so it lies on the target; the first in sample order of equally near
 * ones) with the cell's whole measure, in the order of the cells' keys.
 * A fine target (a level set on a fine background, a dense scan) gets
 * about two descent samples per boundary facet of the template, whatever
 * its own facet count: the term's cost per iteration is then that of a
 * boundary sampling (3D example: 0.34 s an iteration on every sample,
 * ...).  The target's samples are made facet by facet, three times (the
 * grid's corner, the cells' sums, the samples nearest the centroids),
 * and not kept: the 3D example's 470k took 30 MB with their sort, at the
 * time the elastic factor is made beside (sm_job_inputs); only each
 * sample's cell is (4 bytes).  Also sums tmeasure.  Returns -1 when out
 * of memory. */
static int thin_samples(sm_coverage *c)
{
    const int dim = c->dim;
    const sm_surface *s = c->target;
    double *pts = NULL, *w = NULL;
    int64_t cap = 0;
    thin_table t = {0};
    /* each sample's cell, from the second pass to the third */
    int32_t *cell_of = malloc(((size_t)c->nt + 1) * sizeof *cell_of);
    int failed = !cell_of;
    double lo[3] = {DBL_MAX, DBL_MAX, DBL_MAX};
    c->tmeasure = 0;
    for (int pass = 0; pass < 3 && !failed; pass++) {
        if (pass == 2) /* the centroids: as the sorted merge computed them */
            for (int64_t j = 0; j < t.n; j++)
                for (int k = 0; k < dim; k++)
                    t.cells[j].centre[k] = t.cells[j].w > 0 ? t.cells[j].g[k] / t.cells[j].w
                                                            : t.cells[j].g[k];
        int64_t at = 0;
        for (int32_t f = 0; f < s->nfacets && !failed; f++) {
            int64_t n = facet_target_samples(c, f, &pts, &w, &cap);
            if (n < 0 || at + n > c->nt) {
                failed = 1;
                break;
            }
            for (int64_t i = 0; i < n; i++, at++) {
                const double *y = pts + i * dim;
                if (pass == 0) {
                    for (int k = 0; k < dim; k++)
                        lo[k] = fmin(lo[k], y[k]);
                    c->tmeasure += w[i];
                } else if (pass == 1) {
                    uint64_t key = 0;
                    for (int k = 0; k < dim; k++) {
                        double q = floor((y[k] - lo[k]) / (THIN_CELL * c->tspacing));
                        uint64_t u = q < 0 ? 0 : q > 2097151 ? 2097151 : (uint64_t)q;
                        key = (key << 21) | u;
                    }
                    int64_t j = thin_cell_of(&t, key);
                    if (j < 0) {
                        failed = 1;
                        break;
                    }
                    cell_of[at] = (int32_t)j;
                    t.cells[j].w += w[i];
                    for (int k = 0; k < dim; k++)
                        t.cells[j].g[k] += w[i] * y[k];
                } else {
                    thin_cell *cell = t.cells + cell_of[at];
                    double d2 = 0;
                    for (int k = 0; k < dim; k++) {
                        double e = y[k] - cell->centre[k];
                        d2 += e * e;
                    }
                    if (d2 < cell->bd) {
                        cell->bd = d2;
                        memcpy(cell->best, y, (size_t)dim * sizeof *y);
                    }
                }
            }
        }
    }
    free(pts), free(w), free(cell_of), free(t.slots);
    const int64_t cells = t.n;
    c->dy = malloc(((size_t)cells * dim + 1) * sizeof *c->dy);
    c->dw = malloc(((size_t)cells + 1) * sizeof *c->dw);
    c->cfacet = malloc(((size_t)cells + 1) * sizeof *c->cfacet);
    c->cbary = malloc(((size_t)cells * dim + 1) * sizeof *c->cbary);
    c->cdist = malloc(((size_t)cells + 1) * sizeof *c->cdist);
    if (failed || !c->dy || !c->dw || !c->cfacet || !c->cbary || !c->cdist) {
        free(t.cells);
        return -1;
    }
    if (cells > 0)
        qsort(t.cells, (size_t)cells, sizeof *t.cells, cmp_thin_cell);
    for (c->nd = 0; c->nd < cells; c->nd++) {
        memcpy(c->dy + c->nd * dim, t.cells[c->nd].best, (size_t)dim * sizeof *c->dy);
        c->dw[c->nd] = t.cells[c->nd].w;
    }
    free(t.cells);
    return 0;
}

/* The edges between the active facets' vertices, both ways. */
static sm_status boundary_graph(sm_coverage *c, sm_error *err)
{
    const int dim = c->dim;
    const int32_t nv = c->m->nverts;
    int64_t ne = (int64_t)c->nactive * (dim == 3 ? 6 : 2);
    uint64_t *e = malloc((size_t)(ne ? ne : 1) * sizeof *e);
    c->adj_start = calloc((size_t)nv + 1, sizeof *c->adj_start);
    c->spread_tmp = malloc(((size_t)nv * dim + 1) * sizeof *c->spread_tmp);
    if (!e || !c->adj_start || !c->spread_tmp) {
        free(e);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    }
    int64_t m = 0;
    for (int32_t f = 0; f < c->nactive; f++) {
        const int32_t *v = c->afacets + (size_t)f * dim;
        for (int i = 0; i < dim; i++)
            for (int j = 0; j < dim; j++)
                if (i != j)
                    e[m++] = ((uint64_t)v[i] << 32) | (uint64_t)v[j];
    }
    qsort(e, (size_t)m, sizeof *e, cmp_u64);
    int64_t u = 0;
    for (int64_t i = 0; i < m; i++)
        if (i == 0 || e[i] != e[i - 1])
            e[u++] = e[i];
    c->adj = malloc((size_t)(u ? u : 1) * sizeof *c->adj);
    if (!c->adj) {
        free(e);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    }
    for (int64_t i = 0; i < u; i++) {
        c->adj_start[(e[i] >> 32) + 1]++;
        c->adj[i] = (int32_t)(e[i] & 0xffffffffu);
    }
    for (int32_t v = 0; v < nv; v++)
        c->adj_start[v + 1] += c->adj_start[v];
    free(e);
    return SM_OK;
}

/* The target's nt samples at tspacing, into ty and tw (and tdist
 * allocated): the same points every call.  Returns -1 when out of
 * memory. */
static int make_target_samples(sm_coverage *c)
{
    const sm_surface *s = c->target;
    if (!c->ty) {
        c->ty = malloc(((size_t)c->nt * c->dim + 1) * sizeof *c->ty);
        c->tw = malloc(((size_t)c->nt + 1) * sizeof *c->tw);
    }
    if (!c->ty || !c->tw)
        return -1;
    sample_facets(c->dim, s->coords, s->facets, s->nfacets, c->tspacing, 0, c->ty, c->tw);
    return 0;
}

static sm_status sample_target(sm_coverage *c, sm_error *err)
{
    const sm_surface *s = c->target;
    /* no finer than a quarter of its own mean edge either: a target far
     * larger than the template (other units: the job warns) would get
     * billions of samples at the template's spacing, each far from every
     * facet of the template, which the hierarchy then cannot prune */
    c->tspacing = fmax(c->spacing, 0.25 * sm_surface_mean_edge(s));
    int64_t n = sample_facets(c->dim, s->coords, s->facets, s->nfacets, c->tspacing, 0, NULL, NULL);
    while (n > MAX_TARGET_SAMPLES && n > s->nfacets) {
        c->tspacing *= 2;
        n = sample_facets(c->dim, s->coords, s->facets, s->nfacets, c->tspacing, 0, NULL, NULL);
    }
    c->nt = n;
    if (thin_samples(c) != 0)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for %lld target samples",
                            (long long)n);
    for (int64_t i = 0; i < c->nd; i++)
        c->cfacet[i] = -1;
    return SM_OK;
}

sm_status sm_coverage_new(const sm_field *target, const sm_surface *surface, const sm_mesh *m,
                          const int32_t *free_refs, int nfree, sm_coverage **out,
                          sm_error *err)
{
    *out = NULL;
    if (!target || !m || !m->bfacets)
        return sm_error_set(err, SM_ERR_INVALID, "no target, or a template without its boundary");
    if (sm_field_dim(target) != m->dim || (surface && surface->dim != m->dim))
        return sm_error_set(err, SM_ERR_INVALID, "the template and the target differ in dimension");
    sm_coverage *c = calloc(1, sizeof *c);
    if (!c)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    c->dim = m->dim;
    c->m = m;
    c->bvh_age = -1;
    sm_status st = check_boundary(c, m, free_refs, nfree, err);
    if (st == SM_OK && surface) {
        c->target = surface;
        c->method = SM_DISTANCE_SURFACE;
    } else if (st == SM_OK) {
        st = extract_level_set(target, &c->own, err);
        c->target = c->own;
        c->method = SM_DISTANCE_LEVEL_SET;
    }
    if (st == SM_OK)
        st = sample_target(c, err);
    if (st == SM_OK)
        st = boundary_graph(c, err);
    if (st != SM_OK) {
        sm_coverage_free(c);
        return st;
    }
    find_topology(c);
    *out = c;
    return SM_OK;
}

void sm_coverage_free(sm_coverage *c)
{
    if (!c)
        return;
    sm__bvh_free(&c->target_bvh);
    sm_surface_free(c->own);
    free(c->ty), free(c->tw), free(c->tdist);
    free(c->rpts), free(c->rw), free(c->rdist);
    free(c->dy), free(c->dw);
    free(c->afacets);
    free(c->cfacet), free(c->cbary), free(c->cdist);
    free(c->adj_start), free(c->adj), free(c->spread_tmp);
    sm__bvh_free(&c->bvh);
    free(c);
}

sm_distance_method sm_coverage_method(const sm_coverage *c)
{
    return c->method;
}

int64_t sm_coverage_target_samples(const sm_coverage *c, double *measure)
{
    if (measure)
        *measure = c->tmeasure;
    return c->nt;
}

void sm_coverage_get_topology(const sm_coverage *c, sm_coverage_topology *out)
{
    *out = c->topo;
}

/* 1 when any of d[0..n) is NAN (a search out of memory for its stack). */
static int any_nan(int64_t n, const double *d)
{
    for (int64_t i = 0; i < n; i++)
        if (isnan(d[i]))
            return 1;
    return 0;
}

/* The two sides share the threads: the searches and the boundary's
 * sampling are tasks, which the other threads take while this one builds
 * the target's hierarchy (its first measure: 28 ms of the 3D example's)
 * and makes the target side's figures; what is allocated is allocated
 * here (memory a second thread frees stays in its own arena: the peak
 * grew 11 MB when the figures were a task).  Each search's answer is its
 * own and the figures are made on whole arrays, so they do not depend on
 * the thread count. */
sm_status sm_coverage_measure(sm_coverage *c, const double *coords, sm_distance *out,
                              sm_error *err)
{
    const int dim = c->dim;
    const sm_surface *s = c->target;
    memset(out, 0, sizeof *out);
    out->method = c->method;
    /* result -> target: the boundary's samples and vertices */
    int64_t nb = sample_facets(dim, coords, c->afacets, c->nactive, c->spacing, 1, NULL, NULL);
    int64_t nv = (int64_t)c->nactive * dim; /* facet corners (repeats are harmless) */
    double *pts = malloc(((size_t)(nb + nv) * dim + 1) * sizeof *pts);
    double *w = malloc(((size_t)nb + 1) * sizeof *w);
    double *d = malloc(((size_t)(nb + nv) + 1) * sizeof *d);
    /* target -> result: its samples, and its vertices toward the max */
    double *vd = malloc(((size_t)s->nverts + 1) * sizeof *vd);
    sm_bvh bvh;
    memset(&bvh, 0, sizeof bvh);
    sm_surface view = boundary_view(c, coords);
    sm_status st = SM_OK, st_target = SM_OK;
    if (!c->tdist)
        c->tdist = malloc(((size_t)c->nt + 1) * sizeof *c->tdist);
    if (!pts || !w || !d || !vd || !c->tdist || make_target_samples(c) != 0)
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory for the distance samples");
    if (st == SM_OK)
        st = sm__bvh_build_boxes(&view, &bvh, err);
    if (st == SM_OK) {
        const int64_t work = nb + nv + c->nt + s->nverts;
        /* the master: the caller's thread, whose arena the rest of the
         * run allocates from */
#pragma omp parallel if (work > PARALLEL_MIN)
#pragma omp master
        {
            nearest_tasks(&bvh, dim, c->nt, c->ty, c->tdist);
            nearest_tasks(&bvh, dim, s->nverts, s->coords, vd);
#pragma omp task
            {
                sample_facets(dim, coords, c->afacets, c->nactive, c->spacing, 1, pts, w);
                for (int64_t i = 0; i < nv; i++)
                    memcpy(pts + (nb + i) * dim, coords + (size_t)c->afacets[i] * dim,
                           (size_t)dim * sizeof *pts);
            }
            if (!c->target_bvh_built &&
                (st_target = sm__bvh_build_boxes(c->target, &c->target_bvh, err)) == SM_OK)
                c->target_bvh_built = 1;
#pragma omp taskwait
            if (st_target == SM_OK) {
                nearest_tasks(&c->target_bvh, dim, nb + nv, pts, d);
                side_figures(c->nt, c->tdist, c->tw, s->nverts, vd, &out->target_to_result);
                out->target_to_result.max =
                    refine_max(dim, s->coords, s->facets, s->nfacets, c->tspacing, 0, c->tdist,
                               out->target_to_result.max, &bvh);
#pragma omp taskwait
                /* the max over the samples and corners, as side_figures
                 * takes it, starts the refinement, a task beside the
                 * figures (its buffers are one facet's samples) */
                double mx = 0, refined = 0;
                for (int64_t i = 0; i < nb + nv; i++)
                    mx = d[i] > mx ? d[i] : mx;
#pragma omp task shared(refined)
                refined = refine_max(dim, coords, c->afacets, c->nactive, c->spacing, 1, d, mx,
                                     &c->target_bvh);
                side_figures(nb, d, w, nv, d + nb, &out->result_to_target);
#pragma omp taskwait
                out->result_to_target.max = refined;
            }
        }
        if (st_target != SM_OK)
            st = st_target;
        else if (any_nan(c->nt, c->tdist) || any_nan(s->nverts, vd) || any_nan(nb + nv, d))
            st = sm_error_set(err, SM_ERR_NOMEM, "out of memory for the distance search");
        else if (isnan(out->target_to_result.p99) || isnan(out->result_to_target.p99))
            st = sm_error_set(err, SM_ERR_NOMEM, "out of memory for the distance figures");
    }
    sm__bvh_free(&bvh);
    free(vd);
    /* kept for sm_coverage_missed_part (the vertices are not samples) */
    free(c->rpts), free(c->rw), free(c->rdist);
    c->rpts = pts, c->rw = w, c->rdist = d, c->nr = st == SM_OK ? nb : 0;
    c->rmeasure = 0;
    for (int64_t i = 0; i < c->nr; i++)
        c->rmeasure += w[i];
    return st;
}

void sm_coverage_missed_part(const sm_coverage *c, int result_side, double threshold,
                             sm_coverage_missed *out)
{
    const int dim = c->dim;
    const int64_t n = result_side ? c->nr : c->ty && c->tdist ? c->nt : 0; /* 0 before a measure */
    const double *pts = result_side ? c->rpts : c->ty, *w = result_side ? c->rw : c->tw;
    const double *dist = result_side ? c->rdist : c->tdist;
    const double total = result_side ? c->rmeasure : c->tmeasure;
    memset(out, 0, sizeof *out);
    for (int k = 0; k < 3; k++) {
        out->lo[k] = k < dim ? DBL_MAX : 0;
        out->hi[k] = k < dim ? -DBL_MAX : 0;
    }
    for (int64_t i = 0; i < n; i++) {
        if (!(dist[i] > threshold))
            continue;
        const double *y = pts + i * dim;
        out->samples++;
        out->measure += w[i];
        out->max = fmax(out->max, dist[i]);
        for (int k = 0; k < dim; k++) {
            out->lo[k] = fmin(out->lo[k], y[k]);
            out->hi[k] = fmax(out->hi[k], y[k]);
            out->centre[k] += w[i] * y[k];
        }
    }
    if (out->samples == 0) {
        memset(out->lo, 0, sizeof out->lo);
        memset(out->hi, 0, sizeof out->hi);
        return;
    }
    for (int k = 0; k < dim; k++)
        out->centre[k] = out->measure > 0 ? out->centre[k] / out->measure : out->lo[k];
    out->fraction = total > 0 ? out->measure / total : 0;
}

/* ---- the descent's target-side term ---- */

/* How far a distance is beyond the term's dead zone: the
 * term is 0 where the target is already that close to the boundary. */
static double excess(const sm_coverage *c, double d)
{
    return d > c->dead ? d - c->dead : 0.0;
}

/* The closest point of y's facet at coords, from the barycentric
 * coordinates kept. */
static void corresponding_point(const sm_coverage *c, const double *coords, int64_t i, double *p)
{
    const int dim = c->dim;
    const int32_t *v = c->afacets + (size_t)c->cfacet[i] * dim;
    const double *b = c->cbary + i * dim;
    for (int k = 0; k < dim; k++) {
        p[k] = 0;
        for (int j = 0; j < dim; j++)
            p[k] += b[j] * coords[(size_t)v[j] * dim + k];
    }
}

sm_status sm__coverage_correspond(sm_coverage *c, const double *coords, sm_distance_side *fig,
                                  double *term, sm_error *err)
{
    const int dim = c->dim;
    c->view = boundary_view(c, coords);
    if (c->bvh_age < 0 || c->bvh_age >= REBUILD_EVERY) {
        sm__bvh_free(&c->bvh);
        c->bvh_age = -1;
        sm_status st = sm__bvh_build_boxes(&c->view, &c->bvh, err);
        if (st != SM_OK)
            return st;
        c->bvh_age = 0;
    } else {
        sm__bvh_refit(&c->bvh);
        c->bvh_age++;
    }
    const sm_bvh bvh = c->bvh;
    int failed = 0;
#pragma omp parallel reduction(| : failed) if (c->nd > CORRESPOND_PARALLEL_MIN)
    {
        sm_bvh_entry *stack = malloc((size_t)(2 * bvh.depth + 2) * sizeof *stack);
        failed |= !stack;
#pragma omp for schedule(dynamic, 512)
        for (int64_t i = 0; i < c->nd; i++) {
            if (!stack)
                continue;
            double p[3] = {0, 0, 0};
            memcpy(p, c->dy + i * dim, (size_t)dim * sizeof *p);
            int32_t h = c->cfacet[i];
            sm__bvh_nearest(&bvh, p, &h, stack);
            c->cfacet[i] = h;
            const int32_t *v = c->afacets + (size_t)h * dim;
            const double *a = coords + (size_t)v[0] * dim, *b = coords + (size_t)v[1] * dim;
            double *bary = c->cbary + i * dim, d2;
            if (dim == 3) {
                d2 = sm__triangle_closest(p, a, b, coords + (size_t)v[2] * 3, bary);
            } else {
                double t;
                d2 = sm__segment_closest(p, a, b, 2, &t);
                bary[0] = 1 - t, bary[1] = t;
            }
            c->cdist[i] = sqrt(d2);
        }
        free(stack);
    }
    if (failed)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the distance search");
    double t2 = 0;
    for (int64_t i = 0; i < c->nd; i++) {
        double e = excess(c, c->cdist[i]);
        t2 += c->dw[i] * e * e;
    }
    *term = t2;
    side_figures(c->nd, c->cdist, c->dw, 0, NULL, fig);
    if (isnan(fig->p99))
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the distance figures");
    return SM_OK;
}

void sm__coverage_add_load(const sm_coverage *c, const double *coords, double weight,
                           double *load)
{
    const int dim = c->dim;
    for (int64_t i = 0; i < c->nd; i++) {
        double p[3];
        if (!(c->cdist[i] > c->dead))
            continue;
        corresponding_point(c, coords, i, p);
        /* the gradient of (|y - p| - delta)^2: the factor e / |y - p| */
        double f = excess(c, c->cdist[i]) / c->cdist[i];
        const int32_t *v = c->afacets + (size_t)c->cfacet[i] * dim;
        const double *b = c->cbary + i * dim;
        const double *y = c->dy + i * dim;
        for (int j = 0; j < dim; j++)
            for (int k = 0; k < dim; k++)
                load[(size_t)v[j] * dim + k] += 2 * weight * f * c->dw[i] * b[j] * (y[k] - p[k]);
    }
}

void sm__coverage_spread(sm_coverage *c, const double *load, double *out, int passes)
{
    const int dim = c->dim;
    const int32_t nv = c->m->nverts;
    memcpy(out, load, (size_t)nv * dim * sizeof *out);
    for (int p = 0; p < passes; p++) {
        double *src = c->spread_tmp;
        memcpy(src, out, (size_t)nv * dim * sizeof *src);
        memset(out, 0, (size_t)nv * dim * sizeof *out);
        for (int32_t v = 0; v < nv; v++) {
            int32_t a = c->adj_start[v], b = c->adj_start[v + 1];
            double share = 1.0 / (double)(b - a + 1);
            for (int k = 0; k < dim; k++) {
                double x = src[(size_t)v * dim + k] * share;
                out[(size_t)v * dim + k] += x;
                for (int32_t j = a; j < b; j++)
                    out[(size_t)c->adj[j] * dim + k] += x;
            }
        }
    }
}
