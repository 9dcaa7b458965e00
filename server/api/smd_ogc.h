/* OGC API - Processes documents of shapematchd beside the landing page:
 * GET /v1/conformance (the conformance classes really implemented) and
 * the JSON schemas the OpenAPI document refers to, served next to it so
 * that /v1/openapi.yaml resolves as served: /v1/params.schema.json and
 * /v1/events.schema.json (embedded from proto/, like the document). */
#ifndef SMD_OGC_H
#define SMD_OGC_H

#include <stddef.h>

#include "http/smd_reply.h"

enum MHD_Result smd_route_conformance(struct MHD_Connection *conn, smd_request *req);
enum MHD_Result smd_route_params_schema(struct MHD_Connection *conn, smd_request *req);
enum MHD_Result smd_route_events_schema(struct MHD_Connection *conn, smd_request *req);

/* POST /v1/processes/{pid}/execution (OGC API - Processes Part 1, core):
 * an application/json execute request {"inputs": {...}} whose inputs are
 * the multipart parts: template, target_mesh, target_sol, target_surface
 * inline as {"value": base64, "mediaType": any} (href is refused: the
 * daemon fetches nothing), params as the parameters object (or
 * {"value": object}).  "outputs" and "response" are accepted and change
 * nothing; other members (subscriber) are a 400.  Decoded into the upload
 * folder and then checked and submitted by the multipart path
 * (smd_upload_begin_decoded), so the same 400/413/422 problems apply.
 * Execution is always asynchronous (jobControlOptions: async-execute):
 * 201 + Location + status document, with Preference-Applied:
 * respond-async when Prefer asked for it; Prefer: wait is not honoured
 * (OGC: a process that executes asynchronously only answers so).  The
 * body is held in memory: at most 64 MiB (413). */
enum MHD_Result smd_route_execute(struct MHD_Connection *conn, smd_request *req);

/* Decodes base64 (RFC 4648, padding optional, CR/LF skipped) of in[0..n)
 * into out (room for n / 4 * 3 + 3 bytes); the length, or SIZE_MAX with
 * *pos at the offending character. */
size_t smd_base64_decode(const char *in, size_t n, unsigned char *out, size_t *pos);

#endif
