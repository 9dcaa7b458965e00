/* A batch whose template comes from the population itself
 * (`shapematch batch --template-from FILE|medoid|mean [--rounds K]`,
 * docs/populations.md): rounds of sm_job_batch_run, each on the template
 * the previous round chose, so that the model does not depend on a
 * hand-picked template.
 *
 *   file    one round on the given template (sm_job_batch_run), the
 *           model's files saying so;
 *   medoid  round 1 on the given template; the medoid is the target whose
 *           matched shape is closest to all others: the smallest sum over
 *           the other targets of the two-sided RMS distance between the
 *           matched shapes' boundaries (vertices of each to the facets of
 *           the other, exact, sm_sdf.h), each pair after the model's
 *           alignment (opts->model.align: rigid by default, least squares
 *           over the corresponding vertices; the matched shapes share the
 *           template's mesh).  Round 2 runs on the medoid's result mesh
 *           (a mesh already shaped like that target, on the template's
 *           topology: no re-meshing);
 *   mean    round k+1 runs on round k's model mean (model/mean.mesh, on
 *           the template's topology) placed on round k's template: moved
 *           onto it by the least-squares rigid motion over the
 *           corresponding vertices (none with model.align none), since
 *           the model leaves its mean in the first member's frame, whose
 *           rotation is arbitrary on a round member and would make the
 *           template turn from round to round.  The rounds stop when the
 *           placed mean moves less than tolerance (the two-sided RMS
 *           distance between its boundary and round k's template's,
 *           divided by its bounding-box diagonal) or after rounds rounds.
 *           A mean with an inverted element is no template: the
 *           iteration stops there and keeps that round's results (on the
 *           last valid template), saying so.
 *
 * The rounds run here (sm_job_batch_run) or where r->run sends them (a
 * daemon: `batch --server`); a target with a result is one whose status
 * is finished or not_converged (local) or successful (a daemon's).
 *
 * Files: with medoid and mean each round is a whole batch folder
 * out_dir/rounds/K/ (targets/, model/, summary.json; for the mean,
 * template.mesh: the placed mean round K > 1 runs on); the last round's
 * targets/ and model/ are then moved to out_dir/targets and
 * out_dir/model, its template copied to out_dir/template.mesh, and
 * out_dir/summary.json and out_dir/model/summary.json get a
 * "template_from" object: {"mode", "start" (the given template),
 * "template" (the last round's), "rounds", "max_rounds", "tolerance",
 * "movement" [one per round after the first], "mean_min_quality" [one
 * per round], "stop", "medoid", "medoid_distances" {name: sum}}. */
#ifndef SM_JOB_TEMPLATE_FROM_H
#define SM_JOB_TEMPLATE_FROM_H

#include "job/sm_job_batch.h"
#include "sm_proto_vocab.h"

/* sm_template_from, its names and SM_TEMPLATE_ROUNDS_MAX: sm_proto_vocab.h
 * (the daemon's batch request spells them too) */
#define SM_TEMPLATE_ROUNDS_DEFAULT 3   /* mean: at most this many rounds */
/* mean: relative movement below which the mean has settled.  On the 2D
 * ellipses of tests/cli/batch_rounds.sh the movement is about 1e-3
 * between rounds 1 and 2 and a few 1e-4 after: 1e-3 stops at the second
 * or third round (docs/populations.md). */
#define SM_TEMPLATE_TOLERANCE_DEFAULT 1e-3


typedef struct sm_rounds_opts {
    sm_template_from from;
    int rounds;        /* mean: 2..SM_TEMPLATE_ROUNDS_MAX (0: default) */
    double tolerance;  /* mean: > 0 (0: default) */
    /* after each round (may be NULL): its number, the template it ran on,
     * the mean's movement (NAN for none), and the next round's template
     * (NULL: the last round) */
    void (*round_done)(int round, const char *template_path, double movement,
                       const char *next_template, void *user);
    /* one round's batch (NULL: sm_job_batch_run, on this machine): list
     * on opts (opts->template_mesh: the round's template) into round_dir,
     * which then holds targets/NAME/ (each result mesh), model/
     * (mean.mesh, summary.json) and summary_file ("targets": each one's
     * "name" and "status"); round: its number, 1 first.  `batch --server`
     * runs each round as a daemon's batch (client/cmd_batch_remote.c);
     * the choice of the next template stays here, one for both. */
    sm_status (*run)(const sm_batch_list *list, const sm_batch_opts *opts, int round,
                     const char *round_dir, sm_batch_outcome *out, void *user, sm_error *err);
    void *run_user;
    const char *summary_file; /* the round's summary (NULL: "summary.json") */
} sm_rounds_opts;

#define SM_ROUNDS_STOP_LEN 32
typedef struct sm_rounds_outcome {
    int rounds;                        /* rounds run */
    char stop[SM_ROUNDS_STOP_LEN];     /* "file", "medoid", "converged",
                                        * "rounds", "mean_inverted",
                                        * "model_failed", "no_medoid",
                                        * "cancelled" */
    char medoid[SM_ERROR_MSG_LEN];     /* the medoid's name (medoid) */
    double movement[SM_TEMPLATE_ROUNDS_MAX];  /* [k]: between the means of
                                        * rounds k + 1 and k + 2 */
    char message[SM_ERROR_MSG_LEN];    /* why it stopped early, or "" */
} sm_rounds_outcome;

/* The batch of list with opts (whose template_mesh is the given or first
 * template) and r into out_dir; *out is the last round's outcome.
 * Errors: sm_job_batch_run's (the template, the parameters, writing),
 * SM_ERR_INVALID for options that do not go together (template
 * landmarks or no model with medoid/mean: they belong to one template;
 * rounds or tolerance out of range), SM_ERR_IO when out_dir already
 * holds targets/ or rounds/ (nothing of an earlier batch is
 * overwritten).  A mean that cannot be a template is not an error: the
 * rounds stop, r's outcome says why (stop, message). */
sm_status sm_job_batch_rounds(const sm_batch_list *list, const sm_batch_opts *opts,
                              const sm_rounds_opts *r, const char *out_dir,
                              sm_batch_outcome *out, sm_rounds_outcome *ro, sm_error *err);

/* After `batch --model-from BATCH_DIR` built BATCH_DIR/model again: its
 * summary.json gets BATCH_DIR/summary.json's "template_from" back (when
 * there is one), so the model still says which template it stands on.
 * SM_ERR_IO / SM_ERR_NOMEM. */
sm_status sm_job_rounds_keep_template_from(const char *batch_dir, unsigned write_flags,
                                           sm_error *err);

/* The two-sided RMS distance between the boundaries of one mesh's
 * topology m (sm_mesh_build_boundary done) at coordinates a and b: the
 * root of the mean, over the boundary vertices of both, of the squared
 * distance of a vertex of one to the boundary facets of the other
 * (exact, sm_sdf.h).  -1 when out of memory. */
double sm_job_boundary_rms(const sm_mesh *m, const double *a, const double *b);

#endif
