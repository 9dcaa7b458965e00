/* P1 linear elasticity with Dirichlet elimination and CHOLMOD.
 *
 * Layout of the unknowns: every vertex referenced by an element and not
 * clamped carries dim free DOFs, numbered vertex-major, component-minor in
 * vertex order.  Because all components of a vertex are free or clamped
 * together, the columns of vertex b in any row are dim consecutive,
 * sorted entries; the CSR position of a coupling is therefore
 * rowptr[row] + (rank of b among the row vertex's free neighbours)*dim + d
 * (for the AMG solver, whose rows start with their diagonal, one place
 * later when b comes before the row's vertex; see build_patterns).
 *
 * Everything that depends only on the topology is computed once in
 * sm_elasticity_new: the CSR pattern of the free x free block (both
 * triangles), the CSR pattern of the free x clamped block (it carries the
 * Dirichlet values to the right-hand side), a slot map telling where each
 * entry of each element matrix goes, and CHOLMOD's symbolic analysis
 * (with a fill-reducing order computed on the free-vertex graph).
 * sm_elasticity_factorize then computes the element matrices
 * (sm_element.h), scatters them through the map (no search) and
 * refactorizes numerically, or rebuilds the AMG hierarchy on the same
 * arrays, which hypre reads in place (sm_solver_amg.c). */
#include "shapematch/sm_clock.h"
#include "sm_alloc.h"
#include "sm_elasticity.h"
#include "sm_element.h"
#include "sm_solver_amg.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <cholmod.h>

/* Slot map encoding (one slot per vertex pair of an element, the start
 * of its block): s >= 0 is a position in the free x free values;
 * SLOT_ELIMINATED marks the rows of a clamped vertex (the equations are
 * removed); s <= -2 is position -(s + 2) in the free x clamped values. */
#define SLOT_ELIMINATED (-1)
#define SLOT_COUPLING(p) (-2 - (p))


struct sm_elasticity {
    int dim;
    int32_t nverts;
    int32_t nelems;
    const int32_t *elems;   /* borrowed from the mesh */
    double lambda, mu, alpha;

    int32_t nfree;          /* free DOFs */
    int32_t nclamped_dofs;  /* clamped DOFs (of vertices used by elements) */
    int32_t *dof;           /* nverts*dim: free DOF index or -1 */
    int32_t *clamped_global;/* nclamped_dofs: global index v*dim+c */

    /* free x free block, full symmetric pattern; columns ascending, or
     * with diag_first (the AMG solver's layout) the diagonal entry first
     * and the others ascending */
    int32_t *rowptr, *colind;
    double *values;
    int diag_first;
    /* free x clamped block; columns are clamped DOF indices */
    int32_t *cpl_rowptr, *cpl_colind;
    double *cpl_values;

    int32_t *slots;         /* nelems * (dim+1)^2: block starts (build_slot_map) */

    cholmod_common cc;
    int cc_started;
    cholmod_sparse A;       /* wraps rowptr/colind/values */
    cholmod_factor *L;
    cholmod_dense *X, *Y, *E; /* cholmod_solve2 workspaces, reused */
    double *rhs;            /* nfree */
    int factorized;

    double lnz, flops;      /* from the symbolic analysis */
    double rcond;           /* of the last numeric factorization */
    double t_analyze, t_assembly, t_factor, t_solve;

    sm_solver_kind solver;  /* CHOLMOD or AMG (resolved) */
    double amg_rtol;
    sm_amg *amg;            /* AMG: hypre's matrix, hierarchy, warm start */
    double *amg_coords;     /* AMG: free vertex positions (rigid modes) */
};

/* ---------------------------------------------------------------------- */
/* Setup                                                                   */
/* ---------------------------------------------------------------------- */

