/* The generated background mesh (sm_sdf.h): a Kuhn subdivision of a
 * uniform grid.  The vertex of grid node (i, j, k) is i + nx' (j + ny' k)
 * with nx' = nx + 1 points per row. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "shapematch/sm_mesh.h"
#include "shapematch/sm_sdf.h"

/* the 6 axis orders of the Kuhn tetrahedra */
static const int kuhn3[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};

static int32_t node_id(const int64_t *np, const int64_t *ijk, int dim)
{
    return (int32_t)(ijk[0] + np[0] * (ijk[1] + (dim == 3 ? np[1] * ijk[2] : 0)));
}

static void cell_elements(sm_mesh *m, const int64_t *np, const int64_t *c, int32_t *e)
{
    int dim = m->dim;
    int nperm = dim == 3 ? 6 : 2;
    for (int t = 0; t < nperm; t++) {
        int64_t ijk[3] = {c[0], c[1], dim == 3 ? c[2] : 0};
        int32_t *v = m->elems + (size_t)(*e) * (dim + 1);
        v[0] = node_id(np, ijk, dim);
        for (int s = 0; s < dim; s++) {
            ijk[dim == 3 ? kuhn3[t][s] : (t + s) % 2]++;
            v[s + 1] = node_id(np, ijk, dim);
        }
        (*e)++;
    }
}

sm_status sm_background_new(int dim, const double *lo, const double *hi, double h,
                            sm_mesh **out, sm_error *err)
{
    *out = NULL;
    if ((dim != 2 && dim != 3) || !(h > 0) || !isfinite(h))
        return sm_error_set(err, SM_ERR_INVALID, "background: bad dimension or size %g", h);
    int64_t n[3] = {1, 1, 1}, np[3] = {2, 2, 2};
    double total = 1;
    for (int k = 0; k < dim; k++) {
        double len = hi[k] - lo[k];
        if (!(len > 0) || !isfinite(len))
            return sm_error_set(err, SM_ERR_INVALID, "background: empty box along axis %d", k);
        double cells = ceil(len / h);
        if (cells > 1e6)
            cells = 1e6;
        n[k] = (int64_t)(cells < 1 ? 1 : cells);
        np[k] = n[k] + 1;
        total *= (double)np[k];
    }
    if (total > SM_BACKGROUND_MAX_VERTS)
        return sm_error_set(err, SM_ERR_INVALID,
                            "background of size %g would have %.3g vertices (limit %d): give "
                            "a larger --background-size", h, total, SM_BACKGROUND_MAX_VERTS);
    int64_t ncells = n[0] * n[1] * (dim == 3 ? n[2] : 1);
    sm_mesh *m;
    sm_status st = sm_mesh_alloc(&m, dim, (int32_t)total, (int32_t)(ncells * (dim == 3 ? 6 : 2)),
                                 0, err);
    if (st != SM_OK)
        return st;
    int64_t kmax = dim == 3 ? np[2] : 1;
    for (int64_t k = 0; k < kmax; k++)
        for (int64_t j = 0; j < np[1]; j++)
            for (int64_t i = 0; i < np[0]; i++) {
                int64_t ijk[3] = {i, j, k};
                double *x = m->coords + (size_t)node_id(np, ijk, dim) * dim;
                for (int a = 0; a < dim; a++)
                    x[a] = ijk[a] == n[a] ? hi[a] : lo[a] + (hi[a] - lo[a]) * (double)ijk[a] / (double)n[a];
            }
    int32_t e = 0;
    for (int64_t k = 0; k < (dim == 3 ? n[2] : 1); k++)
        for (int64_t j = 0; j < n[1]; j++)
            for (int64_t i = 0; i < n[0]; i++) {
                int64_t c[3] = {i, j, k};
                cell_elements(m, np, c, &e);
            }
    *out = m;
    return SM_OK;
}

