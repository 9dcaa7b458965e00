/* GET /v1/jobs/{id}/mesh/latest: the shape of a job as it deforms.
 *
 * While a job runs, its worker publishes the current shape into the job
 * folder (smd_worker.h: SMD_LIVE_PAYLOAD, SMD_LIVE_MESH, replaced
 * atomically every params.live_every iterations and at least every
 * SMD_LIVE_PERIOD seconds).  This route serves the latest: the binary
 * payload (proto/PAYLOAD.md, with the displacement and the distance |d|
 * at the vertices) by default or with ?format=binary, Medit ASCII with
 * ?format=mesh; 404 result-not-ready before the first publication.  The
 * last shape stays after the job ends, until the job is deleted. */
#ifndef SMD_LIVE_H
#define SMD_LIVE_H

#include "http/smd_reply.h"

enum MHD_Result smd_route_live_mesh(struct MHD_Connection *conn, smd_request *req);

#endif
