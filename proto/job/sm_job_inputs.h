/* A job's inputs, read and checked together: the template mesh, the
 * target (background) mesh, the target's signed distance and the
 * parameters.  One set of rules for every way a job is run: the daemon
 * applies them to an upload before accepting it (a job known to be bad is
 * never queued), and the job runner (sm_job_runner.h) applies them again
 * in `shapematch-worker` and in `shapematch run`:
 *
 *   - each file parses (core readers, hostile-input safe);
 *   - template and target have the same dimension;
 *   - the distance is a scalar field with one finite value per target
 *     vertex;
 *   - the template has a valid topology (sm_mesh_build_boundary on a
 *     copy, kept as `prepared` for the run) and the target mesh supports
 *     point location (sm_field_new: the field is built here, once, and
 *     the run and the outputs use it);
 *   - the parameters are in range for that dimension, and the clamp set
 *     is not empty (ball, element or vertex references that match
 *     nothing), does not hold every vertex, and pins rigid rotations.
 *
 * Messages start with the part they are about ("template: ...",
 * "target_sol: ...", "params.clamp.radius: ...").  With SM_JOB_NAME_PARTS
 * (the daemon: its paths are its own business) every path in a message
 * is replaced by the part name; with SM_JOB_NAME_PATHS (a local run) the
 * files are named as the user gave them. */
#ifndef SM_JOB_INPUTS_H
#define SM_JOB_INPUTS_H

#include <stddef.h>
#include <stdint.h>

#include <jansson.h>

#include "shapematch/sm_coverage.h"
#include "shapematch/sm_error.h"
#include "shapematch/sm_field.h"
#include "shapematch/sm_io.h"
#include "shapematch/sm_match.h"
#include "shapematch/sm_mesh.h"
#include "shapematch/sm_params.h"
#include "shapematch/sm_sdf.h"
#include "shapematch/sm_surface.h"
#include "job/sm_job_image.h"
#include "job/sm_job_template.h"
#include "sm_proto_params.h"
#include "sm_proto_vocab.h"

/* The target is either target_mesh + target_sol (a sampled distance), or
 * target_surface (STL, OBJ, Medit or Gmsh surface; sm_surface.h) with an
 * optional target_mesh: the distance to the surface is then computed
 * exactly at the vertices of target_mesh, or of a background generated
 * around the template and the surface when target_mesh is NULL
 * (sm_background_graded_new: the box of both padded by 10% of its
 * diagonal, graded toward the surface, near-surface cells of the smaller
 * of the template's and the surface's mean edge lengths; background_size
 * and background_padding change both, and only make sense then:
 * sm_job_files_check_background).  target_surface excludes target_sol. */
/* Voxels a target image may declare per vertex a mesh may (the daemon's
 * --max-vertices, 1M for a 4 GiB --memory-limit: 256M voxels, 512 x 512 x
 * 1024; a check of one costs about 2 bytes and 30 ns per voxel). */
#define SM_JOB_VOXELS_PER_VERTEX 256

typedef struct sm_job_files {
    const char *template_mesh;
    /* or the template made from a closed surface or a label map's label
     * (sm_job_template.h: meshed by nglib at template_size, 0: the
     * surface's mean edge); one of template_mesh, template_surface and
     * template_image.  Their messages start "template_surface" or
     * "template_image" (with the path for a local run). */
    const char *template_surface;
    const char *template_image;
    int64_t template_label;
    double template_size;
    /* the quality floor the meshed template must meet: the job's
     * min_quality (0: the default's) */
    double template_min_quality;
    const char *target_mesh;
    const char *target_sol;
    const char *target_surface;
    /* a label-map image (sm_job_image.h): the target is the boundary of
     * the params' label, its distance on target_mesh or on a background
     * generated around it and the template; excludes target_sol and
     * target_surface.  It is read after the parameters are known:
     * sm_job_inputs_read_target takes label, level and image_space from
     * out->params (sm_job_inputs_load sets them from the params text
     * first) */
    const char *target_image;
    /* generated background: near-surface size (0: the default) and
     * padding as a fraction of the box's diagonal (0: 0.1); > 0 only
     * with target_surface and no target_mesh.  sm_job_inputs_load takes
     * them from the params when they are 0 here */
    double background_size, background_padding;
    /* bounds of the readers (sm_io.h) for untrusted files, NULL: none;
     * an image's voxels count against SM_JOB_VOXELS_PER_VERTEX times
     * max_vertices (as SM_LIMIT_VERTICES).  After a refusal limits->hit
     * names the bound and `failed` the part (the daemon answers 413
     * naming its flag). */
    sm_read_limits *limits;
    /* sm_job_inputs_load: set up the run's template side while the
     * target is read (sm_job_inputs_read_target's prepare); for a caller
     * that runs the job next (the worker), not for the upload's check */
    int prepare_run;
    /* landmark CSV files (sm_job_align.h), both or none: the alignment's
     * start; NULL: none */
    const char *landmarks_template, *landmarks_target;
    /* inputs already in memory (the binding API's arrays,
     * shapematch_job.h): each, when set, is copied instead of reading
     * the file of its part, whose path member then only names it in
     * messages (it must be set too) */
    const sm_mesh *template_given, *target_mesh_given;
    const sm_sol *target_sol_given;
    const sm_surface *target_surface_given;
    /* a generated background and the target's distance at its vertices
     * (files, read with limits) that an earlier read of the same inputs
     * built: the daemon's upload check keeps them in the job's folder
     * (server/worker/smd_job_file.h) and the worker names them here when
     * they are the job's.  With target_surface, no target_mesh and no
     * alignment they are read instead of being built again (the surface
     * is still read and repaired: its health, the run's exact
     * distances), the rest as with a generated background (its size and
     * padding, the units refusal); otherwise, or NULL, ignored */
    const char *checked_background, *checked_distance;
    /* the template an earlier read of the same inputs meshed from
     * template_surface or template_image (a mesh file, read without
     * copying anything of the meshing) and that meshing's figures: the
     * upload check's, kept the same way.  Read instead of meshing again
     * when both are set and the job has a template to mesh (the figures'
     * source must be its kind, their vertices the file's); otherwise
     * ignored */
    const char *checked_template;
    const sm_job_template_made *checked_template_made;
    const sm_surface *template_surface_given;
} sm_job_files;

