/* Marching tetrahedra on the voxel centres (sm_image_march.h): Kuhn's 6
 * tetrahedra per cell, the vertices on the grid's edges shared through a
 * hash of the edges, the cells the level crosses found in parallel and
 * marched in parallel chunks of whole slices, joined. */
#include "sm_image_march.h"

#include <omp.h>
#include <stdlib.h>
#include <string.h>

static const int kuhn[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};

int sm__image_grow(void **p, int64_t *cap, int64_t need, size_t size)
{
    if (need <= *cap)
        return 1;
    int64_t c = *cap ? *cap : 1024;
    while (c < need)
        c *= 2;
    void *q = realloc(*p, (size_t)c * size);
    if (!q)
        return 0;
    *p = q;
    *cap = c;
    return 1;
}

/* The slot of key in an edge hash of cap slots (a power of two): where
 * it is, or the empty slot where it goes (linear probing). */
static int64_t edge_slot(const int64_t *keys, int64_t cap, int64_t key)
{
    uint64_t hsh = (uint64_t)key * 0x9E3779B97F4A7C15ull;
    int64_t t = (int64_t)(hsh >> 20) & (cap - 1);
    while (keys[t] && keys[t] != key)
        t = (t + 1) & (cap - 1);
    return t;
}

static int rehash(mt_builder *b)
{
    int64_t cap = b->hcap ? b->hcap * 2 : 1 << 16;
    int64_t *keys = calloc((size_t)cap, sizeof *keys);
    int32_t *vals = malloc((size_t)cap * sizeof *vals);
    if (!keys || !vals) {
        free(keys);
        free(vals);
        return 0;
    }
    for (int64_t s = 0; s < b->hcap; s++) {
        if (!b->keys[s])
            continue;
        int64_t t = edge_slot(keys, cap, b->keys[s]);
        keys[t] = b->keys[s];
        vals[t] = b->vals[s];
    }
    free(b->keys);
    free(b->vals);
    b->keys = keys;
    b->vals = vals;
    b->hcap = cap;
    return 1;
}

/* The surface vertex on the edge of nodes p (inside) and q (outside),
 * shared by every tetrahedron on that edge. */
static int32_t edge_vertex(mt_builder *b, int64_t p, int64_t q)
{
    int64_t lo = p < q ? p : q, hi = p < q ? q : p;
    int64_t key = lo * 27 + (hi - lo <= 1 ? 0 : hi - lo == b->n[0] ? 1 : hi - lo == b->n[0] + 1 ? 2
                             : hi - lo == b->n[0] * b->n[1] ? 3 : hi - lo == b->n[0] * b->n[1] + 1 ? 4
                             : hi - lo == b->n[0] * b->n[1] + b->n[0] ? 5 : 6) + 1;
    if (2 * (b->nv + 1) > b->hcap && !rehash(b)) {
        b->fail = 1;
        return 0;
    }
    int64_t t = edge_slot(b->keys, b->hcap, key);
    if (b->keys[t])
        return b->vals[t];
    if (!sm__image_grow((void **)&b->coords, &b->capv, 3 * (b->nv + 1), sizeof(double)) || b->nv >= INT32_MAX) {
        b->fail = 1;
        return 0;
    }
    /* interpolated from the lower node, so the same on every side */
    double fl = b->f[lo], fh = b->f[hi], s = (b->level - fl) / (fh - fl);
    double ijk[3];
    for (int a = 0; a < 3; a++) {
        int64_t stride = a == 0 ? 1 : a == 1 ? b->n[0] : b->n[0] * b->n[1];
        double il = (double)((lo / stride) % b->n[a]), ih = (double)((hi / stride) % b->n[a]);
        ijk[a] = il + s * (ih - il);
    }
    sm__grid_world(b->map, ijk[0], ijk[1], ijk[2], b->coords + 3 * b->nv);
    b->keys[t] = key;
    b->vals[t] = (int32_t)b->nv;
    return (int32_t)b->nv++;
}

/* Triangle (a, b, c) turned so that its normal points away from the
 * inside node pin (world position). */
