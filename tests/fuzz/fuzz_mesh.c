/* Medit .mesh / .meshb, optionally gzip'ed (the reader tells them apart by
 * content): sm_mesh_read must fail cleanly or give a mesh whose indices
 * are in range, never crash or leak.  A mesh it accepts also goes through
 * the boundary build, which trusts the reader's index checks. */
#include <stdint.h>
#include <stdlib.h>
#include <unistd.h>

#include "fuzz_input.h"
#include "shapematch/sm_io.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    char path[64];
    int fd = fuzz_memfile(data, size, path, sizeof path);
    if (fd < 0)
        return 0;
    sm_error err;
    sm_error_clear(&err);
    sm_mesh *m = NULL;
    if (sm_mesh_read(path, &m, &err) == SM_OK) {
        int per = m->dim + 1;
        for (int64_t i = 0; i < (int64_t)m->nelems * per; i++)
            if (m->elems[i] < 0 || m->elems[i] >= m->nverts)
                abort(); /* the reader let a bad index through */
        for (int64_t i = 0; i < (int64_t)m->nfacets * m->dim; i++)
            if (m->facets[i] < 0 || m->facets[i] >= m->nverts)
                abort();
        sm_error_clear(&err);
        (void)sm_mesh_build_boundary(m, &err);
        sm_mesh_free(m);
    } else if (m != NULL || err.msg[0] == '\0') {
        abort(); /* contract: *out NULL and a message on error */
    }
    close(fd);
    return 0;
}
