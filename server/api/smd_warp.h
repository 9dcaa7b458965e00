/* POST /v1/jobs/{id}/warp: points, a mesh or a field carried through a
 * successful job's map, answered on the request (docs/api.md, docs/warp.md).
 *
 * The body is the points: text/csv (proto/sm_points_csv.h: x,y[,z] per
 * line, an optional header) or application/json ({"points": [[x, y(,
 * z)], ...], optional "direction" and "strict"}); the query may give
 * direction=forward|inverse and strict=true|false (a body member wins).
 * The answer has the request's type: the CSV with its `inside` column,
 * or {"direction", "points", "inside", "outside"}.  A mesh
 * (application/x-medit-mesh or -meshb: Medit or Gmsh, read by content)
 * or a field at the template's vertices (application/x-medit-sol or
 * -solb; normalize=true for unit vectors) goes through a temporary file
 * in the spool's tmp/ and comes back as Medit ASCII, the vertices moved
 * or the field carried, as `shapematch warp` writes them.  The body is held in
 * memory, at most --max-upload bytes and 64 MiB (413, before reading it
 * when Content-Length says so), counted by --max-body-memory (503 past
 * it).  Once it is in, the connection is suspended and the warp runs in
 * a check child (jobs/smd_check.h: forked, --check-timeout, --memory-limit):
 * the job layer's use case (job/sm_job_warp.h) reads the body within
 * --max-vertices, --max-elements and --max-inflated, the map from the
 * job's results, and writes the answer to a temporary file that the
 * resumed handler sends; no HTTP thread parses or computes.
 *
 * Answers: 200; 400 malformed body (the CSV line, the JSON member, the
 * mesh reader's place named) or query; 404
 * unknown job or another tenant's; 409 the job is not successful (queued,
 * running, failed, dismissed: no map); 413 (the size, a reader's bound);
 * 415 another Content-Type; 422 points, mesh or field of the wrong
 * dimension (or vertex count), outside the mesh with strict, an answer
 * format that cannot hold the body, or past --check-timeout; 503 past
 * --max-body-memory, with the check queue full or while shutting down. */
#ifndef SMD_WARP_H
#define SMD_WARP_H

#include <stddef.h>

#include "http/smd_reply.h"

typedef struct smd_warp_body smd_warp_body;

/* First call (headers in): refuses at once, or attaches the body reader
 * (req->body_state) and returns MHD_YES. */
enum MHD_Result smd_route_warp(struct MHD_Connection *conn, smd_request *req);
/* A piece of the body (*size > 0) or its end (*size 0: answers). */
enum MHD_Result smd_warp_continue(struct MHD_Connection *conn, smd_request *req, const char *data,
                                  size_t *size);
void smd_warp_body_free(smd_warp_body *b);

#endif
