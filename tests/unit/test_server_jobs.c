/* The job state machine (smd_jobs.h) without HTTP or workers: every
 * allowed transition changes the state, writes its event and counts it;
 * every refused one answers SM_ERR_INVALID and changes nothing. */
#include <fcntl.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <cmocka.h>

#include "jobs/smd_jobs.h"
#include "jobs/smd_spool_backend.h"

typedef struct fixture {
    char spool[256];
    smd_server srv;
    smd_backend backend; /* the spool's */
    int nupload;
} fixture;

static const char *const labels[] = {"other"};

static int setup(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    snprintf(f->spool, sizeof f->spool, "/tmp/sm-test-jobs-XXXXXX");
    if (!f || !mkdtemp(f->spool))
        return -1;
    f->srv.log.fd = open("/dev/null", O_WRONLY);
    f->srv.log.level = SMD_LOG_DEBUG;
    sm_error err;
    if (smd_store_open(f->spool, &f->srv.log, &f->srv.store, &err) != SM_OK ||
        !(f->srv.queue = smd_queue_local_new()) ||
        smd_metrics_init(&f->srv.metrics, labels, 1) != 0)
        return -1;
    smd_spool_backend_init(&f->backend, f->srv.store, f->srv.queue);
    f->srv.backend = &f->backend;
    *state = f;
    return 0;
}

static int teardown(void **state)
{
    fixture *f = *state;
    smd_queue_free(f->srv.queue);
    smd_store_close(f->srv.store);
    smd_metrics_destroy(&f->srv.metrics);
    close(f->srv.log.fd);
    smd_rmtree(f->spool);
    free(f);
    return 0;
}

/* A new job as an upload hands it over. */
static smd_job *submit(fixture *f, const char *id, const char *key, smd_jobs_after *after)
{
    char dir[512], p[600];
    snprintf(dir, sizeof dir, "%s/tmp/up-%d", f->spool, f->nupload++);
    assert_int_equal(smd_mkdirs(dir, 0700), 0);
    snprintf(p, sizeof p, "%s/job.json", dir);
    assert_int_equal(smd_write_file_atomic(p, "{}", 2), 0);
    smd_submission sub = {.dir = dir, .id = id, .idempotency_key = key, .dim = 2, .max_iter = 10};
    smd_job *job = NULL;
    int created = -1;
    sm_error err;
    assert_int_equal(smd_jobs_submit(&f->srv, &sub, &job, &created, after, &err), SM_OK);
    assert_non_null(job);
    if (created)
        rmdir(dir); /* moved: nothing left (rmdir fails, fine) */
    return job;
}

/* The type of the job's last event in its log. */
static void last_event(fixture *f, smd_job *job, char *type, size_t cap)
{
    char path[512];
    assert_int_equal(smd_store_path(f->srv.store, job->id, "events.ndjson", path, sizeof path), 0);
    FILE *fp = fopen(path, "r");
    assert_non_null(fp);
    char line[4096], last[4096] = "";
    while (fgets(line, sizeof line, fp))
        snprintf(last, sizeof last, "%s", line);
    fclose(fp);
    sm_event ev;
    sm_error err;
    assert_int_equal(sm_event_from_json(last, strlen(last), &ev, &err), SM_OK);
    snprintf(type, cap, "%s", sm_event_type_name(ev.type));
}

