/* Route handlers of shapematchd (smd_routes.c): landing page, OpenAPI
 * document, health, metrics, processes, job list, job status,
 * cancel/delete, event streams.  Each answers one request completely
 * (smd_reply*, smd_reply.h); smd_route_table.c maps paths to them. */
#ifndef SMD_ROUTES_H
#define SMD_ROUTES_H

#include "http/smd_reply.h"
#include "api/smd_stream.h"
#include "store/spool/smd_job.h"

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

/* What an event stream's request asks for (GET .../events). */
typedef struct smd_stream_request {
    int sse;                   /* text/event-stream, else NDJSON */
    int64_t after;             /* Last-Event-ID, else ?after=, else 0 */
    int resumed;               /* one of the two was given */
    smd_follow_credential cred; /* for smd_stream_revoke (the request's strings) */
} smd_stream_request;
/* The common part of every event stream's request: the encoding by
 * Accept (406), the resume point (400 when malformed) and the
 * connection's place among the streams (503 when full, evicting the
 * oldest of an address over its share as smd_conns_stream says).  1 to go on, or 0
 * with the refusal answered into *r. */
int smd_stream_request_open(struct MHD_Connection *conn, smd_request *req, smd_stream_request *sr,
                            enum MHD_Result *r);

/* Status document of a job (OGC statusInfo with links): a record under
 * the lock, or a copy (smd_job_view). */
json_t *smd_status_document(const smd_job *job);

/* Embedded documents (generated from proto/ by server/embed.sh). */
extern const unsigned char smd_openapi_yaml[];
extern const size_t smd_openapi_yaml_len;
extern const unsigned char smd_params_schema[];
extern const size_t smd_params_schema_len;
extern const unsigned char smd_events_schema[];
extern const size_t smd_events_schema_len;

#endif
