/* The signed distance on the label map's crop grid (sm_image_target.h's
 * sm__image_distance_field, for sm_image_sdf.c): exact at the sites (the
 * corners of the cells the surface crosses), through the nearest site's
 * nearest surface point beyond (sm_edt.h's nearest-site transform), the
 * band's voxels lowered by their site's cell's triangles. */
#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

#include "sm_bvh.h"
#include "sm_edt.h"
#include "sm_image_march.h"
#include "sm_image_target.h"

/* A triangle's bounds made once for the several corners that test it. */
typedef struct tri_bounds {
    const double *a, *b, *c;
    double lo[3], hi[3], nrm[3];
    double inn; /* (1 - 1e-9) / |nrm|^2, 0 for a degenerate triangle */
} tri_bounds;

static void tri_bounds_make(const sm_surface *s, int32_t f, tri_bounds *tb)
{
    const int32_t *v = s->facets + 3 * f;
    const double *a = s->coords + 3 * v[0], *b = s->coords + 3 * v[1], *c = s->coords + 3 * v[2];
    tb->a = a;
    tb->b = b;
    tb->c = c;
    for (int r = 0; r < 3; r++) {
        double lo = a[r] < b[r] ? a[r] : b[r], hi = a[r] < b[r] ? b[r] : a[r];
        tb->lo[r] = c[r] < lo ? c[r] : lo;
        tb->hi[r] = c[r] > hi ? c[r] : hi;
    }
    double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    double w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    tb->nrm[0] = u[1] * w[2] - u[2] * w[1];
    tb->nrm[1] = u[2] * w[0] - u[0] * w[2];
    tb->nrm[2] = u[0] * w[1] - u[1] * w[0];
    double nn = tb->nrm[0] * tb->nrm[0] + tb->nrm[1] * tb->nrm[1] + tb->nrm[2] * tb->nrm[2];
    tb->inn = nn > 0 ? (1 - 1e-9) / nn : 0;
}

/* *best2, *bestf lowered to triangle f (bounds e) when nearer. */
static inline void tri_nearest(const tri_bounds *e, int32_t f, const double *p, double *best2,
                               int32_t *bestf)
{
    double box2 = 0;
    for (int row = 0; row < 3; row++) {
        double g = p[row] < e->lo[row]   ? e->lo[row] - p[row]
                   : p[row] > e->hi[row] ? p[row] - e->hi[row]
                                         : 0;
        box2 += g * g;
    }
    if (box2 >= *best2)
        return;
    double h = e->nrm[0] * (p[0] - e->a[0]) + e->nrm[1] * (p[1] - e->a[1]) +
               e->nrm[2] * (p[2] - e->a[2]);
    if (h * h * e->inn >= *best2)
        return;
    double w[3], d2 = sm__triangle_closest(p, e->a, e->b, e->c, w);
    if (d2 < *best2) {
        *best2 = d2;
        *bestf = f;
    }
}

/* *best2, *bestf lowered to crossed cell ct's triangles: its first cnt
 * by their bounds tb, the rest (a cell of more triangles than a cell can
 * make) without. */
static inline void cell_nearest(const sm_image_target *t, const cell_tris *ct, const tri_bounds *tb,
                                int32_t cnt, const double *p, double *best2, int32_t *bestf)
{
    for (int32_t q = 0; q < cnt; q++)
        tri_nearest(tb + q, ct->first + q, p, best2, bestf);
    if (ct->count > cnt)
        sm__image_range_nearest(t, ct->first + cnt, ct->count - cnt, p, best2, bestf);
}

/* The nearest point of every site among the triangles of the crossed
 * cells it is a corner of (best2, bestf: INFINITY, -1 on entry), cell
 * by cell: node plane z takes the four corners in it of the cells of
 * slices z - 1 and z, planes in parallel (a site is in one plane only),
 * each triangle's bounds made once for its four corners. */
