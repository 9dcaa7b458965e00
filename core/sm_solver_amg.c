/* PCG + BoomerAMG through hypre's IJ / ParCSR interface, one MPI rank.
 *
 * Parameters, measured (CPU time, one thread) on a 105k-tetrahedron
 * ball of bench/scale.sh with the shape-gradient-like loads of
 * tests/unit/test_solver.c: PMIS coarsening with extended+i
 * interpolation truncated to 4 entries per row and one level of
 * aggressive coarsening keep the hierarchy small (operator complexity
 * 1.1; memory is what this path is for): set-up 1.2 s against 4 s
 * without aggressive coarsening, for the same PCG iterations.  The
 * symmetric l1 Gauss-Seidel smoother keeps the V-cycle symmetric as PCG
 * needs (l1-Jacobi: 3x the iterations; Chebyshev: no gain); strong
 * threshold 0.5 is hypre's advice for 3D.  Nodal coarsening (row-sum
 * norm of the vertex blocks: 9 iterations against 14 with the Frobenius
 * norm) and the rotation modes as interpolation vectors (GM approach 2:
 * 7 warm-started iterations to 0.1 against 11 without) make it a
 * systems AMG for elasticity.  HMIS coarsening failed hypre's set-up
 * with the interpolation vectors on a small 3D case, PMIS does not. */
#include "sm_solver_amg.h"

#include "shapematch/sm_clock.h"

#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#include <mpi.h>
#include <HYPRE.h>
#include <HYPRE_parcsr_ls.h>
#include <_hypre_parcsr_mv.h>

_Static_assert(sizeof(HYPRE_Int) == sizeof(int32_t) && sizeof(HYPRE_BigInt) == sizeof(int32_t),
               "hypre is expected with 32-bit integers (Debian's build)");

#define MAX_MODES 3       /* rotations: 1 in 2D, 3 in 3D */
#define PCG_MAX_ITER 1000

struct sm_amg {
    int32_t n;
    int dim;
    double rtol;
    HYPRE_IJMatrix ij_A;
    HYPRE_ParCSRMatrix A;
    HYPRE_ParVector b, x, ax;       /* rhs, solution / warm start, scratch */
    HYPRE_ParVector modes[MAX_MODES];
    int nmodes;
    HYPRE_Solver amg, pcg;
    int have_start;                 /* x holds the previous solution */
    sm_amg_stats stats;
};

/* MPI's process-lifetime allocations are not leaks of ours: LeakSanitizer
 * ignores what MPI_Init allocates (sanitized builds only). */
#if defined(__SANITIZE_ADDRESS__)
#define SM_LSAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define SM_LSAN 1
#endif
#endif
#ifdef SM_LSAN
#include <sanitizer/lsan_interface.h>
#define LSAN_DISABLE() __lsan_disable()
#define LSAN_ENABLE() __lsan_enable()
#else
#define LSAN_DISABLE() ((void)0)
#define LSAN_ENABLE() ((void)0)
#endif

/* MPI is a per-process resource: initialised once, for the whole
 * process, the first time an AMG set-up runs, and left to the exit
 * (MPI_Finalize would unload components LeakSanitizer then cannot name).  The
 * once-flag is the only process-wide state of this file. */
static pthread_once_t mpi_once = PTHREAD_ONCE_INIT;
static int mpi_ok;

static void mpi_init_once(void)
{
    int initialized = 0, provided = 0;
    MPI_Initialized(&initialized);
    /* Open MPI: a singleton without its helper daemon (orted), which
     * it would otherwise fork; set only if the user did not choose. */
    setenv("OMPI_MCA_ess_singleton_isolated", "1", 0);
    if (!initialized) {
        LSAN_DISABLE();
        initialized = MPI_Init_thread(NULL, NULL, MPI_THREAD_SERIALIZED, &provided) == MPI_SUCCESS;
        LSAN_ENABLE();
    }
    mpi_ok = initialized;
}

static double *vec_data(HYPRE_ParVector v)
{
    return hypre_VectorData(hypre_ParVectorLocalVector((hypre_ParVector *)v));
}

static HYPRE_ParVector vec_new(int32_t n)
{
    HYPRE_ParVector v = NULL;
    HYPRE_BigInt part[2] = {0, n};
    if (HYPRE_ParVectorCreate(MPI_COMM_SELF, n, part, &v) != 0)
        return NULL;
    if (HYPRE_ParVectorInitialize(v) != 0) {
        HYPRE_ParVectorDestroy(v);
        return NULL;
    }
    memset(vec_data(v), 0, (size_t)n * sizeof(double));
    return v;
}

