/* /v1/batches: one template matched onto many targets, and a shape model
 * of the results (issue 25; docs/api.md, "Batches").
 *
 * A batch is a parent with child jobs.  The children (the batch's
 * targets) are ordinary jobs, submitted one by one with POST /v1/jobs
 * (each its own upload, checks and limits), that any worker on any node
 * runs; POST /v1/batches groups them, by id, and adds the parent: the
 * batch's *model job*, whose id is the batch's id.  The model job is an
 * ordinary job too (listed, owned, cancelled and deleted like any), with
 * no upload: its job.json names the members (worker/smd_job_file.h), its
 * record their ids and their dimension (so it survives a restart).  It
 * waits, queued, until no member is queued or running (the spool: kept
 * out of its FIFO, jobs/smd_spool_backend.c; PostgreSQL: its claim
 * skips it, store/pg/smd_pg_queue.c), then a worker builds the model from
 * the members that succeeded (proto/job/sm_job_model.h); a member that
 * failed or was dismissed is reported and left out, not fatal.
 *
 *   POST   /v1/batches                 {"targets": [{"job": ID, "name": N}...],
 *                                       "model_align": "none|rigid|similarity"}
 *   GET    /v1/batches/{id}            per-target status, progress, ETA
 *   GET    /v1/batches/{id}/events     the same as a stream of changes
 *                                      (api/smd_batch_events.h)
 *   DELETE /v1/batches/{id}            cancels the model job and the live
 *                                      members it owns alone; on a final
 *                                      batch deletes the model job and the
 *                                      members it dismissed (shared and
 *                                      finished ones stay; ?members=all:
 *                                      every member goes with it)
 *   GET    /v1/batches/{id}/model      the model's summary and file links
 *   GET    /v1/batches/{id}/model/{file}  mean.mesh, mean.vtu, modes.vtu,
 *                                      mode_K.sol, scores.csv, summary.json
 *
 * Tenancy is the jobs': a batch is visible to whom its model job is, and
 * groups only jobs its submitter sees. */
#ifndef SMD_BATCHES_H
#define SMD_BATCHES_H

#include <stddef.h>

#include <jansson.h>

#include "base/smd_server.h"
#include "http/smd_reply.h"
#include "store/spool/smd_job.h"

enum MHD_Result smd_route_batch_create(struct MHD_Connection *conn, smd_request *req);
/* The JSON body of POST /v1/batches (req->body_state), then the answer. */
enum MHD_Result smd_batches_continue(struct MHD_Connection *conn, smd_request *req,
                                     const char *data, size_t *size);
void smd_batches_body_free(void *body);

/* The model job's description (its batch object: "align", "members"
 * [{"job", "name"}...]; new reference) from its folder, read without the
 * lock; NULL when it cannot be read (deleted, or no batch). */
json_t *smd_batch_read(smd_server *srv, const char *id);
/* Lock held: the batch document of GET /v1/batches/{id} (new reference,
 * NULL out of memory). */
json_t *smd_batch_document(smd_server *srv, const smd_job *model, const json_t *batch);

enum MHD_Result smd_route_batch_get(struct MHD_Connection *conn, smd_request *req);
enum MHD_Result smd_route_batch_delete(struct MHD_Connection *conn, smd_request *req);
enum MHD_Result smd_route_batch_model(struct MHD_Connection *conn, smd_request *req);
enum MHD_Result smd_route_batch_model_file(struct MHD_Connection *conn, smd_request *req);

#endif