typedef enum sm_job_naming {
    SM_JOB_NAME_PARTS = 0,
    SM_JOB_NAME_PATHS = 1
} sm_job_naming;

/* What building a generated background later needs (the files' values,
 * copied: the files need not outlive the read). */
typedef struct sm_job_background_plan {
    sm_job_naming naming;
    double size, padding;      /* as given (0: the default) */
    sm_read_limits *limits;    /* the files' bounds (NULL: none) */
    const char *target_path;   /* the target file, for messages */
} sm_job_background_plan;

typedef struct sm_job_inputs {
    sm_mesh *template_mesh;   /* as read (outputs keep its connectivity) */
    sm_job_template_made template_made; /* a meshed template's figures
                               * (source SM_TEMPLATE_GIVEN: as read) */
    sm_mesh *prepared;        /* copy with its boundary built (the run's) */
    sm_mesh *background;
    sm_sol *distance;
    sm_field *field;          /* d on the background (borrows both) */
    sm_params params;         /* defaults until parameters are set */
    int dim;
    int32_t nclamped;         /* template vertices in the clamp set */
    int clamp_default;        /* 1: no clamp was given, params.clamp is the
                               * default ball (sm_clamp_resolve) */
    double clamp_inradius;    /* then: the depth of its centre */
    int field_builds;         /* sm_field_new calls for this job (1) */
    double read_seconds;      /* reading and checking the files, the
                               * field included (wall; with prepare also
                               * the run's measure set-up, and the
                               * elastic set-up beside, which is often
                               * the longer) */
    double field_build_seconds;
    int has_surface;          /* the target came from target_surface: */
    sm_surface *surface;      /* that surface (repaired), for the run's
                               * exact two-sided distances; NULL otherwise */
    sm_surface_health health; /* its health report (after repair) */
    int background_generated; /* no target_mesh: generated background */
    double background_size;   /* the generated background's near-surface
                               * size and padding (fraction of the box's
                               * diagonal) used, defaults included */
    double background_padding;
    sm_background_params background_asked; /* what the job asked for (0:
                               * not given): what job.json keeps */
    double sdf_seconds;       /* distance computation (surface and image
                               * targets) */
    int checked_reused;       /* the background and distance were read
                               * from files->checked_* (nothing built) */
    int template_reused;      /* the template was read from
                               * files->checked_template (not meshed) */
    int has_image;            /* the target came from target_image: */
    sm_job_image_info image;  /* what the image and its label hold */
    sm_part failed;           /* after a failure: the part the message is
                               * about; SM_NPARTS when none (dimension
                               * mismatch, out of memory) */
    double read_started;      /* sm_clock_seconds() when reading began */
    /* The run's template side (sm_match_new with params), when it was
     * set up while the target was read: sm_job_run_exec continues from
     * it (and frees it), or reports its failure as the run's.  NULL and
     * SM_OK otherwise; sm_job_inputs_set_params drops it (stale). */
    sm_match *match;
    sm_status match_status;
    sm_error match_error;
    double match_seconds;
    /* The run's two-sided measure (sm_coverage_new on the field), built
     * beside that set-up after the field when there is no alignment (it
     * would be longer than the set-up's thread otherwise: 3D example
     * 0.17 s): sm_job_run_exec takes it.  NULL when not built, or when
     * its build failed (the run builds it again and reports that). */
    sm_coverage *coverage;
    /* landmark pairs (template's, target's: nlandmarks*dim each), read
     * with the template (sm_job_read_landmarks); NULL and 0 when none */
    double *landmarks[2];
    int32_t nlandmarks;
    /* the frame each set is in, when its file stated one (Slicer's
     * markups; sm_points_frame: 0 unstated, 1 LPS, 2 RAS): set_params
     * puts them in params image_space's */
    int landmarks_frame[2];
    /* With an alignment (params align set before the target is read):
     * the target's exact surface and distance kept for it (a surface
     * target's; for an image, target_sdf over image_target's level-set
     * surface),
     * so that it aligns onto the exact surface; and when the background
     * is to be generated, it is not built yet (target_deferred): the
     * alignment runs without one, then sm_job_inputs_finish_target
     * builds it around the moved template and the target, where the
     * match happens.  NULL and 0 otherwise. */
    sm_surface *target_surface;
    sm_sdf *target_sdf;
    sm_image_target *image_target;
    int target_deferred;
    sm_job_background_plan plan;
    sm_read_limits plan_limits; /* the plan's copies */
    char *plan_path;
    /* an image target: the template as given against the label's
     * surface, RMS distance of its boundary vertices in the image space
     * read ([0]) and in the other ([1]): the image-frame warning's
     * figures (0: not measured) */
    double frame_rms[2];
} sm_job_inputs;

