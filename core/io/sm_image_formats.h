/* The image readers behind sm_image_read (internal, not part of the
 * public API), rows of the format table in sm_io.c (the dispatch by
 * content); sm_image_build.c holds what the three formats share — the checked allocation, the voxel bytes read raw
 * or inflated (zlib or gzip stream inside the file), byte swapping, the
 * detached data file, the geometry check; sm_io_nifti.c, sm_io_nrrd.c
 * and sm_io_mha.c parse their headers.  NRRD and MetaImage share the
 * text-header line reader (sm_image_text.c). */
#ifndef SM_IMAGE_FORMATS_H
#define SM_IMAGE_FORMATS_H

#include "io/sm_reader.h"
#include "shapematch/sm_image.h"

/* What a header says about the voxel data that follows it. */
typedef struct sm_image_data {
    int compressed; /* 1: a zlib or gzip stream (auto-detected) */
    int swap;       /* stored in the other byte order */
    int64_t skip;   /* bytes before the data; -1: the data ends the file
                       (raw only) */
} sm_image_data;

/* The reader's input: memory inputs may not name a detached file. */
typedef struct sm_image_src {
    const char *path;
    int in_memory;
    sm_image_limits *limits;
} sm_image_src;

/* A new image with dims and type checked (positive, each at most
 * SM_IMAGE_MAX_DIM, product and bytes without overflow and within the
 * limits); its voxels are NULL until sm__image_read_voxels allocates them.
 * where: the header place to name in errors ("byte 40", "line 3"). */
sm_status sm__image_new(const sm_image_src *src, const char *where, const int64_t dims[3],
                        sm_voxel_type type, sm_image **out, sm_error *err);

/* Allocates and fills im->voxels from r at its position as d says, the
 * allocation only once r is known to be able to hold them (raw: its bytes
 * left; compressed: SM_DEFLATE_MAX_RATIO times them); errors name the
 * byte where the data ran short or went bad. */
sm_status sm__image_read_voxels(sm_reader *r, const sm_image_src *src, const sm_image_data *d,
                                sm_image *im, sm_error *err);

/* Opens the data file name given by the header at src->path (relative,
 * no "..", in the header's folder through no symbolic link, a regular
 * file: no FIFO, device or folder); refused for memory inputs and when
 * the limits say no_detached.  where: the header line, for messages. */
sm_status sm__image_open_detached(const sm_image_src *src, const char *where, const char *name,
                                  sm_reader *r, char **data_path, sm_error *err);

/* The voxels from the data file name that the header at src->path gives
 * on its line `line` (sm__image_open_detached's rules), read as d says;
 * a data file the reader inflates itself (.gz) is not inflated twice. */
sm_status sm__image_read_detached(const sm_image_src *src, long line, const char *name,
                                  sm_image_data d, sm_image *im, sm_error *err);

/* The voxel-to-world map finite and non-singular. */
sm_status sm__image_check_geometry(const sm_image_src *src, const sm_image *im, sm_error *err);

int sm__nifti_detect(sm_reader *r);
sm_status sm__nifti_read(sm_reader *r, const sm_image_src *src, sm_image **out, sm_error *err);
int sm__nrrd_detect(sm_reader *r);
sm_status sm__nrrd_read(sm_reader *r, const sm_image_src *src, sm_image **out, sm_error *err);
int sm__mha_detect(sm_reader *r);
sm_status sm__mha_read(sm_reader *r, const sm_image_src *src, sm_image **out, sm_error *err);

/* ---- text headers (NRRD, MetaImage) ---- */

#define SM_IMAGE_LINE_LEN 4096
/* The next header line into buf (without its "\n" or "\r\n"): *found 0
 * at the end of the file; a line longer than SM_IMAGE_LINE_LEN - 1 or
 * holding a NUL byte is an error naming it.  r->token_line is its number. */
sm_status sm__image_line(sm_reader *r, const char *path, char *buf, int *found, sm_error *err);
/* Parses up to max reals (finite) separated by spaces, commas or the
 * brackets of NRRD vectors "(a,b,c)"; *n how many. */
int sm__image_reals(const char *s, double *v, int max, int *n);
/* Parses up to max integers in [lo, hi]; 0 on a malformed one. */
int sm__image_ints(const char *s, int64_t lo, int64_t hi, int64_t *v, int max, int *n);

#endif
