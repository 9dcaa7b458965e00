/* Label-map images — the target users have when they have a segmentation
 * rather than a surface: NIfTI-1/-2 (.nii, .nii.gz), NRRD (.nrrd, .nhdr +
 * data file) and MetaImage (.mha, .mhd + data file), 3D or 2D (dims[2]
 * 1: NIfTI dim[0] 2, NRRD dimension 2, MetaImage NDims 2), one channel,
 * unsigned/signed 8/16/32-bit integers or float32/float64 voxels.
 *
 * Every image is mapped into one frame, LPS (left-posterior-superior: ITK,
 * Slicer, DICOM): NIfTI's RAS world (sform when sform_code > 0, else
 * qform when qform_code > 0, else the pixdim scaling alone, as the NIfTI-1
 * standard orders them) is flipped in x and y; NRRD's `space` names its
 * frame (RAS, LAS and LPS and their long names; without `space` the
 * `space directions`/`spacings` are taken as LPS); MetaImage's world is
 * ITK's, LPS.  sm_image_flip_ras turns the result into RAS.
 *
 * Readers treat their input as hostile like the mesh readers (sm_io.h):
 * dimensions, voxel counts and byte sizes are checked for overflow and
 * against the file and the limits before anything is allocated; reals
 * (spacing, directions, origin) must be finite, spacings nonzero, the
 * direction matrix non-singular; errors are SM_ERR_FORMAT naming the
 * file and the byte offset (NIfTI) or header line (NRRD, MetaImage), e.g.
 *   "x.nii: byte 42: dim[1] = -3 is not a positive size"
 *   "x.nrrd:4: unknown or unsupported type (...), found 'complex'"
 * A detached data file (NRRD `data file`, MetaImage `ElementDataFile`)
 * must be a relative name without "..", resolved beside the header, and
 * is refused when limits->no_detached is set (a daemon's uploads are one
 * file).  On error *out is NULL and nothing leaks. */
#ifndef SM_IMAGE_H
#define SM_IMAGE_H

#include <stdint.h>

#include "sm_error.h"
#include "sm_mesh.h"
#include "sm_surface.h"

typedef enum sm_voxel_type {
    SM_VOXEL_U8 = 1,
    SM_VOXEL_S8,
    SM_VOXEL_U16,
    SM_VOXEL_S16,
    SM_VOXEL_U32,
    SM_VOXEL_S32,
    SM_VOXEL_F32,
    SM_VOXEL_F64
} sm_voxel_type;

/* Bytes of one voxel of type t (0 for an unknown type). */
int sm_voxel_size(sm_voxel_type t);
/* "uint8", ..., "float64". */
const char *sm_voxel_type_name(sm_voxel_type t);

typedef struct sm_image {
    int64_t dims[3];       /* voxels along i, j, k (i fastest in memory) */
    double ijk_to_lps[12]; /* rows x, y, z of the 3x4 affine map from the
                              voxel index (i, j, k, 1) to LPS millimetres;
                              voxel centres are at integer indices */
    sm_voxel_type type;
    double slope, inter;   /* value = slope * stored + inter (NIfTI's
                              scl_slope/scl_inter; 1 and 0 otherwise) */
    void *voxels;          /* dims[0]*dims[1]*dims[2] values, host order */
    const char *format;    /* "NIfTI-1", "NIfTI-2", "NRRD", "MetaImage" */
} sm_image;

/* Bounds for untrusted files (0: no bound beyond the readers' own). */
typedef struct sm_image_limits {
    int64_t max_voxels;    /* dims product */
    uint64_t max_inflated; /* voxel bytes, and decompressed bytes */
    int no_detached;       /* refuse a detached data file */
    int hit;               /* out: 1 voxels, 2 inflated bytes, 3 detached */
} sm_image_limits;
enum { SM_IMAGE_LIMIT_VOXELS = 1, SM_IMAGE_LIMIT_INFLATED, SM_IMAGE_LIMIT_DETACHED };

#define SM_IMAGE_FORMATS "NIfTI-1/-2 (.nii, .nii.gz), NRRD (.nrrd, .nhdr), MetaImage (.mha, .mhd)"
/* The readers' own bound on one axis and on the voxel count. */
#define SM_IMAGE_MAX_DIM ((int64_t)1 << 20)
#define SM_IMAGE_MAX_VOXELS ((int64_t)1 << 32)

