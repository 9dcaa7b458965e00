#include "fuzz_input.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <unistd.h>

#include "io/sm_read_input.h"

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

void fuzz_check_mesh(const sm_reader_input *in)
{
    sm_error err;
    sm_error_clear(&err);
    sm_mesh *m = NULL;
    if (sm__mesh_read_input(in, NULL, &m, &err) != SM_OK) {
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

void fuzz_check_surface(const sm_reader_input *in)
{
    sm_error err;
    sm_error_clear(&err);
    sm_surface *s = NULL;
    if (sm__surface_read_input(in, NULL, &s, &err) != SM_OK) {
        if (s != NULL || err.msg[0] == '\0')
            abort();
        return;
    }
    check_indices(s->facets, (int64_t)s->nfacets * s->dim, s->nverts);
    for (int64_t i = 0; i < (int64_t)s->nverts * s->dim; i++)
        if (!isfinite(s->coords[i]))
            abort();
    /* what a surface target goes through next: the orientation repair
     * (pieces, their boundaries, duplicates) keeps the indices valid and
     * its counts consistent, or fails with a message */
    sm_surface_health h;
    if (sm_surface_repair(s, &h, &err) == SM_OK) {
        check_indices(s->facets, (int64_t)s->nfacets * s->dim, s->nverts);
        if (h.reoriented < 0 || h.reoriented > s->nfacets || h.reoriented_within > h.reoriented ||
            h.pieces_turned > h.components || h.open_components > h.components ||
            h.open_by_volume > h.open_components)
            abort();
    } else if (err.msg[0] == '\0') {
        abort();
    }
    sm_surface_free(s);
}

/* Through a memfd: the readers inflate gzip input from files only. */
static void check_file(const char *prefix, const uint8_t *data, size_t size,
                       void (*check)(const sm_reader_input *in))
{
    char path[64];
    int fd = fuzz_memfile(prefix, data, size, path, sizeof path);
    if (fd < 0)
        return;
    check(&(sm_reader_input){.path = path});
    close(fd);
}

int fuzz_file_target(const char *prefix, const uint8_t *data, size_t size,
                     void (*check)(const sm_reader_input *in))
{
    size_t plen = prefix ? strlen(prefix) : 0;
    if (plen == 0 && size >= 2 && data[0] == 0x1f && data[1] == 0x8b) {
        check_file(prefix, data, size, check);
        return 0;
    }
    /* an exact-size copy when there is a prefix: ASan sees any read past
     * the end of the input */
    uint8_t *buf = plen ? malloc(plen + size) : NULL;
    if (plen && !buf)
        return 0;
    if (buf) {
        memcpy(buf, prefix, plen);
        if (size)
            memcpy(buf + plen, data, size);
    }
    const void *bytes = buf ? buf : size ? (const void *)data : "";
    check(&(sm_reader_input){.path = "fuzz-input", .data = bytes, .size = plen + size});
    free(buf);
    return 0;
}