void sm_amg_free(sm_amg *amg)
{
    if (!amg)
        return;
    if (amg->pcg)
        HYPRE_ParCSRPCGDestroy(amg->pcg);
    if (amg->amg)
        HYPRE_BoomerAMGDestroy(amg->amg);
    if (amg->ij_A)
        HYPRE_IJMatrixDestroy(amg->ij_A);
    HYPRE_ParVector vs[3 + MAX_MODES] = {amg->b, amg->x, amg->ax};
    for (int k = 0; k < amg->nmodes; k++)
        vs[3 + k] = amg->modes[k];
    for (int k = 0; k < 3 + amg->nmodes; k++)
        if (vs[k])
            HYPRE_ParVectorDestroy(vs[k]);
    free(amg);
}

/* The matrix into hypre: row sizes preallocated, so the values land in
 * the CSR directly, every row in one call. */
static sm_status copy_matrix(sm_amg *amg, const int32_t *rowptr, const int32_t *colind,
                             const double *values, sm_error *err)
{
    const int32_t n = amg->n;
    sm_status st = SM_OK;
    HYPRE_Int *sizes = malloc(((size_t)n + 1) * sizeof *sizes);
    HYPRE_Int *zeros = calloc((size_t)n + 1, sizeof *zeros);
    HYPRE_BigInt *rows = malloc(((size_t)n + 1) * sizeof *rows);
    if (!sizes || !zeros || !rows) {
        st = sm_error_set(err, SM_ERR_NOMEM, "elasticity: out of memory for the AMG matrix");
        goto done;
    }
    for (int32_t r = 0; r < n; r++) {
        sizes[r] = rowptr[r + 1] - rowptr[r];
        rows[r] = r;
    }
    HYPRE_ClearAllErrors();
    if (HYPRE_IJMatrixCreate(MPI_COMM_SELF, 0, n - 1, 0, n - 1, &amg->ij_A) != 0 ||
        HYPRE_IJMatrixSetObjectType(amg->ij_A, HYPRE_PARCSR) != 0 ||
        HYPRE_IJMatrixSetDiagOffdSizes(amg->ij_A, sizes, zeros) != 0 ||
        HYPRE_IJMatrixInitialize(amg->ij_A) != 0 ||
        HYPRE_IJMatrixSetValues(amg->ij_A, n, sizes, rows, colind, values) != 0 ||
        HYPRE_IJMatrixAssemble(amg->ij_A) != 0 ||
        HYPRE_IJMatrixGetObject(amg->ij_A, (void **)&amg->A) != 0)
        st = sm_error_set(err, SM_ERR_NUMERIC, "elasticity: hypre could not build the AMG matrix");
done:
    free(sizes);
    free(zeros);
    free(rows);
    return st;
}

/* Rotation modes of the free vertices about their centroid. */
static sm_status set_modes(sm_amg *amg, const double *coords, sm_error *err)
{
    const int dim = amg->dim;
    const int32_t nv = amg->n / dim;
    double c[3] = {0, 0, 0};
    for (int32_t v = 0; v < nv; v++)
        for (int d = 0; d < dim; d++)
            c[d] += coords[(size_t)v * dim + d] / nv;
    amg->nmodes = dim == 2 ? 1 : 3;
    for (int k = 0; k < amg->nmodes; k++)
        if (!(amg->modes[k] = vec_new(amg->n)))
            return sm_error_set(err, SM_ERR_NOMEM, "elasticity: out of memory for the AMG modes");
    for (int32_t v = 0; v < nv; v++) {
        double p[3] = {0, 0, 0};
        for (int d = 0; d < dim; d++)
            p[d] = coords[(size_t)v * dim + d] - c[d];
        double *m0 = vec_data(amg->modes[0]) + (size_t)v * dim;
        if (dim == 2) {
            m0[0] = -p[1];
            m0[1] = p[0];
            continue;
        }
        double *m1 = vec_data(amg->modes[1]) + (size_t)v * 3;
        double *m2 = vec_data(amg->modes[2]) + (size_t)v * 3;
        m0[0] = 0.0;   m0[1] = -p[2]; m0[2] = p[1];
        m1[0] = p[2];  m1[1] = 0.0;   m1[2] = -p[0];
        m2[0] = -p[1]; m2[1] = p[0];  m2[2] = 0.0;
    }
    return SM_OK;
}