/* ---- graded background ----
 * An octree (quadtree) of boxes over the padded box: n[k] coarse cells
 * per axis of about h 2^L, each refined while it is within its own size
 * of the surface (distance from its center < half its diagonal + its
 * largest side), down to level L (cells of about h).  With that rule two
 * face neighbours differ by at most one level (the distance is
 * 1-Lipschitz), so no explicit balance pass is needed.  Corners live on
 * the lattice of the finest level, where they are deduplicated; a corner
 * of a fine cell in the middle of a coarse cell's face is a hanging
 * vertex (non-conforming, which the field accepts).  Leaves are Kuhn
 * split like the uniform grid's cells. */

typedef struct graded_cell {
    int64_t c[3]; /* lower corner on the finest lattice */
    int level;
} graded_cell;

typedef struct graded {
    int dim, L;
    int64_t n[3], np[3]; /* coarse cells per axis; finest lattice points per axis */
    double lo[3], hi[3];
    graded_cell *leaf;
    int64_t nleaf, capleaf;
} graded;

static double lattice_x(const graded *g, int k, int64_t i)
{
    int64_t last = g->np[k] - 1;
    return i == last ? g->hi[k] : g->lo[k] + (g->hi[k] - g->lo[k]) * (double)i / (double)last;
}

static int push_cell(graded_cell **a, int64_t *na, int64_t *cap, graded_cell c)
{
    if (*na == *cap) {
        int64_t nc = *cap ? 2 * *cap : 1024;
        graded_cell *b = realloc(*a, (size_t)nc * sizeof *b);
        if (!b)
            return -1;
        *a = b;
        *cap = nc;
    }
    (*a)[(*na)++] = c;
    return 0;
}

/* One level: the cells near the surface go to *next as their 2^dim
 * children, the others become leaves. */
static sm_status refine_level(graded *g, sm_distance_fn fn, void *user, const graded_cell *cur,
                              int64_t ncur,
                              graded_cell **next, int64_t *nnext, int64_t *capnext,
                              sm_error *err)
{
    int dim = g->dim;
    double *ctr = malloc(((size_t)ncur * dim + 1) * sizeof *ctr);
    double *dist = malloc(((size_t)ncur + 1) * sizeof *dist);
    sm_status st = SM_OK;
    if (!ctr || !dist) {
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory for the background");
        goto done;
    }
    for (int64_t i = 0; i < ncur; i++) {
        int64_t w = (int64_t)1 << (g->L - cur[i].level);
        for (int k = 0; k < dim; k++)
            ctr[i * dim + k] = (lattice_x(g, k, cur[i].c[k]) + lattice_x(g, k, cur[i].c[k] + w)) / 2;
    }
    fn(user, ncur, ctr, dist);
    for (int64_t i = 0; i < ncur && st == SM_OK; i++) {
        int64_t w = (int64_t)1 << (g->L - cur[i].level);
        double half2 = 0, side = 0;
        for (int k = 0; k < dim; k++) {
            double e = lattice_x(g, k, cur[i].c[k] + w) - lattice_x(g, k, cur[i].c[k]);
            half2 += e * e / 4;
            side = fmax(side, e);
        }
        int split = cur[i].level < g->L && dist[i] < sqrt(half2) + side;
        int fail = 0;
        if (!split)
            fail = push_cell(&g->leaf, &g->nleaf, &g->capleaf, cur[i]);
        for (int ch = 0; split && ch < (1 << dim); ch++) {
            graded_cell c = cur[i];
            c.level++;
            for (int k = 0; k < dim; k++)
                c.c[k] += (ch >> k) & 1 ? w / 2 : 0;
            fail |= push_cell(next, nnext, capnext, c);
        }
        if (fail)
            st = sm_error_set(err, SM_ERR_NOMEM, "out of memory for the background");
    }
done:
    free(ctr);
    free(dist);
    return st;
}