static void corner_nearest(const sm_image_target *t, const int32_t *near, double *best2,
                           int32_t *bestf)
{
    const int64_t *n = t->n;
    const sm_surface *sf = t->surface;
#pragma omp parallel for schedule(dynamic, 1)
    for (int64_t z = 0; z < n[2]; z++) {
        tri_bounds tb[12]; /* a cell's: 6 tetrahedra, at most 2 each */
        for (int up = 0; up < 2; up++) {
            int64_t k = z - up;
            if (k < 0 || k >= n[2] - 1)
                continue;
            for (int64_t r = t->slice_cells[k]; r < t->slice_cells[k + 1]; r++) {
                const cell_tris *ct = t->cells + r;
                int32_t cnt = ct->count < 12 ? ct->count : 12;
                for (int32_t q = 0; q < cnt; q++)
                    tri_bounds_make(sf, ct->first + q, tb + q);
                int64_t i0 = ct->cell % n[0], j0 = (ct->cell / n[0]) % n[1];
                for (int corner = 0; corner < 4; corner++) {
                    int64_t i = i0 + (corner & 1), j = j0 + (corner >> 1);
                    int32_t site = near[i + n[0] * (j + n[1] * z)];
                    double p[3], b2 = best2[site];
                    int32_t bf = bestf[site];
                    sm__grid_world(t->map, (double)i, (double)j, (double)z, p);
                    cell_nearest(t, ct, tb, cnt, p, &b2, &bf);
                    best2[site] = b2;
                    bestf[site] = bf;
                }
            }
        }
    }
}

/* The nearest surface point of the voxel centre at ijk, a corner of a
 * cell the surface passes through, and its triangle *tri, from the
 * nearest among the (up to) 8 cells around it (best2, bestf:
 * corner_nearest's): every other cell is at least one index step away,
 * smin in the world, so a point nearer than that is the nearest; one
 * nearer than 3 smin: the cells within two steps whose gap (t->step)
 * and then whose triangles' box is nearer; else the general search. */
static void site_foot(const sm_image_target *t, const int32_t *ijk, double best2, int32_t bestf,
                      double *foot, int32_t *tri)
{
    double x[3];
    sm__grid_world(t->map, ijk[0], ijk[1], ijk[2], x);
    const sm_surface *s = t->surface;
    double w[3];
    double s2 = t->smin * t->smin, st2[3];
    for (int a = 0; a < 3; a++)
        st2[a] = t->step[a] * t->step[a];
    if (bestf >= 0 && best2 > s2 && best2 <= 9 * s2) {
        /* the cells g = (gx, gy, gz) index steps beyond those 8 (at
         * least sqrt(sum (g step)^2) away, step >= smin) nearer than
         * best2, so |g| <= 2 per axis; a cell whose gap is not nearer
         * cannot be */
        for (int gz = -2; gz <= 2; gz++)
            for (int gy = -2; gy <= 2; gy++)
                for (int gx = -2; gx <= 2; gx++) {
                    if (st2[0] * gx * gx + st2[1] * gy * gy + st2[2] * gz * gz >= best2 ||
                        (!gx && !gy && !gz))
                        continue;
                    /* gap g below the block: cell ijk - 1 + g; above: ijk + g */
                    int64_t c[3] = {ijk[0] + gx - (gx <= 0), ijk[1] + gy - (gy <= 0),
                                    ijk[2] + gz - (gz <= 0)};
                    /* gap 0 on an axis: both cells of the block */
                    for (int d = 0; d < 8; d++) {
                        int64_t e[3] = {c[0] + (gx == 0 && (d & 1)), c[1] + (gy == 0 && (d & 2)),
                                        c[2] + (gz == 0 && (d & 4))};
                        if (((d & 1) && gx) || ((d & 2) && gy) || ((d & 4) && gz))
                            continue;
                        if (e[0] < 0 || e[1] < 0 || e[2] < 0 || e[0] >= t->n[0] - 1 ||
                            e[1] >= t->n[1] - 1 || e[2] >= t->n[2] - 1)
                            continue;
                        int64_t cell = e[0] + t->n[0] * (e[1] + t->n[1] * e[2]);
                        sm__cell_nearest(t, sm__cell_triangles(t, cell), x, &best2, &bestf);
                    }
                }
    } else if (bestf < 0 || best2 > s2) {
        sm__image_surface_distance_from(t, x, best2, bestf, foot, tri);
        return;
    }
    *tri = bestf;
    const int32_t *v = s->facets + 3 * bestf;
    const double *a = s->coords + 3 * v[0], *b = s->coords + 3 * v[1], *c = s->coords + 3 * v[2];
    sm__triangle_closest(x, a, b, c, w);
    for (int row = 0; row < 3; row++)
        foot[row] = w[0] * a[row] + w[1] * b[row] + w[2] * c[row];
}

