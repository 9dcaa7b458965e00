/* VTK legacy files (.vtk, ASCII and binary, both cell layouts) through
 * sm_mesh_read and sm_surface_read.  Prefix "# vtk DataFile Version ",
 * so the input starts with the version number (which picks the layout).
 * Contracts: fuzz_check_mesh, fuzz_check_surface. */
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
    return fuzz_file_target("# vtk DataFile Version ", data, size, check_both);
}
