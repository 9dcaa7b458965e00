/* Route handlers: landing page, OpenAPI document, health, metrics,
 * processes, job list, job status, cancel/delete, event streams (see
 * smd_routes.h). */
#include "api/smd_routes.h"
#include "store/spool/smd_store.h"
#include "store/spool/smd_fifo.h"

#include <errno.h>
#include <inttypes.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "sm_proto_vocab.h"
#include "jobs/smd_check.h"
#include "base/smd_body.h"
#include "http/smd_conns.h"
#include "jobs/smd_jobs.h"
#include "jobs/smd_usecases.h"
#include "http/smd_negotiate.h"
#include "jobs/smd_pool.h"
#include "api/smd_stream.h"

#define OGC_REL "http://www.opengis.net/def/rel/ogc/1.0/"
/* largest page of GET /v1/jobs (bounds the status documents built under
 * the lock by one request) */
#define SMD_LIST_LIMIT_MAX 1000

static json_t *mklink(const char *href, const char *rel, const char *type, const char *title)
{
    return json_pack("{s:s,s:s,s:s,s:s}", "href", href, "rel", rel, "type", type, "title", title);
}

json_t *smd_status_document(const smd_job *job)
{
    json_t *doc = smd_job_status_fields(job);
    if (!doc)
        return NULL;
    char self[64], events[80], results[80];
    snprintf(self, sizeof self, "/v1/jobs/%s", job->id);
    snprintf(events, sizeof events, "/v1/jobs/%s/events", job->id);
    snprintf(results, sizeof results, "/v1/jobs/%s/results", job->id);
    json_t *links = json_array();
    json_array_append_new(links, json_pack("{s:s,s:s,s:s,s:s}", "href", self, "rel", "self", "type",
                                           "application/json", "title", "this job"));
    json_array_append_new(links, json_pack("{s:s,s:s,s:s,s:s}", "href", events, "rel", "monitor",
                                           "type", "text/event-stream", "title",
                                           "progress events (SSE, or NDJSON)"));
    if (job->state == SM_JOB_SUCCESSFUL)
        json_array_append_new(links, json_pack("{s:s,s:s,s:s,s:s}", "href", results, "rel",
                                               "http://www.opengis.net/def/rel/ogc/1.0/results",
                                               "type", "application/json", "title", "results"));
    json_object_set_new(doc, "links", links);
    return doc;
}

/* ------------------------------------------------------- landing, docs */

enum MHD_Result smd_route_landing(struct MHD_Connection *conn, smd_request *req)
{
    json_t *links = json_array();
    json_array_append_new(links, mklink("/v1", "self", "application/json", "this document"));
    json_array_append_new(links, mklink("/v1/openapi.yaml", "service-desc",
                                      "application/vnd.oai.openapi;version=3.1",
                                      "the API definition (OpenAPI 3.1)"));
    json_array_append_new(links, mklink("/v1/conformance", OGC_REL "conformance", "application/json",
                                      "the OGC API - Processes conformance classes implemented"));
    json_array_append_new(links, mklink("/v1/processes", OGC_REL "processes", "application/json",
                                      "the processes (one: match)"));
    json_array_append_new(links, mklink("/v1/jobs", OGC_REL "job-list", "application/json", "jobs"));
    json_array_append_new(links, mklink("/healthz", "service-status", "application/json", "liveness"));
    json_array_append_new(links, mklink("/metrics", "service-meta", "text/plain", "Prometheus metrics"));
    json_t *doc = json_pack("{s:s,s:s,s:s,s:o}", "title", "shapematch", "description",
                            "Elastic shape matching jobs: upload a template mesh and a target "
                            "signed distance, follow the progress, fetch the deformed mesh.",
                            "version", SM_VERSION, "links", links);
    return smd_reply_json(conn, req, 200, doc);
}

enum MHD_Result smd_route_openapi(struct MHD_Connection *conn, smd_request *req)
{
    if (smd_openapi_yaml_len == 0)
        return smd_reply_problem(conn, req, 404, SMD_PROBLEM_NOT_FOUND,
                                 "this build carries no OpenAPI document");
    char *copy = malloc(smd_openapi_yaml_len);
    if (!copy)
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE, "out of memory");
    memcpy(copy, smd_openapi_yaml, smd_openapi_yaml_len);
    return smd_reply(conn, req, 200,
                     smd_buffer_response(conn, req, "application/vnd.oai.openapi;version=3.1", copy,
                                         smd_openapi_yaml_len));
}