/* Whether voxel (i, j, k) is a site: a corner of a crossed cell. */
static int is_site(const sm_image_target *t, int64_t i, int64_t j, int64_t k)
{
    for (int64_t c = k > 0 ? k - 1 : 0; c <= k && c < t->n[2] - 1; c++)
        for (int64_t b = j > 0 ? j - 1 : 0; b <= j && b < t->n[1] - 1; b++)
            for (int64_t a = i > 0 ? i - 1 : 0; a <= i && a < t->n[0] - 1; a++) {
                int64_t cell = a + t->n[0] * (b + t->n[1] * c);
                if (t->cbits[cell >> 6] >> (cell & 63) & 1)
                    return 1;
            }
    return 0;
}

/* The band's voxels to refine: the voxel, its distance squared so far
 * and the crossed cell of its site's point. */
typedef struct band_voxel {
    int64_t v;
    double best2;
    int32_t cell;
} band_voxel;

typedef struct band_list {
    band_voxel *at;
    int64_t n, cap;
    int fail;
} band_list;

static void band_add(band_list *b, int64_t v, double best2, int32_t cell)
{
    if (b->fail || !sm__image_grow((void **)&b->at, &b->cap, b->n + 1, sizeof *b->at)) {
        b->fail = 1;
        return;
    }
    b->at[b->n++] = (band_voxel){v, best2, cell};
}

/* One slice k of the distance from the sites (distance_field): each
 * voxel's own nearest site and its six neighbours' (their sites' surface
 * points are as near, often nearer: the nearest site by voxel centres is
 * not always the one with the nearest point), the nearest of those
 * points; signed as its own site (first_inside: the first inside
 * site).  below/above: slices k - 1 and k + 1 of sites (NULL beyond the
 * grid); cellof: each site's point's crossed cell; the voxels within the
 * band (t->grid_band) added to band for band_refine. */
static void slice_distance(const sm_image_target *t, int32_t first_inside, const double *foot,
                           const int32_t *cellof, const int32_t *below, const int32_t *slice,
                           const int32_t *above, int64_t k, float *out, band_list *band)
{
    /* the target's fields in locals: the band's calls would make the
     * compiler load them again at every voxel */
    const int64_t n0 = t->n[0], n1 = t->n[1];
    const double m0 = t->map[0], m4 = t->map[4], m8 = t->map[8];
    const double band2 = t->grid_band ? t->band * t->band : -1;
    for (int64_t j = 0; j < n1; j++) {
        /* a neighbour beyond the grid: the row itself (the voxel's own site) */
        const int32_t *row = slice + j * n0;
        const int32_t *nb0 = j > 0 ? row - n0 : row, *nb1 = j + 1 < n1 ? row + n0 : row,
                      *nb2 = below ? below + j * n0 : row, *nb3 = above ? above + j * n0 : row;
        double x[3];
        for (int r = 0; r < 3; r++)
            x[r] = t->map[4 * r + 1] * (double)j + t->map[4 * r + 2] * (double)k + t->map[4 * r + 3];
        float *orow = out + j * n0;
        for (int64_t i = 0; i < n0; i++) {
            double p[3] = {x[0] + m0 * (double)i, x[1] + m4 * (double)i, x[2] + m8 * (double)i};
            /* the neighbours' sites, most often the voxel's own */
            int32_t own = row[i], cand[6] = {i > 0 ? row[i - 1] : own, i + 1 < n0 ? row[i + 1] : own,
                                             nb0[i], nb1[i], nb2[i], nb3[i]};
            const double *q = foot + 3 * (int64_t)own;
            double best = (p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) +
                          (p[2] - q[2]) * (p[2] - q[2]);
            /* most often (far from the surface) all the same site */
            int32_t other = (cand[0] ^ own) | (cand[1] ^ own) | (cand[2] ^ own) |
                            (cand[3] ^ own) | (cand[4] ^ own) | (cand[5] ^ own);
            for (int c = 0; other && c < 6; c++) {
                if (cand[c] == own)
                    continue;
                q = foot + 3 * (int64_t)cand[c];
                double d2 = (p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) +
                            (p[2] - q[2]) * (p[2] - q[2]);
                best = d2 < best ? d2 : best;
            }
            if (best <= band2 && cellof[own] >= 0 && !is_site(t, i, j, k))
                /* within the band: the other triangles of the cell holding
                 * the voxel's own site's point too, later (band_refine);
                 * a site's own point is its nearest already */
                band_add(band, (k * n1 + j) * n0 + i, best, cellof[own]);
            float d = sqrtf((float)best); /* as near as sqrt then rounding */
            orow[i] = own >= first_inside ? -d : d;
        }
    }
}

