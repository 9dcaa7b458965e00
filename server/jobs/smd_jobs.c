/* The job state machine (see smd_jobs.h). */
#include "jobs/smd_jobs.h"

#include <errno.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* the metrics count the states by proto's numbering */
_Static_assert(SM_JOB_ACCEPTED == 0 && SM_JOB_SUCCESSFUL == SMD_JOB_FIRST_FINAL &&
                   SM_JOB_DISMISSED + 1 == SMD_JOB_STATES,
               "smd_metrics.h's job state count follows sm_job_state");

/* ------------------------------------------------------------- helpers */

static json_t *log_fields(const smd_job *job, json_t *extra)
{
    json_t *f = json_pack("{s:s,s:s,s:s}", "job", job->id, "status", sm_job_state_name(job->state),
                          "message", job->message);
    if (f && extra)
        json_object_update(f, extra);
    json_decref(extra);
    return f;
}

/* The spool refused a write: stop taking work until it takes them again. */
static void spool_refused(smd_server *srv, const char *msg)
{
    smd_logf(&srv->log, SMD_LOG_ERROR, "store_error", "%s", msg);
    if (!atomic_exchange(&srv->unwritable, 1))
        smd_logf(&srv->log, SMD_LOG_ERROR, "spool_unwritable",
                 "a record could not be written: no job is accepted or started until it can be");
}

static void save_or_log(smd_server *srv, smd_job *job)
{
    sm_error err;
    job->unsaved = smd_store_save(srv->store, job, &err) != SM_OK;
    if (job->unsaved)
        spool_refused(srv, err.msg);
}

/* Durable first: writes the record job will have in state (with
 * message) before the change is made or shown to anyone.  SM_ERR_IO
 * (logged, the daemon unready, errno kept) when the spool refuses it:
 * then nothing changed, and a restart cannot undo what clients saw. */
static sm_status save_ahead(smd_server *srv, const smd_job *job, sm_job_state state,
                            const char *message, double finished)
{
    smd_job next = *job; /* plain data: write_record only reads it */
    next.state = state;
    next.updated = sm_time_now();
    if (finished >= 0) { /* a final record: its event comes next */
        next.finished = next.updated = finished;
        next.final_event_at = (int64_t)smd_job_event_offset(job, job->nevents + 1);
    }
    snprintf(next.message, sizeof next.message, "%s", message);
    sm_error err;
    if (smd_store_save(srv->store, &next, &err) == SM_OK)
        return SM_OK;
    int saved = errno;
    spool_refused(srv, err.msg);
    errno = saved;
    return SM_ERR_IO;
}

/* Appends ev to the job's log, counts it and collects the followers;
 * -1 (err filled, errno kept, nothing logged) when the spool refuses. */
static int append_event(smd_server *srv, smd_job *job, sm_event *ev, smd_jobs_after *after,
                        sm_error *err)
{
    if (smd_store_append_event(srv->store, job, ev, err) != SM_OK)
        return -1;
    smd_metrics_add(&srv->metrics, &srv->metrics.events_appended, 1);
    smd_jobs_after_changed(srv, after, job);
    smd_backend_event(srv->backend, job, ev);
    return 0;
}

static void append_or_log(smd_server *srv, smd_job *job, sm_event *ev, smd_jobs_after *after)
{
    sm_error err;
    if (append_event(srv, job, ev, after, &err) != 0)
        spool_refused(srv, err.msg);
}

static sm_status refuse(const smd_job *job, const char *what, sm_error *err)
{
    return sm_error_set(err, SM_ERR_INVALID, "job %s: cannot %s a job that is %s", job->id, what,
                        sm_job_state_name(job->state));
}

/* ------------------------------------------- ends, durable first
 *
 * The end of a run (successful, failed) or of a cancel (dismissed) is
 * published only once it is on disk: first the final record
 * (status.json), then the final event (events.ndjson), then, in the same
 * hold of the lock, the job's state, the metrics, the log line and the
 * followers' wake-up.  While the spool refuses either write the job is
 * "ending": job->ending holds what is left to write, the job is shown
 * as it was (a successful or failed run stays "running", its message
 * says why; a dismissed job stays dismissed, as the cancel already
 * recorded), its event streams stay open, its results stay where the
 * worker put them, and the daemon is unready (srv->unwritable) until
 * smd_jobs_retry_saves writes it.  "running" is the honest state: the
 * disk still says so, and a restart in between recovers the run from
 * the disk (smd_jobs_recover), so no client ever saw a final state that
 * a restart could change. */

#define ENDING_MESSAGE                                                                             \
    "ending: the run is over; its final status is published once the spool can record it "      \
    "(disk full?)"

