/* The PostgreSQL backend against a real PostgreSQL 15 (initdb + pg_ctl by
 * tests/lib/pg.sh into a temporary folder, unix socket only, stopped at
 * exit): concurrent migrations, submission and idempotency keys, claims
 * racing from three processes, leases (renewal, expiry, requeue with the
 * next attempt, failure past the attempt limit), fencing by lease token,
 * events (unique gap-free seq under concurrent appends, NOTIFY), cancel
 * (queued and running), chunked blobs, and a database restart. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>
#include <cmocka.h>

#include <libpq-fe.h>

#include "store/pg/smd_pg.h"

static char pgdir[128];
static char conninfo[512];

static void pg_cmd(const char *what)
{
    char cmd[512];
    snprintf(cmd, sizeof cmd, "bash tests/lib/pg.sh %s %s", what, pgdir);
    FILE *p = popen(cmd, "r");
    if (!p)
        return;
    char line[512] = "";
    if (fgets(line, sizeof line, p) && strcmp(what, "start") == 0) {
        line[strcspn(line, "\n")] = '\0';
        snprintf(conninfo, sizeof conninfo, "%s", line);
    }
    pclose(p);
}

static pid_t main_pid;

static void stop_pg(void)
{
    if (getpid() != main_pid || !pgdir[0])
        return;
    pg_cmd("stop");
    char cmd[256];
    snprintf(cmd, sizeof cmd, "rm -rf %s", pgdir);
    if (system(cmd) != 0)
        fprintf(stderr, "# could not remove %s\n", pgdir);
}

static smd_pg *connect_db(void)
{
    smd_pg *db = NULL;
    sm_error err;
    sm_error_clear(&err);
    if (smd_pg_connect(conninfo, NULL, "test", &db, &err) != SM_OK)
        fail_msg("connect: %s", err.msg);
    return db;
}

/* Runs sql on a fresh connection, returns the first value as a number. */
static long long scalar(const char *sql)
{
    PGconn *c = PQconnectdb(conninfo);
    PGresult *r = PQexec(c, sql);
    long long v = PQresultStatus(r) == PGRES_TUPLES_OK && PQntuples(r) > 0
                      ? strtoll(PQgetvalue(r, 0, 0), NULL, 10) : -1;
    PQclear(r);
    PQfinish(c);
    return v;
}

static void exec_sql(const char *sql)
{
    PGconn *c = PQconnectdb(conninfo);
    PGresult *r = PQexec(c, sql);
    assert_true(PQresultStatus(r) == PGRES_COMMAND_OK || PQresultStatus(r) == PGRES_TUPLES_OK);
    PQclear(r);
    PQfinish(c);
}

static void submit(smd_pg *db, const char *id, const char *owner, const char *key, int *created,
                   char existing[SMD_ID_LEN + 1])
{
    sm_error err;
    smd_pg_job job = {id, owner, key, 42, "{\"params\":{}}", "{\"type\":\"accepted\"}"};
    assert_int_equal(smd_pg_submit(db, &job, created, existing, &err), SM_OK);
}

static void fresh_jobs(void)
{
    exec_sql("TRUNCATE smd_jobs CASCADE");
}

/* Three processes migrate the empty database at once: one schema. */
static void test_migrate_concurrently(void **state)
{
    (void)state;
    for (int i = 0; i < 3; i++) {
        if (fork() == 0) {
            smd_pg *db = connect_db();
            sm_error err;
            int v = 0;
            int ok = smd_pg_migrate(db, &v, &err) == SM_OK && v == SMD_PG_SCHEMA_VERSION;
            if (!ok)
                fprintf(stderr, "# migrate: %s\n", err.msg);
            smd_pg_close(db);
            _exit(ok ? 0 : 1);
        }
    }
    for (int i = 0; i < 3; i++) {
        int status;
        wait(&status);
        assert_true(WIFEXITED(status) && WEXITSTATUS(status) == 0);
    }
    assert_int_equal(scalar("SELECT count(*) FROM smd_schema"), SMD_PG_SCHEMA_VERSION);
    assert_int_equal(scalar("SELECT max(version) FROM smd_schema"), SMD_PG_SCHEMA_VERSION);
    /* a database from a newer program is refused */
    exec_sql("INSERT INTO smd_schema (version) VALUES (99)");
    smd_pg *db = connect_db();
    sm_error err;
    assert_int_equal(smd_pg_migrate(db, NULL, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "schema version 99 is newer"));
    smd_pg_close(db);
    exec_sql("DELETE FROM smd_schema WHERE version = 99");
}

