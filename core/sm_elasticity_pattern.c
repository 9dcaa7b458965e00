/* The sparsity pattern of the elastic operator (sm_elasticity_internal.h):
 * the DOF numbering, the vertex adjacency, the CSR patterns of the free x
 * free and free x clamped blocks and the element-to-CSR slot map, built
 * once per topology in O(elements) with counting sorts (no comparison
 * sort, no search). */
#include "sm_alloc.h"
#include "sm_elasticity_internal.h"

#include <stdlib.h>
#include <string.h>

static void *alloc_n(size_t count, size_t size)
{
    return calloc(count ? count : 1, size);
}

/* What sm__elasticity_new needs while it builds the pattern, freed at its
 * end.  Vertices are FREE (dim unknowns), CLAMPED (Dirichlet values) or
 * UNUSED (in no element: no unknown, treated like clamped ones). */
enum { VERTEX_FREE = 0, VERTEX_CLAMPED = 1, VERTEX_UNUSED = 2 };
typedef struct setup_scratch {
    uint8_t *kind;          /* nverts: VERTEX_* */
    int32_t *clamped_first; /* nverts: a clamped vertex's first clamped DOF
                             * (index into clamped_global), else -1 */
    int64_t *elem_ptr;      /* nverts+1: the elements of each vertex */
    int32_t *elem_list;
    int64_t *nb_ptr;        /* nverts+1: the neighbours of each free vertex */
    int32_t *nb_list;       /* (itself included) in increasing order */
    int32_t *mark;          /* nverts: marks, then ranks (build_slot_map) */
} setup_scratch;

static void setup_scratch_free(setup_scratch *sc)
{
    free(sc->kind);
    free(sc->clamped_first);
    free(sc->elem_ptr);
    free(sc->elem_list);
    free(sc->nb_ptr);
    free(sc->nb_list);
    free(sc->mark);
}

/* The elements of each vertex, by counting sort: O(elements). */
static sm_status build_incidence(const sm_elasticity *el, setup_scratch *sc, sm_error *err)
{
    const int nv = el->dim + 1;
    const int32_t nverts = el->nverts;
    const int64_t nrefs = (int64_t)el->nelems * nv;
    sc->elem_ptr = alloc_n((size_t)nverts + 1, sizeof *sc->elem_ptr);
    sc->elem_list = alloc_n((size_t)nrefs, sizeof *sc->elem_list);
    if (!sc->elem_ptr || !sc->elem_list)
        return sm_error_set(err, SM_ERR_NOMEM, "elasticity: out of memory building the vertex adjacency");
    for (int64_t k = 0; k < nrefs; k++)
        sc->elem_ptr[el->elems[k] + 1]++;
    for (int32_t v = 0; v < nverts; v++)
        sc->elem_ptr[v + 1] += sc->elem_ptr[v];
    /* fill through the starts (elem_ptr[v] runs to the end of v's list),
     * then shift them back */
    for (int64_t k = 0; k < nrefs; k++)
        sc->elem_list[sc->elem_ptr[el->elems[k]]++] = (int32_t)(k / nv);
    for (int32_t v = nverts; v > 0; v--)
        sc->elem_ptr[v] = sc->elem_ptr[v - 1];
    sc->elem_ptr[0] = 0;
    return SM_OK;
}

/* One pass over the vertex pairs (a, b) that share an element, b free,
 * each pair once, a in increasing order: counts b's neighbours into
 * next[b + 1] (fill 0), or appends a to b's list at next[b] (fill 1). */
static void neighbour_pass(const sm_elasticity *el, setup_scratch *sc, int64_t *next, int fill)
{
    const int nv = el->dim + 1;
    for (int32_t v = 0; v < el->nverts; v++)
        sc->mark[v] = -1;
    for (int32_t a = 0; a < el->nverts; a++) {
        for (int64_t k = sc->elem_ptr[a]; k < sc->elem_ptr[a + 1]; k++) {
            const int32_t *ev = el->elems + (int64_t)sc->elem_list[k] * nv;
            for (int i = 0; i < nv; i++) {
                int32_t b = ev[i];
                if (sc->kind[b] != VERTEX_FREE || sc->mark[b] == a)
                    continue;
                sc->mark[b] = a;
                if (fill)
                    sc->nb_list[next[b]++] = a;
                else
                    next[b + 1]++;
            }
        }
    }
}

/* The neighbours of every free vertex in increasing order, without a
 * sort: adjacency is symmetric, so appending each a to the lists of its
 * neighbours b, a in increasing order, gives every b its own neighbours
 * already sorted.  O(elements * (dim+1)^2); the qsort of each list it
 * replaces took most of sm__elasticity_new. */
