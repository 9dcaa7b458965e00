/* Job parameters on the wire: JSON <-> sm_params (shapematch/sm_params.h).
 *
 * The JSON shape is described by proto/params.schema.json.  Only "clamp" is
 * required; every other field has the default of sm_params_default():
 *
 *   {"clamp": {"kind": "ball", "center": [0.5, 0.5], "radius": 0.04}}
 *   {"clamp": {"kind": "elements", "refs": [3]}, "free_boundary": [7]}
 *   {"clamp": {"kind": "vertices", "refs": [1, 2]}, "young": 2.0}
 *   {"clamp": {"kind": "elements", "refs": ["core"]}, "free_boundary": ["cut", 7]}
 *   {"clamp": {"kind": "none", "alpha": 0.01}, "max_iter": 100}
 *
 * Top-level fields: the rows of the parameter table (sm_params_table,
 * shapematch/sm_params.h: clamp, free_boundary, young, ..., solver; alpha
 * is a member of the clamp) and the generated background's
 * background_size and background_padding (sm_background_params_table
 * below: not the descent's, so outside sm_params); their names, types
 * and bounds are the tables'.  Decoding is strict: unknown fields, wrong types,
 * out-of-range values and duplicate keys are errors, and the message
 * starts with the JSON path of the offending field, e.g.
 *   "params.clamp.radius: must be > 0 (got -1)".
 *
 * Link with libsmproto.a and -ljansson. */
#ifndef SM_PROTO_PARAMS_H
#define SM_PROTO_PARAMS_H

#include <stddef.h>

#include <jansson.h>

#include "shapematch/sm_error.h"
#include "shapematch/sm_mesh.h"
#include "shapematch/sm_params.h"

/* Largest params document accepted (bytes).  A complete params with two
 * full reference lists is well under 2 KiB. */
#define SM_PARAMS_JSON_MAX_BYTES (64 * 1024)

/* How a generated background is made (params "background_size" and
 * "background_padding"; `--background-size`, `--background-padding` of
 * the CLI).  They mean something only for a target_surface without
 * target_mesh (sm_job_files_check_background, sm_job_inputs.h, refuses
 * them otherwise).  Kept outside sm_params: the descent never sees them,
 * the job's inputs do.  0 means "not given": the defaults of
 * sm_job_inputs.h (size from the meshes' mean edge lengths, padding
 * SM_BACKGROUND_PADDING_DEFAULT). */
typedef struct sm_background_params {
    double size;    /* near-surface cell side, a length in the meshes' unit: > 0 */
    double padding; /* margin around template and surface, a fraction of their
                     * box's diagonal: > 0 and <= SM_BACKGROUND_PADDING_MAX */
    double template_size; /* a meshed template's element size (template_surface,
                           * template_image: sm_job_template.h), a length: > 0 */
    int template_label;   /* template_image's label (an integer row, as the
                           * core's label): >= 0, 0 every nonzero voxel */
} sm_background_params;

/* The padding when none is given (the schema's default). */
#define SM_BACKGROUND_PADDING_DEFAULT 0.1
/* A padding beyond 100 diagonals only makes coarse cells nobody samples
 * (and past ~1e300 an infinite box). */
#define SM_BACKGROUND_PADDING_MAX 100.0

/* The rows of the background members (background_size,
 * background_padding, template_size: SM_PARAM_REAL; template_label:
 * SM_PARAM_INT, an int member), of the same kind as sm_params_table's and after
 * them in a params document; offsets are into sm_background_params.
 * Their default: 0 in the struct means "not given"; def is what that
 * means (a row's def_text when it depends on the meshes). */
const sm_param_info *sm_background_params_table(size_t *count);

/* Decodes a params document (text need not be NUL-terminated; len bytes
 * are read).  dim is the mesh dimension (2 or 3) when known; with dim = 0
 * ("not known yet") clamp.center may have 2 or 3 entries (missing ones are
 * 0) and sm_params_validate is not called: call sm_params_from_json again
 * with the template's dimension once the mesh is parsed (the daemon does
 * this before accepting a job).  With dim 2 or 3 the result has also
 * passed sm_params_validate(out, dim).
 *
 * On error: returns SM_ERR_FORMAT (not JSON, duplicate key, too large) or
 * SM_ERR_INVALID (well-formed JSON with a bad field), err->msg names the
 * field path ("params.max_iter: must be an integer >= 1 (got 0)") or the
 * position of a syntax error, and *out is left filled with defaults. */