static smd_job_ending ending_of(sm_job_state state, const char *message, const sm_event *ev,
                                int log_level, const char *log_event, json_t *extra)
{
    smd_job_ending e = {.state = state, .finished = sm_time_now(), .ev = *ev,
                        .log_level = log_level, .log_event = log_event, .log_fields = extra};
    snprintf(e.message, sizeof e.message, "%s", message);
    e.ev.seq = 0;
    return e;
}

/* The ending is on disk: now it is what clients see. */
static void publish_ending(smd_server *srv, smd_job *job, smd_job_ending *e, smd_jobs_after *after)
{
    job->state = e->state;
    job->finished = job->updated = e->finished;
    if (e->state == SM_JOB_SUCCESSFUL) {
        job->progress = 100;
        job->not_converged = !e->ev.result.converged;
    }
    snprintf(job->message, sizeof job->message, "%s", e->message);
    smd_job_close_log(job);
    smd_metrics_job_finished(&srv->metrics, e->state);
    smd_log(&srv->log, e->log_level, e->log_event, log_fields(job, e->log_fields));
    e->log_fields = NULL;
    smd_jobs_after_changed(srv, after, job);
}

/* Writes what is left of e (record, then event) and publishes it: 0, or
 * -1 while the spool refuses (err filled, errno kept; e remembers how
 * far it got). */
static int write_ending(smd_server *srv, smd_job *job, smd_job_ending *e, smd_jobs_after *after,
                        sm_error *err)
{
    if (smd_store_load_events(srv->store, job, err) != SM_OK)
        return -1;
    if (!e->record_written) {
        smd_job rec = *job; /* plain data: the store only reads it */
        rec.state = e->state;
        rec.finished = rec.updated = e->finished;
        if (e->state == SM_JOB_SUCCESSFUL) {
            rec.progress = 100;
            rec.not_converged = !e->ev.result.converged;
        }
        snprintf(rec.message, sizeof rec.message, "%s", e->message);
        /* where the final event will start: a restart before it is
         * written finds it missing (restore_final_event) */
        rec.final_event_at = (int64_t)smd_job_event_offset(job, job->nevents + 1);
        if (smd_store_save(srv->store, &rec, err) != SM_OK)
            return -1;
        e->record_written = 1;
        job->final_event_at = rec.final_event_at;
        job->unsaved = 0; /* superseded: an older record must not overwrite it */
    }
    e->ev.seq = 0;
    e->ev.time = e->finished;
    snprintf(e->ev.message, sizeof e->ev.message, "%s", e->message);
    if (smd_store_append_event(srv->store, job, &e->ev, err) != SM_OK)
        return -1;
    smd_metrics_add(&srv->metrics, &srv->metrics.events_appended, 1);
    publish_ending(srv, job, e, after);
    /* after the state: a shared backend publishes the final state it sees */
    smd_backend_event(srv->backend, job, &e->ev);
    return 0;
}

/* Ends the job with e (taken over): published at once, or kept as
 * job->ending when the spool refuses (logged, the daemon unready). */
static void end_job(smd_server *srv, smd_job *job, smd_job_ending e, smd_jobs_after *after)
{
    sm_error err;
    smd_unroot(e.message, srv->cfg.spool); /* the status and the last event name no spool path */
    if (write_ending(srv, job, &e, after, &err) == 0)
        return;
    spool_refused(srv, err.msg);
    smd_job_ending *kept = malloc(sizeof *kept);
    if (!kept) { /* out of memory too: published unwritten, as a last resort */
        smd_logf(&srv->log, SMD_LOG_ERROR, "store_error",
                 "job %s: out of memory keeping its end: published before it is on disk", job->id);
        job->unsaved = !e.record_written;
        publish_ending(srv, job, &e, after);
        return;
    }
    *kept = e;
    job->ending = kept;
    job->updated = e.finished;
    if (!smd_job_state_final(job->state))
        snprintf(job->message, sizeof job->message, "%s", ENDING_MESSAGE);
    smd_log(&srv->log, SMD_LOG_WARN, "job_ending_held",
            json_pack("{s:s,s:s,s:s}", "job", job->id, "ends", sm_job_state_name(e.state),
                      "why",
                      "the spool refuses its final record or event: published once both are written"));
    smd_jobs_after_changed(srv, after, job); /* the message changed */
}

/* Writes a held ending: 0 when it is published now (or there was none). */
static int write_held(smd_server *srv, smd_job *job, smd_jobs_after *after, sm_error *err)
{
    if (!job->ending)
        return 0;
    if (write_ending(srv, job, job->ending, after, err) != 0)
        return -1;
    free(job->ending);
    job->ending = NULL;
    return 0;
}

