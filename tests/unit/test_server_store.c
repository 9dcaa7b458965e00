/* The job store: committing an upload folder, status records that
 * survive a reopen, crash recovery (running jobs become queued again,
 * partial results go, a torn event line is cut), the event index, stray
 * and corrupt folders, deletion. */
#include <errno.h>
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
    smd_logger log;
} fixture;

static int setup(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    snprintf(f->spool, sizeof f->spool, "/tmp/sm-test-store-XXXXXX");
    if (!mkdtemp(f->spool))
        return -1;
    f->log.fd = open("/dev/null", O_WRONLY);
    f->log.level = SMD_LOG_DEBUG;
    *state = f;
    return 0;
}

static int teardown(void **state)
{
    fixture *f = *state;
    smd_rmtree(f->spool);
    close(f->log.fd);
    free(f);
    return 0;
}

/* An upload folder as the daemon prepares it. */
static void make_upload(const char *spool, char *dir, size_t cap)
{
    snprintf(dir, cap, "%s/tmp/up-test", spool);
    assert_int_equal(smd_mkdirs(dir, 0700), 0);
    char p[600];
    snprintf(p, sizeof p, "%s/job.json", dir);
    assert_int_equal(smd_write_file_atomic(p, "{}", 2), 0);
}

static smd_job *commit(fixture *f, smd_store *s, const char *id, const char *key)
{
    char dir[512];
    make_upload(f->spool, dir, sizeof dir);
    /* the record as the state machine makes it (smd_jobs_submit) */
    smd_job *job = smd_job_new(id);
    assert_non_null(job);
    job->state = SM_JOB_ACCEPTED;
    job->created = job->updated = 1700000000;
    job->dim = 2;
    job->max_iter = 100;
    if (key)
        snprintf(job->idempotency_key, sizeof job->idempotency_key, "%s", key);
    sm_event ev;
    sm_event_init(&ev, SM_EVENT_ACCEPTED);
    sm_error err;
    assert_int_equal(smd_store_commit(s, dir, job, &ev, &err), SM_OK);
    assert_int_equal(ev.seq, 1);
    struct stat st;
    assert_int_equal(stat(dir, &st), -1); /* moved */
    return job;
}

/* A daemon start: the store opened, then the state machine's recovery
 * (running jobs queued again, partial results removed, logs repaired). */
static sm_status open_recovered(fixture *f, smd_store **s, size_t *queued, sm_error *err)
{
    sm_status st = smd_store_open(f->spool, &f->log, s, err);
    if (st != SM_OK)
        return st;
    static smd_server srv; /* zeroed; only what recovery uses is set */
    static smd_backend backend;
    static const char *const labels[] = {"other"};
    memset(&srv, 0, sizeof srv);
    srv.log = f->log;
    srv.store = *s;
    srv.queue = smd_queue_local_new();
    assert_non_null(srv.queue);
    smd_spool_backend_init(&backend, srv.store, srv.queue);
    srv.backend = &backend;
    assert_int_equal(smd_metrics_init(&srv.metrics, labels, 1), 0);
    st = smd_jobs_recover(&srv, queued, err);
    smd_queue_free(srv.queue);
    smd_metrics_destroy(&srv.metrics);
    return st;
}

static int64_t count_lines(const char *path)
{
    FILE *fp = fopen(path, "r");
    assert_non_null(fp);
    int64_t n = 0;
    int c;
    while ((c = fgetc(fp)) != EOF)
        n += c == '\n';
    fclose(fp);
    return n;
}

