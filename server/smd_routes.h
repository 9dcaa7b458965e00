/* Route handlers of shapematchd.  Each answers one request completely
 * (smd_reply*), under the conventions of smd_http.h. */
#ifndef SMD_ROUTES_H
#define SMD_ROUTES_H

#include "smd_http.h"

/* smd_routes.c */
enum MHD_Result smd_route_landing(struct MHD_Connection *conn, smd_request *req);
enum MHD_Result smd_route_openapi(struct MHD_Connection *conn, smd_request *req);
enum MHD_Result smd_route_healthz(struct MHD_Connection *conn, smd_request *req);
enum MHD_Result smd_route_readyz(struct MHD_Connection *conn, smd_request *req);
enum MHD_Result smd_route_metrics(struct MHD_Connection *conn, smd_request *req);
enum MHD_Result smd_route_processes(struct MHD_Connection *conn, smd_request *req);
enum MHD_Result smd_route_process(struct MHD_Connection *conn, smd_request *req, const char *pid);
enum MHD_Result smd_route_jobs_list(struct MHD_Connection *conn, smd_request *req);
enum MHD_Result smd_route_job_get(struct MHD_Connection *conn, smd_request *req);
enum MHD_Result smd_route_job_delete(struct MHD_Connection *conn, smd_request *req);
enum MHD_Result smd_route_events(struct MHD_Connection *conn, smd_request *req);

/* smd_results.c: /v1/jobs/{id}/results[/mesh|/displacement|/history] */
enum MHD_Result smd_route_results(struct MHD_Connection *conn, smd_request *req);

/* Embedded documents (generated from proto/ by server/embed.sh). */
extern const unsigned char smd_openapi_yaml[];
extern const size_t smd_openapi_yaml_len;
extern const unsigned char smd_params_schema[];
extern const size_t smd_params_schema_len;

#endif
