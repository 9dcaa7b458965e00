/* Gmsh .msh (4.1 ASCII/binary, 2.2 ASCII) through sm_mesh_read: every
 * input is prefixed with "$MeshFormat\n", so the fuzzer spends its time in
 * the .msh reader (the seeds are .msh files without that first line).
 * The reader must fail cleanly or give a mesh whose indices are in range;
 * an accepted mesh also goes through the boundary build. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "fuzz_input.h"
#include "shapematch/sm_io.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static const char prefix[] = "$MeshFormat\n";

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
    sm_mesh *m = NULL;
    if (sm_mesh_read(path, &m, &err) == SM_OK) {
        for (int64_t i = 0; i < (int64_t)m->nelems * (m->dim + 1); i++)
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