void smd_jobs_retry_saves(smd_server *srv, smd_jobs_after *after)
{
    if (!atomic_load(&srv->unwritable))
        return;
    sm_error err;
    size_t left = 0;
    for (size_t i = 0; i < smd_store_count(srv->store); i++) {
        smd_job *job = smd_store_at(srv->store, i);
        if (job->ending) {
            left += write_held(srv, job, after, &err) != 0;
            continue; /* its final record supersedes job->unsaved */
        }
        if (job->unsaved && (job->unsaved = smd_store_save(srv->store, job, &err) != SM_OK) != 0)
            left++;
    }
    if (left == 0 && smd_store_writable(srv->store)) {
        atomic_store(&srv->unwritable, 0);
        smd_logf(&srv->log, SMD_LOG_INFO, "spool_writable", "every record is written again: jobs are accepted");
    }
}

/* Moves the job's folder to trash/ and remembers it for after the lock;
 * -1 (logged, errno kept) when the spool refuses the rename. */
static int trash_job(smd_server *srv, const smd_job *job, smd_jobs_after *after)
{
    char path[PATH_MAX];
    if (smd_store_trash(srv->store, job->id, path, sizeof path) != 0) {
        int saved = errno;
        smd_logf(&srv->log, SMD_LOG_ERROR, "store_error", "job %s: cannot delete: %s", job->id,
                 strerror(saved));
        errno = saved;
        return -1;
    }
    char **t = path[0] ? realloc(after->trash, (after->ntrash + 1) * sizeof *after->trash) : NULL;
    if (!t)
        return 0; /* left in trash/: emptied at the next start */
    after->trash = t;
    if ((t[after->ntrash] = strdup(path)) != NULL)
        after->ntrash++;
    return 0;
}

/* The job leaves the table: its followers end (with its final status);
 * its folder goes now, or when its worker is gone.  Durable or refused:
 * when the spool cannot take the rename the job stays as it was and
 * SM_ERR_IO is returned (never "deleted" and back after a restart). */
static sm_status remove_job(smd_server *srv, smd_job *job, smd_jobs_after *after, sm_error *err)
{
    if (job->worker_active) {
        if (!smd_store_can_trash(srv->store))
            return sm_error_set(err, SM_ERR_IO, "the spool cannot be written (%s): job %s kept",
                                strerror(errno), job->id);
        job->delete_requested = 1;
    } else if (trash_job(srv, job, after) != 0) {
        return sm_error_set(err, SM_ERR_IO, "the spool cannot be written (%s): job %s kept",
                            strerror(errno), job->id);
    }
    smd_jobs_after_changed(srv, after, job);
    smd_store_unlink(srv->store, job);
    return SM_OK;
}

void smd_jobs_after_changed(smd_server *srv, smd_jobs_after *a, const smd_job *job)
{
    a->srv = srv;
    if (a->nchanged > 0 && strcmp(a->changed[a->nchanged - 1], job->id) == 0)
        return; /* an end writes its record and its event: one wake-up */
    if (a->nchanged == a->changed_cap) {
        size_t ncap = a->changed_cap ? 2 * a->changed_cap : 8;
        char(*c)[SMD_ID_LEN + 1] = realloc(a->changed, ncap * sizeof *c);
        if (!c)
            return;
        a->changed = c;
        a->changed_cap = ncap;
    }
    snprintf(a->changed[a->nchanged++], sizeof a->changed[0], "%s", job->id);
}

void smd_jobs_after_tick(smd_server *srv, smd_jobs_after *a)
{
    a->srv = srv;
    a->keepalive = 1;
}

void smd_jobs_after_wake(smd_server *srv, smd_jobs_after *a)
{
    a->srv = srv;
    a->wake_pool = 1;
}

void smd_jobs_after_run(smd_jobs_after *a)
{
    if (a->srv && a->srv->jobs_changed && (a->nchanged > 0 || a->keepalive))
        a->srv->jobs_changed(a->srv, (const char(*)[SMD_ID_LEN + 1])a->changed, a->nchanged,
                             a->keepalive);
    if (a->srv && a->srv->work_queued && a->wake_pool)
        a->srv->work_queued(a->srv);
    a->nchanged = 0;
    a->keepalive = 0;
    a->wake_pool = 0;
    for (size_t i = 0; i < a->ntrash; i++) {
        smd_rmtree(a->trash[i]);
        free(a->trash[i]);
    }
    free(a->trash);
    a->trash = NULL;
    a->ntrash = 0;
}

void smd_jobs_after_free(smd_jobs_after *a)
{
    smd_jobs_after_run(a);
    free(a->changed);
    a->changed = NULL;
    a->changed_cap = 0;
}

/* -------------------------------------------------------------- submit */

sm_status smd_jobs_publish(smd_server *srv, smd_submission *sub, sm_error *err)
{
    sub->created = 0;
    sub->existing[0] = '\0';
    if (!smd_id_valid(sub->id))
        return sm_error_set(err, SM_ERR_INVALID, "bad job id");
    return smd_backend_publish(srv->backend, sub, &sub->created, sub->existing, err);
}

