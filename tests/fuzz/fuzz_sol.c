/* Medit .sol / .solb, optionally gzip'ed: sm_sol_read fails cleanly or
 * returns a solution whose size matches its header. */
#include <stdint.h>
#include <stdlib.h>

#include "fuzz_input.h"
#include "io/sm_read_input.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static void check_sol(const sm_reader_input *in)
{
    sm_error err;
    sm_error_clear(&err);
    sm_sol *s = NULL;
    if (sm__sol_read_input(in, NULL, &s, &err) != SM_OK) {
        if (s != NULL || err.msg[0] == '\0')
            abort();
        return;
    }
    if (s->ncomp != 1 && s->ncomp != s->dim && s->ncomp != s->dim * (s->dim + 1) / 2)
        abort();
    volatile double sum = 0; /* touch every value: ASan checks the size */
    for (int64_t i = 0; i < (int64_t)s->nverts * s->ncomp; i++)
        sum += s->values[i];
    (void)sum;
    sm_sol_free(s);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    return fuzz_file_target(NULL, data, size, check_sol);
}
