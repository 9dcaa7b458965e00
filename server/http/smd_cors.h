/* Cross-origin requests (CORS) and cross-site safety for shapematchd.
 *
 * Browsers on another origin may use the daemon only when their origin is
 * listed (--cors-origin, SHAPEMATCH_CORS_ORIGINS): responses then carry
 * Access-Control-Allow-Origin and expose the headers clients need
 * (Location, Preference-Applied, Retry-After, Content-Disposition), and a
 * preflight OPTIONS on any route answers 204 with that route's methods
 * (from the route table), the request headers the API reads and a
 * Max-Age.  Every response says Vary: Origin, so that caches keep the
 * answers for different origins apart.
 *
 * Cross-site safety: a plain multipart POST needs no preflight, so any
 * page could start jobs on a daemon without tokens.  A state-changing
 * request (POST, DELETE) that carries an Origin which is neither the
 * daemon's own (its Host header when that names the daemon — an address,
 * localhost, the listen host, an --allowed-host —, or the origin of
 * --public-url behind a reverse proxy) nor a listed one is refused (403),
 * tokens or not: a page whose name an attacker rebinds to the daemon's
 * address (DNS rebinding) is foreign.  With --allowed-host, a request
 * whose Host names something else is refused outright (421).
 * Requests without Origin (curl, the shapematch client) are unaffected.
 *
 * This module reads only headers and the configuration: it knows nothing
 * of the routes or the reply layer (the reply layer calls
 * smd_cors_decorate on every response, the dispatcher the rest). */
#ifndef SMD_CORS_H
#define SMD_CORS_H

#include <microhttpd.h>
#include <stddef.h>

#include "base/smd_config.h"

/* Headers a preflight allows, and how long a browser may cache it. */
#define SMD_CORS_ALLOW_HEADERS "Authorization, Content-Type, Idempotency-Key, Last-Event-ID, Prefer"
#define SMD_CORS_EXPOSE_HEADERS "Location, Preference-Applied, Retry-After, Content-Disposition"
#define SMD_CORS_MAX_AGE "600"

/* 1 when the request's Origin header is listed (or "*" is). */
int smd_cors_listed(const smd_config *cfg, const char *origin);

/* 1 when authority (a Host header, host[:port]) names this daemon: an IP
 * address, localhost, the --listen host, --public-url's host or an
 * --allowed-host (with its port when the entry has one).  A name an
 * attacker controls (DNS rebinding) is none of these. */
int smd_cors_trusted_host(const smd_config *cfg, const char *authority);

/* 1 when origin is the daemon's own: its scheme://host[:port] equals the
 * origin of cfg->public_url, or its host[:port] equals host (the request's
 * Host header) and that names this daemon (smd_cors_trusted_host). */
int smd_cors_same_origin(const smd_config *cfg, const char *origin, const char *host);

/* 1 when the request is a state-changing one (method_is_write) from a
 * foreign origin: it carries an Origin header that is neither the
 * daemon's own nor listed.  Such a request is refused with 403. */
int smd_cors_cross_site(const smd_config *cfg, struct MHD_Connection *conn, int method_is_write);

/* Adds Vary: Origin and, for a listed Origin, Access-Control-Allow-Origin
 * and Access-Control-Expose-Headers to resp. */
void smd_cors_decorate(const smd_config *cfg, struct MHD_Connection *conn,
                       struct MHD_Response *resp);

/* Adds the preflight headers to resp (a 204): Access-Control-Allow-Methods
 * (methods, e.g. "GET, HEAD, POST", plus OPTIONS), -Allow-Headers and
 * -Max-Age when the Origin is listed; nothing for an unlisted one (the
 * browser then refuses the request it asked about). */
void smd_cors_preflight(const smd_config *cfg, struct MHD_Connection *conn,
                        struct MHD_Response *resp, const char *methods);

#endif