static const char *cholmod_status_text(int status)
{
    switch (status) {
    case CHOLMOD_OK: return "ok";
    case CHOLMOD_NOT_INSTALLED: return "method not installed";
    case CHOLMOD_OUT_OF_MEMORY: return "out of memory";
    case CHOLMOD_TOO_LARGE: return "problem too large (integer overflow)";
    case CHOLMOD_INVALID: return "invalid input";
    case CHOLMOD_GPU_PROBLEM: return "GPU problem";
    case CHOLMOD_NOT_POSDEF: return "matrix not positive definite";
    case CHOLMOD_DSMALL: return "diagonal entry too small";
    }
    return "unknown status";
}

static const char *ordering_name(int ordering)
{
    switch (ordering) {
    case CHOLMOD_NATURAL: return "natural";
    case CHOLMOD_GIVEN: return "given";
    case CHOLMOD_AMD: return "amd";
    case CHOLMOD_METIS: return "metis";
    case CHOLMOD_NESDIS: return "nesdis";
    case CHOLMOD_COLAMD: return "colamd";
    case CHOLMOD_POSTORDERED: return "postordered";
    }
    return "unknown";
}

void sm_elasticity_free(sm_elasticity *el)
{
    if (!el)
        return;
    if (el->cc_started) {
        if (el->L)
            cholmod_free_factor(&el->L, &el->cc);
        if (el->X)
            cholmod_free_dense(&el->X, &el->cc);
        if (el->Y)
            cholmod_free_dense(&el->Y, &el->cc);
        if (el->E)
            cholmod_free_dense(&el->E, &el->cc);
        cholmod_finish(&el->cc);
    }
    sm_amg_free(el->amg); /* before the arrays it borrows */
    free(el->dof);
    free(el->clamped_global);
    free(el->rowptr);
    free(el->colind);
    free(el->values);
    free(el->cpl_rowptr);
    free(el->cpl_colind);
    free(el->cpl_values);
    free(el->slots);
    free(el->rhs);
    free(el->amg_coords);
    free(el);
}

static void *alloc_n(size_t count, size_t size)
{
    return calloc(count ? count : 1, size);
}

/* What sm_elasticity_new needs while it builds the pattern, freed at its
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
 * replaces took most of sm_elasticity_new. */
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
     * pages (sm_alloc.h): on the 30k example, sm_elasticity_new's page
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

/* The arguments of sm_elasticity_new: sizes, material, alpha, factor kind
 * and every element's vertices (in range, distinct). */
static sm_status validate(const sm_mesh *m, const sm_elasticity_opts *opts, sm_error *err)
{
    if (!m)
        return sm_error_set(err, SM_ERR_INVALID, "elasticity: NULL mesh");
    if (!opts)
        return sm_error_set(err, SM_ERR_INVALID, "elasticity: NULL options");
    if (m->dim != 2 && m->dim != 3)
        return sm_error_set(err, SM_ERR_INVALID, "elasticity: mesh dimension %d is not 2 or 3", m->dim);
    if (m->nverts < 0 || m->nelems < 0 || m->nverts > SM_MAX_ENTITIES ||
        m->nelems > SM_MAX_ENTITIES || (m->nelems > 0 && !m->elems))
        return sm_error_set(err, SM_ERR_INVALID,
                            "elasticity: invalid mesh sizes (%ld vertices, %ld elements)",
                            (long)m->nverts, (long)m->nelems);
    const double young = opts->young, poisson = opts->poisson, alpha = opts->alpha;
    const sm_factor_kind kind = opts->factor;
    if (!sm_solver_kind_name(opts->solver))
        return sm_error_set(err, SM_ERR_INVALID, "elasticity: unknown solver %d", (int)opts->solver);
    if (opts->amg_modes != SM_AMG_MODES_AUTO && opts->amg_modes != SM_AMG_MODES_ON &&
        opts->amg_modes != SM_AMG_MODES_OFF)
        return sm_error_set(err, SM_ERR_INVALID, "elasticity: unknown AMG modes setting %d",
                            (int)opts->amg_modes);
    if (!(opts->amg_rtol >= 0.0 && opts->amg_rtol < 1.0))
        return sm_error_set(err, SM_ERR_INVALID,
                            "elasticity: AMG tolerance must lie in [0, 1) (got %g)", opts->amg_rtol);
    if (!(young > 0.0) || !isfinite(young))
        return sm_error_set(err, SM_ERR_INVALID,
                            "elasticity: Young's modulus must be finite and > 0 (got %g)", young);
    if (!(poisson > -1.0 && poisson < 0.5))
        return sm_error_set(err, SM_ERR_INVALID,
                            "elasticity: Poisson ratio must lie in (-1, 0.5) (got %g)", poisson);
    if (!(alpha >= 0.0) || !isfinite(alpha))
        return sm_error_set(err, SM_ERR_INVALID,
                            "elasticity: alpha must be finite and >= 0 (got %g)", alpha);
    if (kind != SM_FACTOR_AUTO && kind != SM_FACTOR_SIMPLICIAL && kind != SM_FACTOR_SUPERNODAL)
        return sm_error_set(err, SM_ERR_INVALID, "elasticity: unknown factor kind %d", (int)kind);

    const int nv = m->dim + 1;
    for (int32_t e = 0; e < m->nelems; e++) {
        const int32_t *ev = m->elems + (int64_t)e * nv;
        for (int i = 0; i < nv; i++) {
            if (ev[i] < 0 || ev[i] >= m->nverts)
                return sm_error_set(err, SM_ERR_INVALID,
                                    "elasticity: element %ld references vertex %ld (mesh has %ld vertices)",
                                    (long)e + 1, (long)ev[i] + 1, (long)m->nverts);
            for (int j = 0; j < i; j++)
                if (ev[j] == ev[i])
                    return sm_error_set(err, SM_ERR_INVALID,
                                        "elasticity: element %ld repeats vertex %ld",
                                        (long)e + 1, (long)ev[i] + 1);
        }
    }
    return SM_OK;
}

