/* The shape model of a batch's results (shapematch/sm_shape_model.h for
 * the mathematics): read each member's deformed template, build the
 * model, write its files.  `shapematch batch` and the daemon's batch
 * parent both build their model through it, so both give the same files.
 *
 * A member is one result folder as `shapematch run` or a job writes it:
 * its deformed template is read from result.mesh (else result.meshb,
 * result.mesh.gz, result.meshb.gz); every member must have the first
 * member's topology (vertex count, elements), which holds for the
 * results of one template.  A member that cannot be read is an error
 * (SM_ERR_IO / SM_ERR_FORMAT / SM_ERR_INVALID naming it): the caller
 * leaves failed targets out before.
 *
 * The model folder (written file by file atomically, summary.json last):
 *   mean.mesh     the mean shape on the template's topology
 *   mean.vtu      the same for ParaView
 *   modes.vtu     the mean with one vector point field per written mode,
 *                 mode1..modeK, each as in mode_K.sol (ParaView: Warp By
 *                 Vector with a scale factor of t standard deviations)
 *   mode_K.sol    mode K as a vector field: the displacement of one
 *                 standard deviation along it (sqrt(lambda_K) u_K), so
 *                 mean + t * mode_K is the shape at t standard deviations
 *   scores.csv    header target,mode1,...,modeK; one row per member, its
 *                 scores X_i . u_k (lengths, every mode)
 *   summary.json  {"members": n, "dimension", "vertices", "align",
 *                 "procrustes_rounds", "modes" (all), "modes_written",
 *                 "total_variance", "variance" (lambda_k, every mode),
 *                 "variance_explained" (fractions, descending),
 *                 "compactness", "generalization", "specificity" (curves
 *                 for 1..neval modes), "evaluation" {modes, held_out,
 *                 samples, seed}, "targets" [names], "files" [...],
 *                 "timings" {read, build, write} (seconds)}
 * Mode files are written for the first max_modes modes (default
 * SM_JOB_MODEL_MAX_MODES); scores, variance and variance_explained cover
 * every mode. */
#ifndef SM_JOB_MODEL_H
#define SM_JOB_MODEL_H

#include <stddef.h>

#include "shapematch/sm_error.h"
#include "shapematch/sm_shape_model.h"

#define SM_JOB_MODEL_MAX_MODES 20
#define SM_MODEL_SUMMARY_FILE "summary.json"

typedef struct {
    const char *name;       /* the target's name (scores.csv, summary) */
    const char *result_dir; /* a folder written by run / a job's results */
} sm_model_member;

typedef struct sm_model_opts {
    sm_shape_align align;   /* the core's enum and names (sm_shape_align_parse) */
    int max_modes;          /* mode files written; 0: SM_JOB_MODEL_MAX_MODES */
    int eval_modes, eval_shapes, samples; /* sm_shape_model_opts; 0: defaults */
    unsigned long long seed;
    unsigned write_flags;   /* SM_ATOMIC_FSYNC: every file durable */
} sm_model_opts;

/* The model of members[0..n-1] (n >= 1) into out_dir (created when
 * missing).  Errors: SM_ERR_IO / SM_ERR_FORMAT for a member that cannot
 * be read or a file that cannot be written, SM_ERR_INVALID for a member
 * of another topology, the core's (sm_shape_model_build). */
sm_status sm_job_model_build(const sm_model_member *members, size_t n, sm_shape_align align,
                             const char *out_dir, sm_error *err);
/* The same with every option (opts NULL: rigid and the defaults). */
sm_status sm_job_model_build_opts(const sm_model_member *members, size_t n,
                                  const sm_model_opts *opts, const char *out_dir,
                                  sm_error *err);

#endif