/* Reads path, the format decided by the content (NIfTI by its header
 * size 348/540 and magic, NRRD by "NRRD000", MetaImage by its keys);
 * gzip files (.nii.gz) are inflated.  limits may be NULL. */
sm_status sm_image_read(const char *path, sm_image_limits *limits, sm_image **out, sm_error *err);
/* The same over size bytes in memory named name in messages (detached
 * data files refused): for the fuzz targets. */
sm_status sm_image_read_memory(const char *name, const void *data, size_t size,
                               sm_image_limits *limits, sm_image **out, sm_error *err);
void sm_image_free(sm_image *im);

/* Writes a float32 image (an sm_image of type SM_VOXEL_F32 whose map is
 * LPS) on its own grid with its geometry, the format by path's name:
 * NIfTI-1 (.nii, .nii.gz: the map as sform, and as qform too when the
 * axes are orthogonal; RAS as the format defines it), NRRD (.nrrd,
 * attached raw, space left-posterior-superior) or MetaImage (.mha,
 * ElementDataFile LOCAL).  Written to a temporary name and renamed.
 * SM_ERR_INVALID for another name or type, SM_ERR_IO when writing fails.
 * sm_image_write_format: 1, 2, 3 for those names, 0 for any other. */
sm_status sm_image_write(const char *path, const sm_image *im, sm_error *err);
int sm_image_write_format(const char *path);

/* Turns the voxel-to-world map from LPS into RAS (x and y negated). */
void sm_image_flip_ras(sm_image *im);

/* Voxel n (linear index) as a real, after slope and intercept. */
double sm_image_value(const sm_image *im, int64_t n);

/* Which voxels are the target: with has_label, those whose value equals
 * label; otherwise every nonzero voxel of an integer image, and those of
 * value >= level of a float image (a probability map or a soft mask). */
typedef struct sm_image_select {
    int has_label;
    int64_t label;
    double level;
} sm_image_select;

/* What the selection holds: voxel count, 26-connected components, the
 * world box (of the selected voxel centres, in the image's frame) and
 * whether a selected voxel lies on the image's border. */
typedef struct sm_label_stats {
    int64_t voxels;
    int64_t components;
    int touches_border;
    double lo[3], hi[3];
    int64_t index_lo[3], index_hi[3]; /* the selected voxels' index box */
} sm_label_stats;

/* mask (dims product bytes): 1 where selected, 0 elsewhere; stats may be
 * NULL.  SM_ERR_NOMEM when the component labelling cannot allocate. */
sm_status sm_image_mask(const sm_image *im, const sm_image_select *sel, uint8_t *mask,
                        sm_label_stats *stats, sm_error *err);

/* Exact Euclidean distance transform (Felzenszwalb & Huttenlocher 2012,
 * separable, linear time, lines in parallel) on an n[0] x n[1] x n[2]
 * grid of spacings h[3]: d[v] = distance from voxel centre v to the
 * nearest voxel centre where feature is nonzero (INFINITY when there is
 * none).  d has n[0]*n[1]*n[2] floats. */
sm_status sm_edt(const int64_t n[3], const double h[3], const uint8_t *feature, float *d,
                 sm_error *err);

/* The signed transform of a mask: -(distance to the nearest outside
 * voxel centre) inside, +(distance to the nearest inside one) outside
 * (the voxel-centre EDT: |d| >= the smallest spacing everywhere). */
sm_status sm_edt_signed(const int64_t n[3], const double h[3], const uint8_t *mask, float *d,
                        sm_error *err);

/* The signed distance to a label's boundary (sm_image_sdf.c): the image
 * cropped to the selection's index box padded by 3 smooth + 2 +
 * pad_voxels voxels; the mask smoothed by a Gaussian of smooth voxels
 * (integer images or a --label; a float image without one keeps its
 * values and the selection's level); its level set (0.5, or the level) as
 * a closed, outward triangle surface (marching tetrahedra, 6 Kuhn
 * tetrahedra per cell of voxel centres); the signed distance at every
 * crop voxel centre: exact at the corners of the cells the surface
 * passes through (the sites), elsewhere the distance to the nearest
 * surface point of the nearest site (a separable nearest-site transform)
 * or of a face neighbour's, whichever is nearer: never below the exact
 * distance, near it (the grid, sm_image_target_grid);
 * sm_image_target_signed gives the exact signed distance to the surface
 * within band_voxels (times the largest spacing) of it, the grid's
 * trilinear interpolation elsewhere in the crop, and beyond the crop (a
 * background larger than the crop) the distance to the crop plus the
 * grid's at its nearest point (an upper bound, positive; exact when that
 * bound is within twice the band).  The exact distance needs no
 * hierarchy: the surface's triangles are indexed by the crop cell that
 * made them, and a point's nearest one is found in rings of cells around
 * it (the nearest triangle of a point within the band lies a few cells
 * away); its sign is the side of the marching's piecewise-linear field
 * (the Kuhn tetrahedron holding the point), the surface's own inside.
 * The nearest site is chosen with the voxel axes' lengths, right for
 * orthogonal axes (any rotation, any spacing); on sheared axes it is a
 * worse choice, the distance still an upper bound. */