static void add_tri(mt_builder *b, int32_t v0, int32_t v1, int32_t v2, const double *pin)
{
    if (b->fail || !sm__image_grow((void **)&b->tris, &b->capt, 3 * (b->nt + 1), sizeof(int32_t)) ||
        !sm__image_grow((void **)&b->tcell, &b->capc, b->nt + 1, sizeof(int64_t)) || b->nt >= INT32_MAX) {
        b->fail = 1;
        return;
    }
    const double *a = b->coords + 3 * v0, *p = b->coords + 3 * v1, *q = b->coords + 3 * v2;
    double u[3], v[3], nrm[3];
    for (int k = 0; k < 3; k++) {
        u[k] = p[k] - a[k];
        v[k] = q[k] - a[k];
    }
    nrm[0] = u[1] * v[2] - u[2] * v[1];
    nrm[1] = u[2] * v[0] - u[0] * v[2];
    nrm[2] = u[0] * v[1] - u[1] * v[0];
    double dot = nrm[0] * (a[0] - pin[0]) + nrm[1] * (a[1] - pin[1]) + nrm[2] * (a[2] - pin[2]);
    b->tcell[b->nt] = b->cell;
    int32_t *t = b->tris + 3 * b->nt++;
    t[0] = v0;
    t[1] = dot >= 0 ? v1 : v2;
    t[2] = dot >= 0 ? v2 : v1;
}

static void world(const mt_builder *b, int64_t node, double *x)
{
    double ijk[3] = {(double)(node % b->n[0]), (double)((node / b->n[0]) % b->n[1]),
                     (double)(node / (b->n[0] * b->n[1]))};
    sm__grid_world(b->map, ijk[0], ijk[1], ijk[2], x);
}

static void tetra(mt_builder *b, const int64_t v[4])
{
    int64_t in[4], out[4];
    int ni = 0, no = 0;
    for (int k = 0; k < 4; k++) {
        if (b->f[v[k]] >= b->level)
            in[ni++] = v[k];
        else
            out[no++] = v[k];
    }
    if (ni == 0 || no == 0)
        return;
    double pin[3];
    world(b, in[0], pin);
    if (ni == 1 || no == 1) {
        int64_t apex = ni == 1 ? in[0] : out[0];
        const int64_t *others = ni == 1 ? out : in;
        int32_t t[3];
        for (int k = 0; k < 3; k++)
            t[k] = ni == 1 ? edge_vertex(b, apex, others[k]) : edge_vertex(b, others[k], apex);
        add_tri(b, t[0], t[1], t[2], pin);
        return;
    }
    /* two in, two out: the quad in0-out0, in0-out1, in1-out1, in1-out0 */
    int32_t q0 = edge_vertex(b, in[0], out[0]), q1 = edge_vertex(b, in[0], out[1]);
    int32_t q2 = edge_vertex(b, in[1], out[1]), q3 = edge_vertex(b, in[1], out[0]);
    add_tri(b, q0, q1, q2, pin);
    add_tri(b, q0, q2, q3, pin);
}

/* The value of key in b's edge hash, -1 when absent. */
static int32_t find_edge(const mt_builder *b, int64_t key)
{
    if (!b->hcap)
        return -1;
    int64_t t = edge_slot(b->keys, b->hcap, key);
    return b->keys[t] ? b->vals[t] : -1;
}

static void march_cells(mt_builder *b, const int64_t *cells, int64_t ncells)
{
    const int64_t *n = b->n;
    int64_t step[3] = {1, n[0], n[0] * n[1]};
    for (int64_t m = 0; !b->fail && m < ncells; m++) {
        int64_t c = cells[m];
        b->cell = c;
        for (int t = 0; t < 6; t++) {
            int64_t v[4] = {c, 0, 0, 0};
            for (int s = 0; s < 3; s++)
                v[s + 1] = v[s] + step[kuhn[t][s]];
            tetra(b, v);
        }
    }
}

static void builder_free(mt_builder *b)
{
    free(b->coords);
    free(b->tris);
    free(b->keys);
    free(b->vals);
    free(b->tcell);
}

/* The chunks' surfaces joined into b (tcell) and *out, numbered as one
 * march over all their cells in order would: chunk c's first slice of
 * cells, K, shares with chunk c - 1 only the edges in the plane of
 * nodes z = K (chunk c - 2 ends below K - 1), whose vertices chunk c - 1
 * made first; every other vertex of chunk c is new, in its own order. */