static void test_submit_idempotency(void **state)
{
    (void)state;
    fresh_jobs();
    smd_pg *db = connect_db();
    int created;
    char existing[SMD_ID_LEN + 1] = "";
    submit(db, "job-a", "t1", "key-1", &created, existing);
    assert_int_equal(created, 1);
    submit(db, "job-b", "t1", "key-1", &created, existing); /* retry, another API node */
    assert_int_equal(created, 0);
    assert_string_equal(existing, "job-a");
    submit(db, "job-c", "t2", "key-1", &created, existing); /* another tenant's key */
    assert_int_equal(created, 1);
    submit(db, "job-d", "t1", "", &created, existing);
    submit(db, "job-e", "t1", "", &created, existing); /* no key: always new */
    assert_int_equal(created, 1);
    assert_int_equal(scalar("SELECT count(*) FROM smd_jobs"), 4);
    assert_int_equal(scalar("SELECT seq FROM smd_events WHERE job = 'job-a'"), 1);
    int64_t q, l;
    sm_error err;
    assert_int_equal(smd_pg_depth(db, &q, &l, &err), SM_OK);
    assert_int_equal(q, 4);
    assert_int_equal(l, 0);
    smd_pg_close(db);
}

/* 200 jobs, three processes claiming as fast as they can: every job is
 * claimed exactly once, at attempt 1. */
static void test_claims_race(void **state)
{
    (void)state;
    fresh_jobs();
    smd_pg *db = connect_db();
    for (int i = 0; i < 200; i++) {
        char id[32], existing[SMD_ID_LEN + 1];
        int created;
        snprintf(id, sizeof id, "race-%03d", i);
        submit(db, id, "", "", &created, existing);
    }
    int fds[3][2];
    for (int w = 0; w < 3; w++) {
        assert_int_equal(pipe(fds[w]), 0);
        if (fork() == 0) {
            smd_pg *mine = connect_db();
            char node[32];
            snprintf(node, sizeof node, "node-%d", w);
            smd_pg_lease l;
            int got = 1;
            sm_error err;
            while (smd_pg_claim(mine, node, 60, &l, &got, &err) == SM_OK && got)
                dprintf(fds[w][1], "%s %d\n", l.id, l.attempt);
            smd_pg_close(mine);
            _exit(0);
        }
        close(fds[w][1]);
    }
    int seen[200] = {0}, per_node[3] = {0};
    for (int w = 0; w < 3; w++) {
        FILE *f = fdopen(fds[w][0], "r");
        int n, attempt;
        while (fscanf(f, "race-%d %d\n", &n, &attempt) == 2) {
            assert_true(n >= 0 && n < 200);
            assert_int_equal(attempt, 1);
            seen[n]++;
            per_node[w]++;
        }
        fclose(f);
    }
    for (int w = 0; w < 3; w++) {
        int status;
        wait(&status);
        assert_true(WIFEXITED(status) && WEXITSTATUS(status) == 0);
    }
    for (int i = 0; i < 200; i++)
        assert_int_equal(seen[i], 1);
    printf("# claims per node: %d %d %d\n", per_node[0], per_node[1], per_node[2]);
    assert_int_equal(scalar("SELECT count(DISTINCT lease_token) FROM smd_jobs WHERE state = 'running'"), 200);
    smd_pg_close(db);
}

static void sleep_s(double s)
{
    struct timespec ts = {(time_t)s, (long)((s - (time_t)s) * 1e9)};
    nanosleep(&ts, NULL);
}

/* A lease that expires: renewal and results refused (fenced), requeued,
 * the next claim is attempt 2 with a new token; the old token stays
 * fenced after the new run ends. */
