/* CORS and cross-site safety (see smd_cors.h). */
#include "http/smd_cors.h"

#include <stdio.h>
#include <string.h>
#include <strings.h>

/* Length of the scheme://host[:port] prefix of url ("" when url has no
 * http or https scheme). */
static size_t origin_prefix(const char *url)
{
    size_t skip;
    if (strncasecmp(url, "http://", 7) == 0)
        skip = 7;
    else if (strncasecmp(url, "https://", 8) == 0)
        skip = 8;
    else
        return 0;
    return skip + strcspn(url + skip, "/?#");
}

/* 2 when "*" is listed, 1 when origin is, 0 otherwise. */
static int listed(const smd_config *cfg, const char *origin)
{
    if (!origin)
        return 0;
    int found = 0;
    for (unsigned i = 0; i < cfg->ncors_origins; i++) {
        if (strcmp(cfg->cors_origins[i], "*") == 0)
            return 2;
        if (strcasecmp(cfg->cors_origins[i], origin) == 0)
            found = 1;
    }
    return found;
}

int smd_cors_listed(const smd_config *cfg, const char *origin)
{
    return listed(cfg, origin) != 0;
}

int smd_cors_same_origin(const smd_config *cfg, const char *origin, const char *host)
{
    size_t n = origin_prefix(origin);
    if (n == 0 || origin[n] != '\0')
        return 0; /* "null" (sandboxed pages, file:) and anything odd */
    size_t p = origin_prefix(cfg->public_url);
    if (p > 0 && p == n && strncasecmp(cfg->public_url, origin, n) == 0)
        return 1;
    const char *authority = strstr(origin, "://") + 3;
    return host && strcasecmp(authority, host) == 0;
}

int smd_cors_cross_site(const smd_config *cfg, struct MHD_Connection *conn, int method_is_write)
{
    if (!method_is_write)
        return 0;
    const char *origin = MHD_lookup_connection_value(conn, MHD_HEADER_KIND, "Origin");
    if (!origin)
        return 0;
    const char *host = MHD_lookup_connection_value(conn, MHD_HEADER_KIND, MHD_HTTP_HEADER_HOST);
    return !smd_cors_same_origin(cfg, origin, host) && !smd_cors_listed(cfg, origin);
}

void smd_cors_decorate(const smd_config *cfg, struct MHD_Connection *conn,
                       struct MHD_Response *resp)
{
    MHD_add_response_header(resp, MHD_HTTP_HEADER_VARY, "Origin");
    const char *origin = MHD_lookup_connection_value(conn, MHD_HEADER_KIND, "Origin");
    int l = listed(cfg, origin);
    if (!l)
        return;
    MHD_add_response_header(resp, MHD_HTTP_HEADER_ACCESS_CONTROL_ALLOW_ORIGIN, l == 2 ? "*" : origin);
    MHD_add_response_header(resp, "Access-Control-Expose-Headers", SMD_CORS_EXPOSE_HEADERS);
}

void smd_cors_preflight(const smd_config *cfg, struct MHD_Connection *conn,
                        struct MHD_Response *resp, const char *methods)
{
    const char *origin = MHD_lookup_connection_value(conn, MHD_HEADER_KIND, "Origin");
    if (!smd_cors_listed(cfg, origin))
        return;
    char allow[96];
    snprintf(allow, sizeof allow, "%s, OPTIONS", methods);
    MHD_add_response_header(resp, "Access-Control-Allow-Methods", allow);
    MHD_add_response_header(resp, "Access-Control-Allow-Headers", SMD_CORS_ALLOW_HEADERS);
    MHD_add_response_header(resp, "Access-Control-Max-Age", SMD_CORS_MAX_AGE);
}