static sm_status join_chunks(mt_builder *b, mt_builder *ch, int nch, const int64_t *first_slice,
                             sm_surface **out, sm_error *err)
{
    int64_t sz = b->n[0] * b->n[1], nv = 0, nt = 0;
    int64_t *voff = malloc((size_t)(nch + 1) * sizeof *voff), *toff = malloc((size_t)(nch + 1) * sizeof *toff);
    int32_t **id = calloc((size_t)nch, sizeof *id); /* chunk's vertex -> joined */
    int fail = !voff || !toff || !id;
    for (int c = 0; !fail && c < nch; c++) {
        id[c] = malloc((size_t)(ch[c].nv > 0 ? ch[c].nv : 1) * sizeof **id);
        if (!(fail = !id[c])) {
            for (int64_t v = 0; v < ch[c].nv; v++)
                id[c][v] = -1;
        }
        /* the shared plane's vertices: chunk c - 1's number */
        for (int64_t s = 0; !fail && c > 0 && s < ch[c].hcap; s++) {
            int64_t key = ch[c].keys[s], lo = (key - 1) / 27, type = (key - 1) % 27;
            if (key && lo / sz == first_slice[c] && type <= 2) {
                int32_t prev = find_edge(&ch[c - 1], key);
                if (prev >= 0)
                    id[c][ch[c].vals[s]] = id[c - 1][prev];
            }
        }
        voff[c] = nv;
        toff[c] = nt;
        for (int64_t v = 0; !fail && v < ch[c].nv; v++)
            if (id[c][v] < 0)
                id[c][v] = (int32_t)nv++;
        nt += ch[c].nt;
        fail |= nv > INT32_MAX || nt > INT32_MAX;
    }
    sm_status st = SM_OK;
    if (fail)
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory for the label's surface");
    else if (nt == 0)
        st = sm_error_set(err, SM_ERR_INVALID, "the label has no boundary (empty selection)");
    else if ((b->tcell = malloc((size_t)nt * sizeof *b->tcell)) == NULL)
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory for the label's surface");
    else
        st = sm_surface_alloc(out, 3, (int32_t)nv, (int32_t)nt, err);
    if (st == SM_OK) {
        b->nv = nv;
        b->nt = nt;
        double *x = (*out)->coords;
        int32_t *f = (*out)->facets;
#pragma omp parallel for schedule(dynamic, 1)
        for (int c = 0; c < nch; c++) {
            for (int64_t v = 0; v < ch[c].nv; v++)
                memcpy(x + 3 * (int64_t)id[c][v], ch[c].coords + 3 * v, 3 * sizeof *x);
            for (int64_t t = 0; t < 3 * ch[c].nt; t++)
                f[3 * toff[c] + t] = id[c][ch[c].tris[t]];
            memcpy(b->tcell + toff[c], ch[c].tcell, (size_t)ch[c].nt * sizeof *b->tcell);
        }
    }
    for (int c = 0; id && c < nch; c++)
        free(id[c]);
    free(id);
    free(voff);
    free(toff);
    return st;
}

/* The crossed cells (ncells, in order) marched in chunks of whole
 * slices, in parallel, then joined: four chunks a thread, of about as
 * many cells each (a thread the machine holds back delays only its
 * chunk). */
