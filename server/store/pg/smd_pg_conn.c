/* The connection, the query helpers, the migrations and LISTEN/NOTIFY of
 * the PostgreSQL backend (see smd_pg.h). */
#include "store/pg/smd_pg_int.h"

#include <errno.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Held by the node applying migrations (any constant: ours). */
#define MIGRATION_LOCK 0x736d64 /* "smd" */

static const char *const migrations[SMD_PG_SCHEMA_VERSION] = {
    /* 1: jobs, events, blobs */
    "CREATE TABLE smd_jobs ("
    " id text PRIMARY KEY,"
    " ord bigint GENERATED ALWAYS AS IDENTITY,"
    " owner text NOT NULL DEFAULT '',"
    " idempotency_key text,"
    " request_hash numeric(20) NOT NULL DEFAULT 0,"
    " state text NOT NULL CHECK (state IN ('accepted','running','successful','failed','dismissed')),"
    " message text NOT NULL DEFAULT '',"
    " params jsonb NOT NULL,"
    " dim integer NOT NULL DEFAULT 0, max_iter integer NOT NULL DEFAULT 0,"
    " tol_boundary float8 NOT NULL DEFAULT 0,"
    " attempt integer NOT NULL DEFAULT 0,"
    " progress integer NOT NULL DEFAULT 0,"
    " nevents bigint NOT NULL DEFAULT 0,"
    " lease_owner text, lease_expires timestamptz, lease_token bigint,"
    " cancel_requested boolean NOT NULL DEFAULT false,"
    " created timestamptz NOT NULL DEFAULT now(), started timestamptz, finished timestamptz,"
    " updated timestamptz NOT NULL DEFAULT now(),"
    " UNIQUE (owner, idempotency_key));"
    "CREATE INDEX smd_jobs_queued ON smd_jobs (ord) WHERE state = 'accepted';"
    "CREATE INDEX smd_jobs_leases ON smd_jobs (lease_expires) WHERE state = 'running';"
    "CREATE INDEX smd_jobs_finished ON smd_jobs (finished) WHERE finished IS NOT NULL;"
    "CREATE SEQUENCE smd_lease_tokens;"
    "CREATE TABLE smd_events ("
    " job text NOT NULL REFERENCES smd_jobs (id) ON DELETE CASCADE,"
    " seq bigint NOT NULL CHECK (seq >= 1),"
    " payload jsonb NOT NULL,"
    " PRIMARY KEY (job, seq));"
    "CREATE TABLE smd_blobs ("
    " job text NOT NULL REFERENCES smd_jobs (id) ON DELETE CASCADE,"
    " name text NOT NULL,"
    " chunk integer NOT NULL CHECK (chunk >= 0),"
    " data bytea NOT NULL,"
    " PRIMARY KEY (job, name, chunk));",
    /* 2: batches (server/api/smd_batches.h): a model job lists its members */
    "ALTER TABLE smd_jobs ADD COLUMN members text[];",
    /* 3: the job's name (part "name"), shown in lists and status */
    "ALTER TABLE smd_jobs ADD COLUMN name text NOT NULL DEFAULT '';",
};

static const char *const state_names[] = {"accepted", "running", "successful", "failed",
                                          "dismissed"};

const char *smd_pg_state_name(sm_job_state s)
{
    return (unsigned)s < 5 ? state_names[s] : "failed";
}

int smd_pg_state_parse(const char *name, sm_job_state *out)
{
    for (int i = 0; i < 5; i++)
        if (strcmp(name, state_names[i]) == 0) {
            *out = (sm_job_state)i;
            return 0;
        }
    return -1;
}

/* libpq's message without its trailing newline. */
static sm_status db_error(smd_pg *db, const char *what, const PGresult *r, sm_error *err)
{
    const char *m = r ? PQresultErrorMessage(r) : "";
    if (!m[0])
        m = db->conn ? PQerrorMessage(db->conn) : "no connection";
    int n = (int)strcspn(m, "\n");
    return sm_error_set(err, SM_ERR_IO, "database: %s: %.*s", what, n, m);
}