/* The distances from the sites over the sites themselves (t->edt: each
 * voxel's site, int32, becomes its distance, float), in slabs of slices
 * (several a thread, taken in turn, so that a thread the machine holds
 * back delays only its slab): a slab's slices in order, each written back
 * once the next one is done (no slice is needed after its neighbours
 * are); every slab's first and last slices are copied before anyone
 * writes.  band: one list a slab. */
static sm_status site_distances(sm_image_target *t, int32_t first_inside, const double *foot,
                                const int32_t *cellof, int32_t *near, band_list *band,
                                int slabs, sm_error *err)
{
    const int64_t *n = t->n;
    int64_t plane = n[0] * n[1];
    int threads = omp_get_max_threads();
    /* each slab's first and last slice's sites; two slices of output a thread */
    int32_t *edges = malloc((size_t)slabs * 2 * (size_t)plane * sizeof *edges);
    float *bufs = malloc((size_t)threads * 2 * (size_t)plane * sizeof *bufs);
    if (!edges || !bufs) {
        free(edges);
        free(bufs);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the distance's sites");
    }
#pragma omp parallel num_threads(threads)
    {
#pragma omp for schedule(static)
        for (int sl = 0; sl < slabs; sl++) {
            int64_t k0 = n[2] * sl / slabs, k1 = n[2] * (sl + 1) / slabs;
            int32_t *first = edges + (size_t)(2 * sl) * (size_t)plane, *last = first + plane;
            memcpy(first, near + k0 * plane, (size_t)plane * sizeof *first);
            memcpy(last, near + (k1 - 1) * plane, (size_t)plane * sizeof *last);
        }
        int me = omp_get_thread_num();
        float *buf[2] = {bufs + (size_t)(2 * me) * (size_t)plane,
                         bufs + (size_t)(2 * me + 1) * (size_t)plane};
#pragma omp for schedule(dynamic, 1)
        for (int sl = 0; sl < slabs; sl++) {
            int64_t k0 = n[2] * sl / slabs, k1 = n[2] * (sl + 1) / slabs;
            for (int64_t k = k0; k < k1; k++) {
                const int32_t *below = k == 0 ? NULL
                                       : k == k0 ? edges + (size_t)(2 * sl - 1) * (size_t)plane
                                                 : near + (k - 1) * plane;
                const int32_t *above = k + 1 == n[2] ? NULL
                                       : k + 1 == k1 ? edges + (size_t)(2 * sl + 2) * (size_t)plane
                                                     : near + (k + 1) * plane;
                slice_distance(t, first_inside, foot, cellof, below, near + k * plane, above, k,
                               buf[k & 1], band + sl);
                if (k > k0) /* slice k - 1 is no one's neighbour any more */
                    memcpy(t->edt + (k - 1) * plane, buf[(k - 1) & 1],
                           (size_t)plane * sizeof(float));
            }
            memcpy(t->edt + (k1 - 1) * plane, buf[(k1 - 1) & 1], (size_t)plane * sizeof(float));
        }
    }
    free(edges);
    free(bufs);
    return SM_OK;
}

static int node_inside(const sm_image_target *t, const float *f, double level, const int32_t *ijk)
{
    for (int a = 0; a < 3; a++)
        if (ijk[a] < t->act_lo[a] || ijk[a] > t->act_hi[a])
            return 0;
    return f[ijk[0] + t->n[0] * (ijk[1] + t->n[1] * (int64_t)ijk[2])] >= level;
}

/* The sites: every corner of a crossed cell, numbered node plane by node
 * plane (plane z: the corners in it of the cells of slices z - 1 and z),
 * those outside the surface first (*first_inside: the first inside);
 * *ijk their voxels; near (the crop's voxels): each site's number at its
 * voxel, -1 elsewhere.  A node's side is the marching's: the field
 * against the level within the active box, outside beyond it.  Planes
 * in parallel: marked and counted, then numbered. */
