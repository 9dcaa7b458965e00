/* A job's template made from what users have (sm_template_mesh.h): a
 * closed surface (template_surface: every format sm_surface_read reads,
 * repaired as a target surface is: sm_surface_repair orients it) or a
 * label map's boundary (template_image with its label: the label's
 * level-set surface as for an image target, sm_job_image.h; a 2D image
 * gives a closed curve), meshed by nglib at template_size.  The one
 * function `shapematch run`, the worker and the binding call through
 * sm_job_inputs_read_template, and that `batch --template-from` may call
 * for a population's mean. */
#ifndef SM_JOB_TEMPLATE_H
#define SM_JOB_TEMPLATE_H

#include <stdint.h>

#include <jansson.h>

#include "shapematch/sm_error.h"
#include "shapematch/sm_io.h"
#include "shapematch/sm_image.h"
#include "shapematch/sm_mesh.h"
#include "shapematch/sm_surface.h"
#include "shapematch/sm_template_mesh.h"

/* Where the template came from (summary.json's template_meshed). */
typedef enum sm_job_template_source {
    SM_TEMPLATE_GIVEN = 0,   /* a volume mesh (template) */
    SM_TEMPLATE_SURFACE = 1, /* template_surface, meshed */
    SM_TEMPLATE_IMAGE = 2    /* template_image's label, meshed */
} sm_job_template_source;

typedef struct sm_job_template_made {
    sm_job_template_source source;
    sm_template_mesh_info mesh;   /* what nglib made */
    sm_surface_health health;     /* the surface's, after repair */
    int64_t label;                /* template_image's label (0: every
                                   * nonzero voxel) */
    int32_t surface_facets;
} sm_job_template_made;

/* Reads path (an image when is_image, with label; given: a surface in
 * memory instead of the file, path naming it) within limits (may be
 * NULL: the mesher's own bounds; else max_vertices bounds the elements,
 * 6 tetrahedra or 2 triangles a vertex), repairs, checks and meshes it at
 * size (0: the surface's mean edge; for an image, its largest voxel
 * spacing, since a label's surface is finer than its voxels), every
 * element at least min_quality (0: the descent's default floor).  An
 * image is read within image_limits (the target image's bounds: voxels,
 * inflated bytes, a detached data file refused for an upload; its hit
 * set on a refusal; NULL: the readers' own).  Messages are the core's
 * ("open: 12 edges ...", "nglib: ..."), unprefixed: the caller names the
 * part.  *out is the caller's (sm_mesh_free). */
sm_status sm_job_template_mesh(const char *path, const sm_surface *given, int is_image,
                               int64_t label, double size, double min_quality,
                               sm_read_limits *limits, sm_image_limits *image_limits,
                               sm_mesh **out, sm_job_template_made *made, sm_error *err);

/* The figures as a JSON object, every member (reals exact through
 * sm_json_dumps), and back: the daemon's upload check meshes the template
 * and keeps the mesh with these figures for the worker, which reads them
 * instead of meshing again (server/worker/smd_job_file.h).  to_json:
 * NULL out of memory.  from_json: SM_ERR_FORMAT naming the first member
 * missing or of the wrong type (a source other than surface or image
 * too), *m untouched then. */
json_t *sm_job_template_made_to_json(const sm_job_template_made *m);
sm_status sm_job_template_made_from_json(const json_t *o, sm_job_template_made *m, sm_error *err);

#endif
