/* P1 linear elasticity with Dirichlet elimination and CHOLMOD.
 *
 * Layout of the unknowns: every vertex referenced by an element and not
 * clamped carries dim free DOFs, numbered vertex-major, component-minor in
 * vertex order.  Because all components of a vertex are free or clamped
 * together, the columns of vertex b in any row are dim consecutive,
 * sorted entries; the CSR position of a coupling is therefore
 * rowptr[row] + (rank of b among the row vertex's free neighbours)*dim + d
 * (for the AMG solver, whose rows start with their diagonal, one place
 * later when b comes before the row's vertex; see build_patterns in
 * sm_elasticity_pattern.c).
 *
 * Everything that depends only on the topology is computed once in
 * sm__elasticity_new: the CSR pattern of the free x free block (both
 * triangles), the CSR pattern of the free x clamped block (it carries the
 * Dirichlet values to the right-hand side), a slot map telling where each
 * entry of each element matrix goes (sm_elasticity_pattern.c), and
 * CHOLMOD's symbolic analysis
 * (with a fill-reducing order computed on the free-vertex graph).
 * sm__elasticity_factorize then computes the element matrices
 * (sm_element.h), scatters them through the map (no search) and
 * refactorizes numerically, or rebuilds the AMG hierarchy on the same
 * arrays, which hypre reads in place (sm_solver_amg.c). */
#include "shapematch/sm_clock.h"
#include "sm_alloc.h"
#include "sm_elasticity_internal.h"
#include "sm_element.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

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

void sm__elasticity_free(sm_elasticity *el)
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
    sm__amg_free(el->amg); /* before the arrays it borrows */
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

/* The options of sm__elasticity_new: material, alpha, solver and factor
 * kinds, AMG settings. */
static sm_status validate_opts(const sm_elasticity_opts *opts, sm_error *err)
{
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
    return SM_OK;
}

/* The arguments of sm__elasticity_new: sizes, the options and every
 * element's vertices (in range, distinct). */
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
    sm_status st = validate_opts(opts, err);
    if (st != SM_OK)
        return st;
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

/* A fill-reducing order of the free DOFs, computed on the graph of the
 * free vertices and expanded to their dim DOFs each.  The DOF graph is
 * that graph with every vertex a dim-clique, so both give orders of the
 * same quality, but CHOLMOD's choice (AMD, then METIS when the fill is
 * high) runs on dim^2 times fewer entries: 0.03 s instead of 0.2 s for
 * the 30k-tetrahedron example.  The free DOFs are vertex-major (DOF
 * d * dim + c is component c of free vertex d).  Returns the order of the
 * DOFs (malloc'ed, nfree entries), or NULL when it could not be computed
 * (out of memory), and CHOLMOD then orders the DOF graph itself.
 * *lnz_v and *flops_v receive the vertex graph's factor entries and
 * flops (left alone on failure). */
static int32_t *vertex_block_order(sm_elasticity *el, double *lnz_v, double *flops_v)
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
    *lnz_v = el->cc.lnz;
    *flops_v = el->cc.fl;
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

/* CHOLMOD's common block (factor kind forced or not) and the matrix
 * header over el's CSR arrays. */
static sm_status start_cholmod(sm_elasticity *el, sm_factor_kind kind, sm_error *err)
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
    return SM_OK;
}

/* CHOLMOD's symbolic analysis in the order perm (vertex_block_order's;
 * NULL: CHOLMOD orders the DOF graph itself). */
static sm_status analyse(sm_elasticity *el, const int32_t *perm, sm_error *err)
{
    if (el->nfree == 0)
        return SM_OK;
    if (perm) {
        el->cc.nmethods = 1;
        el->cc.method[0].ordering = CHOLMOD_GIVEN;
    }
    el->L = cholmod_analyze_p(&el->A, (int32_t *)perm, NULL, 0, &el->cc);
    if (!el->L || el->cc.status < CHOLMOD_OK)
        return sm_error_set(err, el->cc.status == CHOLMOD_OUT_OF_MEMORY ? SM_ERR_NOMEM : SM_ERR_NUMERIC,
                            "elasticity: CHOLMOD symbolic analysis failed (status %d: %s) for %ld unknowns",
                            el->cc.status, cholmod_status_text(el->cc.status), (long)el->nfree);
    el->lnz = el->cc.lnz;
    el->flops = el->cc.fl;
    return SM_OK;
}