static void test_run_to_success(void **state)
{
    fixture *f = *state;
    smd_server *srv = &f->srv;
    smd_jobs_after after = {0};
    char type[32];
    smd_job *job = submit(f, "aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa", "k1", &after);
    assert_int_equal(job->state, SM_JOB_ACCEPTED);
    assert_true(after.wake_pool);
    assert_int_equal(smd_queue_depth(srv->queue), 1);
    assert_true(srv->metrics.jobs_submitted == 1);
    /* the same key again: the same job, nothing new */
    int created;
    smd_job *again;
    sm_error err;
    smd_submission sub = {.dir = "/nonexistent", .id = "bbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbb",
                          .idempotency_key = "k1", .dim = 2, .max_iter = 10};
    assert_int_equal(smd_jobs_submit(srv, &sub, &again, &created, &after, &err), SM_OK);
    assert_int_equal(created, 0);
    assert_ptr_equal(again, job);
    assert_true(srv->metrics.jobs_submitted == 1);

    /* refused from accepted: finish, requeue, delete, expire, start without take */
    sm_event fin;
    sm_event_init(&fin, SM_EVENT_FINISHED);
    fin.result.iterations = 3;
    assert_int_equal(smd_jobs_finish(srv, job, &fin, NULL, &after), SM_ERR_INVALID);
    assert_int_equal(smd_jobs_requeue(srv, job, NULL), SM_ERR_INVALID);
    assert_int_equal(smd_jobs_delete(srv, job, &after), SM_ERR_INVALID);
    assert_int_equal(smd_jobs_expire(srv, job, &after), SM_ERR_INVALID);
    assert_int_equal(smd_jobs_started(srv, job, 1, &after), SM_ERR_INVALID);
    assert_int_equal(smd_jobs_cancelled(srv, job, NULL, &after), SM_ERR_INVALID);
    sm_event prog;
    sm_event_init(&prog, SM_EVENT_PROGRESS);
    assert_int_equal(smd_jobs_progress(srv, job, &prog, &after), SM_ERR_INVALID);
    assert_int_equal(job->state, SM_JOB_ACCEPTED);
    assert_int_equal(job->nevents, 1);

    /* accepted -> running */
    assert_ptr_equal(smd_jobs_take_next(srv), job);
    assert_null(smd_jobs_take_next(srv));
    assert_int_equal(job->state, SM_JOB_RUNNING);
    assert_int_equal(job->attempt, 1);
    assert_int_equal(smd_jobs_started(srv, job, 4242, &after), SM_OK);
    assert_true(job->worker_active);
    assert_true(srv->metrics.workers_started == 1);
    last_event(f, job, type, sizeof type);
    assert_string_equal(type, "started");
    assert_int_equal(smd_jobs_started(srv, job, 4242, &after), SM_ERR_INVALID); /* twice */

    /* progress */
    prog.progress.iteration = 5;
    assert_int_equal(smd_jobs_progress(srv, job, &prog, &after), SM_OK);
    assert_int_equal(job->progress, 50);
    assert_int_equal(job->nevents, 3);

    /* running -> successful; then only delete is allowed */
    assert_int_equal(smd_jobs_finish(srv, job, &fin, NULL, &after), SM_OK);
    assert_int_equal(job->state, SM_JOB_SUCCESSFUL);
    assert_int_equal(job->progress, 100);
    assert_true(srv->metrics.jobs_finished[0] == 1);
    last_event(f, job, type, sizeof type);
    assert_string_equal(type, "finished");
    assert_int_equal(smd_jobs_fail(srv, job, "x", NULL, &after), SM_ERR_INVALID);
    assert_int_equal(smd_jobs_cancel(srv, job, &after), SM_ERR_INVALID);
    assert_int_equal(smd_jobs_finish(srv, job, &fin, NULL, &after), SM_ERR_INVALID);
    assert_int_equal(smd_jobs_expire(srv, job, &after), SM_ERR_INVALID); /* worker still active */
    smd_jobs_worker_gone(srv, job, &after);
    assert_false(job->worker_active);
    assert_int_equal(job->state, SM_JOB_SUCCESSFUL);

    /* delete: out of the table, folder to trash, removed after the lock */
    char dir[512];
    assert_int_equal(smd_store_path(srv->store, job->id, "", dir, sizeof dir), 0);
    assert_int_equal(smd_jobs_delete(srv, job, &after), SM_OK);
    assert_null(smd_store_get(srv->store, "aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa"));
    assert_int_equal(after.ntrash, 1);
    smd_jobs_after_free(&after);
    struct stat st;
    assert_int_equal(stat(dir, &st), -1);
    assert_int_equal(after.ntrash, 0);
}

/* What smd_jobs_after_run hands to srv->jobs_changed (the event streams
 * in the daemon): recorded here. */
static char heard[8][SMD_ID_LEN + 1];
static size_t nheard, ncalls;
static int heard_keepalive;

