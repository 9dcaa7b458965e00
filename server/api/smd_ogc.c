/* Conformance and the served schemas (see smd_ogc.h). */
#include "api/smd_ogc.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "sm_json.h"
#include "sm_proto_text.h"
#include "sm_proto_vocab.h"
#include "api/smd_routes.h"
#include "api/smd_upload.h"
#include "base/smd_body.h"

#define CONF "http://www.opengis.net/spec/ogcapi-processes-1/1.0/conf/"

/* What the daemon implements of OGC API - Processes - Part 1, and no
 * more: "core" (POST /v1/processes/match/execution, asynchronous), not
 * "oas30" (the document is OpenAPI 3.1), not "html" (the web app at / is
 * no HTML rendering of the resources), "callback" or "kvp-execute". */
static const char *const classes[] = {
    CONF "core",
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

/* ------------------------------------------------------------ execute */

/* The execute request is held in memory (jansson parses it whole): at
 * most this much, whatever --max-upload allows multipart bodies. */
#define EXECUTE_MAX ((size_t)64 << 20)

typedef struct execute_body {
    smd_body body; /* counted in --max-body-memory (base/smd_body.h) */
    int refused;   /* over a limit: the rest is not kept */
} execute_body;

static void execute_piece(void *cls, smd_upload *u, const char *data, size_t n)
{
    execute_body *b = cls;
    if (b->refused)
        return;
    int rc = smd_body_append(&b->body, data, n);
    if (rc == SMD_BODY_OK)
        return;
    b->refused = 1;
    if (rc == SMD_BODY_TOO_LARGE)
        smd_upload_fail(u, 413, SMD_PROBLEM_TOO_LARGE,
                        "the execute request exceeds %zu bytes (its inline inputs are held in "
                        "memory): send larger files as multipart/form-data to POST /v1/jobs",
                        EXECUTE_MAX);
    else if (rc == SMD_BODY_BUSY)
        smd_upload_fail(u, 503, SMD_PROBLEM_UNAVAILABLE,
                        "the daemon holds %llu bytes of request bodies already (its "
                        "--max-body-memory): try again shortly, or send the files as "
                        "multipart/form-data to POST /v1/jobs",
                        (unsigned long long)b->body.budget);
    else
        smd_upload_fail(u, 503, SMD_PROBLEM_UNAVAILABLE, "out of memory");
}

static int b64_value(unsigned char c)
{
    if (c >= 'A' && c <= 'Z')
        return c - 'A';
    if (c >= 'a' && c <= 'z')
        return c - 'a' + 26;
    if (c >= '0' && c <= '9')
        return c - '0' + 52;
    return c == '+' ? 62 : c == '/' ? 63 : -1;
}

size_t smd_base64_decode(const char *in, size_t n, unsigned char *out, size_t *pos)
{
    uint32_t acc = 0;
    int bits = 0, pad = 0;
    size_t len = 0;
    for (size_t i = 0; i < n; i++) {
        unsigned char c = (unsigned char)in[i];
        if (c == '\r' || c == '\n')
            continue; /* MIME line breaks */
        if (c == '=' ) {
            pad++;
            continue;
        }
        int v = b64_value(c);
        if (v < 0 || pad) {
            *pos = i;
            return SIZE_MAX;
        }
        acc = (acc << 6) | (uint32_t)v;
        bits += 6;
        if (bits >= 8) {
            bits -= 8;
            out[len++] = (unsigned char)(acc >> bits);
        }
    }
    /* leftover bits: 0 (4k chars), 4 (2 chars + "=="), 2 (3 chars + "=") */
    if (bits == 6 || pad > 2 || (pad && pad != bits / 2) || (acc & ((1u << bits) - 1))) {
        *pos = n;
        return SIZE_MAX;
    }
    return len;
}

/* One file input: {"value": base64, "mediaType": ..., "encoding": "base64"}. */
static int execute_file(smd_upload *u, const char *name, json_t *in)
{
    if (json_is_object(in) && json_object_get(in, "href")) {
        smd_upload_fail(u, 400, SMD_PROBLEM_BAD_REQUEST,
                        "%s: inputs by reference (href) are not fetched (the daemon makes no "
                        "outbound requests): give the file inline, {\"value\": base64}", name);
        return -1;
    }
    json_t *value = json_is_object(in) ? json_object_get(in, "value") : NULL;
    const char *enc = json_string_value(json_object_get(in, "encoding"));
    if (!json_is_string(value)) {
        smd_upload_fail(u, 400, SMD_PROBLEM_BAD_REQUEST,
                        "%s: a file input is an object {\"value\": the file in base64, "
                        "\"mediaType\": optional}", name);
        return -1;
    }
    if (enc && strcmp(enc, "base64") != 0) {
        smd_upload_fail(u, 400, SMD_PROBLEM_BAD_REQUEST,
                        "%s: encoding \"%.32s\" is not supported (the value is base64)", name, enc);
        return -1;
    }
    size_t n = json_string_length(value), pos = 0;
    unsigned char *bytes = malloc(n / 4 * 3 + 3);
    if (!bytes) {
        smd_upload_fail(u, 503, SMD_PROBLEM_UNAVAILABLE, "out of memory");
        return -1;
    }
    size_t len = smd_base64_decode(json_string_value(value), n, bytes, &pos);
    if (len == SIZE_MAX)
        smd_upload_fail(u, 400, SMD_PROBLEM_BAD_REQUEST,
                        "%s: value is not base64 (at character %zu)", name, pos);
    else
        smd_upload_part(u, name, bytes, len);
    free(bytes);
    return len == SIZE_MAX ? -1 : 0;
}

/* params: the JSON object itself, or {"value": object}. */
static int execute_params(smd_upload *u, json_t *in)
{
    json_t *value = json_is_object(in) && json_object_size(in) == 1 && json_object_get(in, "value")
                        ? json_object_get(in, "value")
                        : in;
    if (!json_is_object(value)) {
        smd_upload_fail(u, 400, SMD_PROBLEM_BAD_REQUEST,
                        "params: an object (the parameters document, see /v1/params.schema.json)");
        return -1;
    }
    char *text = sm_json_dumps(value, 0);
    if (!text) {
        smd_upload_fail(u, 503, SMD_PROBLEM_UNAVAILABLE, "out of memory");
        return -1;
    }
    smd_upload_part(u, sm_part_names[SM_PART_PARAMS], text, strlen(text));
    free(text);
    return 0;
}

static int execute_input(smd_upload *u, const char *name, json_t *in)
{
    for (int i = 0; i < SM_NPARTS; i++)
        if (strcmp(name, sm_part_names[i]) == 0)
            return i == SM_PART_PARAMS ? execute_params(u, in) : execute_file(u, name, in);
    char shown[64];
    sm_text_printable_copy(shown, sizeof shown, name, "\"");
    smd_upload_fail(u, 400, SMD_PROBLEM_BAD_REQUEST,
                    "unknown input \"%s\": the inputs are template, target_mesh, target_sol, "
                    "target_surface, template_landmarks, target_landmarks, target_image and "
                    "params (see "
                    "/v1/processes/match)", shown);
    return -1;
}

/* The members of an execute request: inputs; outputs and response are
 * accepted and change nothing (every output is kept, by reference);
 * subscriber (callbacks) and anything else is refused. */
static int execute_members(smd_upload *u, json_t *doc)
{
    const char *key;
    json_t *v;
    json_object_foreach(doc, key, v) {
        if (strcmp(key, "inputs") == 0 || strcmp(key, "outputs") == 0)
            continue;
        if (strcmp(key, "response") == 0 && json_is_string(v) &&
            (strcmp(json_string_value(v), "document") == 0 || strcmp(json_string_value(v), "raw") == 0))
            continue;
        char shown[64];
        sm_text_printable_copy(shown, sizeof shown, key, "\"");
        smd_upload_fail(u, 400, SMD_PROBLEM_BAD_REQUEST,
                        "execute request: \"%s\" is not supported (the members are inputs, "
                        "outputs and response; no callbacks)", shown);
        return -1;
    }
    return 0;
}

static void execute_end(void *cls, smd_upload *u)
{
    execute_body *b = cls;
    json_error_t jerr;
    if (b->refused)
        return;
    json_t *doc = json_loadb(b->body.buf ? b->body.buf : "", b->body.len, JSON_REJECT_DUPLICATES, &jerr);
    smd_body_release(&b->body);
    json_t *inputs = json_object_get(doc, "inputs");
    if (!doc)
        smd_upload_fail(u, 400, SMD_PROBLEM_BAD_REQUEST, "execute request: not JSON: %s (line %d)",
                        jerr.text, jerr.line);
    else if (!json_is_object(doc) || !json_is_object(inputs))
        smd_upload_fail(u, 400, SMD_PROBLEM_BAD_REQUEST,
                        "execute request: an object with \"inputs\", an object");
    else if (execute_members(u, doc) == 0) {
        const char *key;
        json_t *v;
        json_object_foreach(inputs, key, v) if (execute_input(u, key, v) != 0) break;
    }
    json_decref(doc);
}

static void execute_free(void *cls)
{
    execute_body *b = cls;
    smd_body_release(&b->body);
    free(b);
}

static const smd_upload_decoder execute_decoder = {execute_piece, execute_end, execute_free};

/* 1 when the Prefer header (RFC 7240) asks for respond-async. */
static int prefers_async(const char *prefer)
{
    for (const char *p = prefer; p && *p;) {
        p += strspn(p, " \t,");
        size_t n = strcspn(p, " \t,;=");
        if (n == 13 && strncasecmp(p, "respond-async", 13) == 0)
            return 1;
        p += strcspn(p, ",");
    }
    return 0;
}

enum MHD_Result smd_route_execute(struct MHD_Connection *conn, smd_request *req)
{
    if (strcmp(req->pid, "match") != 0)
        return smd_reply_problem(conn, req, 404, SMD_PROBLEM_NO_SUCH_PROCESS,
                                 "no process \"%s\" (the only process is \"match\")", req->pid);
    execute_body *b = calloc(1, sizeof *b);
    if (!b)
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE, "out of memory");
    b->body.budget = req->srv->cfg.max_body_memory;
    b->body.max = EXECUTE_MAX;
    enum MHD_Result r = smd_upload_begin_decoded(
        conn, req, "application/json",
        "POST /v1/processes/match/execution takes an application/json execute request "
        "(or send multipart/form-data to POST /v1/jobs)",
        &execute_decoder, b);
    const char *prefer = MHD_lookup_connection_value(conn, MHD_HEADER_KIND, "Prefer");
    if (req->upload && prefers_async(prefer))
        smd_upload_created_header(req->upload, "Preference-Applied", "respond-async");
    return r;
}
