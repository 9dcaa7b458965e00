/* The result set of a job run (sm_job_runner.h) and its summary document.
 *
 * The result set (file names: sm_proto_vocab.h), written into one folder,
 * each file atomically (sm_atomic.h), summary.json last after an older
 * one is removed, so its presence vouches for a complete set from one run:
 *   result.mesh, result.meshb   deformed template (same topology, refs)
 *   result.vtu                  with point fields displacement, distance
 *   result.smmesh               the binary payload (proto/PAYLOAD.md)
 *   displacement.sol, .solb     cumulative displacement x_k - x_0
 *   history.csv, history.json   one row per iteration
 *   summary.json                the summary document below
 * and, with params.save_every K > 0, iter-NNNNN.mesh after iterations K,
 * 2K, ... into the snapshot folder the caller names (the runner writes
 * those during the run).
 *
 * summary.json: sm_result_to_jansson's members (stop_reason, iterations,
 * J_initial, J_final, boundary_l2, boundary_max, min_quality, accepted,
 * rejected, timings, parameters) plus shapematch_version, status,
 * exit_code, inverted_elements, field_builds, timings.read and
 * timings.field_build, inputs (the names the caller gives), template
 * (dimension and counts; physical_names [{dim, tag, name}] when the
 * template is a Gmsh .msh with $PhysicalNames), outputs (the file of each result format) and
 * warnings ([{code, message, figure}], sm_job_warnings.h; [] when none).
 * The daemon serves it as GET /v1/jobs/{id}/results, adding jobID and
 * links. */
#ifndef SM_JOB_RESULTS_H
#define SM_JOB_RESULTS_H

#include <jansson.h>

#include "job/sm_job_inputs.h"
#include "job/sm_job_runner.h"
#include "shapematch/sm_error.h"

/* Writes the whole result set into dir (which exists).  flags:
 * SM_ATOMIC_FSYNC makes every file durable. */
sm_status sm_job_write_results(const sm_job_inputs *in, const sm_job_run *run,
                               const sm_job_files *names, const char *dir,
                               unsigned flags, sm_error *err);

/* sm_job_write_results limited to outputs; the summary's "outputs" lists
 * exactly the files written. */
sm_status sm_job_write_selected(const sm_job_inputs *in, const sm_job_run *run,
                                const sm_job_files *names, const char *dir,
                                unsigned outputs, unsigned flags, sm_error *err);
/* The summary document (a new reference; NULL when out of memory), its
 * "outputs" limited to outputs (SM_RESULT_OUT_ALL: every file).  names: what
 * "inputs" reports for each file. */
/* doc as indented JSON and a newline in dir/name, atomically (flags: the
 * SM_ATOMIC_* of sm_atomic_write_file); a NULL doc is out of memory. */
sm_status sm_job_write_json(const char *dir, const char *name, const json_t *doc, unsigned flags,
                            sm_error *err);

json_t *sm_job_summary_outputs(const sm_job_inputs *in, const sm_job_run *run,
                               const sm_job_files *names, unsigned outputs);

#endif