static sm_status collect_sites(const sm_image_target *t, const float *f, double level,
                               int32_t *near, int32_t **ijk, int64_t *nsites,
                               int32_t *first_inside, sm_error *err)
{
    const int64_t *n = t->n;
    int64_t plane = n[0] * n[1];
    int64_t *count = calloc((size_t)(2 * n[2] + 1), sizeof *count); /* outside, inside a plane */
    if (!count)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the distance's sites");
    int32_t *at = NULL;
    for (int pass = 0; pass < 2; pass++) {
#pragma omp parallel for schedule(dynamic, 1)
        for (int64_t z = 0; z < n[2]; z++) {
            if (pass == 0)
                memset(near + z * plane, 0xff, (size_t)plane * sizeof *near); /* -1: none */
            int64_t next[2] = {pass ? count[2 * z] : 0, pass ? count[2 * z + 1] : 0};
            for (int up = 0; up < 2; up++) {
                int64_t k = z - up;
                if (k < 0 || k >= n[2] - 1)
                    continue;
                for (int64_t r = t->slice_cells[k]; r < t->slice_cells[k + 1]; r++) {
                    int64_t i0 = t->cells[r].cell % n[0], j0 = (t->cells[r].cell / n[0]) % n[1];
                    for (int corner = 0; corner < 4; corner++) {
                        int32_t x[3] = {(int32_t)(i0 + (corner & 1)), (int32_t)(j0 + (corner >> 1)),
                                        (int32_t)z};
                        int32_t *v = near + x[0] + n[0] * (x[1] + n[1] * z);
                        if (*v != (pass ? -2 : -1))
                            continue;
                        int in = node_inside(t, f, level, x);
                        if (pass == 0) {
                            *v = -2; /* marked */
                            count[2 * z + in]++;
                            continue;
                        }
                        *v = (int32_t)next[in]++;
                        memcpy(at + 3 * *v, x, sizeof x);
                    }
                }
            }
        }
        if (pass == 0) {
            /* each plane's first number outside, and inside after all
             * those outside */
            int64_t out = 0, in = 0;
            for (int64_t z = 0; z < n[2]; z++)
                in += count[2 * z];
            *first_inside = (int32_t)(in < INT32_MAX ? in : 0);
            for (int64_t z = 0; z < n[2]; z++) {
                int64_t o = count[2 * z], i = count[2 * z + 1];
                count[2 * z] = out;
                count[2 * z + 1] = in;
                out += o;
                in += i;
            }
            *nsites = in;
            at = in < INT32_MAX ? malloc((size_t)(in > 0 ? in : 1) * 3 * sizeof *at) : NULL;
            if (!at) {
                free(count);
                return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the distance's sites");
            }
        }
    }
    free(count);
    *ijk = at;
    return SM_OK;
}

/* The band's voxels (the threads' lists) lowered to the nearest of the
 * triangles of the cell holding their site's point (the surface around
 * that point, where a nearer one most often is): each list (a slab's
 * voxels, so cells mostly its own) sorted by cell, lists in parallel,
 * then cell by cell, each triangle's bounds made once for all the
 * cell's voxels. */
static sm_status band_refine(sm_image_target *t, const band_list *band, int lists, sm_error *err)
{
    int fail = 0;
    for (int k = 0; k < lists; k++)
        fail |= band[k].fail;
    if (fail)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the distance's band");
    const int64_t *n = t->n;
    const sm_surface *sf = t->surface;
    /* each thread its own list (its slab's voxels), sorted by cell */
#pragma omp parallel for schedule(dynamic, 1) reduction(| : fail)
    for (int k = 0; k < lists; k++) {
        const band_list *b = band + k;
        int64_t *start = calloc((size_t)t->ncells + 1, sizeof *start);
        band_voxel *by = malloc((size_t)(b->n > 0 ? b->n : 1) * sizeof *by);
        if (!start || !by) {
            fail = 1;
            free(start);
            free(by);
            continue;
        }
        for (int64_t e = 0; e < b->n; e++)
            start[b->at[e].cell + 1]++;
        for (int64_t c = 0; c < t->ncells; c++)
            start[c + 1] += start[c];
        for (int64_t e = 0; e < b->n; e++)
            by[start[b->at[e].cell]++] = b->at[e];
        /* start[c] is now cell c's end */
        for (int64_t e = 0; e < b->n;) {
            const cell_tris *ct = t->cells + by[e].cell;
            int64_t end = start[by[e].cell];
            tri_bounds tb[12];
            int32_t cnt = ct->count < 12 ? ct->count : 12;
            for (int32_t q = 0; q < cnt; q++)
                tri_bounds_make(sf, ct->first + q, tb + q);
            for (; e < end; e++) {
                int64_t v = by[e].v, i = v % n[0], j = (v / n[0]) % n[1], kz = v / (n[0] * n[1]);
                double p[3], b2 = by[e].best2;
                int32_t bf = -1;
                sm__grid_world(t->map, (double)i, (double)j, (double)kz, p);
                cell_nearest(t, ct, tb, cnt, p, &b2, &bf);
                if (bf >= 0) {
                    float d = sqrtf((float)b2);
                    t->edt[v] = t->edt[v] < 0 ? -d : d;
                }
            }
        }
        free(start);
        free(by);
    }
    return fail ? sm_error_set(err, SM_ERR_NOMEM, "out of memory for the distance's band") : SM_OK;
}

