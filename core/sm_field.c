/* Target field: P1 values on a background simplicial mesh.
 *
 * Point location, in order:
 *   1. visibility walk from the caller's hint (cross the facet with the
 *      most negative barycentric coordinate), skipped when the hint is far;
 *   2. the bucket grid cell of x: a walk from the cell's seed element (the
 *      one whose bounding box centre is nearest to the cell centre, or for
 *      a cell holding no box centre the seed of the nearest cell that
 *      does), a few steps at most;
 *   3. an exhaustive scan of the cell's list (elements whose bounding box
 *      meets the cell), which is the final answer: walks only stop early
 *      at gaps, overlaps, holes and concavities.
 * Outside points get value(p) + |x - p|, p the nearest point of the mesh,
 * searched over the facets without neighbour binned in the same grid.
 *
 * Per valid element the field keeps its dim+1 neighbour indices and one
 * validity byte, and nothing else: the barycentric coordinates are
 * computed at each walk step from the element's vertices (the inverse of
 * J = [v1-v0 | ... | vd-v0] by cofactors, relative to v0 so that the
 * rounding error stays proportional to the element size even for boxes
 * far from the origin), and the value from the vertex values.  With the
 * grid this comes to about 45 B per tetrahedron on Gmsh meshes
 * (sm_field_get_stats reports it) on top of the mesh the caller keeps.
 * A record of the inverse map, value and gradient per element (128 B a
 * tetrahedron) made a step a third as many instructions, but the field
 * then held 200 B a tetrahedron: 68 MiB for the paper's 345k-tetrahedron
 * background, half the whole run's memory (measured: the 30k-tetrahedron
 * example peaks at 80 MiB instead of 134; its iterations take about 3 ms
 * more each).
 *
 * What an evaluation costs is memory latency more than arithmetic:
 * callers sample points in no particular order, and mesh generators
 * number elements in no spatial order either, so every element a walk
 * visits is likely a cache miss.  Hence the neighbour table sits on huge
 * pages where the system offers them (a TLB miss costs about as much
 * again, in a virtual machine at least), each walk step requests the
 * neighbours of its element before computing with it, so that the misses
 * overlap, and the cell seeds are one array lookup.  The element
 * numbering stays the caller's: an internal renumbering would need a
 * public-to-internal map of the hint, one more miss per call.
 * sm_field_eval_many, for many points with their own hints, keeps
 * several walks in flight so that their misses overlap: a step requests
 * the element's vertex list, then its vertices, then computes.
 *
 * The construction avoids random memory traffic the same way, since the
 * vertex numbering is not spatial either: the adjacency distributes the
 * facets into buckets of their smallest vertex in two rounds of few
 * buckets each, then matches each bucket with a small hash table; whether
 * two elements sharing a facet lie on opposite sides of it comes from the
 * signs of their determinants, with no coordinate access.  The grid
 * lists are filled with the elements sorted by blocks of cells, and their
 * sizes come from a difference array.  The passes over the elements run
 * on the OpenMP threads by fixed chunks, so the structure does not depend
 * on the number of threads.
 *
 * Orientation does not matter (barycentric coordinates are orientation
 * free), flat elements are skipped, and the structure is read-only after
 * sm_field_new: all scratch lives on the caller's stack. */
#include "sm_field_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sm_alloc.h"

/* ------------------------------------------------------------------ */
/* Element validity                                                    */

/* Returns 1 when element e is usable, with *negative set when det J < 0;
 * 0 when it is degenerate: |det J| at most DEGENERATE_REL times its
 * longest edge to the power dim, or an inverse map or gradient that is
 * not finite (what a walk computes from the vertices must be). */
static inline __attribute__((always_inline)) int
element_usable(const sm_field *f, int32_t e, int *negative, const int D)
{
    const int32_t *ev = f->bg->elems + (size_t)e * (size_t)(D + 1);
    const double *p[4];
    for (int k = 0; k <= D; k++)
        p[k] = vcoord(f, ev[k]);
    double hmax2 = 0.0;
    for (int a = 0; a <= D; a++)
        for (int b = a + 1; b <= D; b++) {
            double l2 = 0.0;
            for (int i = 0; i < D; i++) {
                double t = p[b][i] - p[a][i];
                l2 += t * t;
            }
            if (l2 > hmax2)
                hmax2 = l2;
        }
    double cof[3][3];
    double det = elem_cofactors(f->bg->coords, ev, cof, D);
    double hmaxd = D == 2 ? hmax2 : hmax2 * sqrt(hmax2);
    *negative = 0;
    if (!(fabs(det) > DEGENERATE_REL * hmaxd))
        return 0;
    double inv = 1.0 / det, grad[3];
    for (int k = 0; k < D; k++)
        for (int i = 0; i < D; i++)
            if (!isfinite(cof[k][i] * inv))
                return 0;
    elem_gradient(f, e, grad, D);
    for (int i = 0; i < D; i++)
        if (!isfinite(grad[i]))
            return 0;
    *negative = det < 0.0;
    return 1;
}