static sm_status graded_leaves(graded *g, sm_distance_fn fn, void *user, sm_error *err)
{
    graded_cell *cur = NULL, *next = NULL;
    int64_t ncur = 0, capcur = 0, nnext = 0, capnext = 0;
    sm_status st = SM_OK;
    int64_t w = (int64_t)1 << g->L;
    for (int64_t k = 0; k < (g->dim == 3 ? g->n[2] : 1) && st == SM_OK; k++)
        for (int64_t j = 0; j < g->n[1] && st == SM_OK; j++)
            for (int64_t i = 0; i < g->n[0]; i++)
                if (push_cell(&cur, &ncur, &capcur, (graded_cell){{i * w, j * w, k * w}, 0})) {
                    st = sm_error_set(err, SM_ERR_NOMEM, "out of memory for the background");
                    break;
                }
    while (st == SM_OK && ncur > 0) {
        nnext = 0;
        st = refine_level(g, fn, user, cur, ncur, &next, &nnext, &capnext, err);
        graded_cell *t = cur;
        cur = next;
        next = t;
        int64_t tc = capcur;
        capcur = capnext;
        capnext = tc;
        ncur = nnext;
        if (st == SM_OK && g->nleaf + ncur > SM_BACKGROUND_MAX_VERTS)
            st = sm_error_set(err, SM_ERR_INVALID,
                              "graded background: more than %d cells: give a larger "
                              "--background-size", SM_BACKGROUND_MAX_VERTS);
    }
    free(cur);
    free(next);
    return st;
}

static int cmp_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

static uint64_t lattice_key(const graded *g, const int64_t *ijk)
{
    return (uint64_t)ijk[0] +
           (uint64_t)g->np[0] * ((uint64_t)ijk[1] + (uint64_t)g->np[1] * (uint64_t)ijk[2]);
}

static int32_t key_index(const uint64_t *keys, int64_t n, uint64_t key)
{
    int64_t a = 0, b = n;
    while (b - a > 1) {
        int64_t m = a + (b - a) / 2;
        if (keys[m] <= key)
            a = m;
        else
            b = m;
    }
    return (int32_t)a;
}

/* Sorted unique corner keys of the leaves. */
static sm_status graded_corners(const graded *g, uint64_t **keys, int64_t *nkeys, sm_error *err)
{
    int dim = g->dim, nc = 1 << dim;
    uint64_t *k = malloc(((size_t)g->nleaf * nc + 1) * sizeof *k);
    if (!k)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the background");
    for (int64_t i = 0; i < g->nleaf; i++) {
        int64_t w = (int64_t)1 << (g->L - g->leaf[i].level);
        for (int ch = 0; ch < nc; ch++) {
            int64_t ijk[3] = {0, 0, 0};
            for (int a = 0; a < dim; a++)
                ijk[a] = g->leaf[i].c[a] + ((ch >> a) & 1 ? w : 0);
            k[i * nc + ch] = lattice_key(g, ijk);
        }
    }
    int64_t n = g->nleaf * nc, u = 0;
    qsort(k, (size_t)n, sizeof *k, cmp_u64);
    for (int64_t i = 0; i < n; i++)
        if (u == 0 || k[i] != k[u - 1])
            k[u++] = k[i];
    *keys = k;
    *nkeys = u;
    return SM_OK;
}

static void graded_fill(const graded *g, const uint64_t *keys, int64_t nkeys, sm_mesh *m)
{
    int dim = g->dim;
    for (int64_t v = 0; v < nkeys; v++) {
        uint64_t key = keys[v];
        int64_t ijk[3] = {(int64_t)(key % (uint64_t)g->np[0]),
                          (int64_t)(key / (uint64_t)g->np[0] % (uint64_t)g->np[1]),
                          (int64_t)(key / (uint64_t)g->np[0] / (uint64_t)g->np[1])};
        for (int a = 0; a < dim; a++)
            m->coords[v * dim + a] = lattice_x(g, a, ijk[a]);
    }
    int nperm = dim == 3 ? 6 : 2;
    for (int64_t i = 0; i < g->nleaf; i++) {
        int64_t w = (int64_t)1 << (g->L - g->leaf[i].level);
        for (int t = 0; t < nperm; t++) {
            int64_t ijk[3] = {g->leaf[i].c[0], g->leaf[i].c[1], dim == 3 ? g->leaf[i].c[2] : 0};
            int32_t *v = m->elems + (size_t)(i * nperm + t) * (dim + 1);
            v[0] = key_index(keys, nkeys, lattice_key(g, ijk));
            for (int s = 0; s < dim; s++) {
                ijk[dim == 3 ? kuhn3[t][s] : (t + s) % 2] += w;
                v[s + 1] = key_index(keys, nkeys, lattice_key(g, ijk));
            }
        }
    }
}