static void configure_amg(sm_amg *amg)
{
    HYPRE_Solver s = amg->amg;
    HYPRE_BoomerAMGSetPrintLevel(s, 0);
    HYPRE_BoomerAMGSetMaxIter(s, 1); /* one V-cycle per preconditioning */
    HYPRE_BoomerAMGSetTol(s, 0.0);
    HYPRE_BoomerAMGSetNumFunctions(s, amg->dim);
    HYPRE_BoomerAMGSetNodal(s, 4);
    HYPRE_BoomerAMGSetCoarsenType(s, 8);       /* PMIS */
    HYPRE_BoomerAMGSetInterpType(s, 6);        /* extended+i */
    HYPRE_BoomerAMGSetPMaxElmts(s, 4);
    HYPRE_BoomerAMGSetAggNumLevels(s, 1);
    HYPRE_BoomerAMGSetStrongThreshold(s, amg->dim == 3 ? 0.5 : 0.25);
    HYPRE_BoomerAMGSetRelaxType(s, 8);         /* symmetric l1 Gauss-Seidel */
    HYPRE_BoomerAMGSetRelaxOrder(s, 0);
    if (amg->nmodes > 0) {
        HYPRE_BoomerAMGSetInterpVectors(s, amg->nmodes, amg->modes);
        HYPRE_BoomerAMGSetInterpVecVariant(s, 2);
        HYPRE_BoomerAMGSetInterpVecQMax(s, 4);
    }
}

static sm_status build_solvers(sm_amg *amg, sm_error *err)
{
    HYPRE_ClearAllErrors(); /* hypre's error flag is sticky across calls */
    if (HYPRE_BoomerAMGCreate(&amg->amg) != 0 || HYPRE_ParCSRPCGCreate(MPI_COMM_SELF, &amg->pcg) != 0)
        return sm_error_set(err, SM_ERR_NOMEM, "elasticity: hypre could not create the solvers");
    configure_amg(amg);
    HYPRE_PCGSetMaxIter(amg->pcg, PCG_MAX_ITER);
    HYPRE_PCGSetTol(amg->pcg, amg->rtol);
    HYPRE_PCGSetTwoNorm(amg->pcg, 1);
    HYPRE_PCGSetPrintLevel(amg->pcg, 0);
    HYPRE_PCGSetPrecond(amg->pcg, (HYPRE_PtrToSolverFcn)HYPRE_BoomerAMGSolve,
                        (HYPRE_PtrToSolverFcn)HYPRE_BoomerAMGSetup, amg->amg);
    /* PCG's set-up runs BoomerAMG's; it reads b and x only for sizes. */
    if (HYPRE_ParCSRPCGSetup(amg->pcg, amg->A, amg->b, amg->x) != 0) {
        char what[256] = "";
        HYPRE_DescribeError(HYPRE_GetError(), what);
        HYPRE_ClearAllErrors();
        return sm_error_set(err, SM_ERR_NUMERIC,
                            "elasticity: BoomerAMG set-up failed for %ld unknowns (hypre: %s)",
                            (long)amg->n, what);
    }
    return SM_OK;
}

sm_status sm_amg_setup(sm_amg **out, int dim, int32_t n, const int32_t *rowptr,
                       const int32_t *colind, const double *values,
                       const double *coords, double rtol, sm_error *err)
{
    double t0 = sm_clock_seconds();
    pthread_once(&mpi_once, mpi_init_once);
    if (!mpi_ok)
        return sm_error_set(err, SM_ERR_IO, "elasticity: MPI could not be initialised for hypre");
    if (n <= 0 || (dim != 2 && dim != 3) || n % dim != 0 || !(rtol > 0.0))
        return sm_error_set(err, SM_ERR_INVALID, "elasticity: bad AMG problem (%ld unknowns, dim %d)",
                            (long)n, dim);
    sm_amg *old = *out;
    sm_amg *amg = calloc(1, sizeof *amg);
    if (!amg)
        return sm_error_set(err, SM_ERR_NOMEM, "elasticity: out of memory");
    amg->n = n;
    amg->dim = dim;
    amg->rtol = rtol;
    sm_status st = SM_OK;
    if (!(amg->b = vec_new(n)) || !(amg->x = vec_new(n)) || !(amg->ax = vec_new(n))) {
        st = sm_error_set(err, SM_ERR_NOMEM, "elasticity: out of memory for the AMG vectors");
        goto fail;
    }
    if (old && old->n == n && old->have_start) {
        memcpy(vec_data(amg->x), vec_data(old->x), (size_t)n * sizeof(double));
        amg->have_start = 1;
    }
    sm_amg_free(old);
    *out = NULL;
    if ((st = copy_matrix(amg, rowptr, colind, values, err)) != SM_OK)
        goto fail;
    if (coords && (st = set_modes(amg, coords, err)) != SM_OK)
        goto fail;
    if ((st = build_solvers(amg, err)) != SM_OK)
        goto fail;
    amg->stats.min_descent = 1.0;
    amg->stats.setup_time = sm_clock_seconds() - t0;
    *out = amg;
    return SM_OK;
fail:
    sm_amg_free(amg);
    return st;
}