/* ---------------------------------------------------- health, metrics */

enum MHD_Result smd_route_healthz(struct MHD_Connection *conn, smd_request *req)
{
    return smd_reply_json(conn, req, 200, json_pack("{s:s}", "status", "ok"));
}

enum MHD_Result smd_route_readyz(struct MHD_Connection *conn, smd_request *req)
{
    smd_server *srv = req->srv;
    if (atomic_load(&srv->draining))
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE,
                                 "shutting down: no new job is accepted");
    if (atomic_load(&srv->unwritable))
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE,
                                 "a job record could not be written (disk full?): no job is "
                                 "accepted or started until the spool takes writes again");
    char why[512];
    if (!smd_backend_ready(srv->backend, why, sizeof why))
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE, "%s", why);
    char jobs_dir[PATH_MAX];
    if (smd_pathf(jobs_dir, sizeof jobs_dir, "%s/jobs", smd_store_root(srv->store)) != 0 ||
        access(jobs_dir, W_OK) != 0)
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE,
                                 "the spool is not writable: %s", strerror(errno));
    size_t depth, busy, slots;
    smd_jobs_workload(srv, &depth, &busy, &slots);
    return smd_reply_json(conn, req, 200,
                          json_pack("{s:s,s:I,s:I,s:I}", "status", "ready", "queued",
                                    (json_int_t)depth, "workers_busy", (json_int_t)busy, "workers",
                                    (json_int_t)slots));
}

enum MHD_Result smd_route_metrics(struct MHD_Connection *conn, smd_request *req)
{
    smd_server *srv = req->srv;
    smd_gauges g;
    memset(&g, 0, sizeof g);
    smd_jobs_gauges(srv, &g);
    g.start_time = srv->start_time;
    g.ready = !atomic_load(&srv->draining);
    smd_conns_counts cc;
    smd_conns_get_counts(srv->conns, &cc);
    g.connections = cc.open;
    g.cut_headers = cc.header_deadline;
    g.cut_body = cc.slow_body;
    g.cut_reserve = cc.evicted;
    smd_check_counts(srv->checks, &g.checks_running, &g.checks_waiting);
    g.body_bytes = smd_body_held();
    g.body_budget = srv->cfg.max_body_memory;
    size_t len;
    char *text = smd_metrics_render(&srv->metrics, &g, &len);
    if (text)
        smd_backend_metrics(srv->backend, &text, &len);
    if (!text)
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE, "out of memory");
    return smd_reply(conn, req, 200,
                     smd_buffer_response(conn, req, "text/plain; version=0.0.4; charset=utf-8", text,
                                         len));
}

/* ------------------------------------------------------------ processes */

static json_t *process_summary(void)
{
    json_t *links = json_array();
    json_array_append_new(links, mklink("/v1/processes/match", "self", "application/json",
                                      "process description"));
    json_array_append_new(links, mklink("/v1/processes/match/execution", OGC_REL "execute",
                                      "application/json", "execute: POST an OGC execute request"));
    json_array_append_new(links, mklink("/v1/jobs", OGC_REL "execute", "multipart/form-data",
                                      "submit a job: POST multipart/form-data"));
    return json_pack("{s:s,s:s,s:s,s:s,s:[s],s:[s],s:o}", "id", "match", "title",
                     "Elastic shape matching", "description",
                     "Deforms a template simplicial mesh onto a target shape given by its signed "
                     "distance function, by a sequence of linear-elastic displacements that "
                     "decrease J = integral of d over the mesh (de Buhan, Dapogny, Frey, Nardoni "
                     "2016).",
                     "version", SM_VERSION, "jobControlOptions", "async-execute",
                     "outputTransmission", "reference", "links", links);
}

enum MHD_Result smd_route_processes(struct MHD_Connection *conn, smd_request *req)
{
    json_t *links = json_array();
    json_array_append_new(links, mklink("/v1/processes", "self", "application/json", "processes"));
    return smd_reply_json(conn, req, 200,
                          json_pack("{s:[o],s:o}", "processes", process_summary(), "links", links));
}

