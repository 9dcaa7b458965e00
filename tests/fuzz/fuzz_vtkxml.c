/* VTK XML files (.vtu, .vtp: ASCII, base64, appended raw or base64,
 * zlib-compressed) through sm_mesh_read and sm_surface_read.  No prefix:
 * an input is read as VTK XML when "<VTKFile" is in its first 512 bytes,
 * as in the seeds.  Contracts: fuzz_check_mesh, fuzz_check_surface. */
#include <stdint.h>

#include "fuzz_input.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static void check_both(const sm_reader_input *in)
{
    fuzz_check_mesh(in);
    fuzz_check_surface(in);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    return fuzz_file_target(NULL, data, size, check_both);
}