static void record_changes(smd_server *srv, const char (*ids)[SMD_ID_LEN + 1], size_t n,
                           int keepalive)
{
    (void)srv;
    ncalls++;
    heard_keepalive = keepalive;
    nheard = 0;
    for (size_t i = 0; i < n && i < 8; i++)
        snprintf(heard[nheard++], sizeof heard[0], "%s", ids[i]);
}

/* The engine names the jobs whose log or state changed, once each, and
 * nothing for a new, a refused or an idempotent call; the tick asks for
 * keepalives; nothing is called when nothing changed. */
static void test_changes_reported(void **state)
{
    fixture *f = *state;
    smd_server *srv = &f->srv;
    srv->jobs_changed = record_changes;
    ncalls = nheard = 0;
    smd_jobs_after after = {0};
    smd_job *a = submit(f, "aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa", "k", &after);
    smd_job *b = submit(f, "bbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbb", NULL, &after);
    smd_jobs_after_run(&after); /* a new job has no follower yet */
    assert_int_equal(ncalls, 0);

    /* refused, or the same Idempotency-Key: no change, no call */
    sm_event fin;
    sm_event_init(&fin, SM_EVENT_FINISHED);
    assert_int_equal(smd_jobs_finish(srv, a, &fin, NULL, &after), SM_ERR_INVALID);
    int created;
    smd_job *again;
    sm_error err;
    smd_submission sub = {.dir = "/nonexistent", .id = "cccccccccccccccccccccccccccccccc",
                          .idempotency_key = "k", .dim = 2, .max_iter = 10};
    assert_int_equal(smd_jobs_submit(srv, &sub, &again, &created, &after, &err), SM_OK);
    assert_int_equal(created, 0);
    smd_jobs_after_run(&after);
    assert_int_equal(ncalls, 0);

    /* a run: started, two progress events and the end, all of job a */
    assert_ptr_equal(smd_jobs_take_next(srv), a);
    assert_int_equal(smd_jobs_started(srv, a, 99, &after), SM_OK);
    sm_event prog;
    sm_event_init(&prog, SM_EVENT_PROGRESS);
    prog.progress.iteration = 1;
    assert_int_equal(smd_jobs_progress(srv, a, &prog, &after), SM_OK);
    prog.progress.iteration = 2;
    assert_int_equal(smd_jobs_progress(srv, a, &prog, &after), SM_OK);
    assert_int_equal(smd_jobs_finish(srv, a, &fin, NULL, &after), SM_OK);
    /* b dismissed: its followers too */
    assert_int_equal(smd_jobs_cancel(srv, b, &after), SM_OK);
    smd_jobs_after_tick(srv, &after);
    smd_jobs_after_run(&after);
    assert_int_equal(ncalls, 1);
    assert_int_equal(nheard, 2);
    assert_string_equal(heard[0], a->id);
    assert_string_equal(heard[1], b->id);
    assert_true(heard_keepalive);
    assert_int_equal(after.nchanged, 0);
    assert_false(after.keepalive);

    /* deleted: named once more (its followers end) */
    smd_jobs_worker_gone(srv, a, &after);
    smd_jobs_after_run(&after);
    char id[SMD_ID_LEN + 1];
    snprintf(id, sizeof id, "%s", a->id);
    assert_int_equal(smd_jobs_delete(srv, a, &after), SM_OK);
    smd_jobs_after_free(&after);
    assert_int_equal(nheard, 1);
    assert_string_equal(heard[0], id);
    srv->jobs_changed = NULL;
}

