/* STL (ASCII and binary; the reader tells them apart by content) through
 * sm_surface_read.  No prefix: binary STL is told by its size, ASCII by
 * "solid ... facet".  Contract: fuzz_check_surface. */
#include <stdint.h>

#include "fuzz_input.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    return fuzz_file_target(NULL, data, size, fuzz_check_surface);
}