/* ---------------------------------------------------------------------- */
/* auto: the cost model                                                    */
/* ---------------------------------------------------------------------- */

/* The fitted constants (bench/solvers.sh measures, bench/solvers_fit.py
 * fits; docs/solvers.md has the fit): CPU seconds of one thread on the
 * 2-core development machine, bytes.  CHOLMOD's set-up is linear in the
 * factorization's flops and the matrix's entries (its analysis), a solve
 * a power of the factor's entries; AMG's set-up is linear in the matrix's
 * entries (dearer with the rigid rotations, SM_AMG_MODES_MIN_UNKNOWNS), a
 * solve (~4 PCG steps) a power of them: larger problems leave the
 * caches. */
#define COST_CHOL_SETUP_PER_FLOP 2.667e-11
#define COST_CHOL_SETUP_PER_NNZ 3.15e-7
#define COST_CHOL_SOLVE_COEF 3.352e-9
#define COST_CHOL_SOLVE_EXP 0.932
#define COST_AMG_SETUP_PER_NNZ 1.189e-7
#define COST_AMG_SETUP_PER_NNZ_MODES 2.309e-7
#define COST_AMG_SOLVE_COEF 3.302e-10
#define COST_AMG_SOLVE_EXP 1.288
#define COST_CHOL_BYTES_PER_LNZ 9.89
#define COST_CHOL_BYTES_PER_NNZ 38.1
#define COST_AMG_BYTES_PER_NNZ 30.25

void sm__solver_cost_model(double unknowns, sm_solver_estimate *est)
{
    const double h = SM_SOLVER_AUTO_HORIZON, nnz = est->nnz;
    const double amg_setup = unknowns >= SM_AMG_MODES_MIN_UNKNOWNS ? COST_AMG_SETUP_PER_NNZ_MODES
                                                                   : COST_AMG_SETUP_PER_NNZ;
    est->amg_seconds = amg_setup * nnz + h * COST_AMG_SOLVE_COEF * pow(nnz, COST_AMG_SOLVE_EXP);
    est->amg_bytes = COST_AMG_BYTES_PER_NNZ * nnz;
    if (est->lnz > 0) {
        est->cholmod_seconds = COST_CHOL_SETUP_PER_FLOP * est->flops + COST_CHOL_SETUP_PER_NNZ * nnz +
                               h * COST_CHOL_SOLVE_COEF * pow(est->lnz, COST_CHOL_SOLVE_EXP);
        est->cholmod_bytes = COST_CHOL_BYTES_PER_LNZ * est->lnz + COST_CHOL_BYTES_PER_NNZ * nnz;
    } else {
        est->cholmod_seconds = est->cholmod_bytes = 0;
    }
}

sm_solver_kind sm__solver_auto_choice(const sm_solver_estimate *est)
{
    if (!(est->lnz > 0))
        return SM_SOLVER_AMG;
    if (est->memory_limit > 0 &&
        est->cholmod_bytes > SM_SOLVER_AUTO_MEMORY_SHARE * est->memory_limit)
        return SM_SOLVER_AMG;
    return est->cholmod_seconds <= est->amg_seconds ? SM_SOLVER_CHOLMOD : SM_SOLVER_AMG;
}

/* The cgroup (v2) memory.max of this process, bytes; 0 if none or
 * unknown. */
static double cgroup_memory_max(void)
{
    char path[512] = "/sys/fs/cgroup/memory.max", line[400];
    FILE *f = fopen("/proc/self/cgroup", "r");
    while (f && fgets(line, sizeof line, f)) {
        if (strncmp(line, "0::", 3) != 0)
            continue;
        line[strcspn(line, "\n")] = 0;
        snprintf(path, sizeof path, "/sys/fs/cgroup%s/memory.max",
                 strcmp(line + 3, "/") == 0 ? "" : line + 3);
        break;
    }
    if (f)
        fclose(f);
    double v = 0;
    f = fopen(path, "r");
    if (f && fscanf(f, "%lf", &v) != 1) /* "max": no limit */
        v = 0;
    if (f)
        fclose(f);
    return v;
}

/* The memory the process may use: the least of its address-space limit
 * (the daemon's workers run under --memory-limit's RLIMIT_AS), its
 * cgroup's memory.max and the machine's memory; 0 if none is known. */
