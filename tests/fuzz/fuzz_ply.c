/* PLY surfaces (ASCII, binary in both byte orders) through
 * sm_surface_read.  Prefix "ply\n": the first line that makes any input a
 * PLY file, so the fuzzer spends its time in the header and data parser.
 * Contract: fuzz_check_surface. */
#include <stdint.h>

#include "fuzz_input.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    return fuzz_file_target("ply\n", data, size, fuzz_check_surface);
}