static void test_cancel_fail_requeue(void **state)
{
    fixture *f = *state;
    smd_server *srv = &f->srv;
    smd_jobs_after after = {0};
    char type[32];
    /* a queued job is dismissed at once */
    smd_job *a = submit(f, "0123456789abcdef0123456789abcdef", NULL, &after);
    smd_job *b = submit(f, "fedcba9876543210fedcba9876543210", NULL, &after);
    after.wake_pool = 0;
    assert_int_equal(smd_jobs_cancel(srv, a, &after), SM_OK);
    assert_int_equal(a->state, SM_JOB_DISMISSED);
    assert_false(after.wake_pool);
    assert_true(a->finished > 0);
    assert_true(srv->metrics.jobs_finished[2] == 1);
    last_event(f, a, type, sizeof type);
    assert_string_equal(type, "cancelled");
    assert_int_equal(smd_jobs_cancel(srv, a, &after), SM_ERR_INVALID);
    assert_int_equal(smd_jobs_cancelled(srv, a, NULL, &after), SM_ERR_INVALID);
    /* the queue skips it */
    assert_ptr_equal(smd_jobs_take_next(srv), b);

    /* a running job: dismissed, its worker asked to stop, then gone */
    assert_int_equal(smd_jobs_started(srv, b, 1, &after), SM_OK);
    assert_int_equal(smd_jobs_cancel(srv, b, &after), SM_OK);
    assert_int_equal(b->state, SM_JOB_DISMISSED);
    assert_true(b->cancel_requested);
    assert_true(after.wake_pool);
    last_event(f, b, type, sizeof type);
    assert_string_equal(type, "started"); /* "cancelled" when the worker is gone */
    sm_event prog;
    sm_event_init(&prog, SM_EVENT_PROGRESS);
    assert_int_equal(smd_jobs_progress(srv, b, &prog, &after), SM_ERR_INVALID);
    assert_int_equal(smd_jobs_cancelled(srv, b, NULL, &after), SM_OK);
    last_event(f, b, type, sizeof type);
    assert_string_equal(type, "cancelled");
    assert_true(srv->metrics.jobs_finished[2] == 2);
    /* a DELETE while the worker is stopping removes the files when it is gone */
    smd_job_ref(b); /* the pool's reference */
    assert_int_equal(smd_jobs_delete(srv, b, &after), SM_OK);
    assert_true(b->delete_requested);
    assert_true(b->removed);
    assert_int_equal(after.ntrash, 0);
    smd_jobs_worker_gone(srv, b, &after);
    assert_int_equal(after.ntrash, 1);
    smd_job_unref(b);

    /* fail from running and from a worker that never started */
    smd_job *c = submit(f, "cccccccccccccccccccccccccccccccc", NULL, &after);
    smd_job *d = submit(f, "dddddddddddddddddddddddddddddddd", NULL, &after);
    assert_ptr_equal(smd_jobs_take_next(srv), c);
    assert_int_equal(smd_jobs_fail(srv, c, "cannot start the worker: test", NULL, &after), SM_OK);
    assert_int_equal(c->state, SM_JOB_FAILED);
    assert_string_equal(c->message, "cannot start the worker: test");
    last_event(f, c, type, sizeof type);
    assert_string_equal(type, "failed");
    assert_true(srv->metrics.jobs_finished[1] == 1);

    /* running -> accepted at a shutdown; recovered at the next start */
    assert_ptr_equal(smd_jobs_take_next(srv), d);
    assert_int_equal(smd_jobs_started(srv, d, 2, &after), SM_OK);
    assert_int_equal(smd_jobs_requeue(srv, d, NULL), SM_OK);
    assert_int_equal(d->state, SM_JOB_ACCEPTED);
    assert_int_equal(smd_jobs_requeue(srv, d, NULL), SM_ERR_INVALID);
    assert_int_equal(smd_queue_depth(srv->queue), 0);
    size_t queued;
    sm_error err;
    assert_int_equal(smd_jobs_recover(srv, &queued, &err), SM_OK);
    assert_int_equal(queued, 1);
    assert_ptr_equal(smd_jobs_take_next(srv), d);
    assert_int_equal(d->attempt, 2);
    smd_jobs_after_free(&after);
}

/* ------------------------------------------------ ends, durable first */

/* The status.json of job as the disk has it ("" when unreadable). */
static void disk_state(fixture *f, const smd_job *job, char *state, size_t cap)
{
    char path[512];
    assert_int_equal(smd_store_path(f->srv.store, job->id, "status.json", path, sizeof path), 0);
    json_error_t jerr;
    json_t *o = json_load_file(path, 0, &jerr);
    snprintf(state, cap, "%s", o ? json_string_value(json_object_get(o, "status")) : "");
    json_decref(o);
}