static double memory_limit_bytes(void)
{
    double lim = 0;
    struct rlimit rl;
    if (getrlimit(RLIMIT_AS, &rl) == 0 && rl.rlim_cur != RLIM_INFINITY)
        lim = (double)rl.rlim_cur;
    double cg = cgroup_memory_max();
    if (cg > 0 && (lim == 0 || cg < lim))
        lim = cg;
    long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
    double phys = pages > 0 && page > 0 ? (double)pages * (double)page : 0;
    if (phys > 0 && (lim == 0 || phys < lim))
        lim = phys;
    return lim;
}

/* The 3D auto path: the pattern is in CHOLMOD's layout; the vertex
 * graph's order and analysis give the factor's size (a vertex entry of L
 * is a dim x dim block, a diagonal one its lower triangle; the flops
 * grow with the cube of the block size), the model decides, and the
 * solver chosen is set up (the order reused by CHOLMOD's analysis, the
 * pattern turned into AMG's layout). */
static sm_status choose_and_setup(sm_elasticity *el, const sm_elasticity_opts *opts, sm_error *err)
{
    sm_status st = start_cholmod(el, opts->factor, err);
    if (st != SM_OK)
        return st;
    const double d = el->dim, nfv = (double)el->nfree / d;
    double lnz_v = 0, flops_v = 0;
    int32_t *perm = el->nfree > 0 ? vertex_block_order(el, &lnz_v, &flops_v) : NULL;
    sm_solver_estimate *est = &el->estimate;
    est->nnz = (double)el->rowptr[el->nfree];
    est->lnz = lnz_v > 0 ? d * d * (lnz_v - nfv) + d * (d + 1) / 2 * nfv : 0;
    est->flops = flops_v * d * d * d;
    est->memory_limit = memory_limit_bytes();
    sm__solver_cost_model((double)el->nfree, est);
    el->solver = perm ? sm__solver_auto_choice(est)
                      : sm_solver_resolve(SM_SOLVER_AUTO, el->dim, el->nelems);
    if (el->solver == SM_SOLVER_CHOLMOD) {
        st = analyse(el, perm, err);
        free(perm);
        return st;
    }
    free(perm);
    cholmod_finish(&el->cc);
    el->cc_started = 0;
    sm__elasticity_pattern_diag_first(el);
    return SM_OK;
}

