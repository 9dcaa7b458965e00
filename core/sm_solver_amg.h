/* Preconditioned conjugate gradients with hypre's BoomerAMG, for the
 * elastic operator of large templates (sm_elasticity with
 * SM_SOLVER_AMG).  Internal to the core.
 *
 * The matrix is the free x free block in CSR with both triangles, DOFs
 * vertex-major (dim unknowns per vertex), each row's diagonal first, as
 * sm_elasticity builds it for this solver; hypre reads it in place.
 * BoomerAMG runs as a systems AMG for elasticity: num_functions = dim,
 * nodal coarsening on the dim x dim vertex blocks, and on large problems
 * the rotations of the rigid-body modes (the translations are implicit)
 * as interpolation vectors, so that the coarse spaces represent the
 * near-null space.
 *
 * hypre in Debian is built with MPI: the first sm__amg_new initialises MPI
 * once for the process (a single rank, no mpirun needed) and everything
 * runs on MPI_COMM_SELF.  hypre is built without OpenMP, so the result
 * does not depend on the thread count. */
#ifndef SM_SOLVER_AMG_H
#define SM_SOLVER_AMG_H

#include <stdint.h>

#include "shapematch/sm_error.h"

typedef struct sm_amg sm_amg;

/* Wraps the matrix (n rows; rowptr/colind/values as in sm_csr_view,
 * each row's diagonal entry first) for hypre without copying it: the
 * arrays are borrowed, must outlive the object, and values may change
 * between set-ups (hypre only reads them).  Initialises MPI for the
 * process on the first call.  rtol: relative error of the PCG solves in
 * the energy norm (> 0), bounded by the preconditioned residual over the
 * smallest Ritz value of the preconditioned operator (sm_solver_amg.c).
 * rigid_modes: 1 if the hierarchy takes the rotations as interpolation
 * vectors (see SM_AMG_MODES_MIN_UNKNOWNS), 0 if not.
 * SM_ERR_INVALID if a row does not start with its diagonal. */
sm_status sm__amg_new(int dim, int32_t n, const int32_t *rowptr, const int32_t *colind,
                     const double *values, double rtol, int rigid_modes, sm_amg **out,
                     sm_error *err);
void sm__amg_free(sm_amg *amg);

/* From how many unknowns a 3D hierarchy takes the rigid-body rotations
 * as interpolation vectors (sm_elasticity's SM_AMG_MODES_AUTO; 2D ones,
 * where the AMG path is only used when asked for, always do).  They
 * make the set-up dearer (the coarse levels carry 6 unknowns per vertex
 * in 3D instead of 3: 2.4x the instructions at 30k tetrahedra) and pay
 * back as PCG iterations on larger templates.  Measured on the balls of
 * bench/scale.sh (match_bench, 40 iterations; PCG iterations per solve
 * without / with, iteration reaching 1.5e-4 without / with): 10k-50k
 * tetrahedra 2.6 / 2.6 and 14-16 / 15; the 30k example 2.7 / 2.8 over
 * 160 iterations, 2.9e-4 at 13 and 1.5e-4 at 15 either way, set-up
 * 0.033 / 0.057 s; 100k (55k unknowns) 2.8 / 2.7, 14 / 15, set-up
 * 0.18 / 0.27 CPU s; 200k (107k unknowns) 3.2 / 2.8, 16 / 15; 300k
 * 3.3 / 2.7, 16 / 13; 988k 3.2 / 2.5 (1.10 / 0.89 CPU s per
 * iteration).  Those figures predate issue 21: the V-cycle is now
 * balanced with all rigid motions at every size, which is what bounds
 * the near-rigid error below this threshold (sm_solver_amg.c). */
#define SM_AMG_MODES_MIN_UNKNOWNS 80000

/* Builds the AMG hierarchy on the matrix's current values (after each
 * assembly) and the balancing of the V-cycle with the rigid motions.
 * coords: the positions of the n/dim free vertices (dim each, in DOF
 * order) for the rigid-body modes (of the hierarchy if the object takes
 * them, and of the balancing), or NULL for neither.  hypre's flag for a
 * zero row on a coarse level is not a failure when the hierarchy is
 * otherwise sound (see hierarchy_usable).  The previous solution stays
 * the warm start of the next solve. */
sm_status sm__amg_setup(sm_amg *amg, const double *coords, sm_error *err);

/* Solves A x = rhs (n entries) by PCG from a warm start: the previous
 * solution, scaled to minimise the energy along it (or zero if it does
 * not descend for rhs), so that the start has energy 1/2 x'Ax - rhs'x
 * <= 0 and every CG iterate, which only lowers it, is a descent
 * direction for rhs (rhs'x > 0).  At least one PCG step, then until the
 * bound of the energy-norm error is below rtol with rhs'x > 0.  If PCG
 * breaks down from the warm start (round-off), solves again from zero.
 * SM_ERR_NUMERIC if PCG breaks down or does not reach the tolerance. */
sm_status sm__amg_solve(sm_amg *amg, const double *rhs, double *x, sm_error *err);

typedef struct sm_amg_stats {
    int last_iterations;     /* PCG iterations of the last solve */
    double last_residual;    /* its final bound of the relative energy error */
    long total_iterations;   /* over all solves since set-up */
    int solves;
    int restarts;            /* solves that had to restart from zero */
    double min_descent;      /* min over solves of rhs'x / (|rhs| |x|) */
    double setup_time;       /* seconds of the last sm__amg_setup */
    double hierarchy_time;   /* of which hypre's BoomerAMG set-up */
    double operator_complexity;
} sm_amg_stats;
void sm__amg_get_stats(const sm_amg *amg, sm_amg_stats *stats);

#endif
