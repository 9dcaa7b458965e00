/* Route handlers of the results of a successful job (smd_results.c):
 * /v1/jobs/{id}/results (the summary), /results/mesh, /displacement,
 * /history (a format by ?format=, else Accept), /results/snapshots and
 * /results/snapshots/{iteration}.  Each answers 404 result-not-ready
 * until the job is successful. */
#ifndef SMD_RESULTS_H
#define SMD_RESULTS_H

#include "http/smd_reply.h"

enum MHD_Result smd_route_results(struct MHD_Connection *conn, smd_request *req);
enum MHD_Result smd_route_result_mesh(struct MHD_Connection *conn, smd_request *req);
enum MHD_Result smd_route_result_displacement(struct MHD_Connection *conn, smd_request *req);
enum MHD_Result smd_route_result_history(struct MHD_Connection *conn, smd_request *req);
/* GET results/template: the meshed template (template.mesh) of a job
 * given a template_surface or a template_image; 404 otherwise. */
enum MHD_Result smd_route_result_template(struct MHD_Connection *conn, smd_request *req);
enum MHD_Result smd_route_snapshots(struct MHD_Connection *conn, smd_request *req);
/* the iteration is req->arg */
enum MHD_Result smd_route_snapshot(struct MHD_Connection *conn, smd_request *req);

#endif