PGresult *smd_pg_exec(smd_pg *db, const char *what, const char *sql, int n,
                      const char *const *values, sm_error *err)
{
    PGresult *r = PQexecParams(db->conn, sql, n, NULL, values, NULL, NULL, 0);
    ExecStatusType st = PQresultStatus(r);
    if (st == PGRES_COMMAND_OK || st == PGRES_TUPLES_OK)
        return r;
    /* no SQLSTATE (the client saw the socket fail), connection
     * exceptions (08) and operator intervention (57P: shutdown) */
    const char *code = r ? PQresultErrorField(r, PG_DIAG_SQLSTATE) : NULL;
    if (PQstatus(db->conn) != CONNECTION_OK || !code || strncmp(code, "08", 2) == 0 ||
        strncmp(code, "57P", 3) == 0)
        db->lost = 1;
    /* 57014: statement_timeout (query_canceled); 55P03: lock_timeout
     * (lock_not_available) */
    db->timed_out = code && (strcmp(code, "57014") == 0 || strcmp(code, "55P03") == 0);
    db_error(db, what, r, err);
    PQclear(r);
    return NULL;
}

sm_status smd_pg_run(smd_pg *db, const char *what, const char *sql, int n,
                     const char *const *values, sm_error *err)
{
    PGresult *r = smd_pg_exec(db, what, sql, n, values, err);
    if (!r)
        return SM_ERR_IO;
    PQclear(r);
    return SM_OK;
}

sm_status smd_pg_begin(smd_pg *db, sm_error *err)
{
    return smd_pg_run(db, "BEGIN", "BEGIN", 0, NULL, err);
}

sm_status smd_pg_commit(smd_pg *db, sm_error *err)
{
    return smd_pg_run(db, "COMMIT", "COMMIT", 0, NULL, err);
}

void smd_pg_rollback(smd_pg *db)
{
    if (PQtransactionStatus(db->conn) != PQTRANS_IDLE)
        PQclear(PQexec(db->conn, "ROLLBACK"));
}

/* The first line of path, into a new string. */
static sm_status read_password(const char *path, char **out, sm_error *err)
{
    FILE *f = fopen(path, "r");
    if (!f)
        return sm_error_set(err, SM_ERR_IO, "--database-password-file %s: %s", path,
                            strerror(errno));
    char line[1024];
    int ok = fgets(line, sizeof line, f) != NULL;
    fclose(f);
    if (!ok)
        return sm_error_set(err, SM_ERR_IO, "--database-password-file %s: empty", path);
    line[strcspn(line, "\r\n")] = '\0';
    *out = strdup(line);
    return *out ? SM_OK : sm_error_set(err, SM_ERR_NOMEM, "out of memory");
}

/* Server notices ("relation already exists, skipping") are not ours to
 * print: the daemon's stderr carries JSON lines only. */
static void drop_notice(void *arg, const char *message)
{
    (void)arg;
    (void)message;
}

/* SET of the session's timeouts (integers in ms: no text from outside). */
static sm_status apply_timeouts(smd_pg *db, sm_error *err)
{
    static const char *const names[3] = {"statement_timeout", "lock_timeout",
                                         "idle_in_transaction_session_timeout"};
    for (int i = 0; i < 3; i++) {
        if (db->timeouts_ms[i] <= 0)
            continue;
        char sql[96];
        snprintf(sql, sizeof sql, "SET %s = %ld", names[i], db->timeouts_ms[i]);
        if (smd_pg_run(db, "session settings", sql, 0, NULL, err) != SM_OK)
            return SM_ERR_IO;
    }
    return SM_OK;
}

