/* The route table and its matcher (see smd_route_table.h). */
#include "api/smd_route_table.h"

#include <stdio.h>
#include <string.h>

#include "api/smd_app.h"
#include "api/smd_batches.h"
#include "api/smd_batch_events.h"
#include "api/smd_live.h"
#include "api/smd_ogc.h"
#include "api/smd_results.h"
#include "api/smd_routes.h"
#include "jobs/smd_check.h"
#include "api/smd_inputs.h"
#include "api/smd_upload.h"
#include "api/smd_warp.h"

#define JOB "/v1/jobs/{id}"
#define RESULTS JOB "/results"
#define BATCH "/v1/batches/{id}"

const smd_route smd_route_table[] = {
    /* public for the web app's page; the JSON landing checks the token itself */
    {SMD_METHOD_READ, "/", smd_route_root, "/", 1},
    {SMD_METHOD_READ, "/app/{asset}", smd_route_app_asset, "/app/{asset}", 1},
    {SMD_METHOD_READ, "/v1", smd_route_landing, "/", 0},
    {SMD_METHOD_READ, "/v1/", smd_route_landing, "/", 0},
    {SMD_METHOD_READ, "/v1/openapi.yaml", smd_route_openapi, "/v1/openapi.yaml", 0},
    {SMD_METHOD_READ, "/v1/params.schema.json", smd_route_params_schema, "/v1/params.schema.json", 0},
    {SMD_METHOD_READ, "/v1/events.schema.json", smd_route_events_schema, "/v1/events.schema.json", 0},
    {SMD_METHOD_READ, "/v1/conformance", smd_route_conformance, "/v1/conformance", 0},
    {SMD_METHOD_READ, "/healthz", smd_route_healthz, "/healthz", 1},
    {SMD_METHOD_READ, "/readyz", smd_route_readyz, "/readyz", 1},
    {SMD_METHOD_READ, "/metrics", smd_route_metrics, "/metrics", 0},
    {SMD_METHOD_READ, "/v1/processes", smd_route_processes, "/v1/processes", 0},
    {SMD_METHOD_READ, "/v1/processes/{pid}", smd_route_process, "/v1/processes/{id}", 0},
    {SMD_METHOD_POST, "/v1/processes/{pid}/execution", smd_route_execute,
     "/v1/processes/{id}/execution", 0},
    {SMD_METHOD_READ, "/v1/jobs", smd_route_jobs_list, "/v1/jobs", 0},
    {SMD_METHOD_POST, "/v1/jobs", smd_upload_begin, "/v1/jobs", 0},
    {SMD_METHOD_READ, JOB, smd_route_job_get, JOB, 0},
    {SMD_METHOD_DELETE, JOB, smd_route_job_delete, JOB, 0},
    {SMD_METHOD_READ, JOB "/events", smd_route_events, JOB "/events", 0},
    {SMD_METHOD_READ, JOB "/mesh/latest", smd_route_live_mesh, JOB "/mesh/latest", 0},
    {SMD_METHOD_POST, JOB "/warp", smd_route_warp, JOB "/warp", 0},
    /* the stored uploads, for the web app's overlay of the target */
    {SMD_METHOD_READ, JOB "/inputs", smd_route_inputs, JOB "/inputs", 0},
    {SMD_METHOD_READ, JOB "/inputs/{part}", smd_route_input, JOB "/inputs/{part}", 0},
    {SMD_METHOD_READ, RESULTS, smd_route_results, RESULTS, 0},
    {SMD_METHOD_READ, RESULTS "/mesh", smd_route_result_mesh, RESULTS "/mesh", 0},
    {SMD_METHOD_READ, RESULTS "/displacement", smd_route_result_displacement,
     RESULTS "/displacement", 0},
    {SMD_METHOD_READ, RESULTS "/history", smd_route_result_history, RESULTS "/history", 0},
    {SMD_METHOD_READ, RESULTS "/template", smd_route_result_template, RESULTS "/template", 0},
    /* snapshots have no label of their own: counted under /results */
    {SMD_METHOD_READ, RESULTS "/snapshots", smd_route_snapshots, RESULTS, 0},
    {SMD_METHOD_READ, RESULTS "/snapshots/{iteration}", smd_route_snapshot, RESULTS, 0},
    /* batches (smd_batches.h): a model job over target jobs */
    {SMD_METHOD_POST, "/v1/batches", smd_route_batch_create, "/v1/batches", 0},
    {SMD_METHOD_READ, BATCH, smd_route_batch_get, BATCH, 0},
    {SMD_METHOD_DELETE, BATCH, smd_route_batch_delete, BATCH, 0},
    {SMD_METHOD_READ, BATCH "/events", smd_route_batch_events, BATCH "/events", 0},
    {SMD_METHOD_READ, BATCH "/model", smd_route_batch_model, BATCH "/model", 0},
    /* {file} is at most 16 characters (the matcher's bound): mode_9999.sol fits */
    {SMD_METHOD_READ, BATCH "/model/{file}", smd_route_batch_model_file, BATCH "/model", 0},
};
const size_t smd_route_table_len = sizeof smd_route_table / sizeof smd_route_table[0];

/* What one match captures. */
typedef struct captures {
    char id[SMD_ID_LEN + 1];
    int bad_id;
    char pid[sizeof ((smd_request *)0)->pid];
    char arg[sizeof ((smd_request *)0)->arg];
} captures;

/* Stores a variable segment [s, s + n) by the variable's name; 0 when the
 * segment does not fit it (no match). */
