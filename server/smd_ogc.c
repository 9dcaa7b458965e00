/* Conformance and the served schemas (see smd_ogc.h). */
#include "smd_ogc.h"

#include <stdlib.h>
#include <string.h>

#include "smd_routes.h"

#define CONF "http://www.opengis.net/spec/ogcapi-processes-1/1.0/conf/"

/* What the daemon implements of OGC API - Processes - Part 1, and no
 * more: not "core" (it requires POST /processes/{id}/execution, which
 * this daemon does not have: jobs are submitted to POST /v1/jobs as
 * multipart), not "oas30" (the document is OpenAPI 3.1), not "html",
 * "callback" or "kvp-execute". */
static const char *const classes[] = {
    CONF "ogc-process-description",
    CONF "json",
    CONF "job-list",
    CONF "dismiss",
};

enum MHD_Result smd_route_conformance(struct MHD_Connection *conn, smd_request *req)
{
    json_t *list = json_array();
    for (size_t i = 0; i < sizeof classes / sizeof classes[0]; i++)
        json_array_append_new(list, json_string(classes[i]));
    return smd_reply_json(conn, req, 200, json_pack("{s:o}", "conformsTo", list));
}

static enum MHD_Result serve_embedded(struct MHD_Connection *conn, smd_request *req,
                                      const unsigned char *data, size_t len, const char *what)
{
    if (len == 0)
        return smd_reply_problem(conn, req, 404, SMD_PROBLEM_NOT_FOUND, "this build carries no %s",
                                 what);
    char *copy = malloc(len);
    if (!copy)
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE, "out of memory");
    memcpy(copy, data, len);
    return smd_reply(conn, req, 200,
                     smd_buffer_response(conn, req, "application/schema+json", copy, len));
}

enum MHD_Result smd_route_params_schema(struct MHD_Connection *conn, smd_request *req)
{
    return serve_embedded(conn, req, smd_params_schema, smd_params_schema_len,
                          "parameters schema");
}

enum MHD_Result smd_route_events_schema(struct MHD_Connection *conn, smd_request *req)
{
    return serve_embedded(conn, req, smd_events_schema, smd_events_schema_len, "events schema");
}
