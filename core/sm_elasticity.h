/* Linear elasticity with P1 Lagrange elements:
 *   find u with u = g on the clamped vertices such that for all v
 *   (v = 0 there):  int sigma(u):eps(v) + alpha int u.v = F(v),
 * sigma(u) = 2 mu eps(u) + lambda tr(eps(u)) I, Lame coefficients from
 * Young's modulus E and Poisson ratio nu (plane strain in 2D).
 *
 * Dirichlet degrees of freedom are eliminated (not penalised): the system
 * is assembled on the free DOFs only, the clamped values move to the
 * right-hand side.  The sparsity pattern depends only on the topology, so
 * it is built once together with an element-to-CSR-slot map and CHOLMOD's
 * symbolic analysis; each sm__elasticity_factorize() only refills values
 * and refactorizes numerically. */
#ifndef SM_ELASTICITY_H
#define SM_ELASTICITY_H

#include <stdint.h>

#include "shapematch/sm_error.h"
#include "shapematch/sm_mesh.h"
#include "shapematch/sm_params.h"

typedef struct sm_elasticity sm_elasticity;

/* Which Cholesky CHOLMOD computes.  AUTO (the default) lets CHOLMOD
 * decide from the flop count of the symbolic analysis; the other two
 * force one kind, for benchmarks. */
typedef enum sm_factor_kind {
    SM_FACTOR_AUTO = 0,
    SM_FACTOR_SIMPLICIAL = 1,
    SM_FACTOR_SUPERNODAL = 2
} sm_factor_kind;

/* Whether the AMG hierarchy carries the rigid-body rotations as
 * interpolation vectors (sm_solver_amg.h).  AUTO (the default): in 3D
 * from SM_AMG_MODES_MIN_UNKNOWNS free unknowns on, in 2D always; the
 * other two force it, for tests and benchmarks. */
typedef enum sm_amg_modes {
    SM_AMG_MODES_AUTO = 0,
    SM_AMG_MODES_ON = 1,
    SM_AMG_MODES_OFF = 2
} sm_amg_modes;

/* What sm__elasticity_new builds: the material, the zero-order term and
 * the factor kind.  A compound literal names only what it sets:
 *   sm__elasticity_new(m, clamped, &(sm_elasticity_opts){.young = 1,
 *                     .poisson = 0.3}, &el, &err)
 * (alpha 0, SM_FACTOR_AUTO). */
typedef struct sm_elasticity_opts {
    double young;          /* Young's modulus E: finite, > 0 */
    double poisson;        /* Poisson ratio nu: in (-1, 0.5) */
    double alpha;          /* zero-order (mass) term: finite, >= 0 */
    sm_factor_kind factor; /* SM_FACTOR_AUTO (0) unless forced */
    sm_solver_kind solver; /* AUTO (0): sm_solver_resolve on the mesh size */
    double amg_rtol;       /* AMG: relative energy-norm error of each
                            * solve (bounded); 0 = SM_ELASTICITY_AMG_RTOL */
    sm_amg_modes amg_modes; /* AMG: SM_AMG_MODES_AUTO (0) unless forced */
} sm_elasticity_opts;

/* Relative error in the energy norm of the inexact AMG solves, bounded
 * by the preconditioned residual over the smallest Ritz value of the
 * preconditioned operator (sm_solver_amg.c).  Loose on purpose: any SPD
 * solve gives a descent direction and the step search normalises it;
 * tight enough that the map does not depend on the solver (issue 21:
 * within 1.5% of CHOLMOD's on the examples and an asymmetric pull).
 * tests/unit/test_solver.c and test_solver_accuracy.c check the true
 * error against CHOLMOD in 2D and 3D. */
#define SM_ELASTICITY_AMG_RTOL 0.1

/* clamped: nverts flags (all components of a flagged vertex are fixed),
 * may be NULL for none.  With no clamped vertex opts->alpha must be > 0.
 * Checks the mesh and the options (SM_ERR_INVALID naming what is wrong),
 * numbers the DOFs and runs CHOLMOD's symbolic analysis (AMG: hands the
 * matrix's arrays to hypre, initialising MPI on the first call).  opts is read
 * only during the call; the mesh topology (m->elems) is borrowed and must
 * outlive the object. */
sm_status sm__elasticity_new(const sm_mesh *m, const uint8_t *clamped,
                            const sm_elasticity_opts *opts, sm_elasticity **out,
                            sm_error *err);