/* Validity, the counts of the adjacency buckets and the bounding
 * box of the valid elements, in one pass over the elements (in parallel,
 * by chunks: every element writes only its own entries, every chunk its
 * own counts).  The coordinates of the elements a few steps ahead are
 * prefetched: the vertex numbering of mesh generators is rarely local,
 * and each element reads dim+1 scattered vertices. */
static inline __attribute__((always_inline)) void
build_elements_dim(sm_field *f, int shift, size_t *counts, double *lo, double *hi, const int D)
{
    const int32_t ne = f->nelems;
    const int32_t *elems = f->bg->elems;
    const double *coords = f->bg->coords;
    int32_t chunk_valid[BUILD_CHUNKS];
    double chunk_lo[BUILD_CHUNKS][3], chunk_hi[BUILD_CHUNKS][3];
#pragma omp parallel for schedule(static)
    for (int c = 0; c < BUILD_CHUNKS; c++) {
        size_t *my = counts + (size_t)c * ADJ_FANOUT;
        int32_t nvalid = 0, e1 = chunk_begin(ne, c + 1);
        double l[3] = {INFINITY, INFINITY, INFINITY}, h[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (int32_t e = chunk_begin(ne, c); e < e1; e++) {
            if (e + PREFETCH_AHEAD < ne) {
                const int32_t *pv = elems + (size_t)(e + PREFETCH_AHEAD) * (size_t)(D + 1);
                for (int k = 0; k <= D; k++) {
                    __builtin_prefetch(coords + (size_t)pv[k] * (size_t)D);
                    __builtin_prefetch(f->values + pv[k]);
                }
            }
            const int32_t *ev = elems + (size_t)e * (size_t)(D + 1);
            int negative;
            if (!element_usable(f, e, &negative, D)) {
                f->valid[e] = 0;
                continue;
            }
            f->valid[e] = negative ? ELEM_VALID_NEGATIVE : ELEM_VALID_POSITIVE;
            nvalid++;
            /* with s0 < s1 < ... (distinct, or the element would be flat),
             * the facet opposite s0 has smallest vertex s1, the dim others
             * s0 */
            int32_t s[4];
            int loc[4];
            sorted_vertices(ev, D + 1, s, loc);
            my[(uint32_t)s[0] >> shift] += (size_t)D;
            my[(uint32_t)s[1] >> shift] += 1;
            for (int k = 0; k <= D; k++)
                for (int i = 0; i < D; i++) {
                    double x = coords[(size_t)ev[k] * (size_t)D + (size_t)i];
                    l[i] = x < l[i] ? x : l[i];
                    h[i] = x > h[i] ? x : h[i];
                }
        }
        chunk_valid[c] = nvalid;
        memcpy(chunk_lo[c], l, sizeof l);
        memcpy(chunk_hi[c], h, sizeof h);
    }
    f->nvalid = 0;
    for (int i = 0; i < 3; i++) {
        lo[i] = INFINITY;
        hi[i] = -INFINITY;
    }
    for (int c = 0; c < BUILD_CHUNKS; c++) {
        f->nvalid += chunk_valid[c];
        for (int i = 0; i < D; i++) {
            lo[i] = chunk_lo[c][i] < lo[i] ? chunk_lo[c][i] : lo[i];
            hi[i] = chunk_hi[c][i] > hi[i] ? chunk_hi[c][i] : hi[i];
        }
    }
}

/* ------------------------------------------------------------------ */
/* Construction                                                        */

void sm_field_free(sm_field *f)
{
    if (!f)
        return;
    free(f->valid);
    sm__free_large(f->neigh, (size_t)f->nelems * (size_t)(f->dim + 1) * sizeof *f->neigh);
    free(f->cell_seed);
    free(f->elem_start);
    sm__field_lists_free(f->lists);
    free(f->bfacet_id);
    free(f->bfacet_xyz);
    free(f->facet_start);
    free(f->facet_list);
    free(f->cfacet_start);
    free(f->cfacet_list);
    free(f->ftree);
    free(f->ftree_order);
    free(f);
}

sm_status sm_field_new(const sm_mesh *bg, const double *values, sm_field **out,
                       sm_error *err)
{
    if (!out)
        return sm_error_set(err, SM_ERR_INVALID, "sm_field_new: no output pointer");
    *out = NULL;
    if (!bg || !values)
        return sm_error_set(err, SM_ERR_INVALID, "sm_field_new: missing background mesh or values");
    if (bg->dim != 2 && bg->dim != 3)
        return sm_error_set(err, SM_ERR_INVALID,
                            "background mesh dimension %d is not 2 or 3", bg->dim);
    if (bg->nelems <= 0 || bg->nverts <= 0)
        return sm_error_set(err, SM_ERR_INVALID,
                            "background mesh is empty (%ld vertices, %ld elements)",
                            (long)bg->nverts, (long)bg->nelems);
    if (bg->nelems > SM_MAX_ENTITIES || bg->nverts > SM_MAX_ENTITIES)
        return sm_error_set(err, SM_ERR_NOMEM, "background mesh too large");
    if (!bg->coords || !bg->elems)
        return sm_error_set(err, SM_ERR_INVALID, "background mesh has no coordinates or elements");
    const int D = bg->dim;
    for (int32_t v = 0; v < bg->nverts; v++) {
        if (!isfinite(values[v]))
            return sm_error_set(err, SM_ERR_INVALID,
                                "distance value at vertex %ld is not finite (%g)",
                                (long)v + 1, values[v]);
        for (int i = 0; i < D; i++)
            if (!isfinite(bg->coords[(size_t)v * D + i]))
                return sm_error_set(err, SM_ERR_INVALID,
                                    "background vertex %ld has a non-finite coordinate",
                                    (long)v + 1);
    }
    for (size_t i = 0; i < (size_t)bg->nelems * (size_t)(D + 1); i++)
        if (bg->elems[i] < 0 || bg->elems[i] >= bg->nverts)
            return sm_error_set(err, SM_ERR_INVALID,
                                "background element %ld refers to vertex %ld (mesh has %ld)",
                                (long)(i / (size_t)(D + 1)) + 1, (long)bg->elems[i] + 1,
                                (long)bg->nverts);

    sm_field *f = calloc(1, sizeof *f);
    if (!f)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    f->bg = bg;
    f->values = values;
    f->dim = D;
    f->nelems = bg->nelems;
    f->valid = sm__alloc_huge((size_t)bg->nelems);
    if (f->valid)
        memset(f->valid, 0, (size_t)bg->nelems);
    f->neigh = sm__alloc_large((size_t)bg->nelems * (size_t)(D + 1) * sizeof *f->neigh);
    if (!f->valid || !f->neigh) {
        sm_field_free(f);
        return sm_error_set(err, SM_ERR_NOMEM,
                            "out of memory for %ld background elements", (long)bg->nelems);
    }
    /* adjacency buckets: the top ADJ_FANOUT_BITS bits of a vertex index */
    int shift = 0;
    while (((uint32_t)(bg->nverts - 1) >> shift) >= ADJ_FANOUT)
        shift++;
    size_t counts[BUILD_CHUNKS * ADJ_FANOUT];
    memset(counts, 0, sizeof counts);
    double lo[3], hi[3];
    if (D == 2)
        build_elements_dim(f, shift, counts, lo, hi, 2);
    else
        build_elements_dim(f, shift, counts, lo, hi, 3);
    sm_status st = SM_OK;
    if (f->nvalid == 0)
        st = sm_error_set(err, SM_ERR_INVALID,
                          "background mesh has no element of non-zero volume (%ld elements, all degenerate)",
                          (long)bg->nelems);
    if (st == SM_OK)
        st = sm__field_build_adjacency(f, shift, counts, err);
    if (st == SM_OK)
        st = sm__field_build_grids(f, lo, hi, err);
    if (st != SM_OK) {
        sm_field_free(f);
        return st;
    }
    *out = f;
    return SM_OK;
}

int sm_field_dim(const sm_field *f)
{
    return f->dim;
}

void sm_field_get_stats(const sm_field *f, sm_field_stats *st)
{
    memset(st, 0, sizeof *st);
    for (int i = 0; i < 3; i++) {
        st->grid[i] = f->g.n[i];
        st->lo[i] = f->g.lo[i];
        st->hi[i] = f->g.hi[i];
    }
    st->ncells = f->g.ncells;
    st->elem_entries = f->elem_start[f->g.ncells];
    st->max_cell_elems = f->max_cell_elems;
    st->nboundary_facets = f->nbfacets;
    st->facet_entries = f->facet_start[f->g.ncells];
    st->coarse_cells = f->cg.ncells;
    st->coarse_facet_entries = f->cfacet_start[f->cg.ncells];
    st->ndegenerate = f->nelems - f->nvalid;
    size_t ne = (size_t)f->nelems;
    st->bytes = sizeof *f + ne +
                ne * (size_t)(f->dim + 1) * sizeof(int32_t) +
                (size_t)f->nbfacets * (sizeof(int32_t) + (size_t)(f->dim * f->dim) * sizeof(double)) +
                (3 * ((size_t)f->g.ncells + 1) + (size_t)f->cg.ncells + 1) * sizeof(int32_t) +
                (size_t)(st->facet_entries + st->coarse_facet_entries) * sizeof(int32_t) +
                (size_t)f->nftree * sizeof *f->ftree + (size_t)f->nbfacets * sizeof(int32_t) +
                sm__field_lists_bytes(f);
}
