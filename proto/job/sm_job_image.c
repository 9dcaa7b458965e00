/* A label-map image as a job's target (see sm_job_image.h). */
#include "job/sm_job_image.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "shapematch/sm_clock.h"
#include "shapematch/sm_io.h"
#include "shapematch/sm_sdf.h"
#include "sm_proto_params.h"

sm_image_select sm_job_image_select(const sm_params *p)
{
    sm_image_select s = {.has_label = p->label != 0, .label = p->label, .level = p->level};
    return s;
}

static double axis_length(const double *m, int col)
{
    return sqrt(m[col] * m[col] + m[4 + col] * m[4 + col] + m[8 + col] * m[8 + col]);
}

/* The voxels selected (mask: dims product bytes), summarised; an empty
 * selection refused naming what was looked for. */
static sm_status select_voxels(const sm_image *im, const char *path, const sm_image_select *sel,
                               uint8_t *mask, sm_job_image_info *info, sm_error *err)
{
    sm_status st = sm_image_mask(im, sel, mask, &info->stats, err);
    if (st == SM_OK && info->stats.voxels == 0) {
        char what[64];
        if (sel->has_label)
            snprintf(what, sizeof what, "label %lld", (long long)sel->label);
        else if (im->type == SM_VOXEL_F32 || im->type == SM_VOXEL_F64)
            snprintf(what, sizeof what, "values >= %g", sel->level);
        else
            snprintf(what, sizeof what, "nonzero values");
        st = sm_error_set(err, SM_ERR_INVALID,
                          "%s: label-empty: no voxel of the image has %s (a %s image of %lld x "
                          "%lld x %lld %s voxels): give the label's value",
                          path, what, im->format, (long long)im->dims[0], (long long)im->dims[1],
                          (long long)im->dims[2], sm_voxel_type_name(im->type));
    }
    return st;
}

static uint8_t *mask_new(const sm_image *im, sm_error *err)
{
    size_t total = (size_t)(im->dims[0] * im->dims[1] * im->dims[2]);
    uint8_t *mask = malloc(total ? total : 1);
    if (!mask)
        sm_error_set(err, SM_ERR_NOMEM, "out of memory for the label's mask (%zu voxels)", total);
    return mask;
}

/* The voxels selected, summarised; the target built on them. */
static sm_status build(const sm_image *im, const char *path, const sm_image_select *sel,
                       double smooth, double padding, int whole_image, sm_image_target **out,
                       sm_job_image_info *info, sm_error *err)
{
    uint8_t *mask = mask_new(im, err);
    if (!mask)
        return SM_ERR_NOMEM;
    sm_status st = select_voxels(im, path, sel, mask, info, err);
    if (st == SM_OK) {
        double hmin = fmin(info->spacing[0], fmin(info->spacing[1], info->spacing[2]));
        /* the diagonal of the world box of the index box's corners: the
         * background's world-aligned box around the label, rotated into
         * an oblique grid's index space, reaches that far */
        const int64_t *ilo = info->stats.index_lo, *ihi = info->stats.index_hi;
        const double *m = im->ijk_to_lps;
        double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (int corner = 0; corner < 8; corner++)
            for (int row = 0; row < 3; row++) {
                double w = m[4 * row + 3];
                for (int c = 0; c < 3; c++)
                    w += m[4 * row + c] * (double)((corner >> c) & 1 ? ihi[c] : ilo[c]);
                lo[row] = fmin(lo[row], w);
                hi[row] = fmax(hi[row], w);
            }
        double diag = hypot(hypot(hi[0] - lo[0], hi[1] - lo[1]), hi[2] - lo[2]);
        /* the crop covers the background's margin, so that the grid (not
         * the positive extension) gives the far field there */
        sm_image_target_opts to = {smooth, 3.0, fmin(64, padding * diag / hmin + 1), 0,
                                   whole_image};
        st = sm_image_target_new(im, mask, sel, &to, out, err);
        if (st != SM_OK && st != SM_ERR_NOMEM)
            sm_error_prefix(err, "%s", path);
    }
    free(mask);
    return st;
}

/* Step 1: the image read, in the template's frame, summarised. */
static sm_status read_image(const char *path, sm_image_limits *limits, const sm_image_select *sel,
                            sm_image_space space, sm_image **im, sm_job_image_info *info,
                            sm_error *err)
{
    memset(info, 0, sizeof *info);
    sm_status st = sm_image_read(path, limits, im, err);
    if (st != SM_OK)
        return st;
    if (space == SM_IMAGE_SPACE_RAS)
        sm_image_flip_ras(*im);
    snprintf(info->format, sizeof info->format, "%s", (*im)->format);
    memcpy(info->dims, (*im)->dims, sizeof info->dims);
    info->type = (*im)->type;
    for (int c = 0; c < 3; c++)
        info->spacing[c] = axis_length((*im)->ijk_to_lps, c);
    info->sel = *sel;
    info->space = space;
    return SM_OK;
}