void sm__elasticity_free(sm_elasticity *el);

/* Assembles the stiffness (+ alpha mass) matrix on the vertex positions
 * coords (nverts*dim) and factorizes it (numeric Cholesky), or with the
 * AMG solver builds the AMG hierarchy on it (hypre reads the matrix in
 * place; the rigid-body modes from coords). */
sm_status sm__elasticity_factorize(sm_elasticity *el, const double *coords,
                                  sm_error *err);

/* Solves with the last factorization (AMG: by PCG to amg_rtol, warm
 * started from the previous solution, and always a descent direction:
 * load'u > 0 on the free DOFs whenever that load is nonzero).  load: nodal forces (nverts*dim,
 * the assembled F(phi_i e_c)); dirichlet: values on clamped vertices
 * (nverts*dim, only clamped entries read) or NULL for 0; u: output
 * nverts*dim (clamped entries set to the Dirichlet values). */
sm_status sm__elasticity_solve(sm_elasticity *el, const double *load,
                              const double *dirichlet, double *u,
                              sm_error *err);

/* Free-DOF matrix in CSR form with the full symmetric pattern (both
 * triangles stored, each assembled from the element matrices), for tests
 * and diagnostics.  Valid after sm__elasticity_factorize.  Free DOF k of
 * vertex v, component c is given by sm__elasticity_dof().  The columns of
 * a row are in increasing order (CHOLMOD reads them so), except with the
 * AMG solver, where the diagonal entry comes first and the others follow
 * in increasing order: the layout hypre reads in place (its smoothers
 * take the first entry of a row as the diagonal). */
typedef struct sm_csr_view {
    int32_t n;              /* number of free DOFs */
    const int32_t *rowptr;  /* n+1 */
    const int32_t *colind;  /* rowptr[n] entries, in the order above */
    const double *values;   /* nnz */
} sm_csr_view;
void sm__elasticity_matrix(const sm_elasticity *el, sm_csr_view *view);
/* Free DOF index of (vertex, component), or -1 if clamped. */
int32_t sm__elasticity_dof(const sm_elasticity *el, int32_t vertex, int comp);

/* Per-element stiffening for the next factorizations: element e's Lame
 * coefficients are multiplied by scale[e] (> 0, finite; nelems values,
 * borrowed until the next call or sm__elasticity_free), the zero-order
 * term is not.  NULL (the default) = 1 everywhere.  The descent stiffens
 * distorted elements this way (sm_match.c). */
void sm__elasticity_set_stiffness(sm_elasticity *el, const double *scale);

/* Timings (seconds) of the last factorize: assembly, numeric factor. */
void sm__elasticity_timings(const sm_elasticity *el, double *assembly,
                           double *factor);

/* ---- Additions: options, diagnostics and a per-element helper. ---- */

/* Lame coefficients from Young's modulus and Poisson ratio (plane strain
 * in 2D uses the same formulas):
 *   lambda = E nu / ((1+nu)(1-2nu)),  mu = E / (2(1+nu)). */
void sm__lame(double young, double poisson, double *lambda, double *mu);

typedef struct sm_elasticity_info {
    int32_t nfree;          /* free DOFs (order of the system) */
    int32_t nclamped;       /* clamped DOFs */
    int64_t nnz;            /* entries of the free x free CSR (both triangles) */
    int64_t nnz_coupling;   /* entries of the free x clamped CSR block */
    double nnz_factor;      /* entries of L (from the symbolic analysis) */
    double flops;           /* flop count of one numeric factorization */
    int supernodal;         /* 1 if the factor is supernodal */
    const char *ordering;   /* fill-reducing ordering CHOLMOD selected */
    double analyze_time;    /* seconds: pattern, slot map and analysis */
    double solve_time;      /* seconds: last sm__elasticity_solve */
    double rcond;           /* last factorization: (min/max pivot) estimate
                             * of 1/cond (cholmod_rcond); 0 if none */
    sm_solver_kind solver;  /* CHOLMOD or AMG (AUTO resolved) */
    int amg_iterations;     /* AMG: PCG iterations of the last solve */
    long amg_total_iterations; /* AMG: since the last factorize */
    int amg_restarts;       /* AMG: solves restarted from zero (not descent) */
    double amg_min_descent; /* AMG: min load'u / (|load| |u|) over solves */
} sm_elasticity_info;
void sm__elasticity_get_info(const sm_elasticity *el, sm_elasticity_info *info);

