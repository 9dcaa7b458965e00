/* STL (ASCII and binary; the reader tells them apart by content) through
 * sm_surface_read.  No prefix: binary STL is told by its size, ASCII by
 * "solid ... facet".
 * The reader must fail cleanly (NULL and a message) or give a surface
 * whose indices are in range and whose coordinates are finite. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "fuzz_input.h"
#include "shapematch/sm_surface.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static const char prefix[] = "";

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    size_t n = sizeof prefix - 1;
    uint8_t *buf = malloc(n + size + 1);
    if (!buf)
        return 0;
    memcpy(buf, prefix, n);
    if (size)
        memcpy(buf + n, data, size);
    char path[64];
    int fd = fuzz_memfile(buf, n + size, path, sizeof path);
    free(buf);
    if (fd < 0)
        return 0;
    sm_error err;
    sm_error_clear(&err);
    sm_surface *s = NULL;
    if (sm_surface_read(path, &s, &err) == SM_OK) {
        for (int64_t i = 0; i < (int64_t)s->nfacets * s->dim; i++)
            if (s->facets[i] < 0 || s->facets[i] >= s->nverts)
                abort(); /* the reader let a bad index through */
        for (int64_t i = 0; i < (int64_t)s->nverts * s->dim; i++)
            if (!isfinite(s->coords[i]))
                abort();
        sm_surface_free(s);
    } else if (s != NULL || err.msg[0] == '\0') {
        abort(); /* contract: *out NULL and a message on error */
    }
    close(fd);
    return 0;
}
