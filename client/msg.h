/* Error messages of the client's helpers: formatted into the caller's
 * buffer, so that the command that called can add its own context. */
#ifndef CLIENT_MSG_H
#define CLIENT_MSG_H

#include <stddef.h>

/* Formats into msg (cap bytes; either may be 0/NULL) and returns -1, so
 * that `return cli_fail(msg, cap, "...", ...);` reports and fails. */
int cli_fail(char *msg, size_t cap, const char *fmt, ...) __attribute__((format(printf, 3, 4)));

#endif