sm_status smd_pg_set_timeouts(smd_pg *db, double statement, double lock, double idle,
                              sm_error *err)
{
    const double s[3] = {statement, lock, idle};
    for (int i = 0; i < 3; i++) /* at least 1 ms; the config bounds them to an hour */
        db->timeouts_ms[i] = s[i] <= 0 ? 0 : s[i] >= 86400 ? 86400000L : (long)(s[i] * 1000) + (s[i] * 1000 < 1);
    return apply_timeouts(db, err);
}

int smd_pg_timed_out(const smd_pg *db)
{
    return db && db->timed_out;
}

static sm_status open_conn(smd_pg *db, sm_error *err)
{
    const char *keys[] = {"application_name", "dbname", "password", NULL};
    const char *vals[] = {db->app, db->url, db->password, NULL};
    if (!db->password)
        keys[2] = NULL;
    db->conn = PQconnectdbParams(keys, vals, 1);
    if (!db->conn || PQstatus(db->conn) != CONNECTION_OK)
        return db_error(db, "connect", NULL, err);
    PQsetNoticeProcessor(db->conn, drop_notice, NULL);
    if (apply_timeouts(db, err) != SM_OK)
        return SM_ERR_IO;
    for (int i = 0; i < db->nlistens; i++) {
        char sql[64];
        snprintf(sql, sizeof sql, "LISTEN %s", db->listens[i]);
        if (smd_pg_run(db, "LISTEN", sql, 0, NULL, err) != SM_OK)
            return SM_ERR_IO;
    }
    return SM_OK;
}

sm_status smd_pg_connect(const char *url, const char *password_file, const char *app,
                         smd_pg **out, sm_error *err)
{
    *out = NULL;
    smd_pg *db = calloc(1, sizeof *db);
    if (!db || !(db->url = strdup(url))) {
        free(db);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    }
    snprintf(db->app, sizeof db->app, "%s", app ? app : "shapematchd");
    sm_status st = SM_OK;
    if (password_file && password_file[0])
        st = read_password(password_file, &db->password, err);
    if (st == SM_OK)
        st = open_conn(db, err);
    if (st != SM_OK) {
        smd_pg_close(db);
        return st;
    }
    *out = db;
    return SM_OK;
}

void smd_pg_close(smd_pg *db)
{
    if (!db)
        return;
    if (db->conn)
        PQfinish(db->conn);
    free(db->url);
    if (db->password) {
        memset(db->password, 0, strlen(db->password));
        free(db->password);
    }
    free(db);
}

int smd_pg_connected(const smd_pg *db)
{
    return db && db->conn && !db->lost && PQstatus(db->conn) == CONNECTION_OK;
}

sm_status smd_pg_reconnect(smd_pg *db, sm_error *err)
{
    if (db->conn)
        PQfinish(db->conn);
    db->conn = NULL;
    db->lost = 0;
    return open_conn(db, err);
}

sm_status smd_pg_ping(smd_pg *db, sm_error *err)
{
    return smd_pg_run(db, "ping", "SELECT 1", 0, NULL, err);
}

static sm_status schema_version(smd_pg *db, int *version, sm_error *err)
{
    if (smd_pg_run(db, "migrate", "CREATE TABLE IF NOT EXISTS smd_schema (version integer PRIMARY KEY,"
                   " applied timestamptz NOT NULL DEFAULT now())", 0, NULL, err) != SM_OK)
        return SM_ERR_IO;
    PGresult *r = smd_pg_exec(db, "migrate", "SELECT coalesce(max(version), 0) FROM smd_schema",
                              0, NULL, err);
    if (!r)
        return SM_ERR_IO;
    *version = atoi(PQgetvalue(r, 0, 0));
    PQclear(r);
    return SM_OK;
}