sm_status sm__elasticity_new(const sm_mesh *m, const uint8_t *clamped,
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
    el->owner = getpid();
    sm__lame(opts->young, opts->poisson, &el->lambda, &el->mu);

    /* auto in 3D from SM_SOLVER_AUTO_MODEL_MIN_TETS: the cost model
     * after CHOLMOD's analysis (choose_and_setup); otherwise
     * sm_solver_resolve (CHOLMOD for auto: 2D, small 3D) */
    const int by_model = opts->solver == SM_SOLVER_AUTO && m->dim == 3 &&
                         m->nelems >= SM_SOLVER_AUTO_MODEL_MIN_TETS;
    el->solver = by_model ? SM_SOLVER_CHOLMOD : sm_solver_resolve(opts->solver, m->dim, m->nelems);
    el->amg_rtol = opts->amg_rtol > 0.0 ? opts->amg_rtol : SM_ELASTICITY_AMG_RTOL;
    el->diag_first = el->solver == SM_SOLVER_AMG;
    if ((st = sm__elasticity_pattern(el, clamped, err)) != SM_OK) {
        sm__elasticity_free(el);
        return st;
    }
    el->estimate.nnz = (double)el->rowptr[el->nfree];
    if (by_model) {
        st = choose_and_setup(el, opts, err);
    } else if (el->solver == SM_SOLVER_CHOLMOD) {
        int32_t *perm = NULL;
        double lnz_v, flops_v;
        if ((st = start_cholmod(el, opts->factor, err)) == SM_OK) {
            perm = el->nfree > 0 ? vertex_block_order(el, &lnz_v, &flops_v) : NULL;
            st = analyse(el, perm, err);
        }
        free(perm);
    }
    if (!by_model) { /* the figures of the analysis run, if any */
        el->estimate.lnz = el->lnz;
        el->estimate.flops = el->flops;
        el->estimate.memory_limit = memory_limit_bytes();
        sm__solver_cost_model((double)el->nfree, &el->estimate);
    }
    if (st == SM_OK && el->solver == SM_SOLVER_AMG && el->nfree > 0) {
        int rigid_modes = opts->amg_modes == SM_AMG_MODES_ON ||
                          (opts->amg_modes == SM_AMG_MODES_AUTO &&
                           (el->dim == 2 || el->nfree >= SM_AMG_MODES_MIN_UNKNOWNS));
        st = sm__amg_new(el->dim, el->nfree, el->rowptr, el->colind, el->values, el->amg_rtol,
                        rigid_modes, &el->amg, err);
    }
    if (st != SM_OK) {
        sm__elasticity_free(el);
        return st;
    }
    el->t_analyze = sm_clock_seconds() - t0;
    *out = el;
    return SM_OK;
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
        const double w = el->stiffness ? el->stiffness[e] : 1.0;
        if (sm_element_kernel(dim, x, w * el->lambda, w * el->mu, el->alpha, ke, &vol, &lmax) != 0) {
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
 * in place (sm__amg_new).  The positions are
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
    return sm__amg_setup(el->amg, el->amg_coords, err);
}

/* In a process forked after the operator was set up (a batch's target,
 * proto/job/sm_job_batch.c), the matrix's and the factor's values are the
 * parent's pages, shared copy-on-write: rewriting them in place copies
 * each 4 KiB page on its first write, and with the run's other threads
 * on the other cores each copy interrupts them to flush their TLBs.  A
 * refactorization overwrites every value (CHOLMOD's supernodal factor
 * clears each supernode, then assembles it), so this process's first one
 * gives those pages back and writes into new ones instead (the 3D
 * example: 17k copies of a batch's target's first refactorization gone,
 * its new pages huge ones, tests/unit/test_elasticity.c). */
static void unshare_values(sm_elasticity *el)
{
    pid_t self = getpid();
    if (el->owner == self)
        return;
    el->owner = self;
    sm__discard(el->values, (size_t)el->rowptr[el->nfree] * sizeof(double));
    sm__discard(el->cpl_values, (size_t)el->cpl_rowptr[el->nfree] * sizeof(double));
    const cholmod_factor *L = el->L;
    if (el->solver == SM_SOLVER_CHOLMOD && L && L->is_super && L->xtype == CHOLMOD_REAL && L->x)
        sm__discard(L->x, L->xsize * sizeof(double));
}

sm_status sm__elasticity_factorize(sm_elasticity *el, const double *coords, sm_error *err)
{
    if (!el || !coords)
        return sm_error_set(err, SM_ERR_INVALID, "elasticity: NULL argument to factorize");
    el->factorized = 0;
    unshare_values(el);
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

sm_status sm__elasticity_solve(sm_elasticity *el, const double *load,
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
        sm_status st = sm__amg_solve(el->amg, rhs, el->amg_coords, err);
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

void sm__elasticity_matrix(const sm_elasticity *el, sm_csr_view *view)
{
    view->n = el->nfree;
    view->rowptr = el->rowptr;
    view->colind = el->colind;
    view->values = el->values;
}

int32_t sm__elasticity_dof(const sm_elasticity *el, int32_t vertex, int comp)
{
    if (vertex < 0 || vertex >= el->nverts || comp < 0 || comp >= el->dim)
        return -1;
    return el->dof[(int64_t)vertex * el->dim + comp];
}

void sm__elasticity_set_stiffness(sm_elasticity *el, const double *scale)
{
    el->stiffness = scale;
}

void sm__elasticity_timings(const sm_elasticity *el, double *assembly, double *factor)
{
    if (assembly)
        *assembly = el->t_assembly;
    if (factor)
        *factor = el->t_factor;
}

void sm__elasticity_estimate(const sm_elasticity *el, sm_solver_estimate *out)
{
    *out = el->estimate;
}

void sm__elasticity_get_info(const sm_elasticity *el, sm_elasticity_info *info)
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
        sm__amg_get_stats(el->amg, &as);
        info->amg_iterations = as.last_iterations;
        info->amg_total_iterations = as.total_iterations;
        info->amg_restarts = as.restarts;
        info->amg_min_descent = as.min_descent;
    }
    info->analyze_time = el->t_analyze;
    info->solve_time = el->t_solve;
}
