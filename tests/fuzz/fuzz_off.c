/* OFF surfaces through sm_surface_read.  Prefix "OFF\n", without which
 * most inputs would go to other readers.  Contract: fuzz_check_surface. */
#include <stdint.h>

#include "fuzz_input.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    return fuzz_file_target("OFF\n", data, size, fuzz_check_surface);
}
