#include "fuzz_input.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <unistd.h>

#include "shapematch/sm_io.h"
#include "shapematch/sm_surface.h"

static int write_all(int fd, const void *data, size_t size)
{
    const uint8_t *p = data;
    size_t done = 0;
    while (done < size) {
        ssize_t n = write(fd, p + done, size - done);
        if (n <= 0)
            return -1;
        done += (size_t)n;
    }
    return 0;
}

int fuzz_memfile(const char *prefix, const uint8_t *data, size_t size, char *path, size_t cap)
{
    int fd = memfd_create("fuzz-input", MFD_CLOEXEC);
    if (fd < 0)
        return -1;
    if ((prefix && write_all(fd, prefix, strlen(prefix)) != 0) ||
        write_all(fd, data, size) != 0 || lseek(fd, 0, SEEK_SET) != 0) {
        close(fd);
        return -1;
    }
    snprintf(path, cap, "/proc/self/fd/%d", fd);
    return fd;
}

static void check_indices(const int32_t *idx, int64_t n, int32_t nverts)
{
    for (int64_t i = 0; i < n; i++)
        if (idx[i] < 0 || idx[i] >= nverts)
            abort(); /* the reader let a bad index through */
}

void fuzz_check_mesh(const char *path)
{
    sm_error err;
    sm_error_clear(&err);
    sm_mesh *m = NULL;
    if (sm_mesh_read(path, &m, &err) != SM_OK) {
        if (m != NULL || err.msg[0] == '\0')
            abort(); /* contract: *out NULL and a message on error */
        return;
    }
    check_indices(m->elems, (int64_t)m->nelems * (m->dim + 1), m->nverts);
    check_indices(m->facets, (int64_t)m->nfacets * m->dim, m->nverts);
    sm_error_clear(&err);
    (void)sm_mesh_build_boundary(m, &err);
    sm_mesh_free(m);
}

void fuzz_check_surface(const char *path)
{
    sm_error err;
    sm_error_clear(&err);
    sm_surface *s = NULL;
    if (sm_surface_read(path, &s, &err) != SM_OK) {
        if (s != NULL || err.msg[0] == '\0')
            abort();
        return;
    }
    check_indices(s->facets, (int64_t)s->nfacets * s->dim, s->nverts);
    for (int64_t i = 0; i < (int64_t)s->nverts * s->dim; i++)
        if (!isfinite(s->coords[i]))
            abort();
    sm_surface_free(s);
}

int fuzz_file_target(const char *prefix, const uint8_t *data, size_t size,
                     void (*check)(const char *path))
{
    char path[64];
    int fd = fuzz_memfile(prefix, data, size, path, sizeof path);
    if (fd < 0)
        return 0;
    check(path);
    close(fd);
    return 0;
}