/* Makes the spool refuse (on) or take (off) writes of the job's file
 * name: a folder in its place refuses the rename of a new record (root
 * included); the file itself is kept aside meanwhile. */
static void refuse_file(fixture *f, const smd_job *job, const char *name, int on)
{
    char path[512], aside[600];
    assert_int_equal(smd_store_path(f->srv.store, job->id, name, path, sizeof path), 0);
    snprintf(aside, sizeof aside, "%s.aside", path);
    if (on) {
        assert_int_equal(rename(path, aside), 0);
        assert_int_equal(mkdir(path, 0700), 0);
    } else {
        assert_int_equal(rmdir(path), 0);
        assert_int_equal(rename(aside, path), 0);
    }
}

/* A submitted job, taken and started (a worker "runs"). */
static smd_job *running_job(fixture *f, const char *id, smd_jobs_after *after)
{
    smd_job *job = submit(f, id, NULL, after);
    assert_ptr_equal(smd_jobs_take_next(&f->srv), job);
    assert_int_equal(smd_jobs_started(&f->srv, job, 77, after), SM_OK);
    return job;
}

static void test_end_held_until_recorded(void **state)
{
    fixture *f = *state;
    smd_server *srv = &f->srv;
    smd_jobs_after after = {0};
    char type[32], ondisk[32];
    smd_job *job = running_job(f, "abababababababababababababababab", &after);
    sm_event fin;
    sm_event_init(&fin, SM_EVENT_FINISHED);
    fin.result.iterations = 4;
    fin.result.converged = 1;
    refuse_file(f, job, "status.json", 1);
    assert_int_equal(smd_jobs_finish(srv, job, &fin, NULL, &after), SM_OK);
    /* not published: still running, nothing counted, no event, unready */
    assert_int_equal(job->state, SM_JOB_RUNNING);
    assert_non_null(job->ending);
    assert_non_null(strstr(job->message, "ending"));
    assert_true(atomic_load(&srv->unwritable));
    assert_true(srv->metrics.jobs_finished[0] == 0);
    last_event(f, job, type, sizeof type);
    assert_string_equal(type, "started");
    assert_int_equal(smd_jobs_finish(srv, job, &fin, NULL, &after), SM_ERR_INVALID); /* twice */
    assert_int_equal(smd_jobs_fail(srv, job, "x", NULL, &after), SM_ERR_INVALID);
    smd_jobs_worker_gone(srv, job, &after);
    /* the spool still refuses: a retry changes nothing, a cancel is refused */
    smd_jobs_retry_saves(srv, &after);
    assert_int_equal(job->state, SM_JOB_RUNNING);
    assert_true(atomic_load(&srv->unwritable));
    assert_int_equal(smd_jobs_cancel(srv, job, &after), SM_ERR_IO);
    assert_int_equal(job->state, SM_JOB_RUNNING);
    /* space back: written, then published */
    refuse_file(f, job, "status.json", 0);
    smd_jobs_retry_saves(srv, &after);
    assert_int_equal(job->state, SM_JOB_SUCCESSFUL);
    assert_null(job->ending);
    assert_int_equal(job->progress, 100);
    assert_string_equal(job->message, "finished: step_tolerance after 4 iterations");
    assert_false(atomic_load(&srv->unwritable));
    assert_true(srv->metrics.jobs_finished[0] == 1);
    last_event(f, job, type, sizeof type);
    assert_string_equal(type, "finished");
    disk_state(f, job, ondisk, sizeof ondisk);
    assert_string_equal(ondisk, "successful");

    /* a failed end whose event (not its record) is refused: held too, and
     * the record is not overwritten by an older one */
    smd_job *b = running_job(f, "cdcdcdcdcdcdcdcdcdcdcdcdcdcdcdcd", &after);
    smd_job_close_log(b); /* the append reopens the log */
    refuse_file(f, b, "events.ndjson", 1);
    assert_int_equal(smd_jobs_fail(srv, b, "worker killed", NULL, &after), SM_OK);
    assert_int_equal(b->state, SM_JOB_RUNNING);
    disk_state(f, b, ondisk, sizeof ondisk);
    assert_string_equal(ondisk, "failed");
    smd_jobs_worker_gone(srv, b, &after);
    /* a cancel now writes the held end first: the job ended before it */
    refuse_file(f, b, "events.ndjson", 0);
    assert_int_equal(smd_jobs_cancel(srv, b, &after), SM_ERR_INVALID);
    assert_int_equal(b->state, SM_JOB_FAILED);
    assert_string_equal(b->message, "worker killed");
    last_event(f, b, type, sizeof type);
    assert_string_equal(type, "failed");
    assert_true(srv->metrics.jobs_finished[1] == 1);
    smd_jobs_retry_saves(srv, &after);
    assert_false(atomic_load(&srv->unwritable));
    smd_jobs_after_free(&after);
}