static sm_status build_neighbours(const sm_elasticity *el, setup_scratch *sc, sm_error *err)
{
    const int32_t nverts = el->nverts;
    sc->nb_ptr = alloc_n((size_t)nverts + 1, sizeof *sc->nb_ptr);
    sc->mark = malloc(((size_t)nverts + 1) * sizeof *sc->mark);
    int64_t *next = malloc(((size_t)nverts + 1) * sizeof *next);
    if (!sc->nb_ptr || !sc->mark || !next) {
        free(next);
        return sm_error_set(err, SM_ERR_NOMEM, "elasticity: out of memory building the vertex adjacency");
    }
    neighbour_pass(el, sc, sc->nb_ptr, 0);
    for (int32_t v = 0; v < nverts; v++)
        sc->nb_ptr[v + 1] += sc->nb_ptr[v];
    sc->nb_list = alloc_n((size_t)sc->nb_ptr[nverts], sizeof *sc->nb_list);
    if (!sc->nb_list) {
        free(next);
        return sm_error_set(err, SM_ERR_NOMEM, "elasticity: out of memory building the vertex adjacency");
    }
    memcpy(next, sc->nb_ptr, ((size_t)nverts + 1) * sizeof *next);
    neighbour_pass(el, sc, next, 1);
    free(next);
    return SM_OK;
}

/* Builds the two CSR patterns from the neighbour lists: the dim rows of
 * a free vertex have the same columns, its free neighbours' DOFs in the
 * free x free block, its clamped neighbours' in the coupling block, in
 * increasing order; with diag_first each row's columns up to its
 * diagonal are then rotated by one place, which brings the diagonal to
 * the front and keeps the others ascending. */
static sm_status build_patterns(sm_elasticity *el, const setup_scratch *sc, sm_error *err)
{
    const int dim = el->dim;
    const int32_t nverts = el->nverts;
    int64_t nnz = 0, nnz_cpl = 0;
    for (int32_t a = 0; a < nverts; a++)
        for (int64_t k = sc->nb_ptr[a]; k < sc->nb_ptr[a + 1]; k++) {
            if (sc->kind[sc->nb_list[k]] == VERTEX_FREE)
                nnz += (int64_t)dim * dim;
            else
                nnz_cpl += (int64_t)dim * dim;
        }
    /* CHOLMOD_INT and the slot encoding need 32-bit positions. */
    if (nnz > INT32_MAX - 2 || nnz_cpl > INT32_MAX - 2)
        return sm_error_set(err, SM_ERR_NOMEM,
                            "elasticity: matrix too large (%lld entries, %lld coupling entries; limit %d)",
                            (long long)nnz, (long long)nnz_cpl, INT32_MAX - 2);
    /* not zeroed: the patterns are filled below, the values by each
     * factorize before anything reads them.  The largest arrays on huge
     * pages (sm_alloc.h): on the 30k example, sm__elasticity_new's page
     * faults 1683 -> ~1220 and the first assembly's (which first writes
     * the 6.5 MB of values) 0.030 -> 0.012-0.02 s. */
    el->rowptr = malloc(((size_t)el->nfree + 1) * sizeof(int32_t));
    el->colind = sm__alloc_huge(((size_t)nnz + 1) * sizeof(int32_t));
    el->values = sm__alloc_huge(((size_t)nnz + 1) * sizeof(double));
    el->cpl_rowptr = malloc(((size_t)el->nfree + 1) * sizeof(int32_t));
    el->cpl_colind = malloc(((size_t)nnz_cpl + 1) * sizeof(int32_t));
    el->cpl_values = malloc(((size_t)nnz_cpl + 1) * sizeof(double));
    if (!el->rowptr || !el->colind || !el->values || !el->cpl_rowptr || !el->cpl_colind ||
        !el->cpl_values)
        return sm_error_set(err, SM_ERR_NOMEM,
                            "elasticity: out of memory for a matrix of %lld entries", (long long)nnz);
    int32_t p = 0, q = 0, row = 0;
    for (int32_t a = 0; a < nverts; a++) {
        if (sc->kind[a] != VERTEX_FREE)
            continue;
        /* the first row of the vertex, then copies of it (rotated) */
        const int32_t p0 = p, q0 = q;
        int32_t own = 0; /* where the vertex's own block starts */
        for (int64_t k = sc->nb_ptr[a]; k < sc->nb_ptr[a + 1]; k++) {
            int32_t b = sc->nb_list[k];
            if (b == a)
                own = p - p0;
            int32_t *col = el->colind + p, first = el->dof[(int64_t)b * dim];
            if (sc->kind[b] != VERTEX_FREE) {
                col = el->cpl_colind + q;
                first = sc->clamped_first[b];
            }
            for (int d = 0; d < dim; d++)
                col[d] = first + d;
            if (sc->kind[b] == VERTEX_FREE)
                p += dim;
            else
                q += dim;
        }
        const int32_t len = p - p0, len_cpl = q - q0;
        for (int c = dim - 1; c >= 0; c--) {
            int32_t *cols = el->colind + p0 + c * len;
            el->rowptr[row + c] = p0 + c * len;
            el->cpl_rowptr[row + c] = q0 + c * len_cpl;
            if (c > 0) {
                memcpy(cols, el->colind + p0, (size_t)len * sizeof(int32_t));
                memcpy(el->cpl_colind + q0 + c * len_cpl, el->cpl_colind + q0,
                       (size_t)len_cpl * sizeof(int32_t));
            }
            if (el->diag_first) { /* the columns up to the diagonal rotate */
                const int32_t at = own + c;
                memmove(cols + 1, cols, (size_t)at * sizeof(int32_t));
                cols[0] = el->dof[(int64_t)a * dim + c];
            }
        }
        row += dim;
        p = p0 + dim * len;
        q = q0 + dim * len_cpl;
    }
    el->rowptr[row] = p;
    el->cpl_rowptr[row] = q;
    return SM_OK;
}

