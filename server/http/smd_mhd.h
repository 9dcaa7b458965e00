/* libmicrohttpd for the layers above http/ that name its types (a
 * handler's connection, the PostProcessor's part callback, a suspended
 * event stream): they include this header, and only http/ includes
 * <microhttpd.h> itself (tests/integration/daemon_layers.sh), so the one
 * library the HTTP layer wraps has one door. */
#ifndef SMD_MHD_H
#define SMD_MHD_H

#include <microhttpd.h>

#endif