/* background_size and background_padding (> 0: given) are for a
 * generated background: target_surface without target_mesh.  Otherwise
 * SM_ERR_INVALID, the message naming them as naming says: the params
 * ("params.background_size: background_size and background_padding are
 * for a generated background (target_surface without target_mesh) ...")
 * or the CLI's flags ("--background-size and --background-padding are
 * ..."); the one check of `run`, `submit` and the daemon. */
sm_status sm_job_files_check_background(const sm_job_files *files, sm_job_naming naming,
                                        sm_error *err);

/* Reads and checks the input files and builds the field; parameters are
 * left at their defaults.  sm_job_files_check_background comes first
 * (failed: SM_PART_PARAMS), then the template (its file, then its
 * topology), then the target.  On failure every member is freed and
 * NULL.  It is sm_job_inputs_read_template then
 * sm_job_inputs_read_target without prepare. */
sm_status sm_job_inputs_read(const sm_job_files *files, sm_job_naming naming,
                             sm_job_inputs *out, sm_error *err);

/* The same in two steps, for a caller that runs the job next: between
 * them it sets the parameters (sm_job_inputs_set_params), and with
 * prepare the run's template side (sm_match_new: the elastic operator
 * and its first factorization or AMG hierarchy, a few tenths of a second
 * at 30k tetrahedra) is set up while the target is read and its field
 * built, on a second thread when the OpenMP limit allows two: in->match
 * and in->match_status (a failure there is not the inputs': the run
 * reports it).  read_template fills *out from scratch; both free every
 * member on failure. */
sm_status sm_job_inputs_read_template(const sm_job_files *files, sm_job_naming naming,
                                      sm_job_inputs *out, sm_error *err);
sm_status sm_job_inputs_read_target(const sm_job_files *files, sm_job_naming naming, int prepare,
                                    sm_job_inputs *out, sm_error *err);

/* Sets the parameters after checking them against the inputs
 * (sm_params_validate for the dimension, then the clamp set).  Messages
 * are the core's, unprefixed: callers name the option or field.  On
 * failure in->params is unchanged. */
sm_status sm_job_inputs_set_params(sm_job_inputs *in, const sm_params *params,
                                   sm_error *err);

/* The daemon's and the worker's way: params as JSON (params_text need not
 * be NUL-terminated; its syntax is checked before any mesh is parsed, its
 * values after the files), messages with part names.  With
 * files->prepare_run, the values are checked against the template before
 * the target is read, and the run's template side is set up meanwhile
 * (sm_job_inputs_read_target's prepare).  The params' background_size
 * and background_padding size a generated background (files' own, when
 * > 0, win), so the upload's check and the worker's run build the same
 * one.  On failure every member is freed and NULL. */
sm_status sm_job_inputs_load(const sm_job_files *files, const char *params_text,
                             size_t params_len, sm_job_inputs *out,
                             sm_error *err);

/* The same on params already parsed (the worker: job.json's params
 * object), decoded from the object itself: no text in between. */
sm_status sm_job_inputs_load_json(const sm_job_files *files, const json_t *params,
                                  sm_job_inputs *out, sm_error *err);
/* A deferred target (in->target_deferred) finished: its background
 * generated around template_mesh (the moved template; the box of both,
 * sized as for any generated background, the units refusal included),
 * the distance at its vertices, the field; the image target and the
 * plan are released, the surface and its distance kept.  SM_OK doing
 * nothing when nothing is deferred.  Messages as the read's. */
sm_status sm_job_inputs_finish_target(sm_job_inputs *in, const sm_mesh *template_mesh,
                                      sm_error *err);

void sm_job_inputs_free(sm_job_inputs *in);

#endif