/* The slot map holds one slot per element and vertex pair (i, j): where
 * the dim x dim block of (vertex i, vertex j) starts, entry (c, d) being
 * at that slot + c * (row length of vertex i) + d, since the dim rows of
 * a vertex have the same columns (build_patterns) - except for
 * diag_first, where the block of (a, b) with b before a starts one place
 * later, and assemble moves the entries of each block (a, a) (see there).
 * (dim+1)^2 slots per
 * element instead of ((dim+1) dim)^2: 2 MB instead of 17.5 MB for the
 * 30k-tetrahedron example.  Each free vertex a scatters the ranks of its
 * neighbours (in its free or its coupling columns) into sc->mark, then
 * fills its row of the slots of each of its elements: no search. */
static sm_status build_slot_map(sm_elasticity *el, setup_scratch *sc, sm_error *err)
{
    const int dim = el->dim, nv = dim + 1;
    const size_t per_elem = (size_t)nv * (size_t)nv;
    el->slots = sm__alloc_huge(((size_t)el->nelems * per_elem + 1) * sizeof(int32_t));
    if (!el->slots)
        return sm_error_set(err, SM_ERR_NOMEM,
                            "elasticity: out of memory for the slot map of %ld elements",
                            (long)el->nelems);
    int32_t *rank = sc->mark;
    for (int32_t a = 0; a < el->nverts; a++) {
        const int32_t row0 = el->dof[(int64_t)a * dim];
        int32_t nfree = 0, ncpl = 0;
        for (int64_t k = sc->nb_ptr[a]; k < sc->nb_ptr[a + 1]; k++) {
            int32_t b = sc->nb_list[k];
            rank[b] = sc->kind[b] == VERTEX_FREE ? nfree++ : ncpl++;
        }
        for (int64_t k = sc->elem_ptr[a]; k < sc->elem_ptr[a + 1]; k++) {
            const int32_t e = sc->elem_list[k];
            const int32_t *ev = el->elems + (int64_t)e * nv;
            int i = 0;
            while (ev[i] != a)
                i++;
            int32_t *slot = el->slots + (size_t)e * per_elem + (size_t)i * nv;
            for (int j = 0; j < nv; j++) {
                int32_t b = ev[j];
                if (row0 < 0)
                    slot[j] = SLOT_ELIMINATED; /* the rows of a clamped vertex */
                else if (sc->kind[b] == VERTEX_FREE)
                    slot[j] = el->rowptr[row0] + rank[b] * dim + (el->diag_first && b < a);
                else
                    slot[j] = SLOT_COUPLING(el->cpl_rowptr[row0] + rank[b] * dim);
            }
        }
    }
    return SM_OK;
}

/* Which vertices are free, clamped or unused (sc->kind) and the numbering
 * of the DOFs: el->dof (free DOFs in vertex order, -1 for clamped or
 * unused ones), el->clamped_global with sc->clamped_first, and the sizes
 * nfree and nclamped_dofs; allocates el->rhs. */