static void test_commit_and_reopen(void **state)
{
    fixture *f = *state;
    smd_store *s;
    sm_error err;
    assert_int_equal(smd_store_open(f->spool, &f->log, &s, &err), SM_OK);
    /* one daemon per spool */
    smd_store *other;
    assert_int_not_equal(smd_store_open(f->spool, &f->log, &other, &err), SM_OK);
    assert_non_null(strstr(err.msg, "in use by another shapematchd (pid "));
    assert_null(other);
    const char *a = "aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa", *b = "bbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbb";
    smd_job *ja = commit(f, s, a, "key-1");
    smd_job *jb = commit(f, s, b, NULL);
    assert_int_equal(smd_store_count(s), 2);
    assert_ptr_equal(smd_store_get(s, a), ja);
    assert_ptr_equal(smd_store_get(s, b), jb);
    assert_null(smd_store_get(s, "cccccccccccccccccccccccccccccccc"));
    assert_null(smd_store_get(s, "../../etc"));
    assert_ptr_equal(smd_store_find_key(s, NULL, "key-1"), ja);
    assert_null(smd_store_find_key(s, NULL, "key-2"));
    assert_true(ja->order < jb->order);
    assert_int_equal(ja->state, SM_JOB_ACCEPTED);
    assert_int_equal(ja->nevents, 1); /* "accepted" */

    /* events: seq numbering and the offset index */
    for (int i = 0; i < 5; i++) {
        sm_event ev;
        sm_event_init(&ev, SM_EVENT_PROGRESS);
        ev.progress.iteration = i;
        assert_int_equal(smd_store_append_event(s, ja, &ev, &err), SM_OK);
        assert_int_equal(ev.seq, i + 2);
        assert_string_equal(ev.job_id, a);
        assert_true(ev.time > 1e9);
    }
    char path[512];
    assert_int_equal(smd_store_path(s, a, "events.ndjson", path, sizeof path), 0);
    assert_int_equal(count_lines(path), 6);
    struct stat st;
    assert_int_equal(stat(path, &st), 0);
    assert_true(smd_job_event_offset(ja, 7) == (uint64_t)st.st_size);
    assert_true(smd_job_event_offset(ja, 1) == 0);
    /* each indexed event starts with '{' and the one before ends with '\n' */
    FILE *fp = fopen(path, "r");
    for (int64_t seq = 1; seq <= 6; seq++) {
        fseek(fp, (long)smd_job_event_offset(ja, seq), SEEK_SET);
        char line[1024];
        assert_non_null(fgets(line, sizeof line, fp));
        sm_event ev;
        assert_int_equal(sm_event_from_json(line, strlen(line), &ev, &err), SM_OK);
        assert_int_equal(ev.seq, seq);
    }
    fclose(fp);

    /* state changes persist */
    jb->state = SM_JOB_SUCCESSFUL;
    jb->progress = 100;
    jb->started = 1700000000.5;
    jb->finished = 1700000001.25;
    snprintf(jb->message, sizeof jb->message, "finished");
    assert_int_equal(smd_store_save(s, jb, &err), SM_OK);
    ja->state = SM_JOB_RUNNING;
    ja->attempt = 1;
    assert_int_equal(smd_store_save(s, ja, &err), SM_OK);
    smd_store_close(s);

    size_t queued;
    assert_int_equal(open_recovered(f, &s, &queued, &err), SM_OK);
    assert_int_equal(queued, 1);
    assert_int_equal(smd_store_count(s), 2);
    assert_string_equal(smd_store_at(s, 0)->id, a); /* submission order */
    assert_string_equal(smd_store_at(s, 1)->id, b);
    jb = smd_store_get(s, b);
    assert_int_equal(jb->state, SM_JOB_SUCCESSFUL);
    assert_int_equal(jb->progress, 100);
    assert_true(jb->started == 1700000000.5);
    assert_true(jb->finished == 1700000001.25);
    assert_string_equal(jb->message, "finished");
    /* the running job is queued again, its attempt count kept */
    ja = smd_store_get(s, a);
    assert_int_equal(ja->state, SM_JOB_ACCEPTED);
    assert_int_equal(ja->attempt, 1);
    assert_non_null(strstr(ja->message, "re-queued"));
    assert_int_equal(ja->nevents, 6);
    assert_ptr_equal(smd_store_find_key(s, NULL, "key-1"), ja);
    /* the next job sorts after the reloaded ones */
    smd_job *jc = commit(f, s, "cccccccccccccccccccccccccccccccc", NULL);
    assert_true(jc->order > jb->order);
    smd_store_close(s);
}

static void put(const char *path, const char *text)
{
    FILE *fp = fopen(path, "a");
    assert_non_null(fp);
    fputs(text, fp);
    fclose(fp);
}

