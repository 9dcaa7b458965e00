/* Request bodies held in memory (the OGC execute request, a warp's
 * points or mesh, a batch description), counted together against
 * --max-body-memory: however many connections park a body, the daemon
 * holds at most that much of them (issues 28 and 37).  The count is the
 * process's (one daemon per process); a body's whole buffer counts, from
 * its growth to its release. */
#ifndef SMD_BODY_H
#define SMD_BODY_H

#include <stddef.h>
#include <stdint.h>

typedef struct smd_body {
    char *buf;       /* NUL-terminated after len */
    size_t len, cap; /* cap counted in the shared total */
    size_t max;      /* this body's own bound */
    uint64_t budget; /* --max-body-memory: every body together */
} smd_body;

enum { SMD_BODY_OK, SMD_BODY_TOO_LARGE, SMD_BODY_BUSY, SMD_BODY_NOMEM };

/* Appends n bytes: SMD_BODY_OK, or (the buffer released, nothing kept)
 * SMD_BODY_TOO_LARGE past b->max, SMD_BODY_BUSY when every body together
 * would pass b->budget, SMD_BODY_NOMEM. */
int smd_body_append(smd_body *b, const char *data, size_t n);
/* Frees the buffer and takes it out of the count (again: nothing). */
void smd_body_release(smd_body *b);
/* Bytes held by every body now (for tests and /metrics). */
uint64_t smd_body_held(void);

#endif