static void test_lease_expiry_and_fencing(void **state)
{
    (void)state;
    fresh_jobs();
    smd_pg *db = connect_db();
    sm_error err;
    int created, got, held;
    char existing[SMD_ID_LEN + 1];
    submit(db, "lease-1", "", "", &created, existing);
    smd_pg_lease a, b;
    assert_int_equal(smd_pg_claim(db, "node-a", 0.3, &a, &got, &err), SM_OK);
    assert_int_equal(got, 1);
    assert_int_equal(a.attempt, 1);
    assert_int_equal(smd_pg_renew(db, &a, 0.3, &held, &err), SM_OK);
    assert_int_equal(held, 1);
    int64_t seq;
    assert_int_equal(smd_pg_append_event(db, "lease-1", &a, "{\"type\":\"started\"}", &seq, &err), SM_OK);
    assert_int_equal(seq, 2);
    sleep_s(0.5);
    assert_int_equal(smd_pg_renew(db, &a, 0.3, &held, &err), SM_OK);
    assert_int_equal(held, 0); /* expired: fenced before anyone requeues */
    assert_int_equal(smd_pg_append_event(db, "lease-1", &a, "{\"type\":\"progress\"}", &seq, &err), SM_OK);
    assert_int_equal(seq, 0);
    size_t requeued, failed;
    assert_int_equal(smd_pg_expire(db, 3, &requeued, &failed, &err), SM_OK);
    assert_int_equal(requeued, 1);
    assert_int_equal(failed, 0);
    assert_int_equal(smd_pg_claim(db, "node-b", 30, &b, &got, &err), SM_OK);
    assert_int_equal(got, 1);
    assert_int_equal(b.attempt, 2);
    assert_true(b.token != a.token);
    assert_int_equal(smd_pg_complete(db, &a, SM_JOB_SUCCESSFUL, "", "{\"type\":\"finished\"}", &held, &err), SM_OK);
    assert_int_equal(held, 0); /* the lost node does not publish */
    int gotblob = 0;
    assert_int_equal(smd_pg_blob_put(db, "lease-1", "result.mesh", &a, "/etc/hostname", &gotblob, &err), SM_OK);
    assert_int_equal(gotblob, 0);
    assert_int_equal(smd_pg_complete(db, &b, SM_JOB_SUCCESSFUL, "", "{\"type\":\"finished\"}", &held, &err), SM_OK);
    assert_int_equal(held, 1);
    sm_job_state st;
    int attempt, found;
    assert_int_equal(smd_pg_state(db, "lease-1", &st, &attempt, &found, &err), SM_OK);
    assert_int_equal(st, SM_JOB_SUCCESSFUL);
    assert_int_equal(attempt, 2);
    assert_int_equal(scalar("SELECT count(*) FROM smd_blobs"), 0);
    assert_int_equal(scalar("SELECT max(seq) FROM smd_events WHERE job = 'lease-1'"), 3);
    assert_int_equal(scalar("SELECT count(*) FROM smd_events WHERE job = 'lease-1' AND "
                            "payload->>'type' = 'finished' AND (payload->>'seq')::int = 3"), 1);
    smd_pg_close(db);
}

/* Past --max-attempts the job fails with the reason and a "failed" event. */
static void test_max_attempts(void **state)
{
    (void)state;
    fresh_jobs();
    smd_pg *db = connect_db();
    sm_error err;
    int created, got;
    char existing[SMD_ID_LEN + 1];
    submit(db, "doomed", "", "", &created, existing);
    size_t requeued = 0, failed = 0;
    for (int i = 1; i <= 2; i++) {
        smd_pg_lease l;
        assert_int_equal(smd_pg_claim(db, "node-x", 0.05, &l, &got, &err), SM_OK);
        assert_int_equal(got, 1);
        assert_int_equal(l.attempt, i);
        sleep_s(0.15);
        assert_int_equal(smd_pg_expire(db, 2, &requeued, &failed, &err), SM_OK);
    }
    assert_int_equal(requeued, 0);
    assert_int_equal(failed, 1);
    sm_job_state st;
    int attempt, found;
    assert_int_equal(smd_pg_state(db, "doomed", &st, &attempt, &found, &err), SM_OK);
    assert_int_equal(st, SM_JOB_FAILED);
    assert_int_equal(attempt, 2);
    assert_int_equal(scalar("SELECT count(*) FROM smd_jobs WHERE message LIKE '%lost%--max-attempts 2%'"), 1);
    assert_int_equal(scalar("SELECT count(*) FROM smd_events WHERE job = 'doomed' AND "
                            "payload->>'type' = 'failed' AND payload->>'message' LIKE '%node-x%'"), 1);
    smd_pg_lease none;
    assert_int_equal(smd_pg_claim(db, "node-x", 1, &none, &got, &err), SM_OK);
    assert_int_equal(got, 0);
    smd_pg_close(db);
}

/* 3 x 50 appends at once on one job, a listener on another connection:
 * seq 1..151 each once, and the notifications arrive. */