typedef struct sm_image_target_opts {
    double smooth;      /* Gaussian sigma in voxels, 0: none (default 1) */
    double band_voxels; /* exact within (default 3) */
    double pad_voxels;  /* extra crop margin */
    int hierarchy;      /* 1: also build the surface's sm_sdf (winding
                         * numbers; sm_image_target_sdf), else NULL */
    int whole_image;    /* 1: the crop also covers the whole image, so
                         * that every voxel centre has the grid's value
                         * (not the bound beyond the crop), and the grid
                         * within the band also tries the triangles of
                         * its site's point's cell (the grid is then the
                         * output) */
} sm_image_target_opts;
typedef struct sm_image_target sm_image_target;

/* mask: sm_image_mask's of sel (not empty).  The world is the image's
 * frame (ijk_to_lps, after sm_image_flip_ras when that was called). */
sm_status sm_image_target_new(const sm_image *im, const uint8_t *mask, const sm_image_select *sel,
                              const sm_image_target_opts *o, sm_image_target **out, sm_error *err);
void sm_image_target_free(sm_image_target *t);
/* The graded background (sm_background_graded_fn_new) over lo..hi with
 * near-surface cells of h, graded by |sm_image_target_signed|. */
sm_status sm_image_target_background(const sm_image_target *t, const double lo[3],
                                     const double hi[3], double h, sm_mesh **out,
                                     sm_error *err);
/* The level-set surface and, with opts hierarchy, its distance
 * hierarchy (NULL without; both owned by t). */
const sm_surface *sm_image_target_surface(const sm_image_target *t);
const struct sm_sdf *sm_image_target_sdf(const sm_image_target *t);
/* The crop's size, its index-to-world map and the signed distance at
 * its voxel centres (the grid above: exact at the corners of the cells
 * the surface passes through, an upper bound near the exact elsewhere). */
void sm_image_target_grid(const sm_image_target *t, int64_t n[3], double map[12],
                          const float **dist);
/* The distance array of sm_image_target_grid handed to the caller (who
 * frees it with free()); t is then only to be freed. */
float *sm_image_target_take_grid(sm_image_target *t);
/* The voxel-centre signed EDT (sm_edt_signed) of the thresholded field
 * on the same crop, into a new array (*edt, free with free()). */
sm_status sm_image_target_voxel_edt(const sm_image_target *t, float **edt, sm_error *err);
/* Signed distance (negative inside) at n world points; *exact (may be
 * NULL) receives how many were computed exactly. */
sm_status sm_image_target_signed(const sm_image_target *t, int64_t n, const double *pts,
                                 double *out, int64_t *exact, sm_error *err);

/* The boundary of a 2D image's selection (dims[2] == 1: NIfTI dim[0] 2,
 * NRRD dimension 2, MetaImage NDims 2, or one slice) as a closed curve
 * for a 2D template: the mask (sm_image_mask's, not empty) smoothed by a
 * Gaussian of smooth voxels (0: none), its level set 0.5 traced by
 * marching triangles (each cell of four voxel centres cut along its
 * diagonal, the smoothed mask linear on each triangle), the crop of the
 * selection padded by 2 + 3 smooth voxels of background so that a label
 * touching the image's border still closes; segments with the inside on
 * their left, in the world x and y of ijk_to_lps.  SM_ERR_INVALID for an
 * image of several slices, an image whose plane is not z = constant (its
 * axes with z components), or a selection thinner than the smoothing;
 * SM_ERR_NOMEM. */
sm_status sm_image_contour_2d(const sm_image *im, const uint8_t *mask, double smooth,
                              sm_surface **out, sm_error *err);

#endif