static void test_crash_leftovers(void **state)
{
    fixture *f = *state;
    smd_store *s;
    sm_error err;
    const char *a = "0123456789abcdef0123456789abcdef";
    assert_int_equal(smd_store_open(f->spool, &f->log, &s, &err), SM_OK);
    smd_job *ja = commit(f, s, a, NULL);
    ja->state = SM_JOB_RUNNING;
    assert_int_equal(smd_store_save(s, ja, &err), SM_OK);
    char dir[512], p[600];
    assert_int_equal(smd_store_path(s, a, "", dir, sizeof dir), 0);
    smd_store_close(s);

    /* what a kill -9 in the middle of things leaves */
    snprintf(p, sizeof p, "%s/results.tmp", dir);
    assert_int_equal(smd_mkdirs(p, 0700), 0);
    snprintf(p, sizeof p, "%s/results", dir);
    assert_int_equal(smd_mkdirs(p, 0700), 0);
    snprintf(p, sizeof p, "%s/events.ndjson", dir);
    put(p, "{\"type\":\"progress\",\"iter");
    snprintf(p, sizeof p, "%s/jobs/not-a-job", f->spool);
    assert_int_equal(smd_mkdirs(p, 0700), 0);
    snprintf(p, sizeof p, "%s/jobs/ffffffffffffffffffffffffffffffff", f->spool);
    assert_int_equal(smd_mkdirs(p, 0700), 0);
    snprintf(p, sizeof p, "%s/jobs/ffffffffffffffffffffffffffffffff/status.json", f->spool);
    put(p, "{ not json");
    snprintf(p, sizeof p, "%s/jobs/eeeeeeeeeeeeeeeeeeeeeeeeeeeeeeee", f->spool);
    assert_int_equal(smd_mkdirs(p, 0700), 0);
    snprintf(p, sizeof p, "%s/jobs/eeeeeeeeeeeeeeeeeeeeeeeeeeeeeeee/status.json", f->spool);
    put(p, "{\"jobID\": \"0123456789abcdef0123456789abcdef\", \"status\": \"accepted\"}");
    snprintf(p, sizeof p, "%s/tmp/up-half", f->spool);
    assert_int_equal(smd_mkdirs(p, 0700), 0);
    snprintf(p, sizeof p, "%s/trash/old", f->spool);
    assert_int_equal(smd_mkdirs(p, 0700), 0);

    size_t queued;
    assert_int_equal(open_recovered(f, &s, &queued, &err), SM_OK);
    assert_int_equal(queued, 1);
    /* the foreign folder is left alone; the two damaged records are
     * quarantined and answer as failed jobs */
    assert_int_equal(smd_store_count(s), 3);
    assert_int_equal(smd_store_quarantined(s), 2);
    const char *damaged[] = {"ffffffffffffffffffffffffffffffff", "eeeeeeeeeeeeeeeeeeeeeeeeeeeeeeee"};
    for (int k = 0; k < 2; k++) {
        smd_job *jd = smd_store_get(s, damaged[k]);
        assert_non_null(jd);
        assert_int_equal(jd->state, SM_JOB_FAILED);
        assert_non_null(strstr(jd->message, "record damaged"));
    }
    ja = smd_store_get(s, a);
    assert_non_null(ja);
    assert_int_equal(ja->state, SM_JOB_ACCEPTED);
    assert_int_equal(ja->nevents, 1);
    struct stat st;
    snprintf(p, sizeof p, "%s/results.tmp", dir);
    assert_int_equal(stat(p, &st), -1);
    snprintf(p, sizeof p, "%s/results", dir);
    assert_int_equal(stat(p, &st), -1);
    snprintf(p, sizeof p, "%s/events.ndjson", dir);
    assert_int_equal(stat(p, &st), 0);
    assert_true((uint64_t)st.st_size == smd_job_event_offset(ja, 2)); /* torn line cut */
    assert_int_equal(count_lines(p), 1);
    snprintf(p, sizeof p, "%s/jobs/not-a-job", f->spool);
    assert_int_equal(stat(p, &st), 0); /* not ours: left alone */
    snprintf(p, sizeof p, "%s/tmp/up-half", f->spool);
    assert_int_equal(stat(p, &st), -1);
    snprintf(p, sizeof p, "%s/trash/old", f->spool);
    assert_int_equal(stat(p, &st), -1);
    /* appending after the repair continues the numbering */
    sm_event ev;
    sm_event_init(&ev, SM_EVENT_STARTED);
    ev.attempt = 2;
    assert_int_equal(smd_store_append_event(s, ja, &ev, &err), SM_OK);
    assert_int_equal(ev.seq, 2);
    smd_store_close(s);
}

