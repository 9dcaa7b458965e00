/* The wire vocabulary: the names the daemon, the worker and the client
 * must spell the same way, one table each.
 *
 *   - the parts of a job submission (multipart part names, job.json keys);
 *   - the result set: every file a run writes (job/sm_job_results.h), grouped by
 *     what GET /v1/jobs/{id}/results/{what}?format=F serves, with the
 *     format names, media types and file names;
 *   - the Idempotency-Key length limit;
 *   - the ways a batch's template is chosen (`batch --template-from`,
 *     a batch request's template_from; job/sm_job_template_from.h).
 *
 * The OpenAPI document (proto/openapi.yaml) describes the same names; a
 * change here is a change of the contract. */
#ifndef SM_PROTO_VOCAB_H
#define SM_PROTO_VOCAB_H

#include <stddef.h>

/* ---- job inputs: multipart parts and job.json members ---- */
typedef enum sm_part {
    SM_PART_TEMPLATE = 0,
    SM_PART_TARGET_MESH = 1,
    SM_PART_TARGET_SOL = 2,
    SM_PART_TARGET_SURFACE = 3,
    SM_PART_TEMPLATE_LANDMARKS = 4,
    SM_PART_TARGET_LANDMARKS = 5,
    SM_PART_TARGET_IMAGE = 6,
    SM_PART_TEMPLATE_SURFACE = 7,
    SM_PART_TEMPLATE_IMAGE = 8,
    SM_PART_PARAMS = 9,
    SM_PART_NAME = 10,
    SM_NPARTS = 11
} sm_part;
/* The file parts are the members before SM_PART_PARAMS (loops over the
 * files stop there: params and name stay last).  name is optional: the
 * job's label for people (lists, status, watch), no input of the run.
 * template and params are always required; the target is either
 * target_mesh + target_sol (a sampled
 * distance) or target_surface with an optional target_mesh
 * (sm_job_inputs.h); target_surface excludes target_sol.  The landmark
 * CSV files (template_landmarks, target_landmarks: the alignment's start,
 * sm_job_align.h) come both or not at all, and only with params align
 * other than none.  target_image (a label map: NIfTI, NRRD or MetaImage
 * in one file, sm_job_image.h) is a target of its own, with an optional
 * target_mesh like target_surface; it excludes target_sol and
 * target_surface.  template_surface (a closed surface meshed into the
 * template by nglib, sm_job_template.h; params template_size) and
 * template_image (a label map as target_image, its label params
 * template_label, meshed likewise) stand in for template: one of the
 * three. */
#define SM_PART_NAME_TARGET_SURFACE "target_surface"
#define SM_PART_NAME_TARGET_IMAGE "target_image"
/* The template made from a closed surface or a label map
 * (sm_job_template.h), in place of a volume mesh. */
#define SM_PART_NAME_TEMPLATE_SURFACE "template_surface"
#define SM_PART_NAME_TEMPLATE_IMAGE "template_image"
/* Largest landmark part (bytes): a landmark file is a few rows; the
 * daemon refuses a larger one (422) while it arrives. */
#define SM_LANDMARKS_MAX_BYTES (1 << 20)
/* "template", "target_mesh", "target_sol", "target_surface",
 * "template_landmarks", "target_landmarks", "target_image",
 * "template_surface", "template_image", "params", "name", indexed by
 * sm_part. */
extern const char *const sm_part_names[SM_NPARTS];
/* sm_part_names[part], NULL outside. */
const char *sm_part_name(sm_part part);

/* A job's name (part "name", `submit --name`): 1 to SM_JOB_NAME_MAX bytes
 * of UTF-8 without control characters, so that it shows as it is in a
 * terminal, a log line and a web page.  0 when s (n bytes) is one, else
 * -1 and why (e.g. "longer than 200 bytes"). */
#define SM_JOB_NAME_MAX 200
int sm_job_name_check(const char *s, size_t n, char *why, size_t cap);

/* ---- the result set ---- */
/* What /results/{what} serves: one resource, several formats. */
typedef enum sm_result_kind {
    SM_RESULT_MESH = 0,         /* the deformed mesh */
    SM_RESULT_DISPLACEMENT = 1, /* cumulative displacement per vertex */
    SM_RESULT_HISTORY = 2,      /* one row per iteration */
    SM_NRESULT_KINDS = 3
} sm_result_kind;

typedef struct sm_result_format {
    sm_result_kind kind;
    const char *name;   /* ?format= value ("mesh", "vtu", "csv", ...) */
    const char *media;  /* Content-Type */
    const char *file;   /* file name in a result folder */
} sm_result_format;