sm_status sm_params_from_json(const char *text, size_t len, int dim,
                              sm_params *out, sm_error *err);

/* Same, from an already parsed JSON value (e.g. a member of a larger
 * document).  root must be an object.  path is the prefix used in
 * messages ("params" when NULL). */
sm_status sm_params_from_jansson(const json_t *root, int dim,
                                 const char *path, sm_params *out,
                                 sm_error *err);

/* The same with the background members: *bg gets them (0 when absent).
 * The functions above are these with bg NULL: the members are decoded
 * and checked all the same (every decoder accepts the same documents),
 * then dropped.  On error *bg is zeroed. */
sm_status sm_job_params_from_json(const char *text, size_t len, int dim, sm_params *out,
                                  sm_background_params *bg, sm_error *err);
sm_status sm_job_params_from_jansson(const json_t *root, int dim, const char *path,
                                     sm_params *out, sm_background_params *bg,
                                     sm_error *err);

/* Longest physical name a reference list may give (bytes). */
#define SM_PARAMS_NAME_MAX 255

/* Physical names.  A reference list (clamp.refs, free_boundary) may give
 * Gmsh physical names ("core") among its integers.  The decoders accept
 * them with dim 0 only (the syntax check before the template is read;
 * they stand as 0 there) and refuse them with dim 2 or 3: they must
 * first be turned into their tags against the template's $PhysicalNames
 * (sm_mesh.names), by sm_params_resolve_names or, in one call,
 * sm_job_params_from_json_for. */

/* Replaces, in the params object root, every name in clamp.refs (kind
 * elements: the names of groups of the template's dimension; vertices:
 * of any dimension) and free_boundary (groups of facets, dimension - 1)
 * by its tag in m.  A name m does not have is SM_ERR_INVALID, the
 * message naming the item ("params.clamp.refs[0]: the template has no
 * physical group named \"cor\" of elements (its names of elements:
 * \"core\" (1), ...)").  Anything else is left to the decoder.  path
 * as in sm_params_from_jansson. */
sm_status sm_params_resolve_names(json_t *root, const sm_mesh *m, const char *path,
                                  sm_error *err);

/* sm_job_params_from_json for the template m: its names resolved, then
 * decoded and validated for m's dimension. */
sm_status sm_job_params_from_json_for(const char *text, size_t len, const sm_mesh *m,
                                      sm_params *out, sm_background_params *bg, sm_error *err);
/* The same on a parsed params object (root is left as it is: the names
 * are resolved in a copy). */
sm_status sm_job_params_from_jansson_for(const json_t *root, const sm_mesh *m, sm_params *out,
                                         sm_background_params *bg, sm_error *err);

/* Encodes every field (defaults included), compact, one line, keys in a
 * stable order; fields that do not apply to the clamp kind are left out
 * (center/radius only for ball, refs only for elements/vertices, alpha
 * only for none).  dim (2 or 3) is the number of center entries written;
 * dim = 0 writes 2 entries when clamp_center[2] == 0 and 3 otherwise.
 * Returns a malloc'd NUL-terminated string (caller frees with free()), or
 * NULL when p holds something JSON cannot carry (NaN/Inf, a bad clamp or
 * solver kind, a ref count outside 0..SM_MAX_REFS) or memory runs out.
 * sm_params_from_json(sm_params_to_json(p, dim), dim) gives back p
 * exactly (doubles are printed with 17 significant digits). */
char *sm_params_to_json(const sm_params *p, int dim);

/* Same as a new jansson object (caller owns the reference), or NULL. */
json_t *sm_params_to_jansson(const sm_params *p, int dim);

/* The same plus the background members that are given (> 0): absent
 * ones are left out, like the clamp members that do not apply, so that
 * a job without them reads back without them.  bg NULL: none.  NULL
 * also for a member that is NaN, infinite or negative. */
json_t *sm_job_params_to_jansson(const sm_params *p, const sm_background_params *bg, int dim);
char *sm_job_params_to_json(const sm_params *p, const sm_background_params *bg, int dim);

#endif
