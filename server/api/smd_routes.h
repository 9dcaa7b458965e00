/* Route handlers of shapematchd (smd_routes.c): landing page, OpenAPI
 * document, health, metrics, processes, job list, job status,
 * cancel/delete, event streams.  Each answers one request completely
 * (smd_reply*, smd_reply.h); smd_route_table.c maps paths to them. */
#ifndef SMD_ROUTES_H
#define SMD_ROUTES_H

#include "http/smd_reply.h"
#include "jobs/smd_job.h"

enum MHD_Result smd_route_landing(struct MHD_Connection *conn, smd_request *req);
enum MHD_Result smd_route_openapi(struct MHD_Connection *conn, smd_request *req);
enum MHD_Result smd_route_healthz(struct MHD_Connection *conn, smd_request *req);
enum MHD_Result smd_route_readyz(struct MHD_Connection *conn, smd_request *req);
enum MHD_Result smd_route_metrics(struct MHD_Connection *conn, smd_request *req);
enum MHD_Result smd_route_processes(struct MHD_Connection *conn, smd_request *req);
/* the process id is req->pid */
enum MHD_Result smd_route_process(struct MHD_Connection *conn, smd_request *req);
enum MHD_Result smd_route_jobs_list(struct MHD_Connection *conn, smd_request *req);
enum MHD_Result smd_route_job_get(struct MHD_Connection *conn, smd_request *req);
enum MHD_Result smd_route_job_delete(struct MHD_Connection *conn, smd_request *req);
enum MHD_Result smd_route_events(struct MHD_Connection *conn, smd_request *req);

/* Status document of a job (OGC statusInfo with links).  Lock held. */
json_t *smd_status_document(const smd_job *job);

/* Embedded documents (generated from proto/ by server/embed.sh). */
extern const unsigned char smd_openapi_yaml[];
extern const size_t smd_openapi_yaml_len;
extern const unsigned char smd_params_schema[];
extern const size_t smd_params_schema_len;
extern const unsigned char smd_events_schema[];
extern const size_t smd_events_schema_len;

#endif
