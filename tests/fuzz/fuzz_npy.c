/* The NumPy .npy reader of `shapematch warp --points` (core/io/sm_io_npy.c):
 * any input is parsed or refused with a message naming the input, never
 * more values than the bytes hold; an accepted array encodes (sm_npy_encode,
 * float64) to a file that parses back to the same values bit for bit, and
 * whose encoding is stable. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "shapematch/sm_io.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    double *v = NULL, *w = NULL;
    int64_t rows, rows2;
    int cols, cols2;
    sm_error err;
    sm_error_clear(&err);
    if (sm_npy_parse(data, size, 0, "in.npy", &v, &rows, &cols, &err) != SM_OK) {
        if (v || strncmp(err.msg, "in.npy: ", 8) != 0)
            abort();
        return 0;
    }
    if (rows < 1 || (cols != 2 && cols != 3) || (uint64_t)rows * (uint64_t)cols * 4 > size)
        abort();
    char *enc = NULL, *enc2 = NULL;
    size_t len, len2;
    if (sm_npy_encode(v, rows, cols, &enc, &len, &err) != SM_OK ||
        sm_npy_parse(enc, len, 0, "again", &w, &rows2, &cols2, &err) != SM_OK || rows2 != rows ||
        cols2 != cols || memcmp(v, w, (size_t)rows * (size_t)cols * sizeof *v) != 0 ||
        sm_npy_encode(w, rows2, cols2, &enc2, &len2, &err) != SM_OK || len2 != len ||
        memcmp(enc, enc2, len) != 0)
        abort();
    free(v);
    free(w);
    free(enc);
    free(enc2);
    return 0;
}