/* The signed distance at every crop voxel centre into t->edt: the sites
 * are the corners of the cells the surface passes through (every voxel
 * within a cell of it), each with its exact nearest surface point; every
 * other voxel takes the nearest site's (sm__edt_nearest, on the grid's
 * axis lengths) and its distance to that point, a point of the surface:
 * an upper bound, off by the square of the sites' sideways offset over
 * twice the distance, so the far field is close to exact where the
 * voxel-centre EDT is off by up to a voxel.  The sign: a site's is its
 * node's side of the level (the marching's); every other voxel's is its
 * nearest site's.  A lattice path from the voxel to that site, each step
 * one index towards it, passes only voxels nearer the voxel than the
 * site, so no other site; two neighbours that are not both sites share
 * no crossed cell, so are on one side; so the whole path is.  (No field
 * read at every voxel.)  t->edt holds the sites (int32) until each
 * voxel's float replaces its own. */
sm_status sm__image_distance_field(sm_image_target *t, const float *f, double level, sm_error *err)
{
    const int64_t *n = t->n;
    int32_t *near = (int32_t *)t->edt;
    int32_t *ijk = NULL, first_inside = 0;
    double *foot = NULL;
    int64_t nsites = 0;
    /* the sites outside the surface first: a voxel's sign is its
     * nearest site's (see above) */
    sm_status st = collect_sites(t, f, level, near, &ijk, &nsites, &first_inside, err);
    if (st != SM_OK)
        return st;
    foot = malloc((size_t)nsites * 3 * sizeof *foot);
    int32_t *cellof = malloc((size_t)nsites * sizeof *cellof);
    double *best2 = malloc((size_t)nsites * sizeof *best2);
    int32_t *bestf = malloc((size_t)nsites * sizeof *bestf);
    if (!foot || !cellof || !best2 || !bestf) {
        free(ijk);
        free(foot);
        free(cellof);
        free(best2);
        free(bestf);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the distance's sites");
    }
    for (int64_t k = 0; k < nsites; k++) {
        best2[k] = INFINITY;
        bestf[k] = -1;
    }
    corner_nearest(t, near, best2, bestf);
    /* each foot's cell (the cell that made its triangle), for the band */
#pragma omp parallel for schedule(dynamic, 256)
    for (int64_t k = 0; k < nsites; k++) {
        int32_t tri = -1;
        site_foot(t, ijk + 3 * k, best2[k], bestf[k], foot + 3 * k, &tri);
        cellof[k] = tri < 0 ? -1 : (int32_t)(sm__image_triangle_cell(t, tri) - t->cells);
    }
    free(best2);
    free(bestf);
    st = sm__edt_nearest(n, t->h, ijk, nsites, near, err);
    free(ijk);
    /* slabs of slices for the distances, four a thread */
    int slabs = 4 * omp_get_max_threads();
    slabs = slabs < n[2] ? slabs : (int)n[2];
    band_list *band = calloc((size_t)slabs, sizeof *band);
    if (st == SM_OK && !band)
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory for the distance's band");
    if (st == SM_OK)
        st = site_distances(t, first_inside, foot, cellof, near, band, slabs, err);
    free(foot);
    free(cellof);
    if (st == SM_OK)
        st = band_refine(t, band, slabs, err);
    for (int k = 0; band && k < slabs; k++)
        free(band[k].at);
    free(band);
    return st;
}