static double dot(const double *a, const double *b, int32_t n)
{
    double s = 0.0;
    for (int32_t i = 0; i < n; i++)
        s += a[i] * b[i];
    return s;
}

/* x <- s x with s minimising the energy along x (s = b'x / x'Ax); 0 if
 * x is not a descent direction for b at all. */
static void scale_start(sm_amg *amg)
{
    double *x = vec_data(amg->x);
    double bx = dot(vec_data(amg->b), x, amg->n);
    HYPRE_ParCSRMatrixMatvec(1.0, amg->A, amg->x, 0.0, amg->ax);
    double xax = dot(x, vec_data(amg->ax), amg->n);
    double s = (bx > 0.0 && xax > 0.0) ? bx / xax : 0.0;
    for (int32_t i = 0; i < amg->n; i++)
        x[i] *= s;
}

/* One PCG solve from the current x; returns the iterations or -1. */
static int pcg(sm_amg *amg, double rtol, double *relres)
{
    HYPRE_Int iters = 0;
    HYPRE_PCGSetTol(amg->pcg, rtol);
    HYPRE_ClearAllErrors();
    int rc = HYPRE_ParCSRPCGSolve(amg->pcg, amg->A, amg->b, amg->x);
    HYPRE_ParCSRPCGGetNumIterations(amg->pcg, &iters);
    HYPRE_ParCSRPCGGetFinalRelativeResidualNorm(amg->pcg, relres);
    HYPRE_PCGSetTol(amg->pcg, amg->rtol);
    if (rc != 0) {
        HYPRE_ClearAllErrors();
        if (!(*relres <= rtol))
            return -1;
    }
    return (int)iters;
}

sm_status sm_amg_solve(sm_amg *amg, const double *rhs, double *x, sm_error *err)
{
    const int32_t n = amg->n;
    double *b = vec_data(amg->b), *xs = vec_data(amg->x);
    memcpy(b, rhs, (size_t)n * sizeof(double));
    double bnorm = sqrt(dot(b, b, n)), relres = 0.0;
    if (bnorm == 0.0) {
        memset(x, 0, (size_t)n * sizeof(double));
        return SM_OK;
    }
    if (amg->have_start)
        scale_start(amg);
    int it = pcg(amg, amg->rtol, &relres);
    double bx = dot(b, xs, n);
    if (it >= 0 && !(bx > 0.0)) {
        amg->stats.restarts++;
        memset(xs, 0, (size_t)n * sizeof(double));
        it = pcg(amg, amg->rtol * 0.01, &relres);
        bx = dot(b, xs, n);
    }
    if (it < 0 || !(bx > 0.0))
        return sm_error_set(err, SM_ERR_NUMERIC,
                            "elasticity: AMG-preconditioned CG did not converge (relative residual %.3g "
                            "after %d iterations, tolerance %.3g)", relres, PCG_MAX_ITER, amg->rtol);
    double xnorm = sqrt(dot(xs, xs, n));
    double descent = bx / (bnorm * xnorm);
    amg->have_start = 1;
    amg->stats.last_iterations = it;
    amg->stats.last_residual = relres;
    amg->stats.total_iterations += it;
    amg->stats.solves++;
    if (descent < amg->stats.min_descent)
        amg->stats.min_descent = descent;
    memcpy(x, xs, (size_t)n * sizeof(double));
    return SM_OK;
}

void sm_amg_get_stats(const sm_amg *amg, sm_amg_stats *stats)
{
    if (amg)
        *stats = amg->stats;
    else
        memset(stats, 0, sizeof *stats);
}