sm_status smd_jobs_submit(smd_server *srv, const smd_submission *sub, smd_job **out,
                          int *created, smd_jobs_after *after, sm_error *err)
{
    const char *key = sub->idempotency_key && sub->idempotency_key[0] ? sub->idempotency_key : NULL;
    int published = sub->created > 0 || sub->existing[0]; /* smd_jobs_publish ran */
    *created = 0;
    *out = key ? smd_store_find_key(srv->store, sub->owner, key) : NULL;
    if (!*out && sub->existing[0] && !(*out = smd_store_get(srv->store, sub->existing)))
        return sm_error_set(err, SM_ERR_IO,
                            "job %s of the Idempotency-Key was deleted meanwhile", sub->existing);
    if (*out) {
        if (published && !sub->existing[0]) /* published, then a local retry won */
            smd_backend_submitted(srv->backend, sub->id);
        return SM_OK; /* a retry with the same key */
    }
    if (!smd_id_valid(sub->id))
        return sm_error_set(err, SM_ERR_INVALID, "bad job id");
    double created_at = sub->created > 0 ? sub->created : sm_time_now();
    smd_job *job = smd_job_new(sub->id);
    if (!job) {
        smd_backend_submitted(srv->backend, sub->id);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    }
    job->state = SM_JOB_ACCEPTED;
    snprintf(job->message, sizeof job->message, "queued");
    job->created = job->updated = created_at;
    job->dim = sub->dim;
    job->max_iter = sub->max_iter;
    job->tol_boundary = sub->tol_boundary;
    if (key)
        snprintf(job->idempotency_key, sizeof job->idempotency_key, "%s", key);
    if (sub->owner)
        snprintf(job->owner, sizeof job->owner, "%s", sub->owner);
    if (sub->name)
        snprintf(job->name, sizeof job->name, "%s", sub->name);
    job->request_hash = sub->request_hash;
    job->batch_model = sub->batch_model;
    if (smd_job_set_members(job, sub->members, sub->nmembers) != 0) {
        smd_job_free(job);
        smd_backend_submitted(srv->backend, sub->id);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    }
    sm_event ev;
    sm_event_init(&ev, SM_EVENT_ACCEPTED);
    ev.time = job->created;
    sm_status st = smd_store_commit(srv->store, sub->dir, job, &ev, err);
    smd_backend_submitted(srv->backend, sub->id);
    if (st != SM_OK)
        return st;
    if (smd_backend_enqueue(srv->backend, job->id) < 0)
        smd_logf(&srv->log, SMD_LOG_ERROR, "queue_error", "job %s: out of memory queueing it",
                 job->id);
    smd_metrics_add(&srv->metrics, &srv->metrics.jobs_submitted, 1);
    json_t *fields = json_pack("{s:s,s:i,s:i,s:i,s:I}", "job", job->id, "dimension", sub->dim,
                               "vertices", (int)sub->nverts, "elements", (int)sub->nelems, "bytes",
                               (json_int_t)sub->bytes);
    smd_log(&srv->log, SMD_LOG_INFO, "job_accepted", fields);
    smd_jobs_after_wake(srv, after);
    *out = job;
    *created = 1;
    return SM_OK;
}

/* --------------------------------------------------------------- runs */

smd_job *smd_jobs_take_next(smd_server *srv)
{
    char id[SMD_ID_LEN + 1];
    smd_job *job = NULL;
    while (!job) {
        if (!smd_queue_pop(srv->queue, id))
            return NULL;
        job = smd_store_get(srv->store, id);
        if (job && job->state != SM_JOB_ACCEPTED)
            job = NULL; /* cancelled or deleted while queued */
    }
    job->state = SM_JOB_RUNNING;
    if (job->attempt < SMD_ATTEMPT_MAX)
        job->attempt++;
    job->started = job->updated = sm_time_now();
    job->finished = -1;
    job->progress = 0;
    job->have_progress = 0;
    snprintf(job->message, sizeof job->message, "running");
    return job;
}

sm_status smd_jobs_started(smd_server *srv, smd_job *job, long pid, smd_jobs_after *after)
{
    sm_error err;
    if (job->state != SM_JOB_RUNNING || job->worker_active)
        return refuse(job, "start", &err);
    job->worker_active = 1;
    save_or_log(srv, job);
    sm_event ev;
    sm_event_init(&ev, SM_EVENT_STARTED);
    ev.attempt = job->attempt;
    ev.time = job->started;
    append_or_log(srv, job, &ev, after);
    smd_metrics_add(&srv->metrics, &srv->metrics.workers_started, 1);
    json_t *f = log_fields(job, NULL);
    json_object_set_new(f, "pid", json_integer(pid));
    json_object_set_new(f, "attempt", json_integer(job->attempt));
    smd_log(&srv->log, SMD_LOG_INFO, "job_started", f);
    return SM_OK;
}