static sm_status number_dofs(sm_elasticity *el, const uint8_t *clamped, setup_scratch *sc,
                             sm_error *err)
{
    const int dim = el->dim, nv = dim + 1;
    const int32_t nverts = el->nverts;
    sc->kind = malloc((size_t)nverts + 1);
    sc->clamped_first = malloc(((size_t)nverts + 1) * sizeof *sc->clamped_first);
    if (!sc->kind || !sc->clamped_first)
        return sm_error_set(err, SM_ERR_NOMEM, "elasticity: out of memory");
    /* Vertices used by no element carry no unknown: they are treated as
     * clamped (their displacement is the Dirichlet value, or 0). */
    memset(sc->kind, VERTEX_UNUSED, (size_t)nverts);
    for (int64_t k = 0; k < (int64_t)el->nelems * nv; k++)
        sc->kind[el->elems[k]] = VERTEX_FREE;
    int32_t nclamped_verts = 0, nfree_verts = 0;
    for (int32_t v = 0; v < nverts; v++) {
        if (sc->kind[v] == VERTEX_UNUSED)
            continue;
        if (clamped && clamped[v]) {
            sc->kind[v] = VERTEX_CLAMPED;
            nclamped_verts++;
        } else {
            nfree_verts++;
        }
    }
    if (nclamped_verts == 0 && nfree_verts > 0 && !(el->alpha > 0.0))
        return sm_error_set(err, SM_ERR_INVALID,
                            "elasticity: no vertex is clamped and alpha = %g: rigid motions make the "
                            "system singular; clamp some vertices or use alpha > 0", el->alpha);
    if ((int64_t)nfree_verts * dim > INT32_MAX - 2)
        return sm_error_set(err, SM_ERR_NOMEM, "elasticity: too many unknowns");
    el->nfree = nfree_verts * dim;
    el->nclamped_dofs = nclamped_verts * dim;
    el->dof = malloc(((size_t)nverts * dim + 1) * sizeof *el->dof);
    el->clamped_global = alloc_n((size_t)el->nclamped_dofs, sizeof *el->clamped_global);
    el->rhs = alloc_n((size_t)el->nfree, sizeof *el->rhs);
    if (!el->dof || !el->clamped_global || !el->rhs)
        return sm_error_set(err, SM_ERR_NOMEM, "elasticity: out of memory");
    int32_t next_free = 0, next_clamped = 0;
    for (int32_t v = 0; v < nverts; v++) {
        sc->clamped_first[v] = sc->kind[v] == VERTEX_CLAMPED ? next_clamped : -1;
        for (int c = 0; c < dim; c++) {
            int64_t g = (int64_t)v * dim + c;
            el->dof[g] = -1;
            if (sc->kind[v] == VERTEX_CLAMPED)
                el->clamped_global[next_clamped++] = (int32_t)g;
            else if (sc->kind[v] == VERTEX_FREE)
                el->dof[g] = next_free++;
        }
    }
    return SM_OK;
}

sm_status sm__elasticity_pattern(sm_elasticity *el, const uint8_t *clamped, sm_error *err)
{
    setup_scratch sc = {0};
    sm_status st;
    if ((st = number_dofs(el, clamped, &sc, err)) == SM_OK &&
        (st = build_incidence(el, &sc, err)) == SM_OK &&
        (st = build_neighbours(el, &sc, err)) == SM_OK &&
        (st = build_patterns(el, &sc, err)) == SM_OK)
        st = build_slot_map(el, &sc, err);
    setup_scratch_free(&sc);
    return st;
}

void sm__elasticity_pattern_diag_first(sm_elasticity *el)
{
    const int dim = el->dim, nv = dim + 1;
    for (int32_t r = 0; r < el->nfree; r++) {
        int32_t *cols = el->colind + el->rowptr[r];
        int32_t at = 0;
        while (cols[at] != r)
            at++;
        memmove(cols + 1, cols, (size_t)at * sizeof *cols);
        cols[0] = r;
    }
    /* a block (a, b) with b before a starts one place later (as
     * build_slot_map sets it with diag_first) */
    for (int32_t e = 0; e < el->nelems; e++) {
        const int32_t *ev = el->elems + (int64_t)e * nv;
        int32_t *slot = el->slots + (size_t)e * nv * nv;
        for (int i = 0; i < nv; i++)
            for (int j = 0; j < nv; j++)
                if (slot[i * nv + j] >= 0 && ev[j] < ev[i])
                    slot[i * nv + j]++;
    }
    el->diag_first = 1;
}
