/* GET /v1/jobs/{id}/inputs[/{part}] (smd_inputs.c): a job's stored input
 * file, as uploaded, so the web app can overlay the target (its zero level
 * set or surface) on the shape.  {part} is template, target_mesh,
 * target_sol or target_surface. */
#ifndef SMD_INPUTS_H
#define SMD_INPUTS_H

#include "http/smd_reply.h"

/* GET /v1/jobs/{id}/inputs: {"inputs": [{"part", "file", "href", "bytes"}]}
 * for each file part the job was sent. */
enum MHD_Result smd_route_inputs(struct MHD_Connection *conn, smd_request *req);
/* the part is req->arg */
enum MHD_Result smd_route_input(struct MHD_Connection *conn, smd_request *req);

#endif