static json_t *file_input(const char *title, const char *description, int min_occurs)
{
    return json_pack("{s:s,s:s,s:i,s:i,s:{s:s,s:s,s:s}}", "title", title, "description",
                     description, "minOccurs", min_occurs, "maxOccurs", 1, "schema", "type", "string",
                     "format", "binary", "contentMediaType", "application/octet-stream");
}

/* An output; media: the default format's media type (its schema's
 * contentMediaType, as OGC's output description requires a schema). */
static json_t *output(const char *title, const char *href_suffix, const char *formats,
                      const char *media)
{
    int json = strcmp(media, "application/json") == 0;
    return json_pack("{s:s,s:s,s:s,s:{s:s,s:s}}", "title", title, "href", href_suffix, "formats",
                     formats, "schema", "type", json ? "object" : "string", "contentMediaType",
                     media);
}

enum MHD_Result smd_route_process(struct MHD_Connection *conn, smd_request *req)
{
    const char *pid = req->pid;
    if (strcmp(pid, "match") != 0)
        return smd_reply_problem(conn, req, 404, SMD_PROBLEM_NO_SUCH_PROCESS,
                                 "no process \"%s\" (the only process is \"match\")", pid);
    json_t *doc = process_summary();
    json_t *schema = smd_params_schema_len
                         ? json_loadb((const char *)smd_params_schema, smd_params_schema_len, 0, NULL)
                         : NULL;
    if (!schema)
        schema = json_pack("{s:s}", "type", "object");
    json_t *inputs = json_object();
    json_object_set_new(inputs, sm_part_names[SM_PART_TEMPLATE],
                        file_input("Template mesh", "The mesh to deform: Medit .mesh or .meshb "
                                                    "(triangles in 2D, tetrahedra in 3D), optionally "
                                                    "gzip-compressed; or template_surface or template_image "
                                                    "instead.",
                                   0));
    json_object_set_new(inputs, sm_part_names[SM_PART_TEMPLATE_SURFACE],
                        file_input("Template surface",
                                   "Instead of template: a closed surface (STL, OBJ, PLY, OFF, "
                                   "VTK, Medit or Gmsh; a closed curve in 2D) meshed into the "
                                   "template by Netgen's nglib at params template_size (default "
                                   "its mean edge); open, non-manifold or self-intersecting "
                                   "surfaces are refused (422).  The meshed template is a result "
                                   "file, template.mesh.", 0));
    json_object_set_new(inputs, sm_part_names[SM_PART_TEMPLATE_IMAGE],
                        file_input("Template image",
                                   "Instead of template: a label map in the formats of "
                                   "target_image (NIfTI, NRRD or MetaImage in one file, within "
                                   "the same limits); the boundary of params template_label (0: "
                                   "every nonzero voxel) is meshed into the template by Netgen's "
                                   "nglib at params template_size, as template_surface is.  A "
                                   "label the image does not hold is refused (422).  The meshed "
                                   "template is a result file, template.mesh.", 0));
    json_object_set_new(inputs, sm_part_names[SM_PART_TARGET_MESH],
                        file_input("Target (background) mesh",
                                   "The mesh carrying the target's signed distance: .mesh or "
                                   ".meshb, optionally gzip-compressed; same dimension as the "
                                   "template; optional with target_surface.", 0));
    json_object_set_new(inputs, sm_part_names[SM_PART_TARGET_SOL],
                        file_input("Target signed distance",
                                   "SolAtVertices scalar field (.sol or .solb, optionally "
                                   "gzip-compressed), one value per target mesh vertex, negative "
                                   "inside the target; required unless target_surface is given.", 0));
    json_object_set_new(inputs, sm_part_names[SM_PART_TARGET_SURFACE],
                        file_input("Target surface",
                                   "Instead of target_sol: the target's surface (STL, OBJ, Medit "
                                   "or Gmsh .msh, optionally gzip-compressed); its exact signed "
                                   "distance is computed at the vertices of target_mesh, or of a "
                                   "background generated around template and surface when "
                                   "target_mesh is not given (sized by params background_size "
                                   "and background_padding).  Excludes target_sol.", 0));
    json_object_set_new(inputs, sm_part_names[SM_PART_TEMPLATE_LANDMARKS],
                        file_input("Template landmarks",
                                   "CSV, one point a row (2 or 3 numbers as the template's "
                                   "dimension): the alignment's start, with target_landmarks "
                                   "(matching rows); needs params align other than none.", 0));
    json_object_set_new(inputs, sm_part_names[SM_PART_TARGET_LANDMARKS],
                        file_input("Target landmarks",
                                   "CSV, the target's points matching template_landmarks row for "
                                   "row.", 0));
    json_object_set_new(inputs, sm_part_names[SM_PART_TARGET_IMAGE],
                        file_input("Target image",
                                   "Instead of target_sol and target_surface: a label map, "
                                   "NIfTI-1/-2 (.nii, .nii.gz), NRRD (.nrrd) or MetaImage (.mha) "
                                   "in one file (a detached .nhdr or .mhd header is refused, "
                                   "422); the target is the boundary of params label (0: every "
                                   "nonzero voxel; float images: values >= params level), mapped "
                                   "into params image_space (lps or ras), its signed distance "
                                   "computed at the vertices of target_mesh or of a generated "
                                   "background.", 0));
    json_object_set_new(inputs, sm_part_names[SM_PART_PARAMS],
                        json_pack("{s:s,s:s,s:i,s:i,s:o}", "title", "Parameters", "description",
                                  "JSON document; only clamp is required.", "minOccurs", 1,
                                  "maxOccurs", 1, "schema", schema));
    json_object_set_new(doc, "inputs", inputs);
    json_t *outputs = json_object();
    json_object_set_new(outputs, "summary",
                        output("Summary: stop reason, iterations, J, boundary error, quality, "
                               "timings",
                               "results", "application/json", "application/json"));
    json_object_set_new(outputs, "mesh", output("Deformed template mesh", "results/mesh",
                                                "format=mesh|meshb|vtu|binary",
                                                "application/x-medit-mesh"));
    json_object_set_new(outputs, "displacement",
                        output("Cumulative displacement per template vertex",
                               "results/displacement", "format=sol|solb", "application/x-medit-sol"));
    json_object_set_new(outputs, "history",
                        output("One row per iteration", "results/history", "format=csv|json",
                               "text/csv"));
    json_object_set_new(outputs, "snapshots",
                        output("The mesh every save_every iterations (a list, then one per "
                               "iteration: results/snapshots/{iteration})",
                               "results/snapshots", "format=mesh", "application/json"));
    json_object_set_new(doc, "outputs", outputs);
    return smd_reply_json(conn, req, 200, doc);
}

