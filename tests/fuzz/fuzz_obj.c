/* OBJ through sm_surface_read: every input is prefixed with "v 0 0 0\n",
 * so it is read as OBJ (the seeds are OBJ files).  Contract:
 * fuzz_check_surface. */
#include <stdint.h>

#include "fuzz_input.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    return fuzz_file_target("v 0 0 0\n", data, size, fuzz_check_surface);
}
