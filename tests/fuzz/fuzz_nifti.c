/* Label-map images through sm_image_read: NIFTI (no prefix: the header
 * size 348 or 540 and the magic say NIfTI; gzip inputs go through a file).  Contract: fuzz_check_image. */
#include <stdint.h>

#include "fuzz_image.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    return fuzz_file_target(NULL, data, size, fuzz_check_image);
}
