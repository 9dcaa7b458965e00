/* Label-map images through sm_image_read: MHA (the prefix steers
 * the detection to it).  Contract: fuzz_check_image. */
#include <stdint.h>

#include "fuzz_image.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    return fuzz_file_target("ObjectType = Image\n", data, size, fuzz_check_image);
}