/* results/summary.json of a finished run, as the job runner writes it
 * (a run that did not converge: exit code 10, "converged": false) */
static void write_summary_of(fixture *f, const smd_job *job, const char *status, int converged)
{
    char dir[512], path[600];
    assert_int_equal(smd_store_path(f->srv.store, job->id, "results", dir, sizeof dir), 0);
    assert_int_equal(smd_mkdirs(dir, 0700), 0);
    sm_result r;
    memset(&r, 0, sizeof r);
    r.stop = SM_STOP_MAX_ITER;
    r.iterations = 7;
    r.converged = converged;
    json_t *doc = sm_result_to_jansson(&r, NULL, 2);
    json_object_set_new(doc, "status", json_string(status));
    json_object_set_new(doc, "exit_code", json_integer(converged ? 0 : 10));
    json_object_set_new(doc, "warnings",
                        json_pack("[{s:s,s:s,s:f}]", "code", "alpha-small", "message",
                                  "alpha is small", "figure", 0.5));
    snprintf(path, sizeof path, "%s/summary.json", dir);
    assert_int_equal(json_dump_file(doc, path, 0), 0);
    json_decref(doc);
}

static void write_summary(fixture *f, const smd_job *job, const char *status)
{
    write_summary_of(f, job, status, 1);
}

static void restart(fixture *f, size_t *queued)
{
    sm_error err;
    smd_queue_free(f->srv.queue);
    smd_store_close(f->srv.store);
    assert_int_equal(smd_store_open(f->spool, &f->srv.log, &f->srv.store, &err), SM_OK);
    assert_non_null(f->srv.queue = smd_queue_local_new());
    smd_spool_backend_init(&f->backend, f->srv.store, f->srv.queue);
    assert_int_equal(smd_jobs_recover(&f->srv, queued, &err), SM_OK);
}

static void test_recover_from_results(void **state)
{
    fixture *f = *state;
    smd_server *srv = &f->srv;
    smd_jobs_after after = {0};
    char type[32], ondisk[32], results[512];
    static const char done_id[] = "efefefefefefefefefefefefefefefef";
    static const char bad_id[] = "12121212121212121212121212121212";
    smd_job *done = running_job(f, done_id, &after);
    smd_job *bad = running_job(f, bad_id, &after);
    write_summary(f, done, "finished");
    write_summary(f, bad, "cancelled");
    size_t queued;
    restart(f, &queued);
    /* a complete result set: ended as that run ended, not run again */
    done = smd_store_get(srv->store, done_id);
    assert_non_null(done);
    assert_int_equal(done->state, SM_JOB_SUCCESSFUL);
    assert_int_equal(done->attempt, 1);
    assert_string_equal(done->message, "finished: max_iterations after 7 iterations; "
                                       "warning: alpha-small: alpha is small");
    last_event(f, done, type, sizeof type);
    assert_string_equal(type, "finished");
    disk_state(f, done, ondisk, sizeof ondisk);
    assert_string_equal(ondisk, "successful");
    assert_int_equal(
        smd_store_path(srv->store, done_id, "results/summary.json", results, sizeof results), 0);
    assert_int_equal(access(results, R_OK), 0);
    /* a summary that does not say "finished": queued again, results gone */
    bad = smd_store_get(srv->store, bad_id);
    assert_int_equal(bad->state, SM_JOB_ACCEPTED);
    assert_int_equal(queued, 1);
    assert_int_equal(smd_store_path(srv->store, bad_id, "results", results, sizeof results), 0);
    assert_int_equal(access(results, F_OK), -1);
    assert_false(atomic_load(&srv->unwritable));
    smd_jobs_after_free(&after);
}

