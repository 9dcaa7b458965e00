/* Medit .mesh / .meshb, optionally gzip'ed (the reader tells them apart by
 * content): sm_mesh_read must fail cleanly or give a mesh whose indices
 * are in range, never crash or leak (fuzz_check_mesh). */
#include <stdint.h>

#include "fuzz_input.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    return fuzz_file_target(NULL, data, size, fuzz_check_mesh);
}