/* ----------------------------------------------------------------- jobs */

enum MHD_Result smd_route_jobs_list(struct MHD_Connection *conn, smd_request *req)
{
    smd_server *srv = req->srv;
    const char *status = MHD_lookup_connection_value(conn, MHD_GET_ARGUMENT_KIND, "status");
    const char *limit_s = MHD_lookup_connection_value(conn, MHD_GET_ARGUMENT_KIND, "limit");
    const char *offset_s = MHD_lookup_connection_value(conn, MHD_GET_ARGUMENT_KIND, "offset");
    unsigned wanted = 0; /* bit per state; 0 = all */
    if (status && *status) {
        char buf[128];
        snprintf(buf, sizeof buf, "%s", status);
        char *save = NULL;
        for (char *tok = strtok_r(buf, ",", &save); tok; tok = strtok_r(NULL, ",", &save)) {
            sm_job_state st;
            if (sm_job_state_from_name(tok, &st) != 0)
                return smd_reply_problem(conn, req, 400, SMD_PROBLEM_BAD_REQUEST,
                                         "status: expected a comma-separated list of accepted, "
                                         "running, successful, failed, dismissed");
            wanted |= 1u << st;
        }
    }
    uint64_t limit_u = 100, offset_u = 0;
    if (limit_s && smd_parse_uint(limit_s, 1, SMD_LIST_LIMIT_MAX, &limit_u) != SMD_NUM_OK)
        return smd_reply_problem(conn, req, 400, SMD_PROBLEM_BAD_REQUEST,
                                 "limit: expected an integer in [1, %d]", SMD_LIST_LIMIT_MAX);
    if (offset_s && smd_parse_uint(offset_s, 0, SMD_REQUEST_INT_MAX, &offset_u) != SMD_NUM_OK)
        return smd_reply_problem(conn, req, 400, SMD_PROBLEM_BAD_REQUEST,
                                 "offset: expected an integer in [0, %lld]", SMD_REQUEST_INT_MAX);
    /* both bounded (limit <= 1000, offset < 2^53): every sum below fits */
    int64_t limit = (int64_t)limit_u, offset = (int64_t)offset_u;
    smd_job *views;
    size_t nviews;
    int64_t matched;
    if (smd_jobs_list(srv, req->who.tenant, req->who.admin, wanted, offset, limit, &views, &nviews,
                      &matched) != 0)
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE, "out of memory");
    json_t *jobs = json_array();
    for (size_t k = 0; k < nviews; k++)
        json_array_append_new(jobs, smd_status_document(&views[k]));
    free(views);
    json_t *links = json_array();
    char href[256], filter[160] = "";
    if (wanted) {
        snprintf(filter, sizeof filter, "&status=");
        int first = 1;
        for (int s = 0; s < SMD_JOB_STATES; s++)
            if (wanted & (1u << s)) {
                strncat(filter, first ? "" : ",", sizeof filter - strlen(filter) - 1);
                strncat(filter, sm_job_state_name((sm_job_state)s), sizeof filter - strlen(filter) - 1);
                first = 0;
            }
    }
    snprintf(href, sizeof href, "/v1/jobs?limit=%" PRId64 "&offset=%" PRId64 "%s", limit, offset,
             filter);
    json_array_append_new(links, mklink(href, "self", "application/json", "this page"));
    if (offset + limit < matched) {
        snprintf(href, sizeof href, "/v1/jobs?limit=%" PRId64 "&offset=%" PRId64 "%s", limit,
                 offset + limit, filter);
        json_array_append_new(links, mklink(href, "next", "application/json", "next page"));
    }
    if (offset > 0) {
        snprintf(href, sizeof href, "/v1/jobs?limit=%" PRId64 "&offset=%" PRId64 "%s", limit,
                 offset > limit ? offset - limit : 0, filter);
        json_array_append_new(links, mklink(href, "prev", "application/json", "previous page"));
    }
    json_t *doc = json_pack("{s:o,s:I,s:I,s:o}", "jobs", jobs, "numberMatched", (json_int_t)matched,
                            "numberReturned", (json_int_t)json_array_size(jobs), "links", links);
    return smd_reply_json(conn, req, 200, doc);
}