/* `auto`'s choice between the solvers (3D; 2D templates always take
 * CHOLMOD), made by sm__elasticity_new from a cost model instead of a size
 * threshold (from SM_SOLVER_AUTO_MODEL_MIN_TETS on): CHOLMOD's fill-reducing order and symbolic analysis are
 * computed first (cheap next to a factorization; they are kept when
 * CHOLMOD is chosen), and with the factor's entries and flops and the
 * matrix's entries the model predicts each solver's time for a set-up and
 * SM_SOLVER_AUTO_HORIZON solves, and its memory.  CHOLMOD is taken when it
 * is predicted faster and its memory fits SM_SOLVER_AUTO_MEMORY_SHARE of
 * the memory the process may use (the least of RLIMIT_AS, the cgroup's
 * memory.max and the machine's memory).  The constants are fitted on
 * measurements (bench/solver_bench.c, docs/solvers.md). */
#define SM_SOLVER_AUTO_HORIZON 100
/* Below this many tetrahedra auto takes CHOLMOD without the model: the
 * model is fitted from 30k up, and there CHOLMOD was 1.2-2x cheaper on
 * every shape measured (and its solves are exact). */
#define SM_SOLVER_AUTO_MODEL_MIN_TETS 20000
#define SM_SOLVER_AUTO_MEMORY_SHARE 0.5

typedef struct sm_solver_estimate {
    double nnz;             /* entries of the free x free matrix */
    double lnz, flops;      /* CHOLMOD's factor from the analysis; 0 if the
                             * analysis was not run (an AMG run asked for) */
    double cholmod_seconds; /* predicted: a factorization and the horizon's
                             * solves (0 without the analysis) */
    double amg_seconds;     /* predicted: a hierarchy and the horizon's solves */
    double cholmod_bytes;   /* predicted peak memory of each (0: unknown) */
    double amg_bytes;
    double memory_limit;    /* bytes the process may use, 0 = unknown */
} sm_solver_estimate;

/* The model's figures for el's template (what auto decided on). */
void sm__elasticity_estimate(const sm_elasticity *el, sm_solver_estimate *out);

/* The model itself, for tests and the benchmark: the estimate's predicted
 * fields from its nnz, lnz, flops and unknowns. */
void sm__solver_cost_model(double unknowns, sm_solver_estimate *est);

/* The model's choice: SM_SOLVER_CHOLMOD or SM_SOLVER_AMG. */
sm_solver_kind sm__solver_auto_choice(const sm_solver_estimate *est);

/* Element matrix of one simplex, for tests and diagnostics: vertex_coords
 * holds the dim+1 vertices (dim doubles each, any orientation); ke
 * receives the ((dim+1)*dim)^2 entries row-major, local DOF i*dim+c for
 * vertex i, component c:
 *   |K| (mu (grad phi_i . grad phi_j) delta_cd + mu d_d phi_i d_c phi_j
 *        + lambda d_c phi_i d_d phi_j) + alpha int_K phi_i phi_j delta_cd.
 * *volume receives the signed volume.  SM_ERR_NUMERIC if the simplex is
 * degenerate (|volume| <= 1e-12 * (longest edge)^dim) or not finite. */
sm_status sm__elasticity_element_matrix(int dim, const double *vertex_coords,
                                       double lambda, double mu, double alpha,
                                       double *ke, double *volume,
                                       sm_error *err);

/* Behaviour notes:
 * - Element orientation is irrelevant (|volume| is used); a degenerate
 *   element (see above) or non-finite coordinates make
 *   sm__elasticity_factorize fail with SM_ERR_NUMERIC naming the element.
 * - A matrix CHOLMOD finds not positive definite, or numerically singular
 *   (pivot ratio estimate below SM_ELASTICITY_MIN_RCOND, e.g. a clamp
 *   that leaves a rigid motion free), fails with SM_ERR_NUMERIC and the
 *   CHOLMOD status in the message.
 * - load may be NULL (no load).  sm__elasticity_solve before a successful
 *   factorize returns SM_ERR_INVALID.
 * - When every vertex is clamped there is no system: solve returns the
 *   Dirichlet values.  Vertices used by no element carry no unknown and
 *   are treated like clamped ones (0 or their Dirichlet value).
 * - Error messages number elements and vertices from 1, as in the files. */
#define SM_ELASTICITY_MIN_RCOND 1e-14

#endif