sm_status sm_job_image_target(const char *path, sm_image_limits *limits, const sm_image_select *sel,
                              sm_image_space space, double smooth, double padding,
                              sm_image_target **out, sm_job_image_info *info, sm_error *err)
{
    *out = NULL;
    double t0 = sm_clock_seconds();
    if (padding < 0)
        padding = SM_BACKGROUND_PADDING_DEFAULT;
    sm_image *im = NULL;
    sm_status st = read_image(path, limits, sel, space, &im, info, err);
    if (st != SM_OK)
        return st;
    if (im->dims[2] == 1)
        st = sm_error_set(err, SM_ERR_INVALID, "%s: a 2D %s image (%lld x %lld voxels): it is "
                          "the target of a 2D template (`run --target-image`); a 3D template "
                          "and `sdf --image` need a 3D image", path, im->format,
                          (long long)im->dims[0], (long long)im->dims[1]);
    else
        st = build(im, path, sel, smooth, padding, 0, out, info, err);
    sm_image_free(im);
    if (st == SM_OK)
        info->surface_triangles = sm_image_target_surface(*out)->nfacets;
    info->seconds = sm_clock_seconds() - t0;
    return st;
}

sm_status sm_job_image_contour(const char *path, sm_image_limits *limits,
                               const sm_image_select *sel, sm_image_space space, double smooth,
                               sm_surface **out, sm_job_image_info *info, sm_error *err)
{
    *out = NULL;
    double t0 = sm_clock_seconds();
    sm_image *im = NULL;
    sm_status st = read_image(path, limits, sel, space, &im, info, err);
    if (st != SM_OK)
        return st;
    uint8_t *mask = NULL;
    if (im->dims[2] != 1) {
        st = sm_error_set(err, SM_ERR_INVALID, "%s: a 3D %s image (%lld x %lld x %lld voxels): "
                          "a 2D template needs a 2D image (NIfTI dim[0] = 2, NRRD dimension 2, "
                          "MetaImage NDims 2, or one slice)", path, im->format,
                          (long long)im->dims[0], (long long)im->dims[1], (long long)im->dims[2]);
    } else if (!(mask = mask_new(im, err))) {
        st = SM_ERR_NOMEM;
    } else if ((st = select_voxels(im, path, sel, mask, info, err)) == SM_OK &&
               (st = sm_image_contour_2d(im, mask, smooth, out, err)) != SM_OK &&
               st != SM_ERR_NOMEM) {
        sm_error_prefix(err, "%s", path);
    }
    free(mask);
    sm_image_free(im);
    if (st == SM_OK)
        info->surface_triangles = (*out)->nfacets;
    info->seconds = sm_clock_seconds() - t0;
    return st;
}

static double det3(const double *u, const double *v, const double *w)
{
    return u[0] * (v[1] * w[2] - v[2] * w[1]) - v[0] * (u[1] * w[2] - u[2] * w[1]) +
           w[0] * (u[1] * v[2] - u[2] * v[1]);
}

/* x solving the 3x3 part of the 3x4 map m: m x = r (Cramer's rule). */
static void solve3(const double *m, const double *r, double *x)
{
    double c0[3] = {m[0], m[4], m[8]}, c1[3] = {m[1], m[5], m[9]}, c2[3] = {m[2], m[6], m[10]};
    double det = det3(c0, c1, c2);
    x[0] = det3(r, c1, c2) / det;
    x[1] = det3(c0, r, c2) / det;
    x[2] = det3(c0, c1, r) / det;
}