sm_status smd_jobs_progress(smd_server *srv, smd_job *job, sm_event *ev, smd_jobs_after *after)
{
    sm_error err;
    if (job->state != SM_JOB_RUNNING)
        return refuse(job, "report progress of", &err); /* cancelled: the log ends with "cancelled" */
    smd_unroot(ev->message, srv->cfg.spool); /* clients read it */
    ev->seq = 0; /* numbered by the store */
    ev->time = sm_time_now();
    append_or_log(srv, job, ev, after);
    job->have_progress = 1;
    job->last_progress = ev->progress;
    job->updated = ev->time;
    if (job->max_iter > 0) {
        long pct = (long)ev->progress.iteration * 100 / job->max_iter;
        job->progress = (int)(pct > 99 ? 99 : pct < 0 ? 0 : pct);
    }
    return SM_OK;
}

sm_status smd_jobs_warning(smd_server *srv, smd_job *job, sm_event *ev, smd_jobs_after *after)
{
    sm_error err;
    if (job->state != SM_JOB_RUNNING)
        return refuse(job, "report a warning of", &err);
    smd_unroot(ev->message, srv->cfg.spool); /* clients read it */
    ev->seq = 0; /* numbered by the store */
    ev->time = sm_time_now();
    append_or_log(srv, job, ev, after);
    job->updated = ev->time;
    return SM_OK;
}

/* The status message of a finished run: "finished: STOP after N
 * iterations", or "finished, not converged: ..." with why when its result
 * did not converge (the job stays successful: OGC's status values are
 * fixed, docs/api.md; "converged" in the status document says it too),
 * then the run's warnings (truncated). */
static void finished_message(const sm_result *r, const char *warnings, char *buf, size_t cap)
{
    const char *stop = sm_stop_reason_name(r->stop);
    int n = r->converged
                ? snprintf(buf, cap, "finished: %s after %d iterations", stop, r->iterations)
                : snprintf(buf, cap, "finished, not converged: %s after %d iterations (%s)", stop,
                           r->iterations,
                           r->stop == SM_STOP_QUALITY
                               ? "the quality floor rejected every step"
                               : "the match does not lie on, or does not cover, the target "
                                 "within what the background resolves");
    size_t used = n > 0 ? (size_t)n : 0, room = used < cap ? cap - used : 0;
    if (warnings && warnings[0] && room > 3)
        snprintf(buf + used, room, "; %.*s", (int)(room - 3), warnings);
}

sm_status smd_jobs_finish(smd_server *srv, smd_job *job, const sm_event *finished,
                          json_t *extra, smd_jobs_after *after)
{
    sm_error err;
    if (job->state != SM_JOB_RUNNING || job->ending) {
        json_decref(extra);
        return refuse(job, "finish", &err);
    }
    char message[SM_EVENT_MESSAGE_MAX];
    if (job->batch_model) /* a model has no iterations: the worker says what it built */
        snprintf(message, sizeof message, "finished: %.*s", (int)sizeof message - 16,
                 finished->message);
    else
        finished_message(&finished->result, finished->message, message, sizeof message);
    end_job(srv, job,
            ending_of(SM_JOB_SUCCESSFUL, message, finished, SMD_LOG_INFO, "job_finished", extra),
            after);
    return SM_OK;
}

sm_status smd_jobs_fail(smd_server *srv, smd_job *job, const char *message, json_t *extra,
                        smd_jobs_after *after)
{
    sm_error err;
    if ((job->state != SM_JOB_RUNNING && job->state != SM_JOB_ACCEPTED) || job->ending) {
        json_decref(extra);
        return refuse(job, "fail", &err);
    }
    /* a worker that could not start is an error of the daemon's; one that
     * ended without a result, of the job's */
    int level = job->worker_active ? SMD_LOG_WARN : SMD_LOG_ERROR;
    sm_event ev;
    sm_event_init(&ev, SM_EVENT_FAILED);
    end_job(srv, job, ending_of(SM_JOB_FAILED, message, &ev, level, "job_failed", extra), after);
    return SM_OK;
}

sm_status smd_jobs_requeue(smd_server *srv, smd_job *job, json_t *extra)
{
    sm_error err;
    if (job->state != SM_JOB_RUNNING) {
        json_decref(extra);
        return refuse(job, "queue again", &err);
    }
    job->state = SM_JOB_ACCEPTED;
    job->progress = 0;
    job->updated = sm_time_now();
    snprintf(job->message, sizeof job->message,
             "interrupted by a daemon shutdown: runs again at the next start");
    save_or_log(srv, job);
    smd_backend_requeued(srv->backend, job);
    smd_log(&srv->log, SMD_LOG_INFO, "job_requeued", log_fields(job, extra));
    return SM_OK;
}

