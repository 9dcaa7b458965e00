/* The web app of shapematchd (issue 11): GET / answers a browser (an
 * Accept that prefers text/html) with web/index.html, any other client
 * with the JSON landing page; GET /app/{asset} serves the app's scripts
 * and styles (web/) and the npm libraries it uses (three, uPlot, from
 * node_modules at build time: nothing comes from a CDN), all embedded in
 * the binary by server/embed.sh.  The page and its assets are public: a
 * user must reach the page to type a token into it; the JSON landing at
 * / keeps requiring a token when tokens are on.  Every URL of the app is
 * relative, so it also works behind a reverse proxy's path prefix. */
#ifndef SMD_APP_H
#define SMD_APP_H

#include "http/smd_reply.h"

enum MHD_Result smd_route_root(struct MHD_Connection *conn, smd_request *req);
enum MHD_Result smd_route_app_asset(struct MHD_Connection *conn, smd_request *req);

#endif
