/* Text that quotes hostile input (paths, header values, part names, JSON
 * keys) made safe for messages, logs, JSON strings and headers: every
 * byte that is not printable ASCII (below 0x20, or 0x7f and above) and
 * every byte of `also` (NULL: none) becomes '?'.  Shared by the daemon
 * and, as they move to it, the client and proto's own messages. */
#ifndef SM_PROTO_TEXT_H
#define SM_PROTO_TEXT_H

#include <stddef.h>

/* In place; returns s. */
char *sm_text_make_printable(char *s, const char *also);

/* Into dst (cap >= 4 bytes): src made printable, cut to cap - 4 bytes
 * and marked "..." when longer.  NULL src gives "".  Returns dst. */
char *sm_text_printable_copy(char *dst, size_t cap, const char *src, const char *also);

#endif
