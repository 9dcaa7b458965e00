/* OGC API - Processes documents of shapematchd beside the landing page:
 * GET /v1/conformance (the conformance classes really implemented) and
 * the JSON schemas the OpenAPI document refers to, served next to it so
 * that /v1/openapi.yaml resolves as served: /v1/params.schema.json and
 * /v1/events.schema.json (embedded from proto/, like the document). */
#ifndef SMD_OGC_H
#define SMD_OGC_H

#include "smd_reply.h"

enum MHD_Result smd_route_conformance(struct MHD_Connection *conn, smd_request *req);
enum MHD_Result smd_route_params_schema(struct MHD_Connection *conn, smd_request *req);
enum MHD_Result smd_route_events_schema(struct MHD_Connection *conn, smd_request *req);

#endif