static enum MHD_Result no_such_job(struct MHD_Connection *conn, smd_request *req)
{
    return smd_reply_problem(conn, req, 404, SMD_PROBLEM_NO_SUCH_JOB, "no job %s", req->id);
}

enum MHD_Result smd_route_job_get(struct MHD_Connection *conn, smd_request *req)
{
    smd_job view;
    if (!smd_jobs_find(req->srv, req->id, req->who.tenant, req->who.admin, &view))
        return no_such_job(conn, req);
    return smd_reply_json(conn, req, 200, smd_status_document(&view));
}

enum MHD_Result smd_route_job_delete(struct MHD_Connection *conn, smd_request *req)
{
    smd_job view;
    sm_error err;
    switch (smd_jobs_withdraw(req->srv, req->who.tenant, req->who.admin, req->id,
                              SMD_WITHDRAW_CANCEL | SMD_WITHDRAW_DELETE, &view, &err)) {
    case SMD_WITHDRAWN_NONE:
    case SMD_WITHDRAWN_KEPT: /* not asked of a visible job: deleted meanwhile */
        return no_such_job(conn, req);
    case SMD_WITHDRAWN_REFUSED:
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE,
                                 "cannot delete job %s now: %s; the job is kept, try again",
                                 req->id, err.msg);
    case SMD_WITHDRAWN_UNWRITABLE:
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_STORAGE,
                                 "cannot delete job %s: %s; the job is kept, try again when the "
                                 "spool is writable", req->id, err.msg);
    case SMD_WITHDRAWN_CANCELLED: /* dismissed at once (a running worker is stopped) */
        return smd_reply_json(conn, req, 200, smd_status_document(&view));
    case SMD_WITHDRAWN_DELETED: { /* the job and its files went: its last status */
        json_t *doc = smd_status_document(&view);
        json_object_set_new(doc, "message", json_string("deleted"));
        json_object_del(doc, "links");
        return smd_reply_json(conn, req, 200, doc);
    }
    }
    return no_such_job(conn, req);
}

