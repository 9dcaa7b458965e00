/* CORS and cross-site safety (see smd_cors.h). */
#include "http/smd_cors.h"

#include <arpa/inet.h>
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

/* The host part of an authority "host[:port]" or "[v6][:port]" into buf
 * (brackets kept off); its length, 0 when it does not fit, is empty, or
 * what follows it is anything but nothing or ":" and 1 to 5 digits. */
static size_t host_part(const char *authority, char *buf, size_t cap)
{
    const char *h = authority, *rest;
    size_t n;
    if (h[0] == '[') {
        h++;
        n = strcspn(h, "]");
        rest = h[n] == ']' ? h + n + 1 : NULL;
    } else {
        n = strcspn(h, ":");
        rest = h + n;
    }
    if (n == 0 || n >= cap || !rest)
        return 0;
    if (*rest == ':') {
        size_t digits = strspn(rest + 1, "0123456789");
        if (digits == 0 || digits > 5 || rest[1 + digits] != '\0')
            return 0;
    } else if (*rest != '\0') {
        return 0;
    }
    memcpy(buf, h, n);
    buf[n] = '\0';
    return n;
}

/* 1 for localhost and the names under it (RFC 6761: they resolve to the
 * loopback address and nowhere else), with or without a final dot. */
static int localhost_name(const char *host)
{
    size_t n = strlen(host);
    if (n > 0 && host[n - 1] == '.')
        n--;
    static const char name[] = "localhost";
    size_t k = sizeof name - 1;
    if (n < k || strncasecmp(host + n - k, name, k) != 0)
        return 0;
    return n == k || host[n - k - 1] == '.';
}

int smd_cors_trusted_host(const smd_config *cfg, const char *authority)
{
    char host[SMD_ORIGIN_MAX], other[SMD_ORIGIN_MAX];
    if (!authority || !host_part(authority, host, sizeof host))
        return 0;
    /* a rebinding attack needs a name it controls: an address is no name
     * (a v6 one only in brackets) */
    unsigned char a[16];
    if (authority[0] == '[' ? inet_pton(AF_INET6, host, a) == 1 : inet_pton(AF_INET, host, a) == 1)
        return 1;
    if (localhost_name(host) || strcasecmp(host, cfg->listen_host) == 0)
        return 1;
    size_t p = origin_prefix(cfg->public_url);
    if (p > 0) {
        char pub[SMD_ORIGIN_MAX];
        snprintf(pub, sizeof pub, "%.*s", (int)p, cfg->public_url);
        if (host_part(strstr(pub, "://") + 3, other, sizeof other) && strcasecmp(other, host) == 0)
            return 1;
    }
    for (unsigned i = 0; i < cfg->nallowed_hosts; i++) {
        const char *e = cfg->allowed_hosts[i];
        int with_port = strchr(e[0] == '[' ? strchr(e, ']') : e, ':') != NULL;
        if (with_port ? strcasecmp(e, authority) == 0
                      : host_part(e, other, sizeof other) && strcasecmp(other, host) == 0)
            return 1;
    }
    return 0;
}

int smd_cors_same_origin(const smd_config *cfg, const char *origin, const char *host)
{
    size_t n = origin_prefix(origin);
    if (n == 0 || origin[n] != '\0')
        return 0; /* "null" (sandboxed pages, file:) and anything odd */
    size_t p = origin_prefix(cfg->public_url);
    if (p > 0 && p == n && strncasecmp(cfg->public_url, origin, n) == 0)
        return 1;
    /* the Host header is the client's word: it counts only when it names
     * this daemon (an address, localhost, the listen host, --public-url's
     * or an --allowed-host), never an attacker's name rebound to us */
    const char *authority = strstr(origin, "://") + 3;
    return host && strcasecmp(authority, host) == 0 && smd_cors_trusted_host(cfg, host);
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