sm_status sm_job_image_grid_distance(const char *path, sm_image_limits *limits,
                                     const sm_image_select *sel, sm_image_space space,
                                     double smooth, sm_image **out, sm_job_image_info *info,
                                     sm_error *err)
{
    *out = NULL;
    sm_image_target *t = NULL;
    sm_image *im = NULL;
    double t0 = sm_clock_seconds();
    sm_status st = read_image(path, limits, sel, space, &im, info, err);
    if (st != SM_OK)
        return st;
    if (im->dims[2] == 1)
        st = sm_error_set(err, SM_ERR_INVALID, "%s: a 2D %s image: `sdf --image -o` an image "
                          "needs a 3D one", path, im->format);
    else
        st = build(im, path, sel, smooth, 0, 1, &t, info, err);
    if (st == SM_OK)
        info->surface_triangles = sm_image_target_surface(t)->nfacets;
    info->seconds = sm_clock_seconds() - t0;
    if (st != SM_OK) {
        sm_image_free(im);
        return st;
    }
    /* the crop covers the image: its distance read at the image's voxels
     * (the crop's index of image voxel 0 from the two maps' origins) */
    const int64_t *n = im->dims;
    int64_t total = n[0] * n[1] * n[2], cn[3], off[3];
    double cm[12];
    const float *cd;
    sm_image_target_grid(t, cn, cm, &cd);
    const double *m = im->ijk_to_lps;
    double r[3] = {m[3] - cm[3], m[7] - cm[7], m[11] - cm[11]}, x[3];
    solve3(cm, r, x);
    for (int c = 0; c < 3; c++)
        off[c] = (int64_t)llround(x[c]);
    if (off[0] < 0 || off[1] < 0 || off[2] < 0 || off[0] + n[0] > cn[0] || off[1] + n[1] > cn[1] ||
        off[2] + n[2] > cn[2])
        st = sm_error_set(err, SM_ERR_INVALID, "the distance's grid does not cover the image");
    int same = st == SM_OK && cn[0] == n[0] && cn[1] == n[1] && cn[2] == n[2];
    float *d = same ? sm_image_target_take_grid(t) /* the crop is the image */
               : st == SM_OK ? malloc((size_t)total * sizeof *d) : NULL;
    if (st == SM_OK && !d)
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory for the distance on %lld voxels",
                          (long long)total);
#pragma omp parallel for schedule(static) if (st == SM_OK && !same)
    for (int64_t line = 0; line < (st == SM_OK && !same ? n[1] * n[2] : 0); line++) {
        int64_t j = line % n[1], k = line / n[1];
        memcpy(d + line * n[0], cd + off[0] + cn[0] * (off[1] + j + cn[1] * (off[2] + k)),
               (size_t)n[0] * sizeof *d);
    }
    sm_image_target_free(t);
    if (st != SM_OK) {
        free(d);
        sm_image_free(im);
        return st;
    }
    if (space == SM_IMAGE_SPACE_RAS)
        sm_image_flip_ras(im); /* back to the file's own frame */
    free(im->voxels);
    im->voxels = d;
    im->type = SM_VOXEL_F32;
    im->slope = 1;
    im->inter = 0;
    *out = im;
    return SM_OK;
}

sm_status sm_job_image_background(const sm_image_target *t, const sm_job_image_info *info,
                                  const sm_mesh *template_mesh, double size, double padding,
                                  sm_mesh **bg, double *size_used, sm_error *err)
{
    const sm_surface *s = sm_image_target_surface(t);
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int32_t v = 0; v < s->nverts; v++)
        for (int k = 0; k < 3; k++) {
            lo[k] = fmin(lo[k], s->coords[3 * v + k]);
            hi[k] = fmax(hi[k], s->coords[3 * v + k]);
        }
    if (template_mesh) {
        double tlo[3], thi[3];
        sm_mesh_bbox(template_mesh, template_mesh->coords, tlo, thi);
        for (int k = 0; k < 3; k++) {
            lo[k] = fmin(lo[k], tlo[k]);
            hi[k] = fmax(hi[k], thi[k]);
        }
    }
    double diag = hypot(hypot(hi[0] - lo[0], hi[1] - lo[1]), hi[2] - lo[2]);
    double pad = (padding >= 0 ? padding : SM_BACKGROUND_PADDING_DEFAULT) * diag, vol = 1;
    for (int k = 0; k < 3; k++) {
        lo[k] -= pad;
        hi[k] += pad;
        vol *= hi[k] - lo[k];
    }
    double hmin = fmin(info->spacing[0], fmin(info->spacing[1], info->spacing[2]));
    /* the voxel size, but no finer than a uniform grid of 250k vertices
     * over the box: a 256^3 map's 1.4M-voxel ellipsoid at 1 mm gave 1.65M
     * vertices (8.9 s of the command's 19.5 s), at 2.9 mm 0.2M */
    *size_used = size > 0 ? size : fmax(hmin, cbrt(vol / 250000.0));
    return sm_image_target_background(t, lo, hi, *size_used, bg, err);
}

sm_status sm_job_image_distance(const sm_image_target *t, const sm_mesh *bg, sm_sol **dist,
                                sm_job_image_info *info, sm_error *err)
{
    sm_status st = sm_sol_alloc(dist, 3, bg->nverts, 1, err);
    if (st == SM_OK)
        st = sm_image_target_signed(t, bg->nverts, bg->coords, (*dist)->values,
                                    &info->exact_vertices, err);
    if (st != SM_OK) {
        sm_sol_free(*dist);
        *dist = NULL;
    }
    return st;
}