/* --------------------------------------------------------------- events */

int smd_stream_request_open(struct MHD_Connection *conn, smd_request *req, smd_stream_request *sr,
                            enum MHD_Result *r)
{
    smd_server *srv = req->srv;
    static const char *const offered[] = {"application/x-ndjson", "text/event-stream"};
    const char *accept = MHD_lookup_connection_value(conn, MHD_HEADER_KIND, MHD_HTTP_HEADER_ACCEPT);
    int choice = smd_accept_choose(accept, offered, 2);
    *r = MHD_NO;
    if (choice < 0) {
        *r = smd_reply_problem(conn, req, 406, SMD_PROBLEM_NOT_ACCEPTABLE,
                               "events are served as text/event-stream or application/x-ndjson");
        return 0;
    }
    /* a sequence number beyond the log is fine (nothing to replay: the
     * stream waits for the job's end); one beyond 2^53 - 1 is refused */
    uint64_t after = 0;
    const char *last = MHD_lookup_connection_value(conn, MHD_HEADER_KIND, "Last-Event-ID");
    const char *after_q = MHD_lookup_connection_value(conn, MHD_GET_ARGUMENT_KIND, "after");
    if (last && *last && smd_parse_uint(last, 0, SMD_REQUEST_INT_MAX, &after) != SMD_NUM_OK) {
        *r = smd_reply_problem(conn, req, 400, SMD_PROBLEM_BAD_REQUEST,
                               "Last-Event-ID: expected an event sequence number in [0, %lld]",
                               SMD_REQUEST_INT_MAX);
        return 0;
    }
    if (!(last && *last) && after_q &&
        smd_parse_uint(after_q, 0, SMD_REQUEST_INT_MAX, &after) != SMD_NUM_OK) {
        *r = smd_reply_problem(conn, req, 400, SMD_PROBLEM_BAD_REQUEST,
                               "after: expected an event sequence number in [0, %lld]",
                               SMD_REQUEST_INT_MAX);
        return 0;
    }
    sr->resumed = (last && *last) || after_q;
    struct MHD_Connection *evict = NULL;
    int full = smd_conns_stream(conn, &evict);
    if (evict)
        smd_follow_evict(srv, evict);
    if (full != 0) {
        *r = smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE,
                               "too many event streams and request bodies in progress (from "
                               "your address: --max-streams-per-ip; in all: --max-connections "
                               "minus --reserved-connections): try again shortly");
        return 0;
    }
    sr->sse = choice == 1;
    sr->after = (int64_t)after;
    /* the credential authenticate() checked, kept for smd_stream_revoke */
    sr->cred = (smd_follow_credential){0};
    if (srv->tokens && !req->public_path) {
        sr->cred.authorization = MHD_lookup_connection_value(conn, MHD_HEADER_KIND,
                                                             MHD_HTTP_HEADER_AUTHORIZATION);
        if (!sr->cred.authorization)
            sr->cred.token = MHD_lookup_connection_value(conn, MHD_GET_ARGUMENT_KIND, "access_token");
    }
    return 1;
}

enum MHD_Result smd_route_events(struct MHD_Connection *conn, smd_request *req)
{
    smd_server *srv = req->srv;
    smd_stream_request sr;
    enum MHD_Result r;
    if (!smd_stream_request_open(conn, req, &sr, &r))
        return r;
    char msg[256];
    int found;
    smd_follow_request rq = {.id = req->id, .tenant = req->who.tenant, .admin = req->who.admin,
                             .sse = sr.sse, .after_seq = sr.after, .bytes_out = &req->bytes_out,
                             .cred = sr.cred};
    struct MHD_Response *resp = smd_stream_response(srv, conn, &rq, &found, msg, sizeof msg);
    if (!found)
        return no_such_job(conn, req);
    if (!resp)
        return smd_reply_problem(conn, req, 500, SMD_PROBLEM_INTERNAL, "cannot open the event log: %s",
                                 msg);
    return smd_reply(conn, req, 200, resp);
}