/* Levels and coarse cells: L as large as keeps at least about 2 coarse
 * cells along the longest axis. */
static sm_status graded_setup(graded *g, int dim, const double *lo, const double *hi, double h,
                              sm_error *err)
{
    double longest = 0;
    for (int k = 0; k < dim; k++) {
        double len = hi[k] - lo[k];
        if (!(len > 0) || !isfinite(len))
            return sm_error_set(err, SM_ERR_INVALID, "background: empty box along axis %d", k);
        longest = fmax(longest, len);
    }
    g->dim = dim;
    g->L = 0;
    while (g->L < 20 && h * (double)((int64_t)1 << (g->L + 1)) <= longest / 2)
        g->L++;
    double coarse = h * (double)((int64_t)1 << g->L), lattice = 1, coarse_cells = 1;
    for (int k = 0; k < 3; k++) {
        /* counted in doubles and bounded before any becomes an integer: a
         * tiny size (1e-300) gives counts no int64_t holds, and their
         * conversion and shift would be undefined */
        double cells = k < dim ? fmax(1, ceil((hi[k] - lo[k]) / coarse)) : 1;
        coarse_cells *= cells;
        lattice *= k < dim ? cells * (double)((int64_t)1 << g->L) + 1 : 1;
        if (!(coarse_cells <= SM_BACKGROUND_MAX_VERTS) || !(lattice <= 4e18))
            return sm_error_set(err, SM_ERR_INVALID,
                                "background of size %g is too fine for its box: give a larger "
                                "--background-size", h);
        g->lo[k] = k < dim ? lo[k] : 0;
        g->hi[k] = k < dim ? hi[k] : 0;
        g->n[k] = (int64_t)cells;
        g->np[k] = k < dim ? (g->n[k] << g->L) + 1 : 1;
    }
    return SM_OK;
}

/* sm_sdf_distance as an sm_distance_fn */
static void sdf_distance(void *user, int64_t n, const double *pts, double *dist)
{
    sm_sdf_distance(user, n, pts, dist, NULL);
}

sm_status sm_background_graded_new(int dim, const double *lo, const double *hi, double h,
                                   const sm_sdf *d, sm_mesh **out, sm_error *err)
{
    return sm_background_graded_fn_new(dim, lo, hi, h, sdf_distance, (void *)d, out, err);
}

sm_status sm_background_graded_fn_new(int dim, const double *lo, const double *hi, double h,
                                      sm_distance_fn fn, void *user, sm_mesh **out,
                                      sm_error *err)
{
    *out = NULL;
    if ((dim != 2 && dim != 3) || !(h > 0) || !isfinite(h))
        return sm_error_set(err, SM_ERR_INVALID, "background: bad dimension or size %g", h);
    graded g;
    memset(&g, 0, sizeof g);
    uint64_t *keys = NULL;
    int64_t nkeys = 0;
    sm_status st = graded_setup(&g, dim, lo, hi, h, err);
    if (st == SM_OK)
        st = graded_leaves(&g, fn, user, err);
    if (st == SM_OK)
        st = graded_corners(&g, &keys, &nkeys, err);
    int64_t nel = g.nleaf * (dim == 3 ? 6 : 2);
    if (st == SM_OK && (nkeys > SM_BACKGROUND_MAX_VERTS || nel > INT32_MAX))
        st = sm_error_set(err, SM_ERR_INVALID,
                          "graded background of size %g would have %lld vertices (limit %d): "
                          "give a larger --background-size", h, (long long)nkeys,
                          SM_BACKGROUND_MAX_VERTS);
    if (st == SM_OK)
        st = sm_mesh_alloc(out, dim, (int32_t)nkeys, (int32_t)nel, 0, err);
    if (st == SM_OK)
        graded_fill(&g, keys, nkeys, *out);
    free(keys);
    free(g.leaf);
    return st;
}