/* A run that finished without converging (summary exit code 10): ended
 * successful from its results, not run again, "converged": false in its
 * status fields, its message and its record, which a restart reads back;
 * a converged one says true. */
static void test_recover_not_converged(void **state)
{
    fixture *f = *state;
    smd_server *srv = &f->srv;
    smd_jobs_after after = {0};
    static const char id[] = "56565656565656565656565656565656";
    static const char yes_id[] = "78787878787878787878787878787878";
    write_summary_of(f, running_job(f, id, &after), "finished", 0);
    write_summary_of(f, running_job(f, yes_id, &after), "finished", 1);
    size_t queued;
    restart(f, &queued);
    assert_int_equal(queued, 0);
    for (int round = 0; round < 2; round++) { /* recovered, then read back */
        smd_job *job = smd_store_get(srv->store, id);
        assert_non_null(job);
        assert_int_equal(job->state, SM_JOB_SUCCESSFUL);
        assert_true(job->not_converged);
        assert_non_null(strstr(job->message, "finished, not converged: max_iterations after 7 "
                                             "iterations"));
        json_t *doc = smd_job_status_fields(job);
        assert_true(json_is_false(json_object_get(doc, "converged")));
        json_decref(doc);
        smd_job *yes = smd_store_get(srv->store, yes_id);
        assert_false(yes->not_converged);
        doc = smd_job_status_fields(yes);
        assert_true(json_is_true(json_object_get(doc, "converged")));
        json_decref(doc);
        restart(f, &queued);
    }
    smd_jobs_after_free(&after);
}

/* The final record was written, its event refused, then the daemon
 * stopped: the next start writes the missing event, once. */
static void test_final_event_restored(void **state)
{
    fixture *f = *state;
    smd_server *srv = &f->srv;
    smd_jobs_after after = {0};
    char type[32];
    static const char id[] = "34343434343434343434343434343434";
    smd_job *job = running_job(f, id, &after);
    smd_job_close_log(job); /* the append reopens the log */
    refuse_file(f, job, "events.ndjson", 1);
    assert_int_equal(smd_jobs_fail(srv, job, "worker killed", NULL, &after), SM_OK);
    assert_int_equal(job->state, SM_JOB_RUNNING); /* held: the record is final, the event is not */
    smd_jobs_worker_gone(srv, job, &after);
    size_t queued;
    restart(f, &queued); /* the log still refuses: nothing written, logged */
    job = smd_store_get(srv->store, id);
    assert_non_null(job);
    assert_int_equal(job->state, SM_JOB_FAILED);
    refuse_file(f, job, "events.ndjson", 0);
    restart(f, &queued);
    job = smd_store_get(srv->store, id);
    assert_int_equal(job->state, SM_JOB_FAILED);
    last_event(f, job, type, sizeof type);
    assert_string_equal(type, "failed");
    restart(f, &queued); /* written once */
    job = smd_store_get(srv->store, id);
    sm_error err;
    assert_int_equal(smd_store_load_events(srv->store, job, &err), SM_OK);
    assert_int_equal(job->nevents, 3); /* accepted, started, failed */
    assert_int_equal(queued, 0);
    smd_jobs_after_free(&after);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_run_to_success, setup, teardown),
        cmocka_unit_test_setup_teardown(test_cancel_fail_requeue, setup, teardown),
        cmocka_unit_test_setup_teardown(test_changes_reported, setup, teardown),
        cmocka_unit_test_setup_teardown(test_end_held_until_recorded, setup, teardown),
        cmocka_unit_test_setup_teardown(test_recover_not_converged, setup, teardown),
        cmocka_unit_test_setup_teardown(test_recover_from_results, setup, teardown),
        cmocka_unit_test_setup_teardown(test_final_event_restored, setup, teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
