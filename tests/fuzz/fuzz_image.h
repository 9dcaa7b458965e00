/* The contract the image fuzz targets check (fuzz_nifti, fuzz_nrrd,
 * fuzz_mha): sm_image_read of the input (in memory, or the memfd of a
 * gzip input) fails cleanly — NULL and a message naming the input — or
 * gives an image whose dims are in range and whose voxels can all be
 * read; the selection and its summary then run over it.  A voxel limit
 * keeps lying headers from asking for gigabytes (refused before
 * allocation, as the daemon's limits are). */
#ifndef FUZZ_IMAGE_H
#define FUZZ_IMAGE_H

#include <stdlib.h>
#include <string.h>

#include "fuzz_input.h"
#include "shapematch/sm_image.h"

static inline void fuzz_check_image(const sm_reader_input *in)
{
    sm_image_limits lim = {.max_voxels = 1 << 20, .max_inflated = 64 << 20};
    sm_image *im = (sm_image *)(uintptr_t)1;
    sm_error err;
    sm_error_clear(&err);
    sm_status st = in->data ? sm_image_read_memory(in->path, in->data, in->size, &lim, &im, &err)
                            : sm_image_read(in->path, &lim, &im, &err);
    if (st != SM_OK) {
        if (im != NULL || err.msg[0] == '\0' || !strstr(err.msg, in->path))
            abort();
        return;
    }
    int64_t total = 1;
    for (int k = 0; k < 3; k++) {
        if (im->dims[k] < 1 || im->dims[k] > SM_IMAGE_MAX_DIM)
            abort();
        total *= im->dims[k];
    }
    if (total > lim.max_voxels || sm_voxel_size(im->type) == 0)
        abort();
    uint8_t *mask = malloc((size_t)total);
    if (mask) {
        sm_image_select sel = {0, 0, 0.5};
        sm_label_stats stats;
        if (sm_image_mask(im, &sel, mask, &stats, &err) == SM_OK && stats.voxels > total)
            abort();
        free(mask);
    }
    sm_image_free(im);
}

#endif