static void test_events_concurrent(void **state)
{
    (void)state;
    fresh_jobs();
    smd_pg *db = connect_db();
    smd_pg *listener = connect_db();
    sm_error err;
    assert_int_equal(smd_pg_listen(listener, SMD_PG_CHANNEL_EVENTS, &err), SM_OK);
    int created;
    char existing[SMD_ID_LEN + 1];
    submit(db, "ev", "", "", &created, existing);
    for (int w = 0; w < 3; w++)
        if (fork() == 0) {
            smd_pg *mine = connect_db();
            int64_t seq;
            int ok = 1;
            for (int i = 0; i < 50 && ok; i++)
                ok = smd_pg_append_event(mine, "ev", NULL, "{\"type\":\"progress\"}", &seq,
                                         &err) == SM_OK && seq > 1;
            smd_pg_close(mine);
            _exit(ok ? 0 : 1);
        }
    for (int w = 0; w < 3; w++) {
        int status;
        wait(&status);
        assert_true(WIFEXITED(status) && WEXITSTATUS(status) == 0);
    }
    assert_int_equal(scalar("SELECT count(DISTINCT seq) FROM smd_events WHERE job = 'ev'"), 151);
    assert_int_equal(scalar("SELECT max(seq) FROM smd_events WHERE job = 'ev'"), 151);
    assert_int_equal(scalar("SELECT count(*) FROM smd_events WHERE job = 'ev' AND (payload->>'seq')::int = seq"), 151);
    char channel[64], payload[128];
    int n = 0, last = 0;
    while (smd_pg_wait(listener, 2, channel, sizeof channel, payload, sizeof payload, &err) == 1) {
        assert_string_equal(channel, SMD_PG_CHANNEL_EVENTS);
        assert_true(strncmp(payload, "ev ", 3) == 0);
        last = atoi(payload + 3);
        if (++n == 151)
            break;
    }
    assert_int_equal(n, 151); /* the accepted event's too */
    assert_true(last >= 1 && last <= 151);
    smd_pg_close(listener);
    smd_pg_close(db);
}

static void test_cancel(void **state)
{
    (void)state;
    fresh_jobs();
    smd_pg *db = connect_db();
    smd_pg *worker = connect_db();
    sm_error err;
    assert_int_equal(smd_pg_listen(worker, SMD_PG_CHANNEL_CANCEL, &err), SM_OK);
    int created, got, was, held;
    char existing[SMD_ID_LEN + 1];
    submit(db, "run-c", "", "", &created, existing);
    submit(db, "queued-c", "", "", &created, existing);
    smd_pg_lease l;
    assert_int_equal(smd_pg_claim(worker, "node-w", 30, &l, &got, &err), SM_OK);
    assert_string_equal(l.id, "run-c");
    assert_int_equal(smd_pg_cancel(db, "queued-c", &was, &err), SM_OK);
    assert_int_equal(was, 1);
    assert_int_equal(scalar("SELECT count(*) FROM smd_jobs WHERE id = 'queued-c' AND state = 'dismissed'"), 1);
    assert_int_equal(scalar("SELECT count(*) FROM smd_events WHERE job = 'queued-c' AND payload->>'type' = 'cancelled'"), 1);
    assert_int_equal(smd_pg_cancel(db, "run-c", &was, &err), SM_OK);
    assert_int_equal(was, 2);
    char channel[64], payload[128];
    assert_int_equal(smd_pg_wait(worker, 5, channel, sizeof channel, payload, sizeof payload, &err), 1);
    assert_string_equal(channel, SMD_PG_CHANNEL_CANCEL);
    assert_string_equal(payload, "run-c");
    assert_int_equal(smd_pg_renew(worker, &l, 30, &held, &err), SM_OK);
    assert_int_equal(held, 2); /* cancel requested: the run must stop */
    assert_int_equal(smd_pg_complete(worker, &l, SM_JOB_DISMISSED, "stopped", "{\"type\":\"cancelled\"}", &held, &err), SM_OK);
    assert_int_equal(held, 1);
    assert_int_equal(scalar("SELECT count(*) FROM smd_jobs WHERE id = 'run-c' AND state = 'dismissed'"), 1);
    assert_int_equal(smd_pg_cancel(db, "run-c", &was, &err), SM_OK);
    assert_int_equal(was, 0); /* final */
    smd_pg_close(worker);
    smd_pg_close(db);
}