static void test_unlink_and_trash(void **state)
{
    fixture *f = *state;
    smd_store *s;
    sm_error err;
    const char *a = "abcdefabcdefabcdefabcdefabcdefab";
    assert_int_equal(smd_store_open(f->spool, &f->log, &s, &err), SM_OK);
    smd_job *ja = commit(f, s, a, NULL);
    smd_job_ref(ja); /* as a follower would */
    char trash[512], dir[512];
    assert_int_equal(smd_store_path(s, a, "", dir, sizeof dir), 0);
    assert_int_equal(smd_store_trash(s, a, trash, sizeof trash), 0);
    smd_store_unlink(s, ja);
    assert_null(smd_store_get(s, a));
    assert_int_equal(smd_store_count(s), 0);
    assert_true(ja->removed);
    assert_string_equal(ja->id, a); /* still valid for its holder */
    struct stat st;
    assert_int_equal(stat(dir, &st), -1);
    assert_int_equal(stat(trash, &st), 0);
    assert_non_null(strstr(trash, "/trash/"));
    assert_int_equal(smd_rmtree(trash), 0);
    smd_job_unref(ja); /* frees it (ASan checks) */
    /* paths are only built for valid ids */
    assert_int_equal(smd_store_path(s, "../x", "status.json", dir, sizeof dir), -1);
    assert_int_equal(smd_store_trash(s, "../../etc", trash, sizeof trash), -1);
    smd_store_close(s);
}

/* The summary reader of a restart (smd_store_read_summary) and the
 * record's finalEventAt: read back, bounded. */
static void test_summary_and_final_event(void **state)
{
    fixture *f = *state;
    smd_store *s;
    sm_error err;
    assert_int_equal(smd_store_open(f->spool, &f->log, &s, &err), SM_OK);
    const char *id = "abcdefabcdefabcdefabcdefabcdefab";
    smd_job *job = commit(f, s, id, NULL);
    char p[600];
    sm_event ev;
    double when = 0;
    /* none, not JSON, not a finished run, a finished one */
    assert_int_equal(smd_store_read_summary(s, job, &ev, &when, &err), SM_ERR_IO);
    assert_int_equal(smd_store_path(s, id, "results", p, sizeof p), 0);
    assert_int_equal(smd_mkdirs(p, 0700), 0);
    assert_int_equal(smd_store_path(s, id, "results/summary.json", p, sizeof p), 0);
    assert_int_equal(smd_write_file_atomic(p, "{ torn", 6), 0);
    assert_int_equal(smd_store_read_summary(s, job, &ev, &when, &err), SM_ERR_FORMAT);
    static const char failed[] = "{\"status\": \"failed\", \"exit_code\": 3}";
    assert_int_equal(smd_write_file_atomic(p, failed, sizeof failed - 1), 0);
    assert_int_equal(smd_store_read_summary(s, job, &ev, &when, &err), SM_ERR_FORMAT);
    sm_result r;
    memset(&r, 0, sizeof r);
    r.stop = SM_STOP_STEP;
    r.iterations = 12;
    json_t *doc = sm_result_to_jansson(&r, NULL, 2);
    json_object_set_new(doc, "status", json_string("finished"));
    json_object_set_new(doc, "exit_code", json_integer(0));
    assert_int_equal(json_dump_file(doc, p, 0), 0);
    json_decref(doc);
    assert_int_equal(smd_store_read_summary(s, job, &ev, &when, &err), SM_OK);
    assert_int_equal(ev.type, SM_EVENT_FINISHED);
    assert_int_equal(ev.result.iterations, 12);
    assert_string_equal(ev.message, ""); /* no warnings */
    assert_true(when > 1.7e9);

    /* finalEventAt survives a reopen; the log ending there misses it */
    job->state = SM_JOB_FAILED;
    job->final_event_at = (int64_t)smd_job_event_offset(job, 2); /* after "accepted" */
    assert_int_equal(smd_store_save(s, job, &err), SM_OK);
    assert_true(smd_store_final_event_missing(s, job));
    smd_store_close(s);
    assert_int_equal(smd_store_open(f->spool, &f->log, &s, &err), SM_OK);
    job = smd_store_get(s, id);
    assert_non_null(job);
    assert_true(job->final_event_at > 0);
    assert_true(smd_store_final_event_missing(s, job));
    smd_store_close(s);
    /* out of its bounds: a damaged record, quarantined */
    char rec[700];
    snprintf(rec, sizeof rec, "%s/jobs/%s/status.json", f->spool, id);
    FILE *fp = fopen(rec, "r");
    assert_non_null(fp);
    char text[4096];
    size_t n = fread(text, 1, sizeof text - 1, fp);
    fclose(fp);
    text[n] = '\0';
    char *at = strstr(text, "\"finalEventAt\": ");
    assert_non_null(at);
    at += strlen("\"finalEventAt\": ");
    at[0] = '-'; /* a negative offset */
    assert_int_equal(smd_write_file_atomic(rec, text, strlen(text)), 0);
    assert_int_equal(smd_store_open(f->spool, &f->log, &s, &err), SM_OK);
    assert_int_equal(smd_store_quarantined(s), 1);
    smd_store_close(s);
}

