/* JSON text as every proto encoder writes it: the one serializer (exact,
 * shortest reals) and a string constructor for bytes that may not be
 * UTF-8 (file names).  Link with libsmproto.a and -ljansson. */
#ifndef SM_JSON_H
#define SM_JSON_H

#include <jansson.h>

/* Serializes any JSON value like json_dumps, but prints each real with
 * the fewest digits that read back to the same double (0.3, not
 * 0.29999999999999999) and integral reals as "1.0".  indent 0: compact,
 * one line; 1..8: pretty, that many spaces per level.  Members in
 * insertion order.  Returns a malloc'd string without a trailing newline,
 * or NULL (out of memory, bad indent).  Every encoder here uses it. */
char *sm_json_dumps(const json_t *value, int indent);

/* A JSON string for any bytes: valid UTF-8 is kept, every other byte
 * becomes U+FFFD (file names may hold any byte; json_string refuses
 * them).  NULL for s == NULL or out of memory. */
json_t *sm_json_string_lossy(const char *s);

#endif