/* 1 MiB + 17 bytes: 5 chunks in, the same bytes out. */
static void test_blobs(void **state)
{
    (void)state;
    fresh_jobs();
    smd_pg *db = connect_db();
    sm_error err;
    int created, held, found;
    char existing[SMD_ID_LEN + 1];
    submit(db, "blob", "", "", &created, existing);
    char in[] = "/tmp/sm-test-pg-in-XXXXXX", out[64];
    int fd = mkstemp(in);
    assert_true(fd >= 0);
    size_t size = (1 << 20) + 17;
    unsigned char *data = malloc(size);
    for (size_t i = 0; i < size; i++)
        data[i] = (unsigned char)(i * 2654435761u >> 13);
    assert_int_equal(write(fd, data, size), (ssize_t)size);
    close(fd);
    assert_int_equal(smd_pg_blob_put(db, "blob", "template.mesh", NULL, in, &held, &err), SM_OK);
    assert_int_equal(held, 1);
    assert_int_equal(smd_pg_blob_put(db, "blob", "template.mesh", NULL, in, &held, &err), SM_OK);
    assert_int_equal(scalar("SELECT count(*) FROM smd_blobs WHERE job = 'blob'"), 5);
    assert_int_equal(scalar("SELECT max(length(data)) FROM smd_blobs"), SMD_PG_CHUNK);
    snprintf(out, sizeof out, "%s.out", in);
    assert_int_equal(smd_pg_blob_get(db, "blob", "template.mesh", out, &found, &err), SM_OK);
    assert_int_equal(found, 1);
    FILE *f = fopen(out, "rb");
    unsigned char *back = malloc(size + 1);
    assert_int_equal(fread(back, 1, size + 1, f), size);
    fclose(f);
    assert_memory_equal(back, data, size);
    assert_int_equal(smd_pg_blob_get(db, "blob", "nothing", out, &found, &err), SM_OK);
    assert_int_equal(found, 0);
    assert_int_equal(access(out, F_OK), -1);
    assert_int_equal(smd_pg_blob_put(db, "no-such-job", "x", NULL, in, &held, &err), SM_OK);
    assert_int_equal(held, 0);
    unlink(in);
    free(data);
    free(back);
    smd_pg_close(db);
}

/* The database crashes and comes back: queries fail meanwhile, a
 * reconnect finds every job as it was. */
static void test_restart(void **state)
{
    (void)state;
    fresh_jobs();
    smd_pg *db = connect_db();
    sm_error err;
    int created, got;
    char existing[SMD_ID_LEN + 1];
    submit(db, "keep-q", "", "", &created, existing);
    submit(db, "keep-r", "", "", &created, existing);
    smd_pg_lease l;
    assert_int_equal(smd_pg_claim(db, "node", 60, &l, &got, &err), SM_OK);
    pg_cmd("kill");
    assert_int_equal(smd_pg_ping(db, &err), SM_ERR_IO);
    assert_int_equal(smd_pg_connected(db), 0);
    assert_int_equal(smd_pg_reconnect(db, &err), SM_ERR_IO);
    pg_cmd("start");
    assert_int_equal(smd_pg_reconnect(db, &err), SM_OK);
    assert_int_equal(smd_pg_ping(db, &err), SM_OK);
    int64_t q, r;
    assert_int_equal(smd_pg_depth(db, &q, &r, &err), SM_OK);
    assert_int_equal(q, 1);
    assert_int_equal(r, 1);
    int held;
    assert_int_equal(smd_pg_renew(db, &l, 60, &held, &err), SM_OK);
    assert_int_equal(held, 1);
    smd_pg_close(db);
}

static void test_password_file(void **state)
{
    (void)state;
    smd_pg *db = NULL;
    sm_error err;
    assert_int_equal(smd_pg_connect(conninfo, "/nonexistent/pw", "t", &db, &err), SM_ERR_IO);
    assert_non_null(strstr(err.msg, "--database-password-file /nonexistent/pw"));
    char pw[] = "/tmp/sm-test-pg-pw-XXXXXX";
    int fd = mkstemp(pw);
    assert_int_equal(write(fd, "secret\n", 7), 7);
    close(fd);
    /* trust authentication: the password is sent only if asked; it connects */
    assert_int_equal(smd_pg_connect(conninfo, pw, "t", &db, &err), SM_OK);
    smd_pg_close(db);
    unlink(pw);
    assert_int_equal(smd_pg_connect("host=/nonexistent dbname=x", NULL, "t", &db, &err), SM_ERR_IO);
    assert_non_null(strstr(err.msg, "database: connect:"));
}

int main(void)
{
    main_pid = getpid();
    snprintf(pgdir, sizeof pgdir, "/tmp/sm-test-pg-XXXXXX");
    if (!mkdtemp(pgdir)) {
        printf("not ok 1 - temporary folder\n");
        return 1;
    }
    atexit(stop_pg);
    pg_cmd("start");
    if (!conninfo[0]) {
        printf("not ok 1 - PostgreSQL did not start (tests/lib/pg.sh start %s)\n", pgdir);
        return 1;
    }
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_migrate_concurrently),
        cmocka_unit_test(test_submit_idempotency),
        cmocka_unit_test(test_claims_race),
        cmocka_unit_test(test_lease_expiry_and_fencing),
        cmocka_unit_test(test_max_attempts),
        cmocka_unit_test(test_events_concurrent),
        cmocka_unit_test(test_cancel),
        cmocka_unit_test(test_blobs),
        cmocka_unit_test(test_password_file),
        cmocka_unit_test(test_restart),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
