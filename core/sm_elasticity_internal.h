/* The elastic operator's state, shared by sm_elasticity.c (options,
 * assembly, solvers) and sm_elasticity_pattern.c (DOF numbering, CSR
 * patterns, slot map).  Private to those two files. */
#ifndef SM_ELASTICITY_INTERNAL_H
#define SM_ELASTICITY_INTERNAL_H

#include <stdint.h>
#include <sys/types.h>

#include <cholmod.h>

#include "sm_elasticity.h"
#include "sm_solver_amg.h"

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
    const double *stiffness; /* per-element factor of lambda and mu, or
                              * NULL (sm__elasticity_set_stiffness) */

    int32_t nfree;          /* free DOFs */
    int32_t nclamped_dofs;  /* clamped DOFs (of vertices used by elements) */
    int32_t *dof;           /* nverts*dim: free DOF index or -1 */
    int32_t *clamped_global;/* nclamped_dofs: global index v*dim+c */

    /* free x free block, full symmetric pattern; columns ascending, or
     * with diag_first (the AMG solver's layout) the diagonal entry first
     * and the others ascending; colind, values (and slots) from
     * sm__alloc_huge, freed with free() */
    int32_t *rowptr, *colind;
    double *values;
    int diag_first;
    /* free x clamped block; columns are clamped DOF indices */
    int32_t *cpl_rowptr, *cpl_colind;
    double *cpl_values;

    int32_t *slots;         /* nelems * (dim+1)^2: block starts (build_slot_map,
                             * sm_elasticity_pattern.c) */

    cholmod_common cc;
    int cc_started;
    cholmod_sparse A;       /* wraps rowptr/colind/values */
    cholmod_factor *L;
    cholmod_dense *X, *Y, *E; /* cholmod_solve2 workspaces, reused */
    double *rhs;            /* nfree */
    int factorized;

    pid_t owner;            /* the process whose memory values and L's
                             * values are (sm__elasticity_factorize) */

    double lnz, flops;      /* from the symbolic analysis */
    sm_solver_estimate estimate; /* auto's cost model (sm_elasticity.h) */
    double rcond;           /* of the last numeric factorization */
    double t_analyze, t_assembly, t_factor, t_solve;

    sm_solver_kind solver;  /* CHOLMOD or AMG (resolved) */
    double amg_rtol;
    sm_amg *amg;            /* AMG: hypre's matrix, hierarchy, warm start */
    double *amg_coords;     /* AMG: free vertex positions (rigid modes) */
};

/* Numbers the DOFs of el's mesh (clamped: nverts flags or NULL; the
 * vertices of no element carry no unknown either) and builds the CSR
 * patterns of the free x free and free x clamped blocks, in the layout
 * el->diag_first says, and the slot map; allocates el->rhs.  Needs dim,
 * nverts, nelems, elems, alpha and diag_first set; SM_ERR_INVALID when
 * nothing is clamped and alpha is 0, SM_ERR_NOMEM. */
sm_status sm__elasticity_pattern(sm_elasticity *el, const uint8_t *clamped, sm_error *err);

/* Turns a pattern built in CHOLMOD's layout (columns ascending) into the
 * AMG solver's (diag_first), rows and slot map, in place: what
 * sm__elasticity_pattern builds with diag_first set, without building it
 * again (auto decides after the pattern is built). */
void sm__elasticity_pattern_diag_first(sm_elasticity *el);

#endif
