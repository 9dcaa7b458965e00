/* The web app's routes (see smd_app.h). */
#include "api/smd_app.h"

#include <stdlib.h>
#include <string.h>

#include "http/smd_http.h"
#include "http/smd_negotiate.h"
#include "api/smd_routes.h"

/* server/embed.sh output (build/<variant>/gen/web/smd_app_embedded.c) */
#define EMBEDDED(name)                                                                             \
    extern const unsigned char name[];                                                             \
    extern const size_t name##_len;
EMBEDDED(smd_app_index)
EMBEDDED(smd_app_js)
EMBEDDED(smd_app_view)
EMBEDDED(smd_app_target)
EMBEDDED(smd_app_align)
EMBEDDED(smd_app_warp)
EMBEDDED(smd_app_batch)
EMBEDDED(smd_app_css)
EMBEDDED(smd_app_favicon)
EMBEDDED(smd_app_three)
EMBEDDED(smd_app_three_core)
EMBEDDED(smd_app_orbit)
EMBEDDED(smd_app_uplot)
EMBEDDED(smd_app_uplot_css)

typedef struct asset {
    const char *name;
    const unsigned char *data;
    const size_t *len;
    const char *type;
} asset;

#define JS "text/javascript; charset=utf-8"
static const asset assets[] = {
    {"app.js", smd_app_js, &smd_app_js_len, JS},
    {"view.js", smd_app_view, &smd_app_view_len, JS},
    {"target.js", smd_app_target, &smd_app_target_len, JS},
    {"align.js", smd_app_align, &smd_app_align_len, JS},
    {"warp.js", smd_app_warp, &smd_app_warp_len, JS},
    {"batch.js", smd_app_batch, &smd_app_batch_len, JS},
    {"app.css", smd_app_css, &smd_app_css_len, "text/css; charset=utf-8"},
    {"favicon.svg", smd_app_favicon, &smd_app_favicon_len, "image/svg+xml"},
    {"three.js", smd_app_three, &smd_app_three_len, JS},
    {"three-core.js", smd_app_three_core, &smd_app_three_core_len, JS},
    {"orbit.js", smd_app_orbit, &smd_app_orbit_len, JS},
    {"uplot.js", smd_app_uplot, &smd_app_uplot_len, JS},
    {"uplot.css", smd_app_uplot_css, &smd_app_uplot_css_len, "text/css; charset=utf-8"},
};

/* The page's marker of a daemon with tokens (same length either way). */
#define TOKENS_OFF "data-tokens=\"0\""
#define TOKENS_ON "data-tokens=\"1\""

static enum MHD_Result serve(struct MHD_Connection *conn, smd_request *req, const unsigned char *data,
                             size_t len, const char *type, const char *what)
{
    if (len == 0)
        return smd_reply_problem(conn, req, 404, SMD_PROBLEM_NOT_FOUND,
                                 "this build carries no %s (build it after `make deps`, which "
                                 "installs the npm packages of the web app)",
                                 what);
    char *copy = malloc(len);
    if (!copy)
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE, "out of memory");
    memcpy(copy, data, len);
    if (data == smd_app_index && req->srv->tokens) {
        /* tell the page to ask for a token before it calls the API */
        char *mark = memmem(copy, len, TOKENS_OFF, sizeof TOKENS_OFF - 1);
        if (mark)
            memcpy(mark, TOKENS_ON, sizeof TOKENS_ON - 1);
    }
    struct MHD_Response *resp = smd_buffer_response(conn, req, type, copy, len);
    if (resp)
        MHD_add_response_header(resp, MHD_HTTP_HEADER_CACHE_CONTROL, "no-cache");
    return smd_reply(conn, req, 200, resp);
}

enum MHD_Result smd_route_app_asset(struct MHD_Connection *conn, smd_request *req)
{
    for (size_t i = 0; i < sizeof assets / sizeof assets[0]; i++)
        if (strcmp(req->arg, assets[i].name) == 0)
            return serve(conn, req, assets[i].data, *assets[i].len, assets[i].type, assets[i].name);
    return smd_reply_problem(conn, req, 404, SMD_PROBLEM_NOT_FOUND, "the web app has no such file");
}

enum MHD_Result smd_route_root(struct MHD_Connection *conn, smd_request *req)
{
    static const char *const offered[] = {"application/json", "text/html"};
    const char *accept = MHD_lookup_connection_value(conn, MHD_HEADER_KIND, MHD_HTTP_HEADER_ACCEPT);
    if (smd_accept_choose(accept, offered, 2) == 1)
        return serve(conn, req, smd_app_index, smd_app_index_len, "text/html; charset=utf-8",
                     "web app");
    /* the row is public for the page; the JSON landing page is not */
    smd_server *srv = req->srv;
    if (srv->tokens) {
        const char *auth = MHD_lookup_connection_value(conn, MHD_HEADER_KIND,
                                                       MHD_HTTP_HEADER_AUTHORIZATION);
        smd_auth_result a = smd_http_identify(srv, auth, NULL, &req->who);
        if (a != SMD_AUTH_OK)
            return smd_reply_problem(conn, req, 401, SMD_PROBLEM_UNAUTHORIZED,
                                     a == SMD_AUTH_MISSING ? "this daemon requires a bearer token "
                                                             "(Authorization: Bearer <token>)"
                                                           : "the bearer token is not valid");
    }
    return smd_route_landing(conn, req);
}