void smd_jobs_worker_gone(smd_server *srv, smd_job *job, smd_jobs_after *after)
{
    job->worker_active = 0;
    smd_jobs_after_changed(srv, after, job);
    if (job->delete_requested)
        trash_job(srv, job, after); /* DELETE came while it was stopping */
}

/* ------------------------------------------------------ cancel, delete */

sm_status smd_jobs_cancel(smd_server *srv, smd_job *job, smd_jobs_after *after)
{
    return smd_jobs_stop(srv, job, "cancelled by request (DELETE)", after);
}

sm_status smd_jobs_stop(smd_server *srv, smd_job *job, const char *message, smd_jobs_after *after)
{
    sm_error err;
    if (job->state != SM_JOB_ACCEPTED && job->state != SM_JOB_RUNNING)
        return refuse(job, "cancel", &err);
    if (job->ending) {
        /* the run is over, its end waits for the spool: that end, or 503 */
        if (write_held(srv, job, after, &err) != 0)
            return SM_ERR_IO; /* errno from the refused write */
        return refuse(job, "cancel", &err); /* it ended first */
    }
    int handled = 0; /* a shared backend: another node runs it, or its queue holds it */
    sm_status cst = smd_backend_cancel(srv->backend, srv, job, after, &handled, &err);
    if (cst != SM_OK || handled)
        return cst;
    int running = job->state == SM_JOB_RUNNING;
    double now = sm_time_now();
    if (save_ahead(srv, job, SM_JOB_DISMISSED, message, running ? -1 : now) != SM_OK)
        return SM_ERR_IO;
    snprintf(job->message, sizeof job->message, "%s", message);
    if (!running) {
        /* the final record is on disk: dismissed now, the event follows */
        smd_queue_remove(srv->queue, job->id);
        job->state = SM_JOB_DISMISSED;
        job->finished = job->updated = now;
        job->final_event_at = (int64_t)smd_job_event_offset(job, job->nevents + 1);
        sm_event ev;
        sm_event_init(&ev, SM_EVENT_CANCELLED);
        smd_job_ending e =
            ending_of(SM_JOB_DISMISSED, message, &ev, SMD_LOG_INFO, "job_cancelled", NULL);
        e.finished = now;
        e.record_written = 1;
        end_job(srv, job, e, after);
        return SM_OK;
    }
    /* the worker gets SIGTERM (then SIGKILL) from the supervisor, which
     * calls smd_jobs_cancelled when it is gone */
    job->state = SM_JOB_DISMISSED;
    job->updated = sm_time_now();
    job->cancel_requested = 1;
    smd_jobs_after_wake(srv, after);
    save_or_log(srv, job);
    smd_log(&srv->log, SMD_LOG_INFO, "job_cancel_requested", log_fields(job, NULL));
    smd_jobs_after_changed(srv, after, job);
    return SM_OK;
}

sm_status smd_jobs_cancelled(smd_server *srv, smd_job *job, json_t *extra, smd_jobs_after *after)
{
    sm_error err;
    if (job->state != SM_JOB_DISMISSED || !job->cancel_requested || job->ending) {
        json_decref(extra);
        return refuse(job, "end the cancel of", &err);
    }
    sm_event ev;
    sm_event_init(&ev, SM_EVENT_CANCELLED);
    end_job(srv, job,
            ending_of(SM_JOB_DISMISSED, job->message, &ev, SMD_LOG_INFO, "job_cancelled", extra),
            after);
    return SM_OK;
}

sm_status smd_jobs_delete(smd_server *srv, smd_job *job, smd_jobs_after *after)
{
    sm_error err;
    if (!smd_job_state_final(job->state))
        return refuse(job, "delete", &err);
    char id[sizeof job->id];
    memcpy(id, job->id, sizeof id); /* job may be freed by the removal */
    int deleted = 1; /* 0: another node deleted it first */
    if (smd_backend_remove(srv->backend, id, &deleted, &err) != SM_OK)
        return SM_ERR_IO;
    (void)deleted;
    sm_status st = remove_job(srv, job, after, &err);
    if (st == SM_OK)
        smd_log(&srv->log, SMD_LOG_INFO, "job_deleted", json_pack("{s:s}", "job", id));
    return st; /* errno says why the spool refused */
}