static int capture(const char *name, size_t name_len, const char *s, size_t n, captures *c)
{
    if (name_len == 2 && memcmp(name, "id", 2) == 0) {
        /* any segment matches; only a valid id is kept */
        c->id[0] = '\0';
        if (n == SMD_ID_LEN) {
            memcpy(c->id, s, n);
            c->id[n] = '\0';
        }
        c->bad_id = !smd_id_valid(c->id);
        if (c->bad_id)
            c->id[0] = '\0';
        return 1;
    }
    if (n == 0)
        return 0;
    if (name_len == 3 && memcmp(name, "pid", 3) == 0) {
        /* any process id matches (an unknown one is the handler's 404),
         * kept truncated */
        size_t k = n < sizeof c->pid ? n : sizeof c->pid - 1;
        memcpy(c->pid, s, k);
        c->pid[k] = '\0';
        return 1;
    }
    if (n > 16) /* {iteration}: longer is no route */
        return 0;
    memcpy(c->arg, s, n);
    c->arg[n] = '\0';
    return 1;
}

/* 1 when path matches pattern (segment by segment). */
static int match(const char *pattern, const char *path, captures *c)
{
    const char *p = pattern, *u = path;
    while (*p && *u) {
        if (*p == '{') {
            const char *close = strchr(p, '}');
            size_t seg = strcspn(u, "/");
            if (!close || !capture(p + 1, (size_t)(close - p - 1), u, seg, c))
                return 0;
            p = close + 1;
            u += seg;
            continue;
        }
        if (*p != *u)
            return 0;
        p++;
        u++;
    }
    if (*p == '{' && !*u) /* an empty last segment ("/v1/jobs/") */
        return strcmp(p, "{id}") == 0 && capture("id", 2, u, 0, c);
    return !*p && !*u;
}

const smd_route *smd_route_find(const char *path, unsigned method, smd_request *req,
                                unsigned *allowed, const smd_route **route)
{
    const smd_route *first = NULL;
    *allowed = 0;
    *route = NULL;
    for (size_t i = 0; i < smd_route_table_len; i++) {
        const smd_route *r = &smd_route_table[i];
        captures c = {.bad_id = 0};
        if (!match(r->pattern, path, &c))
            continue;
        if (!first) {
            first = r;
            memcpy(req->id, c.id, sizeof req->id);
            req->bad_id = c.bad_id;
            memcpy(req->pid, c.pid, sizeof req->pid);
            memcpy(req->arg, c.arg, sizeof req->arg);
        }
        *allowed |= r->methods;
        if (!*route && (r->methods & method))
            *route = r;
    }
    return first;
}

size_t smd_route_labels(const char **out, size_t cap)
{
    size_t n = 0;
    if (cap > 0)
        out[n++] = SMD_ROUTE_LABEL_OTHER;
    for (size_t i = 0; i < smd_route_table_len && n < cap; i++) {
        size_t k = 0;
        while (k < n && strcmp(out[k], smd_route_table[i].label) != 0)
            k++;
        if (k == n)
            out[n++] = smd_route_table[i].label;
    }
    return n;
}

/* ------------------------------------------------- the front's view */

static void route_request(smd_request *req, const char *path, unsigned method)
{
    const smd_route *route;
    const smd_route *first = smd_route_find(path, method, req, &req->allowed, &route);
    req->route = route;
    req->route_label = first ? first->label : SMD_ROUTE_LABEL_OTHER;
    req->public_path = first && first->public;
}

static enum MHD_Result handle(struct MHD_Connection *conn, smd_request *req)
{
    return req->route->handler(conn, req);
}

/* The route whose reader owns req->body_state: a batch description
 * (POST /v1/batches), or the warp route's. */
static int batch_body(const smd_request *req)
{
    return req->route && req->route->handler == smd_route_batch_create;
}

/* A body goes to the upload (POST /v1/jobs, the OGC execute) or to the
 * reader a route attached (req->body_state: the warp or batch route's). */
static enum MHD_Result body(struct MHD_Connection *conn, smd_request *req, const char *data,
                            size_t *size)
{
    if (req->body_state && batch_body(req))
        return smd_batches_continue(conn, req, data, size);
    if (req->body_state)
        return smd_warp_continue(conn, req, data, size);
    return smd_upload_continue(conn, req, data, size);
}

static void body_free(smd_request *req)
{
    smd_upload_free(req->upload);
    req->upload = NULL;
    if (batch_body(req))
        smd_batches_body_free(req->body_state);
    else
        smd_warp_body_free(req->body_state);
    req->body_state = NULL;
}

static sm_status checks_open(smd_server *srv, sm_error *err)
{
    const smd_config *cfg = &srv->cfg;
    srv->checks = smd_check_pool_new(cfg->check_threads, cfg->check_timeout, cfg->memory_limit, err);
    return srv->checks ? SM_OK : SM_ERR_IO;
}

/* checks stopped, their connections resumed and answered before the
 * daemon stops (it must not stop with suspended connections) */
static void checks_quiesce(smd_server *srv)
{
    smd_check_pool_stop(srv->checks, 5);
}

static void checks_close(smd_server *srv)
{
    smd_check_pool_free(srv->checks);
    srv->checks = NULL;
}

const smd_http_app smd_api = {
    .route = route_request,
    .handle = handle,
    .body = body,
    .body_free = body_free,
    .open = checks_open,
    .quiesce = checks_quiesce,
    .close = checks_close,
};
