/* A template meshed from a surface or a label map (sm_job_template.h). */
#include "job/sm_job_template.h"

#include <math.h>
#include <string.h>

#include "job/sm_job_image.h"
#include "shapematch/sm_image.h"

/* The label's boundary: a closed outward triangle surface of a 3D image,
 * a closed curve of a 2D one (one slice). */
static sm_status image_surface(const char *path, int64_t label, sm_image_limits *limits,
                               sm_surface **out, double *voxel, sm_error *err)
{
    sm_image_limits none = {0};
    sm_image_limits *lim = limits ? limits : &none;
    sm_image_select sel = {.has_label = label != 0, .label = label, .level = 0.5};
    sm_job_image_info info;
    sm_image_target *t = NULL;
    /* the jobs' smoothing (params smooth's default: 1 voxel) */
    sm_status st = sm_job_image_target(path, lim, &sel, SM_IMAGE_SPACE_LPS, 1.0, 0.0, &t, &info, err);
    if (st == SM_OK)
        *voxel = fmax(info.spacing[0], fmax(info.spacing[1], info.dims[2] == 1 ? 0 : info.spacing[2]));
    if (st == SM_OK && info.dims[2] == 1) {
        sm_image_target_free(t);
        return sm_job_image_contour(path, lim, &sel, SM_IMAGE_SPACE_LPS, 1.0, out, &info, err);
    }
    if (st != SM_OK)
        return st;
    const sm_surface *s = sm_image_target_surface(t);
    st = sm_surface_alloc(out, s->dim, s->nverts, s->nfacets, err);
    if (st == SM_OK) {
        memcpy((*out)->coords, s->coords, sizeof(double) * (size_t)s->dim * (size_t)s->nverts);
        memcpy((*out)->facets, s->facets, sizeof(int32_t) * (size_t)s->dim * (size_t)s->nfacets);
    }
    sm_image_target_free(t);
    return st;
}

sm_status sm_job_template_mesh(const char *path, const sm_surface *given, int is_image,
                               int64_t label, double size, double min_quality,
                               sm_read_limits *limits, sm_image_limits *image_limits,
                               sm_mesh **out, sm_job_template_made *made, sm_error *err)
{
    *out = NULL;
    memset(made, 0, sizeof *made);
    made->source = is_image ? SM_TEMPLATE_IMAGE : SM_TEMPLATE_SURFACE;
    made->label = label;
    sm_surface *s = NULL;
    double voxel = 0;
    sm_status st = is_image ? image_surface(path, label, image_limits, &s, &voxel, err)
                   : given  ? sm_surface_alloc(&s, given->dim, given->nverts, given->nfacets, err)
                            : sm_surface_read_limited(path, limits, &s, err);
    if (st == SM_OK && given && !is_image) {
        memcpy(s->coords, given->coords, sizeof(double) * (size_t)given->dim * (size_t)given->nverts);
        memcpy(s->facets, given->facets, sizeof(int32_t) * (size_t)given->dim * (size_t)given->nfacets);
    }
    if (st != SM_OK)
        return st;
    made->surface_facets = s->nfacets;
    if ((st = sm_surface_repair(s, &made->health, err)) != SM_OK) {
        sm_surface_free(s);
        return st;
    }
    /* a label's surface has triangles finer than its voxels (marching
     * tetrahedra): its resolution is the voxel's, the default size */
    sm_template_mesh_opts o = {.size = size > 0 ? size : voxel, .min_quality = min_quality};
    if (limits && limits->max_vertices > 0)
        o.max_elements = limits->max_vertices * (s->dim == 3 ? 6 : 2);
    st = sm_template_mesh_surface(s, &o, out, &made->mesh, err);
    sm_surface_free(s);
    return st;
}
