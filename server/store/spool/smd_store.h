/* The job store: a spool folder with one folder per job,
 *
 *   SPOOL/jobs/<id>/status.json     job record (OGC status fields plus
 *                                   bookkeeping), replaced atomically
 *                   job.json        the inputs' file names and the
 *                                   canonical parameters (written at upload)
 *                   inputs/         template.*, target_mesh.*, target_sol.*,
 *                                   target_surface.* (the parts sent)
 *                   events.ndjson   append-only event log, seq 1, 2, ...
 *                   results/        written by the worker, renamed into
 *                                   place when complete
 *                   worker.log      the worker's stdout and stderr
 *   SPOOL/lock      flock'ed by the daemon using the spool (holds its pid)
 *   SPOOL/tmp/      uploads being received (emptied at start)
 *   SPOOL/trash/    folders being deleted (emptied at start)
 *
 * and an in-memory table of the jobs (hash by id plus a list in
 * submission order).  status.json is rewritten by temporary file, fsync
 * and rename on every state change, so a crash leaves the old or the new
 * record; events.ndjson is appended one whole line per write(2), and a
 * torn last line (crash in the middle of a write) is cut at the next
 * start.
 *
 * Threading: none inside; the daemon calls every function with its lock
 * held (file writes included: they are short). */
#ifndef SMD_STORE_H
#define SMD_STORE_H

#include <stdint.h>

#include <jansson.h>

#include "shapematch/sm_error.h"
#include "sm_proto_events.h"
#include "sm_proto_vocab.h"
#include "base/smd_log.h"
#include "base/smd_util.h"

#include "store/spool/smd_job.h"

typedef struct smd_store smd_store;

/* Opens (creating) the spool and locks it (a second daemon on the same
 * spool is refused), empties tmp/ and trash/, loads every job record as
 * it is on disk (recovery of interrupted jobs is the state machine's:
 * smd_jobs_recover); unreadable records are logged and skipped.  Jobs
 * are kept in submission order. */
sm_status smd_store_open(const char *spool, const smd_logger *log,
                         smd_store **out, sm_error *err);
void smd_store_close(smd_store *s);

const char *smd_store_root(const smd_store *s);
/* SPOOL/tmp, where uploads are received. */
const char *smd_store_tmp_dir(const smd_store *s);

smd_job *smd_store_get(smd_store *s, const char *id);
/* The job submitted with this Idempotency-Key, or NULL. */
smd_job *smd_store_find_key(smd_store *s, const char *owner, const char *key);
/* smd_store_get, NULL as well when the job is another tenant's (admin:
 * every job is visible): other tenants learn nothing, not even that the
 * id exists. */
smd_job *smd_store_get_visible(smd_store *s, const char *id, const char *tenant, int admin);
size_t smd_store_count(const smd_store *s);
/* i-th job in submission order (0 <= i < count). */
smd_job *smd_store_at(smd_store *s, size_t i);

/* SPOOL/jobs/<id>/<name> (name "" gives the folder).  -1 on overflow. */
int smd_store_path(const smd_store *s, const char *id, const char *name,
                   char *buf, size_t cap);

/* Turns a prepared upload folder (inputs/ and job.json inside) into a
 * job: gives job its submission order, writes first (the "accepted"
 * event, seq 1) as events.ndjson and job as status.json, renames the
 * folder to jobs/<id>, and adds job to the table (which takes it over;
 * on failure it is freed). */
sm_status smd_store_commit(smd_store *s, const char *upload_dir, smd_job *job, sm_event *first,
                           sm_error *err);

/* Removes a job's results.tmp/ (a run in progress), and also results/
 * unless partial_only. */
void smd_store_remove_results(smd_store *s, const smd_job *job, int partial_only);

/* The end of a run read back from its published results (a restart
 * after the final record could not be written): SM_OK when
 * results/summary.json exists (the worker renames results.tmp/ to
 * results/ only when every file is complete), is readable and says the
 * run finished (status "finished", exit_code 0, or 10: finished but not
 * converged); *finished is then the "finished" event (result from the
 * summary, its warnings as the message), *when the summary's modification time.  SM_ERR_IO when
 * there is none, SM_ERR_FORMAT when it says something else. */
sm_status smd_store_read_summary(smd_store *s, const smd_job *job, sm_event *finished,
                                 double *when, sm_error *err);

/* Removes the job from the table (lookups fail from now on) and marks it
 * removed; its files stay until smd_store_delete_files. */
void smd_store_unlink(smd_store *s, smd_job *job);

/* Moves the job's folder to trash/ (instant, atomic, both folders
 * fsync'ed); the caller then removes trash_path (smd_rmtree) without the
 * lock.  -1 on failure (errno), the folder then stays where it was. */
int smd_store_trash(smd_store *s, const char *id, char *trash_path,
                    size_t cap);

/* Whether jobs/ and trash/ accept the rename of smd_store_trash now (a
 * read-only or unwritable spool refuses): the check of a delete that
 * must wait for its worker to be gone. */
int smd_store_can_trash(const smd_store *s);
/* 1 when the spool's root accepts writes again (the engine's retry of
 * unwritten records clears the daemon's unready state on it). */
int smd_store_writable(const smd_store *s);

/* Records found damaged at open (unreadable or invalid status.json): each
 * job folder was moved to SPOOL/quarantine/<id>-<8 hex>, logged
 * (job_quarantined), and replaced by a record of a failed job whose
 * message says "record damaged" and where the folder went. */
size_t smd_store_quarantined(const smd_store *s);

/* Whether a final record's final event is missing from the log (the
 * record was written, the event append was refused, then the daemon
 * stopped): the log ends at job->final_event_at, or in a torn line after
 * it.  0 as well when job->final_event_at is unknown. */
int smd_store_final_event_missing(smd_store *s, const smd_job *job);

/* Persists the record (status.json) after a state change. */
sm_status smd_store_save(smd_store *s, smd_job *job, sm_error *err);

/* Loads the event index from events.ndjson if not done yet, cutting a
 * torn last line. */
sm_status smd_store_load_events(smd_store *s, smd_job *job, sm_error *err);

/* Appends ev to the job's log: sets ev->seq (next number), ev->job_id and
 * ev->time (now, unless already set).  One write(2) of a whole line. */
sm_status smd_store_append_event(smd_store *s, smd_job *job, sm_event *ev,
                                 sm_error *err);



#endif
