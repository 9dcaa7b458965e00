/* Files of `shapematch warp` (see warp_io.h). */
#include "warp_io.h"

#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "shapematch/sm_atomic.h"
#include "shapematch/sm_io.h"
#include "shapematch/sm_surface.h"

sm_status warp_read_file(const char *path, size_t max, char **out, size_t *len, sm_error *err)
{
    *out = NULL;
    *len = 0;
    FILE *f = fopen(path, "rb");
    if (!f)
        return sm_error_set(err, SM_ERR_IO, "cannot open '%s': %s", path, strerror(errno));
    size_t cap = 1 << 16, n = 0;
    char *buf = malloc(cap + 1);
    sm_status st = SM_OK;
    while (buf) {
        if (n == cap) {
            if (cap >= max) {
                st = sm_error_set(err, SM_ERR_NOMEM, "'%s' is larger than %zu bytes", path, max);
                break;
            }
            cap = cap * 2 > max ? max : cap * 2;
            char *grown = realloc(buf, cap + 1);
            if (!grown)
                break;
            buf = grown;
        }
        size_t got = fread(buf + n, 1, cap - n, f);
        n += got;
        if (got == 0) {
            if (ferror(f))
                st = sm_error_set(err, SM_ERR_IO, "cannot read '%s': %s", path, strerror(errno));
            break;
        }
    }
    fclose(f);
    if (!buf)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory reading '%s'", path);
    if (st != SM_OK) {
        free(buf);
        return st;
    }
    buf[n] = '\0';
    *out = buf;
    *len = n;
    return SM_OK;
}
