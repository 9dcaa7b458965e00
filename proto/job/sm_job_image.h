/* A label-map image as a job's target (sm_image.h): the one way
 * `shapematch run --target-image`, the daemon's target_image part and
 * `shapematch sdf --image` turn a segmentation into a signed distance, so
 * that `sdf --image` then `run` on its files and `run --target-image`
 * give the same field.
 *
 *   1. read the image (within limits), map it into the template's frame
 *      (params image_space: LPS as read, RAS flipped);
 *   2. select the voxels (params label, 0: every nonzero voxel; level for
 *      a float image without a label) and summarise them (voxel count,
 *      26-connected components, world box, border contact); an empty
 *      selection is refused;
 *   3. sm_image_target_new: the smoothed level-set surface, the signed
 *      distance at the crop's voxel centres (exact next to the surface,
 *      through the nearest such voxel's surface point beyond), the exact
 *      distance near the surface at any point;
 *   4. a background graded toward that surface over the box of the
 *      surface (and of the template, when one is given) padded by
 *      `padding` of its diagonal, near-surface cells of the voxel size
 *      but no finer than a uniform grid of 250k vertices over the box;
 *      the distance at its vertices. */
#ifndef SM_JOB_IMAGE_H
#define SM_JOB_IMAGE_H

#include <stdint.h>

#include "shapematch/sm_error.h"
#include "shapematch/sm_image.h"
#include "shapematch/sm_io.h"
#include "shapematch/sm_mesh.h"
#include "shapematch/sm_params.h"
#include "shapematch/sm_surface.h"

/* What the image and its selection hold: summary.json's target_image. */
typedef struct sm_job_image_info {
    char format[16];         /* "NIfTI-1", ... */
    int64_t dims[3];
    sm_voxel_type type;
    double spacing[3];       /* lengths of the voxel axes */
    sm_image_select sel;
    sm_image_space space;
    sm_label_stats stats;    /* in the template's frame */
    int32_t surface_triangles;
    int64_t exact_vertices;  /* background vertices computed exactly */
    double seconds;          /* reading, selection, surface and grid */
} sm_job_image_info;

/* The selection params give: label (0: none), level. */
sm_image_select sm_job_image_select(const sm_params *p);

/* Steps 1-3 on path.  smooth: the mask's Gaussian in voxels (1 in jobs);
 * padding: the background's margin (fraction of the diagonal; < 0: 0.1)
 * the crop must cover.  limits may be NULL.  An empty selection is SM_ERR_INVALID
 * "label-empty: ...".  Messages name the file as the readers do. */
sm_status sm_job_image_target(const char *path, sm_image_limits *limits, const sm_image_select *sel,
                              sm_image_space space, double smooth, double padding,
                              sm_image_target **out, sm_job_image_info *info, sm_error *err);

/* The accurate signed distance on the image's own grid, for `sdf
 * --image -o dist.nii.gz`: steps 1-3 with the crop covering the whole
 * image, whose grid (sm_image_target_grid) is then the image's: exact at
 * the voxels next to the surface, elsewhere the distance to the nearest
 * of their surface points (never below the exact distance; within the
 * band also the triangles around that point).  *out is a float32 image with the file's
 * geometry (LPS, whatever space is: the values are lengths, the frame
 * only places the label), for sm_image_write; free with sm_image_free. */
sm_status sm_job_image_grid_distance(const char *path, sm_image_limits *limits,
                                     const sm_image_select *sel, sm_image_space space,
                                     double smooth, sm_image **out, sm_job_image_info *info,
                                     sm_error *err);

/* For a 2D template: steps 1-2 on a 2D image (NIfTI dim[0] 2, NRRD
 * dimension 2, MetaImage NDims 2, or one slice), then the selection's
 * boundary as a closed curve (sm_image_contour_2d, smooth in voxels),
 * which the job takes as a 2D target surface (its exact distance, on
 * target_mesh or a generated background: sm_job_inputs.h).  A 3D image
 * is SM_ERR_INVALID naming its size; info->surface_triangles counts the
 * curve's segments. */
sm_status sm_job_image_contour(const char *path, sm_image_limits *limits,
                               const sm_image_select *sel, sm_image_space space, double smooth,
                               sm_surface **out, sm_job_image_info *info, sm_error *err);
/* Step 4: the background (size > 0: its near-surface cells, else the
 * default; padding >= 0, else 0.1) around the label's surface and, when
 * template is not NULL, the template's box; *size_used the size. */
sm_status sm_job_image_background(const sm_image_target *t, const sm_job_image_info *info,
                                  const sm_mesh *template_mesh, double size, double padding,
                                  sm_mesh **bg, double *size_used, sm_error *err);

/* The distance (negative inside) at bg's vertices into *dist
 * (sm_sol_alloc'd); info->exact_vertices counts the exact ones. */
sm_status sm_job_image_distance(const sm_image_target *t, const sm_mesh *bg, sm_sol **dist,
                                sm_job_image_info *info, sm_error *err);

#endif