sm_status smd_jobs_expire(smd_server *srv, smd_job *job, smd_jobs_after *after)
{
    sm_error err;
    if (!smd_job_state_final(job->state) || job->worker_active)
        return refuse(job, "expire", &err);
    sm_error e;
    char id[sizeof job->id];
    memcpy(id, job->id, sizeof id); /* job may be freed by the removal */
    int deleted = 1; /* cluster: the one node whose DELETE removed it logs it */
    if (smd_backend_remove(srv->backend, id, &deleted, &e) != SM_OK)
        return SM_ERR_IO; /* retried next sweep */
    if (remove_job(srv, job, after, &e) != SM_OK)
        return SM_ERR_IO; /* logged by trash_job; retried next sweep */
    if (deleted)
        smd_logf(&srv->log, SMD_LOG_INFO, "job_expired", "job %s deleted after the retention time",
                 id);
    return SM_OK;
}

/* ------------------------------------------------------ cluster mirror */

static void mirror_run_fields(smd_job *job, const sm_event *ev)
{
    switch (ev->type) {
    case SM_EVENT_STARTED:
        job->state = SM_JOB_RUNNING;
        job->attempt = ev->attempt > 0 && ev->attempt <= SMD_ATTEMPT_MAX ? ev->attempt : job->attempt;
        job->started = ev->time;
        job->finished = -1;
        job->progress = 0;
        job->have_progress = 0;
        snprintf(job->message, sizeof job->message, "running");
        break;
    case SM_EVENT_PROGRESS:
        job->have_progress = 1;
        job->last_progress = ev->progress;
        if (job->max_iter > 0) {
            long pct = (long)ev->progress.iteration * 100 / job->max_iter;
            job->progress = (int)(pct > 99 ? 99 : pct < 0 ? 0 : pct);
        }
        break;
    default:
        break;
    }
}

sm_status smd_jobs_mirror_event(smd_server *srv, smd_job *job, sm_event *ev, smd_jobs_after *after)
{
    sm_error err;
    if (smd_store_load_events(srv->store, job, &err) != SM_OK)
        return SM_ERR_IO;
    if (ev->seq != job->nevents + 1)
        return sm_error_set(&err, SM_ERR_INVALID, "out of order");
    sm_job_state final = ev->type == SM_EVENT_FINISHED ? SM_JOB_SUCCESSFUL
                         : ev->type == SM_EVENT_FAILED ? SM_JOB_FAILED
                         : ev->type == SM_EVENT_CANCELLED ? SM_JOB_DISMISSED : SM_JOB_ACCEPTED;
    mirror_run_fields(job, ev);
    job->updated = ev->time;
    if (final == SM_JOB_ACCEPTED) {
        append_or_log(srv, job, ev, after);
        if (ev->type == SM_EVENT_STARTED)
            save_or_log(srv, job);
        return SM_OK;
    }
    if (final == SM_JOB_SUCCESSFUL && strncmp(ev->message, "finished", 8) == 0)
        /* the node that ran it wrote its status message into the event */
        snprintf(job->message, sizeof job->message, "%s", ev->message);
    else if (final == SM_JOB_SUCCESSFUL)
        finished_message(&ev->result, NULL, job->message, sizeof job->message);
    else if (ev->message[0])
        snprintf(job->message, sizeof job->message, "%s", ev->message);
    job->state = final;
    job->finished = ev->time;
    if (final == SM_JOB_SUCCESSFUL) {
        job->progress = 100;
        job->not_converged = !ev->result.converged;
    }
    save_or_log(srv, job);
    append_or_log(srv, job, ev, after);
    smd_job_close_log(job);
    smd_metrics_job_finished(&srv->metrics, final);
    return SM_OK;
}

void smd_jobs_mirror_state(smd_server *srv, smd_job *job, sm_job_state state, const char *message,
                           int attempt, smd_jobs_after *after)
{
    if (job->state == state && strcmp(job->message, message) == 0 && job->attempt == attempt)
        return;
    if (smd_job_state_final(job->state))
        return; /* final states come with their event */
    job->state = state;
    job->attempt = attempt;
    job->updated = sm_time_now();
    if (state == SM_JOB_ACCEPTED)
        job->progress = 0;
    snprintf(job->message, sizeof job->message, "%s", message);
    save_or_log(srv, job);
    smd_jobs_after_changed(srv, after, job);
}

void smd_jobs_mirror_drop(smd_server *srv, smd_job *job, smd_jobs_after *after)
{
    sm_error err;
    if (remove_job(srv, job, after, &err) != SM_OK)
        smd_logf(&srv->log, SMD_LOG_WARN, "store_error", "%s", err.msg);
}

/* ------------------------------------------------------------ recovery */

/* A run that had finished before the daemon stopped, its final record
 * never written (the spool was full): its published results say how it
 * ended, so it ends now as it did then (no second run); when the spool
 * still refuses the record the job is held ending, as at run time. */
