/* Gmsh .msh (4.1 ASCII/binary, 2.2 ASCII) through sm_mesh_read: every
 * input is prefixed with "$MeshFormat\n", so the fuzzer spends its time in
 * the .msh reader (the seeds are .msh files without that first line).
 * Same contract as the Medit target (fuzz_check_mesh). */
#include <stdint.h>

#include "fuzz_input.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    return fuzz_file_target("$MeshFormat\n", data, size, fuzz_check_mesh);
}