/* Every result file but the summary, by kind, the default format of each
 * kind first.  SM_RESULT_FORMATS_N entries. */
extern const sm_result_format sm_result_formats[];
#define SM_RESULT_FORMATS_N 8
/* The path segment of a kind: "mesh", "displacement", "history". */
const char *sm_result_kind_name(sm_result_kind kind);
/* The format `name` of kind, or NULL. */
const sm_result_format *sm_result_format_find(sm_result_kind kind, const char *name);
/* The formats of kind: *n entries from the returned one (NULL for a bad
 * kind). */
const sm_result_format *sm_result_formats_of(sm_result_kind kind, size_t *n);

/* The summary document (job/sm_job_results.h) and its media type. */
#define SM_RESULT_SUMMARY_FILE "summary.json"
/* A template meshed from template_surface or template_image
 * (sm_job_template.h), written beside the results so that the run can be
 * repeated with --template (the template of the run, before any
 * alignment). */
#define SM_RESULT_TEMPLATE_FILE "template.mesh"
#define SM_RESULT_SUMMARY_MEDIA "application/json"
/* Snapshots (params.save_every K): iter-NNNNN.mesh after iterations K,
 * 2K, ... (the daemon keeps them in results/snapshots/, `shapematch run`
 * in its output folder). */
#define SM_SNAPSHOTS_DIR "snapshots"
#define SM_SNAPSHOT_FORMAT "iter-%05d.mesh"
/* Beside each, the same shape for ParaView (iter-NNNNN.vtu: zlib-compressed,
 * with the displacement from the template), and a collection of them all
 * to scrub through the deformation (snapshots.pvd, rewritten with each). */
#define SM_SNAPSHOT_VTU_FORMAT "iter-%05d.vtu"
#define SM_SNAPSHOT_PVD "snapshots.pvd"
#define SM_SNAPSHOT_MEDIA "application/x-medit-mesh"

/* ---- a choice of result files (`shapematch run --format`) ---- */
/* Bit i is the file of sm_result_formats[i]; history.csv and summary.json
 * are always written (sm_result_outputs_fix adds history.csv).  With
 * SM_RESULT_OUT_GZ the chosen mesh and displacement files are written
 * gzip-compressed as FILE.gz (the same bytes once decompressed).  The
 * daemon's worker writes everything: SM_RESULT_OUT_ALL. */
#define SM_RESULT_OUT_FORMAT(i) (1u << (i))
#define SM_RESULT_OUT_ALL ((1u << SM_RESULT_FORMATS_N) - 1u)
#define SM_RESULT_OUT_GZ (1u << SM_RESULT_FORMATS_N)
/* "vtu-ascii": result.vtu in ASCII rather than zlib-compressed binary.
 * gz does not apply to result.vtu, which is compressed inside (ParaView
 * does not open a .vtu.gz); vtu-ascii with gz is refused. */
#define SM_RESULT_OUT_VTU_ASCII (1u << (SM_RESULT_FORMATS_N + 1))
#define SM_RESULT_OUT_NAMES "mesh, meshb, vtu, vtu-ascii, binary, sol, solb, gz"
unsigned sm_result_outputs_fix(unsigned outputs);
/* 1 when the file of sm_result_formats[i] is written as FILE.gz under
 * outputs (gz chosen, and neither history nor .vtu). */
int sm_result_output_gz(size_t i, unsigned outputs);
/* "mesh,vtu,sol,gz" -> *outputs: the mesh and displacement format names
 * of sm_result_formats plus gz.  0, or -1 with a message in msg (an
 * unknown name, or gz alone). */
int sm_result_outputs_parse(const char *text, unsigned *outputs, char *msg, size_t cap);

/* ---- requests ---- */
/* Longest Idempotency-Key (visible ASCII characters, at least 1). */
#define SM_IDEMPOTENCY_KEY_MAX 255

/* ---- a batch's template: given, or from the population ---- */
typedef enum sm_template_from {
    SM_TEMPLATE_FROM_FILE = 0,
    SM_TEMPLATE_FROM_MEDOID = 1,
    SM_TEMPLATE_FROM_MEAN = 2
} sm_template_from;
#define SM_TEMPLATE_ROUNDS_MAX 20 /* rounds of a mean, at most */

/* "file", "medoid", "mean"; parse: 0, or -1 for another word. */
const char *sm_template_from_name(sm_template_from f);
int sm_template_from_parse(const char *name, sm_template_from *out);

#endif