static void recover_finished(smd_server *srv, smd_job *job, const sm_event *finished, double when,
                             smd_jobs_after *after)
{
    char message[SM_EVENT_MESSAGE_MAX];
    finished_message(&finished->result, finished->message, message, sizeof message);
    job->state = SM_JOB_RUNNING; /* as the disk says (or accepted: requeued at a stop) */
    json_t *f = json_pack("{s:s,s:i}", "recovered_from", "results/" SM_RESULT_SUMMARY_FILE,
                          "attempt", job->attempt);
    smd_job_ending e =
        ending_of(SM_JOB_SUCCESSFUL, message, finished, SMD_LOG_INFO, "job_finished", f);
    e.finished = when;
    end_job(srv, job, e, after);
}

/* A job that was queued or running when the daemon stopped: ended from
 * its complete results, or runnable again.  -1 (logged) when it cannot
 * be either. */
static int recover_job(smd_server *srv, smd_job *job, smd_jobs_after *after)
{
    sm_error err;
    sm_event finished;
    double when = 0;
    /* how its run ended, when the backend knows it from here */
    int ended = smd_backend_read_summary(srv->backend, job, &finished, &when, &err) == SM_OK;
    smd_store_remove_results(srv->store, job, ended || job->state != SM_JOB_RUNNING);
    if (smd_store_load_events(srv->store, job, &err) != SM_OK) {
        smd_logf(&srv->log, SMD_LOG_ERROR, "job_recovery_failed", "%s", err.msg);
        return -1;
    }
    if (ended) {
        recover_finished(srv, job, &finished, when, after);
        return 0;
    }
    if (job->state == SM_JOB_RUNNING) {
        job->state = SM_JOB_ACCEPTED;
        job->progress = 0;
        job->updated = sm_time_now();
        snprintf(job->message, sizeof job->message,
                 "re-queued after a daemon restart (run %d was interrupted)", job->attempt);
        /* a full spool: kept queued in memory and retried; the daemon is
         * unready and starts nothing until the record is written */
        job->unsaved = smd_store_save(srv->store, job, &err) != SM_OK;
        if (job->unsaved)
            spool_refused(srv, err.msg);
        smd_logf(&srv->log, SMD_LOG_INFO, "job_requeued", "job %s was running: queued again",
                 job->id);
    }
    return 0;
}

/* A final record whose final event never reached the log (its append
 * was refused, then the daemon stopped): the event is written now, from
 * the record (and a successful run's summary), so that the log ends with
 * it as every job's does.  Logged either way; a refusal leaves it for the
 * next start. */
static void restore_final_event(smd_server *srv, smd_job *job)
{
    sm_error err;
    sm_event ev;
    double when;
    sm_status st = SM_OK;
    if (job->state == SM_JOB_SUCCESSFUL)
        st = smd_backend_read_summary(srv->backend, job, &ev, &when, &err);
    else
        sm_event_init(&ev, job->state == SM_JOB_FAILED ? SM_EVENT_FAILED : SM_EVENT_CANCELLED);
    if (st == SM_OK) {
        ev.time = job->finished;
        snprintf(ev.message, sizeof ev.message, "%s", job->message);
        if ((st = smd_store_load_events(srv->store, job, &err)) == SM_OK)
            st = smd_store_append_event(srv->store, job, &ev, &err);
        smd_job_close_log(job);
    }
    if (st != SM_OK)
        smd_logf(&srv->log, SMD_LOG_ERROR, "store_error",
                 "job %s: its final event is missing from its log and cannot be written: %s",
                 job->id, err.msg);
    else
        smd_logf(&srv->log, SMD_LOG_WARN, "final_event_restored",
                 "job %s: its final %s event, refused before the restart, is written now", job->id,
                 sm_event_type_name(ev.type));
}

sm_status smd_jobs_recover(smd_server *srv, size_t *queued, sm_error *err)
{
    *queued = 0;
    smd_jobs_after after = {0}; /* no follower yet: nothing to wake */
    sm_status st = SM_OK;
    for (size_t i = 0; i < smd_store_count(srv->store);) {
        smd_job *job = smd_store_at(srv->store, i);
        if (smd_job_state_final(job->state) && smd_backend_final_event_missing(srv->backend, job))
            restore_final_event(srv, job);
        if (!smd_job_state_final(job->state) && recover_job(srv, job, &after) != 0) {
            smd_store_unlink(srv->store, job); /* shifts the list: do not advance i */
            continue;
        }
        if (job->state == SM_JOB_ACCEPTED) { /* a shared backend: its own queue has it */
            int q = smd_backend_enqueue(srv->backend, job->id);
            if (q < 0) {
                st = sm_error_set(err, SM_ERR_NOMEM, "out of memory queueing the jobs");
                break;
            }
            *queued += (size_t)q;
        }
        i++;
    }
    smd_jobs_after_free(&after);
    return st;
}