static sm_status apply_migration(smd_pg *db, int to, sm_error *err)
{
    char v[16];
    snprintf(v, sizeof v, "%d", to);
    const char *vals[] = {v};
    if (smd_pg_begin(db, err) != SM_OK)
        return SM_ERR_IO;
    PGresult *r = PQexec(db->conn, migrations[to - 1]);
    if (PQresultStatus(r) != PGRES_COMMAND_OK) {
        char what[32];
        snprintf(what, sizeof what, "migration %d", to);
        db_error(db, what, r, err);
        PQclear(r);
        smd_pg_rollback(db);
        return SM_ERR_IO;
    }
    PQclear(r);
    if (smd_pg_run(db, "migrate", "INSERT INTO smd_schema (version) VALUES ($1::integer)", 1, vals,
                   err) != SM_OK ||
        smd_pg_commit(db, err) != SM_OK) {
        smd_pg_rollback(db);
        return SM_ERR_IO;
    }
    return SM_OK;
}

sm_status smd_pg_migrate(smd_pg *db, int *version, sm_error *err)
{
    char lock[64];
    snprintf(lock, sizeof lock, "SELECT pg_advisory_lock(%d)", MIGRATION_LOCK);
    if (smd_pg_run(db, "migration lock", lock, 0, NULL, err) != SM_OK)
        return SM_ERR_IO;
    int v = 0;
    sm_status st = schema_version(db, &v, err);
    if (st == SM_OK && v > SMD_PG_SCHEMA_VERSION)
        st = sm_error_set(err, SM_ERR_INVALID,
                          "database: schema version %d is newer than this shapematchd's (%d): "
                          "upgrade the node", v, SMD_PG_SCHEMA_VERSION);
    for (; st == SM_OK && v < SMD_PG_SCHEMA_VERSION; v++)
        st = apply_migration(db, v + 1, err);
    snprintf(lock, sizeof lock, "SELECT pg_advisory_unlock(%d)", MIGRATION_LOCK);
    PQclear(PQexec(db->conn, lock));
    if (version)
        *version = v;
    return st;
}

sm_status smd_pg_listen(smd_pg *db, const char *channel, sm_error *err)
{
    if (db->nlistens == SMD_PG_LISTENS_MAX || strlen(channel) >= sizeof db->listens[0] ||
        strspn(channel, "abcdefghijklmnopqrstuvwxyz_") != strlen(channel))
        return sm_error_set(err, SM_ERR_INVALID, "database: cannot LISTEN on '%s'", channel);
    char sql[64];
    snprintf(sql, sizeof sql, "LISTEN %s", channel);
    if (smd_pg_run(db, "LISTEN", sql, 0, NULL, err) != SM_OK)
        return SM_ERR_IO;
    strcpy(db->listens[db->nlistens++], channel);
    return SM_OK;
}

static int take_notify(smd_pg *db, char *channel, size_t ccap, char *payload, size_t pcap)
{
    PGnotify *n = PQnotifies(db->conn);
    if (!n)
        return 0;
    snprintf(channel, ccap, "%s", n->relname);
    snprintf(payload, pcap, "%s", n->extra);
    PQfreemem(n);
    return 1;
}

int smd_pg_wait(smd_pg *db, double timeout, char *channel, size_t ccap, char *payload,
                size_t pcap, sm_error *err)
{
    if (take_notify(db, channel, ccap, payload, pcap))
        return 1;
    struct pollfd p = {PQsocket(db->conn), POLLIN, 0};
    if (p.fd < 0) {
        db_error(db, "wait", NULL, err);
        return -1;
    }
    int ms = timeout <= 0 ? 0 : (int)(timeout * 1000 + 0.5);
    if (poll(&p, 1, ms) < 0 && errno != EINTR) {
        sm_error_set(err, SM_ERR_IO, "database: wait: %s", strerror(errno));
        return -1;
    }
    if (!PQconsumeInput(db->conn) || PQstatus(db->conn) != CONNECTION_OK) {
        db_error(db, "wait", NULL, err);
        return -1;
    }
    return take_notify(db, channel, ccap, payload, pcap);
}
