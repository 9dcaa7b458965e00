/* JOB_DIR/job.json, the job description the upload's check writes and
 * the worker reads (the format: smd_worker.h).  One owner for both
 * sides, so the writer and the reader cannot drift:
 *   {"template": "inputs/template.mesh", "target_mesh": ..., "target_sol"
 *    | "target_surface": ..., "template_landmarks", "target_landmarks": ...
 *    (optional), "params": {<sm_job_params_to_jansson>},
 *    "checked": {"key": HEX, "background": ..., "distance": ...,
 *                "template": ..., "template_meshed": {...}} (optional)}
 * Paths are relative to JOB_DIR and stay inside it.
 *
 * "checked" (issue 35 item 5): what the upload's check built, kept in the
 * job's inputs/ (binary Medit .meshb/.solb: every double as computed) so
 * that the worker reads it instead of building it again: the generated
 * background and the target's distance on it (a surface target without
 * target_mesh and without alignment), and the template meshed from
 * template_surface or template_image with its figures
 * (sm_job_template_made_to_json: the summary's template.meshed), each
 * pair present or absent together.  key fingerprints what they were
 * built from (smd_job_file_inputs_key): the worker uses them only when
 * its own key of the job is the same.
 *
 * A batch's model job (server/api/smd_batches.h) has no file part; its
 * description is {"params": {}, "batch": {"align": "none|rigid|similarity",
 * "members": [{"job": ID, "name": NAME}, ...]}}: the target jobs whose
 * results the worker puts into the shape model (sm_job_model_build). */
#ifndef SMD_JOB_FILE_H
#define SMD_JOB_FILE_H

#include <limits.h>
#include <stddef.h>

#include <jansson.h>

#include "shapematch/sm_error.h"
#include "sm_proto_vocab.h"

/* A key of smd_job_file_inputs_key: hexadecimal digits. */
#define SMD_JOB_KEY_LEN 16

typedef struct smd_job_file {
    /* each file part's path relative to the job folder, "" when absent */
    char part[SM_PART_PARAMS][PATH_MAX];
    json_t *params; /* the canonical params object (owned) */
    json_t *batch;  /* a model job's batch object (owned), NULL for a match */
    /* what the check built (paths as the parts'), and their key; ""
     * when none: the background and distance (both or neither), the
     * meshed template and its figures (both or neither; the figures
     * owned, sm_job_template_made_to_json's object) */
    char checked_background[PATH_MAX], checked_distance[PATH_MAX];
    char checked_template[PATH_MAX];
    json_t *checked_template_made;
    char checked_key[SMD_JOB_KEY_LEN + 1];
} smd_job_file;

/* Bounds of a batch description (also the daemon's hard ceiling on
 * --max-batch-targets): member names are printable ASCII without '/'. */
#define SMD_BATCH_MEMBERS_MAX 1000
#define SMD_BATCH_NAME_MAX 64

/* A member's name: 1..SMD_BATCH_NAME_MAX printable ASCII characters
 * without '/', '\\', ',' or '"', not "." or ".." (it names a row of the
 * model's scores.csv).  1 when valid. */
int smd_batch_name_valid(const char *s);

/* The description as text (members in part order, then params), with
 * proto's sm_json_dumps: indent 0 compact (the database's copy), 2 the
 * file's layout.  NULL out of memory. */
char *smd_job_file_encode(const smd_job_file *f, int indent);

/* Writes DIR/job.json atomically (fsync'ed).  0, or -1 with errno set. */
int smd_job_file_write(const char *dir, const smd_job_file *f);

/* Reads DIR/job.json: every path relative and inside the folder (no
 * leading '/', no ".."), a template, params an object.  SM_ERR_IO when
 * unreadable, SM_ERR_FORMAT when it is not a job description (err says
 * which); f is then empty.  smd_job_file_free releases it either way. */
sm_status smd_job_file_read(const char *dir, smd_job_file *f, sm_error *err);

/* The same from the text of a description (len bytes, no NUL needed). */
sm_status smd_job_file_parse(const char *text, size_t len, smd_job_file *f, sm_error *err);

/* The fingerprint of what a checked background is built from: the
 * daemon's version, f's params (as encoded) and the bytes of each of f's
 * input files under dir, into key.  0, or -1 with errno set (a file
 * unreadable). */
int smd_job_file_inputs_key(const char *dir, const smd_job_file *f,
                            char key[SMD_JOB_KEY_LEN + 1]);

void smd_job_file_free(smd_job_file *f);

#endif
