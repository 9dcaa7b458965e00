/* The route table of shapematchd: one row per {methods, path pattern,
 * handler, metrics label}.  It alone decides which handler answers a
 * request, what a 405 lists in Allow, and under which label a request is
 * counted in /metrics; a CORS preflight reads the methods of a path from
 * it too (smd_route_find's allowed set).
 *
 * Patterns are literal segments and variables: {id} (a job id: any
 * segment, checked with smd_id_valid, a malformed one answers 404 before
 * any handler runs, so nothing of it reaches the disk), {pid} (a process
 * id) and any other variable, {iteration} or {file} (at most 16
 * characters: longer is no route, so smd_request.arg always holds it
 * whole; the handler checks it against what it serves).  Rows with
 * the same pattern share a path and differ by method; rows may share a
 * label (every /results path is counted under one). */
#ifndef SMD_ROUTE_TABLE_H
#define SMD_ROUTE_TABLE_H

#include <stddef.h>

#include "http/smd_http.h"
#include "http/smd_reply.h"

/* Answers the request completely (smd_reply*), or, for an upload,
 * attaches req->upload and answers when the body is in. */
typedef enum MHD_Result (*smd_handler)(struct MHD_Connection *conn, smd_request *req);

typedef struct smd_route {
    unsigned methods;
    const char *pattern;
    smd_handler handler;
    const char *label;   /* metrics label (a path template) */
    int public;          /* answered without a bearer token (health checks) */
} smd_route;

extern const smd_route smd_route_table[];
extern const size_t smd_route_table_len;

/* The label of requests no row matches. */
#define SMD_ROUTE_LABEL_OTHER "other"

/* Matches path against the table and fills req->id / bad_id / pid / arg
 * from the first row whose pattern matches.  Returns that row (NULL when
 * none), sets *allowed to the union of the methods of every row with a
 * matching pattern and *route to the row that takes method (NULL: 405). */
const smd_route *smd_route_find(const char *path, unsigned method, smd_request *req,
                                unsigned *allowed, const smd_route **route);

/* What the HTTP front serves (smd_http.h): the table, the upload's body
 * and the upload checks; handed to smd_http_start by main. */
extern const smd_http_app smd_api;

/* The distinct metrics labels, "other" first, then in table order:
 * fills out (cap entries) and returns how many there are. */
size_t smd_route_labels(const char **out, size_t cap);

#endif