/* Which vertices are free, clamped or unused (sc->kind) and the numbering
 * of the DOFs: el->dof (free DOFs in vertex order, -1 for clamped or
 * unused ones), el->clamped_global with sc->clamped_first, and the sizes
 * nfree and nclamped_dofs; allocates el->rhs. */
static sm_status number_dofs(sm_elasticity *el, const sm_mesh *m, const uint8_t *clamped,
                             setup_scratch *sc, sm_error *err)
{
    const int dim = m->dim, nv = dim + 1;
    sc->kind = malloc((size_t)m->nverts + 1);
    sc->clamped_first = malloc(((size_t)m->nverts + 1) * sizeof *sc->clamped_first);
    if (!sc->kind || !sc->clamped_first)
        return sm_error_set(err, SM_ERR_NOMEM, "elasticity: out of memory");
    /* Vertices used by no element carry no unknown: they are treated as
     * clamped (their displacement is the Dirichlet value, or 0). */
    memset(sc->kind, VERTEX_UNUSED, (size_t)m->nverts);
    for (int64_t k = 0; k < (int64_t)m->nelems * nv; k++)
        sc->kind[m->elems[k]] = VERTEX_FREE;
    int32_t nclamped_verts = 0, nfree_verts = 0;
    for (int32_t v = 0; v < m->nverts; v++) {
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
    el->dof = malloc(((size_t)m->nverts * dim + 1) * sizeof *el->dof);
    el->clamped_global = alloc_n((size_t)el->nclamped_dofs, sizeof *el->clamped_global);
    el->rhs = alloc_n((size_t)el->nfree, sizeof *el->rhs);
    if (!el->dof || !el->clamped_global || !el->rhs)
        return sm_error_set(err, SM_ERR_NOMEM, "elasticity: out of memory");
    int32_t next_free = 0, next_clamped = 0;
    for (int32_t v = 0; v < m->nverts; v++) {
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

/* A fill-reducing order of the free DOFs, computed on the graph of the
 * free vertices and expanded to their dim DOFs each.  The DOF graph is
 * that graph with every vertex a dim-clique, so both give orders of the
 * same quality, but CHOLMOD's choice (AMD, then METIS when the fill is
 * high) runs on dim^2 times fewer entries: 0.03 s instead of 0.2 s for
 * the 30k-tetrahedron example.  The free DOFs are vertex-major (DOF
 * d * dim + c is component c of free vertex d).  Returns the order of the
 * DOFs (malloc'ed, nfree entries), or NULL when it could not be computed
 * (out of memory), and CHOLMOD then orders the DOF graph itself. */
static int32_t *vertex_block_order(sm_elasticity *el)
{
    const int dim = el->dim;
    const int32_t nfv = el->nfree / dim;
    int32_t *vp = malloc(((size_t)nfv + 1) * sizeof *vp);
    int32_t *vi = malloc(((size_t)el->rowptr[el->nfree] / (size_t)(dim * dim) + 1) * sizeof *vi);
    int32_t *perm = malloc((size_t)el->nfree * sizeof *perm);
    cholmod_factor *Lv = NULL;
    if (!vp || !vi || !perm)
        goto fail;
    /* vertex d's neighbours: the columns c = 0 of its first DOF's row */
    int32_t q = 0;
    for (int32_t d = 0; d < nfv; d++) {
        vp[d] = q;
        const int32_t row = d * dim;
        for (int32_t k = el->rowptr[row]; k < el->rowptr[row + 1]; k += dim)
            vi[q++] = el->colind[k] / dim;
    }
    vp[nfv] = q;
    cholmod_sparse V = {0};
    V.nrow = V.ncol = (size_t)nfv;
    V.nzmax = (size_t)q;
    V.p = vp;
    V.i = vi;
    V.stype = 1;
    V.itype = CHOLMOD_INT;
    V.xtype = CHOLMOD_PATTERN;
    V.dtype = CHOLMOD_DOUBLE;
    V.sorted = 1;
    V.packed = 1;
    /* both orders, the one with the fewer nonzeros in L kept: METIS wins
     * on 3D meshes (5.8M against AMD's 7.6M for the example), AMD on
     * small or flat ones */
    el->cc.nmethods = 2;
    el->cc.method[0].ordering = CHOLMOD_AMD;
    el->cc.method[1].ordering = CHOLMOD_METIS;
    Lv = cholmod_analyze(&V, &el->cc);
    if (!Lv || el->cc.status < CHOLMOD_OK)
        goto fail;
    const int *vperm = Lv->Perm;
    for (int32_t k = 0; k < nfv; k++)
        for (int c = 0; c < dim; c++)
            perm[(size_t)k * dim + c] = vperm[k] * dim + c;
    cholmod_free_factor(&Lv, &el->cc);
    free(vp);
    free(vi);
    return perm;
fail:
    if (Lv)
        cholmod_free_factor(&Lv, &el->cc);
    free(vp);
    free(vi);
    free(perm);
    el->cc.status = CHOLMOD_OK;
    return NULL;
}

/* CHOLMOD on the free x free pattern: its common block (factor kind
 * forced or not), the matrix header over el's CSR arrays, and the
 * symbolic analysis. */
static sm_status setup_solver(sm_elasticity *el, sm_factor_kind kind, sm_error *err)
{
    /* CHOLMOD: a CSR of a symmetric matrix is its CSC; stype = 1 makes
     * CHOLMOD read only the upper triangle (row <= column). */
    if (!cholmod_start(&el->cc))
        return sm_error_set(err, SM_ERR_NOMEM, "elasticity: cholmod_start failed");
    el->cc_started = 1;
    el->cc.print = 0; /* errors are reported through sm_error, not stdout */
    el->cc.quick_return_if_not_posdef = 1;
    if (kind == SM_FACTOR_SIMPLICIAL)
        el->cc.supernodal = CHOLMOD_SIMPLICIAL;
    else if (kind == SM_FACTOR_SUPERNODAL)
        el->cc.supernodal = CHOLMOD_SUPERNODAL;
    el->A.nrow = el->A.ncol = (size_t)el->nfree;
    el->A.nzmax = (size_t)el->rowptr[el->nfree];
    el->A.p = el->rowptr;
    el->A.i = el->colind;
    el->A.nz = NULL;
    el->A.x = el->values;
    el->A.z = NULL;
    el->A.stype = 1;
    el->A.itype = CHOLMOD_INT;
    el->A.xtype = CHOLMOD_REAL;
    el->A.dtype = CHOLMOD_DOUBLE;
    el->A.sorted = 1;
    el->A.packed = 1;
    if (el->nfree > 0) {
        int32_t *perm = vertex_block_order(el);
        if (perm) {
            el->cc.nmethods = 1;
            el->cc.method[0].ordering = CHOLMOD_GIVEN;
        }
        el->L = cholmod_analyze_p(&el->A, perm, NULL, 0, &el->cc);
        free(perm);
        if (!el->L || el->cc.status < CHOLMOD_OK)
            return sm_error_set(err, el->cc.status == CHOLMOD_OUT_OF_MEMORY ? SM_ERR_NOMEM : SM_ERR_NUMERIC,
                                "elasticity: CHOLMOD symbolic analysis failed (status %d: %s) for %ld unknowns",
                                el->cc.status, cholmod_status_text(el->cc.status), (long)el->nfree);
        el->lnz = el->cc.lnz;
        el->flops = el->cc.fl;
    }
    return SM_OK;
}

sm_status sm_elasticity_new(const sm_mesh *m, const uint8_t *clamped,
                            const sm_elasticity_opts *opts, sm_elasticity **out,
                            sm_error *err)
{
    double t0 = sm_clock_seconds();
    if (!out)
        return sm_error_set(err, SM_ERR_INVALID, "elasticity: NULL output pointer");
    *out = NULL;
    sm_status st = validate(m, opts, err);
    if (st != SM_OK)
        return st;

    sm_elasticity *el = calloc(1, sizeof *el);
    if (!el)
        return sm_error_set(err, SM_ERR_NOMEM, "elasticity: out of memory");
    el->dim = m->dim;
    el->nverts = m->nverts;
    el->nelems = m->nelems;
    el->elems = m->elems;
    el->alpha = opts->alpha;
    sm_lame(opts->young, opts->poisson, &el->lambda, &el->mu);

    el->solver = sm_solver_resolve(opts->solver, m->dim, m->nelems);
    el->amg_rtol = opts->amg_rtol > 0.0 ? opts->amg_rtol : SM_ELASTICITY_AMG_RTOL;
    el->diag_first = el->solver == SM_SOLVER_AMG;
    setup_scratch sc = {0};
    if ((st = number_dofs(el, m, clamped, &sc, err)) != SM_OK ||
        (st = build_incidence(el, &sc, err)) != SM_OK ||
        (st = build_neighbours(el, &sc, err)) != SM_OK ||
        (st = build_patterns(el, &sc, err)) != SM_OK ||
        (st = build_slot_map(el, &sc, err)) != SM_OK)
        goto fail;
    setup_scratch_free(&sc);
    if (el->solver == SM_SOLVER_AMG && el->nfree > 0) {
        int rigid_modes = opts->amg_modes == SM_AMG_MODES_ON ||
                          (opts->amg_modes == SM_AMG_MODES_AUTO &&
                           (el->dim == 2 || el->nfree >= SM_AMG_MODES_MIN_UNKNOWNS));
        st = sm_amg_new(el->dim, el->nfree, el->rowptr, el->colind, el->values, el->amg_rtol,
                        rigid_modes, &el->amg, err);
    } else if (el->solver == SM_SOLVER_CHOLMOD) {
        st = setup_solver(el, opts->factor, err);
    }
    if (st != SM_OK) {
        sm_elasticity_free(el);
        return st;
    }
    el->t_analyze = sm_clock_seconds() - t0;
    *out = el;
    return SM_OK;

fail:
    setup_scratch_free(&sc);
    sm_elasticity_free(el);
    return st;
}

/* ---------------------------------------------------------------------- */
/* Assembly and factorization                                              */
/* ---------------------------------------------------------------------- */

/* Assembles for a compile-time dim and layout (diag_first); returns the
 * first degenerate element or -1. */
static inline __attribute__((always_inline)) int32_t
assemble(sm_elasticity *el, const int dim, const int diag_first,
                               const double *coords, double *bad_volume, double *bad_edge)
{
    const int nv = dim + 1, n = nv * dim;
    double *values = el->values, *cpl = el->cpl_values;
    double x[12], ke[144];
    for (int32_t e = 0; e < el->nelems; e++) {
        const int32_t *ev = el->elems + (int64_t)e * nv;
        for (int i = 0; i < nv; i++)
            for (int r = 0; r < dim; r++)
                x[i * dim + r] = coords[(int64_t)ev[i] * dim + r];
        double vol, lmax;
        if (sm_element_kernel(dim, x, el->lambda, el->mu, el->alpha, ke, &vol, &lmax) != 0) {
            *bad_volume = vol;
            *bad_edge = lmax;
            return e;
        }
        const int32_t *slot = el->slots + (size_t)e * nv * nv;
        for (int i = 0; i < nv; i++) {
            int32_t row0 = el->dof[(int64_t)ev[i] * dim];
            if (row0 < 0)
                continue; /* the rows of a clamped vertex are eliminated */
            int32_t len = el->rowptr[row0 + 1] - el->rowptr[row0];
            int32_t len_cpl = el->cpl_rowptr[row0 + 1] - el->cpl_rowptr[row0];
            for (int c = 0; c < dim; c++) {
                const double *krow = ke + (i * dim + c) * n;
                for (int j = 0; j < nv; j++) {
                    if (diag_first && j == i)
                        continue; /* below */
                    int32_t s = slot[i * nv + j];
                    const double *k = krow + j * dim;
                    double *dst = s >= 0 ? values + s + (int64_t)c * len
                                         : cpl + (-2 - s) + (int64_t)c * len_cpl;
                    for (int d = 0; d < dim; d++)
                        dst[d] += k[d];
                }
                if (diag_first) {
                    /* the vertex's own block, in a row whose columns up
                     * to the diagonal were rotated by one place
                     * (build_patterns): the diagonal at the row's start,
                     * the entries before it one place later */
                    const double *k = krow + i * dim;
                    double *row = values + el->rowptr[row0] + (int64_t)c * len;
                    double *dst = values + slot[i * nv + i] + (int64_t)c * len;
                    row[0] += k[c];
                    for (int d = 0; d < dim; d++)
                        if (d != c)
                            dst[d + (d < c)] += k[d];
                }
            }
        }
    }
    return -1;
}

/* AMG "factorization": the free vertices' positions (for the rigid-body
 * modes) and hypre's set-up on the assembled matrix, which hypre reads
 * in place (sm_amg_new).  The positions are
 * only read during the set-up, so their buffer (nfree doubles) then
 * serves as the solution buffer of the solves. */
static sm_status amg_setup(sm_elasticity *el, const double *coords, sm_error *err)
{
    if (el->nfree == 0)
        return SM_OK;
    if (!el->amg_coords && !(el->amg_coords = malloc((size_t)el->nfree * sizeof(double))))
        return sm_error_set(err, SM_ERR_NOMEM, "elasticity: out of memory");
    for (int64_t g = 0; g < (int64_t)el->nverts * el->dim; g++)
        if (el->dof[g] >= 0)
            el->amg_coords[el->dof[g]] = coords[g];
    return sm_amg_setup(el->amg, el->amg_coords, err);
}

sm_status sm_elasticity_factorize(sm_elasticity *el, const double *coords, sm_error *err)
{
    if (!el || !coords)
        return sm_error_set(err, SM_ERR_INVALID, "elasticity: NULL argument to factorize");
    el->factorized = 0;
    double t0 = sm_clock_seconds();
    memset(el->values, 0, (size_t)el->rowptr[el->nfree] * sizeof(double));
    memset(el->cpl_values, 0, (size_t)el->cpl_rowptr[el->nfree] * sizeof(double));
    double bad_volume = 0.0, bad_edge = 0.0;
    int32_t bad;
    if (el->diag_first)
        bad = el->dim == 2 ? assemble(el, 2, 1, coords, &bad_volume, &bad_edge)
                           : assemble(el, 3, 1, coords, &bad_volume, &bad_edge);
    else
        bad = el->dim == 2 ? assemble(el, 2, 0, coords, &bad_volume, &bad_edge)
                           : assemble(el, 3, 0, coords, &bad_volume, &bad_edge);
    double t1 = sm_clock_seconds();
    el->t_assembly = t1 - t0;
    el->t_factor = 0.0;
    if (bad >= 0)
        return sm_error_set(err, SM_ERR_NUMERIC,
                            "elasticity: element %ld is degenerate or has non-finite coordinates "
                            "(volume %g, longest edge %g)",
                            (long)bad + 1, bad_volume, bad_edge);
    el->rcond = 0.0;
    if (el->solver == SM_SOLVER_AMG) {
        sm_status st = amg_setup(el, coords, err);
        el->t_factor = sm_clock_seconds() - t1;
        if (st != SM_OK)
            return st;
    } else if (el->nfree > 0) {
        int ok = cholmod_factorize(&el->A, el->L, &el->cc);
        int status = el->cc.status;
        el->t_factor = sm_clock_seconds() - t1;
        if (!ok || status < CHOLMOD_OK || status == CHOLMOD_NOT_POSDEF)
            return sm_error_set(err, status == CHOLMOD_OUT_OF_MEMORY ? SM_ERR_NOMEM : SM_ERR_NUMERIC,
                                "elasticity: CHOLMOD factorization failed (status %d: %s; pivot %ld of "
                                "%ld unknowns)%s",
                                status, cholmod_status_text(status), (long)el->L->minor + 1,
                                (long)el->nfree,
                                status == CHOLMOD_NOT_POSDEF
                                    ? "; the clamp may not remove all rigid motions"
                                    : "");
        /* A simplicial LDL' factorization does not stop on negative
         * pivots (D may be indefinite); check D so that every kind of
         * factor rejects a matrix that is not positive definite. */
        if (!el->L->is_super && !el->L->is_ll) {
            const int *lp = el->L->p;
            const double *lx = el->L->x;
            for (size_t j = 0; j < el->L->n; j++)
                if (!(lx[lp[j]] > 0.0))
                    return sm_error_set(err, SM_ERR_NUMERIC,
                                        "elasticity: CHOLMOD factorization failed (status %d: %s; "
                                        "pivot %zu of %ld unknowns is %g); the clamp may not remove "
                                        "all rigid motions",
                                        CHOLMOD_NOT_POSDEF, cholmod_status_text(CHOLMOD_NOT_POSDEF),
                                        j + 1, (long)el->nfree, lx[lp[j]]);
        }
        el->rcond = cholmod_rcond(el->L, &el->cc);
        if (!(el->rcond >= SM_ELASTICITY_MIN_RCOND))
            return sm_error_set(err, SM_ERR_NUMERIC,
                                "elasticity: CHOLMOD factorization is numerically singular "
                                "(rcond estimate %.3g < %g, status %d: %s); the clamp may not "
                                "remove all rigid motions",
                                el->rcond, SM_ELASTICITY_MIN_RCOND, el->cc.status,
                                cholmod_status_text(el->cc.status));
    }
    el->factorized = 1;
    return SM_OK;
}

sm_status sm_elasticity_solve(sm_elasticity *el, const double *load,
                              const double *dirichlet, double *u, sm_error *err)
{
    if (!el || !u)
        return sm_error_set(err, SM_ERR_INVALID, "elasticity: NULL argument to solve");
    if (!el->factorized)
        return sm_error_set(err, SM_ERR_INVALID,
                            "elasticity: solve called without a successful factorize");
    double t0 = sm_clock_seconds();
    const int dim = el->dim;
    const int64_t nglobal = (int64_t)el->nverts * dim;
    double *rhs = el->rhs;
    for (int64_t g = 0; g < nglobal; g++) {
        int32_t k = el->dof[g];
        if (k >= 0)
            rhs[k] = load ? load[g] : 0.0;
    }
    if (dirichlet) {
        /* rhs_f -= K_fc g_c */
        for (int32_t r = 0; r < el->nfree; r++) {
            double s = 0.0;
            for (int32_t p = el->cpl_rowptr[r]; p < el->cpl_rowptr[r + 1]; p++)
                s += el->cpl_values[p] * dirichlet[el->clamped_global[el->cpl_colind[p]]];
            rhs[r] -= s;
        }
    }
    const double *x = NULL;
    if (el->solver == SM_SOLVER_AMG && el->nfree > 0) {
        sm_status st = sm_amg_solve(el->amg, rhs, el->amg_coords, err);
        if (st != SM_OK)
            return st;
        x = el->amg_coords; /* reused as the solution buffer, see amg_setup */
    } else if (el->nfree > 0) {
        cholmod_dense B = {0};
        B.nrow = (size_t)el->nfree;
        B.ncol = 1;
        B.nzmax = (size_t)el->nfree;
        B.d = (size_t)el->nfree;
        B.x = rhs;
        B.z = NULL;
        B.xtype = CHOLMOD_REAL;
        B.dtype = CHOLMOD_DOUBLE;
        if (!cholmod_solve2(CHOLMOD_A, el->L, &B, NULL, &el->X, NULL, &el->Y, &el->E, &el->cc) ||
            el->cc.status < CHOLMOD_OK)
            return sm_error_set(err, el->cc.status == CHOLMOD_OUT_OF_MEMORY ? SM_ERR_NOMEM : SM_ERR_NUMERIC,
                                "elasticity: CHOLMOD solve failed (status %d: %s)", el->cc.status,
                                cholmod_status_text(el->cc.status));
        x = el->X->x;
    }
    for (int64_t g = 0; g < nglobal; g++) {
        int32_t k = el->dof[g];
        u[g] = k >= 0 ? x[k] : (dirichlet ? dirichlet[g] : 0.0);
    }
    el->t_solve = sm_clock_seconds() - t0;
    return SM_OK;
}

/* ---------------------------------------------------------------------- */
/* Accessors                                                               */
/* ---------------------------------------------------------------------- */

void sm_elasticity_matrix(const sm_elasticity *el, sm_csr_view *view)
{
    view->n = el->nfree;
    view->rowptr = el->rowptr;
    view->colind = el->colind;
    view->values = el->values;
}

int32_t sm_elasticity_dof(const sm_elasticity *el, int32_t vertex, int comp)
{
    if (vertex < 0 || vertex >= el->nverts || comp < 0 || comp >= el->dim)
        return -1;
    return el->dof[(int64_t)vertex * el->dim + comp];
}

void sm_elasticity_timings(const sm_elasticity *el, double *assembly, double *factor)
{
    if (assembly)
        *assembly = el->t_assembly;
    if (factor)
        *factor = el->t_factor;
}

void sm_elasticity_get_info(const sm_elasticity *el, sm_elasticity_info *info)
{
    memset(info, 0, sizeof *info);
    info->nfree = el->nfree;
    info->nclamped = el->nclamped_dofs;
    info->nnz = el->rowptr[el->nfree];
    info->nnz_coupling = el->cpl_rowptr[el->nfree];
    info->ordering = "none";
    if (el->L) {
        info->nnz_factor = el->lnz;
        info->flops = el->flops;
        info->supernodal = el->L->is_super;
        info->ordering = ordering_name(el->L->ordering);
    }
    info->rcond = el->rcond;
    info->solver = el->solver;
    if (el->amg) {
        sm_amg_stats as;
        sm_amg_get_stats(el->amg, &as);
        info->amg_iterations = as.last_iterations;
        info->amg_total_iterations = as.total_iterations;
        info->amg_restarts = as.restarts;
        info->amg_min_descent = as.min_descent;
    }
    info->analyze_time = el->t_analyze;
    info->solve_time = el->t_solve;
}