static sm_status march_chunks(mt_builder *b, const int64_t *cells, int64_t ncells,
                              sm_surface **out, sm_error *err)
{
    int64_t sz = b->n[0] * b->n[1];
    int want = 4 * omp_get_max_threads(), nch = 0;
    int64_t *from = malloc((size_t)(want + 1) * sizeof *from),
            *first_slice = malloc((size_t)(want + 1) * sizeof *first_slice);
    mt_builder *ch = calloc((size_t)want, sizeof *ch);
    sm_status st = SM_OK;
    if (!from || !first_slice || !ch) {
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory for the label's surface");
        want = 0;
    }
    for (int64_t m = 0; m < ncells && nch < want; nch++) {
        from[nch] = m;
        first_slice[nch] = cells[m] / sz;
        int64_t end = ncells * (nch + 1) / want;
        m = end > m + 1 ? end : m + 1;
        while (m < ncells && cells[m] / sz == cells[m - 1] / sz)
            m++;
    }
    if (st == SM_OK) {
        from[nch] = ncells;
        int fail = 0;
#pragma omp parallel for schedule(dynamic, 1) reduction(| : fail)
        for (int c = 0; c < nch; c++) {
            mt_builder *h = ch + c;
            h->f = b->f;
            memcpy(h->n, b->n, sizeof h->n);
            h->lo = b->lo;
            h->hi = b->hi;
            h->level = b->level;
            h->map = b->map;
            /* sized for the chunk's cells (a crossed cell makes about 2
             * vertices and 4 triangles): no growing on the way */
            int64_t m = from[c + 1] - from[c];
            h->hcap = 1 << 16;
            while (h->hcap < 6 * m)
                h->hcap *= 2;
            h->keys = calloc((size_t)h->hcap, sizeof *h->keys);
            h->vals = malloc((size_t)h->hcap * sizeof *h->vals);
            if (!h->keys || !h->vals ||
                !sm__image_grow((void **)&h->coords, &h->capv, 9 * m, sizeof(double)) ||
                !sm__image_grow((void **)&h->tris, &h->capt, 15 * m, sizeof(int32_t)) ||
                !sm__image_grow((void **)&h->tcell, &h->capc, 5 * m, sizeof(int64_t)))
                h->fail = 1;
            march_cells(h, cells + from[c], m);
            fail |= h->fail;
        }
        st = fail ? sm_error_set(err, SM_ERR_NOMEM, "out of memory for the label's surface")
                  : join_chunks(b, ch, nch, first_slice, out, err);
    }
    for (int c = 0; ch && c < want; c++)
        builder_free(ch + c);
    free(ch);
    free(from);
    free(first_slice);
    return st;
}

sm_status sm__image_march(mt_builder *b, sm_surface **out, sm_error *err)
{
    const int64_t *n = b->n;
    int64_t sx = 1, sy = n[0], sz = n[0] * n[1], c0[3], c1[3];
    /* the cells with a corner in the active box: the others have every
     * corner on one side */
    for (int a = 0; a < 3; a++) {
        c0[a] = b->lo[a] > 0 ? b->lo[a] - 1 : 0;
        c1[a] = b->hi[a] < n[a] - 1 ? b->hi[a] : n[a] - 2;
    }
    /* the cells the level crosses, found in parallel a slice at a time
     * (counted, then listed) */
    int64_t slices = c1[2] - c0[2] + 1, *count = calloc((size_t)slices + 1, sizeof *count);
    int64_t *cells = NULL;
    if (!count) {
        b->fail = 1;
        slices = 0;
    }
    for (int pass = 0; pass < 2 && !b->fail; pass++) {
#pragma omp parallel for schedule(dynamic, 1)
        for (int64_t k = c0[2]; k <= c1[2]; k++) {
            int64_t found = 0, *to = pass ? cells + count[k - c0[2]] : NULL;
            for (int64_t j = c0[1]; j <= c1[1]; j++)
                for (int64_t i = c0[0]; i <= c1[0]; i++) {
                    int64_t c = i + sy * j + sz * k;
                    const float *f = b->f + c;
                    int in = 0;
                    in += f[0] >= b->level;
                    in += f[sx] >= b->level;
                    in += f[sy] >= b->level;
                    in += f[sx + sy] >= b->level;
                    in += f[sz] >= b->level;
                    in += f[sx + sz] >= b->level;
                    in += f[sy + sz] >= b->level;
                    in += f[sx + sy + sz] >= b->level;
                    if (in == 0 || in == 8)
                        continue;
                    if (to)
                        to[found] = c;
                    found++;
                }
            if (!pass)
                count[k - c0[2] + 1] = found;
        }
        if (!pass) {
            for (int64_t k = 0; k < slices; k++)
                count[k + 1] += count[k];
            cells = malloc((size_t)(count[slices] > 0 ? count[slices] : 1) * sizeof *cells);
            b->fail = !cells;
        }
    }
    if (b->fail) {
        free(count);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the label's surface");
    }
    sm_status st = march_chunks(b, cells, count[slices], out, err);
    free(cells);
    free(count);
    return st;
}