/* A batch's model job: its record (members, and the dimension of its
 * targets) survives a reopen, successful as it was; so does a record
 * written before a model job carried a dimension (0, maxIter 0), while
 * an ordinary job with dimension 0 is still a damaged record. */
static void test_model_job_reopen(void **state)
{
    fixture *f = *state;
    smd_store *s;
    sm_error err;
    assert_int_equal(smd_store_open(f->spool, &f->log, &s, &err), SM_OK);
    const char *target = "11111111111111111111111111111111", *model = "22222222222222222222222222222222",
               *old = "33333333333333333333333333333333", *plain = "44444444444444444444444444444444";
    commit(f, s, target, NULL);
    const char ids[1][SMD_ID_LEN + 1] = {"11111111111111111111111111111111"};
    smd_job *m = commit(f, s, model, NULL);
    m->batch_model = 1;
    m->max_iter = 1;
    assert_int_equal(smd_job_set_members(m, ids, 1), 0);
    m->state = SM_JOB_SUCCESSFUL;
    m->progress = 100;
    m->finished = 1700000002;
    assert_int_equal(smd_store_save(s, m, &err), SM_OK);
    smd_job *o = commit(f, s, old, NULL);
    o->batch_model = 1;
    o->dim = 0;
    o->max_iter = 0;
    assert_int_equal(smd_job_set_members(o, ids, 1), 0);
    o->state = SM_JOB_SUCCESSFUL;
    o->finished = 1700000002;
    assert_int_equal(smd_store_save(s, o, &err), SM_OK);
    smd_job *p = commit(f, s, plain, NULL);
    p->dim = 0;
    assert_int_equal(smd_store_save(s, p, &err), SM_OK);
    smd_store_close(s);

    assert_int_equal(smd_store_open(f->spool, &f->log, &s, &err), SM_OK);
    assert_int_equal(smd_store_quarantined(s), 1); /* the plain job only */
    assert_int_equal(smd_store_get(s, plain)->state, SM_JOB_FAILED);
    const char *both[] = {model, old};
    for (int k = 0; k < 2; k++) {
        smd_job *j = smd_store_get(s, both[k]);
        assert_non_null(j);
        assert_int_equal(j->state, SM_JOB_SUCCESSFUL);
        assert_true(j->batch_model);
        assert_int_equal(j->nmembers, 1);
        assert_string_equal(j->members[0], target);
        assert_int_equal(j->dim, k == 0 ? 2 : 0);
    }
    smd_store_close(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_commit_and_reopen, setup, teardown),
        cmocka_unit_test_setup_teardown(test_crash_leftovers, setup, teardown),
        cmocka_unit_test_setup_teardown(test_unlink_and_trash, setup, teardown),
        cmocka_unit_test_setup_teardown(test_summary_and_final_event, setup, teardown),
        cmocka_unit_test_setup_teardown(test_model_job_reopen, setup, teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
