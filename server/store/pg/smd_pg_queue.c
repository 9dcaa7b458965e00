/* Jobs, claims, leases and events in PostgreSQL (see smd_pg.h). */
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "store/pg/smd_pg_int.h"

/* A lease is held while its token matches and it has not expired: a
 * node past its expiry is fenced even before another node requeues. */
#define HELD "lease_token = $2::bigint AND state = 'running' AND lease_expires > now()"

static void fmt_i64(char *buf, size_t cap, int64_t v)
{
    snprintf(buf, cap, "%" PRId64, v);
}

/* The event insert: nevents + 1 under the job's row lock, so that seq is
 * unique and gap-free per job, and a NOTIFY sent at commit. */
#define APPEND_SQL(cond)                                                                    \
    "WITH s AS (UPDATE smd_jobs SET nevents = nevents + 1, updated = now() WHERE id = $1" cond \
    " RETURNING nevents), e AS (INSERT INTO smd_events (job, seq, payload)"                  \
    " SELECT $1, nevents, jsonb_set($3::jsonb, '{seq}', to_jsonb(nevents)) FROM s"           \
    " RETURNING seq) SELECT seq, pg_notify('" SMD_PG_CHANNEL_EVENTS "', $1 || ' ' || seq)"    \
    " FROM e"

sm_status smd_pg_append_event(smd_pg *db, const char *id, const smd_pg_lease *fence,
                              const char *json, int64_t *seq, sm_error *err)
{
    char token[24] = "0";
    if (fence)
        fmt_i64(token, sizeof token, fence->token);
    const char *vals[] = {id, token, json};
    PGresult *r = smd_pg_exec(db, "event", fence ? APPEND_SQL(" AND " HELD)
                                                 : APPEND_SQL(" AND $2::bigint = 0"),
                              3, vals, err);
    if (!r)
        return SM_ERR_IO;
    *seq = PQntuples(r) == 1 ? strtoll(PQgetvalue(r, 0, 0), NULL, 10) : 0;
    PQclear(r);
    return SM_OK;
}

/* The event seq of a job, fenced: SMD_PG_APPENDED when stored as seq
 * expect now; else what the database holds says why not. */
static sm_status append_outcome(smd_pg *db, const char *id, const char *token, int64_t expect,
                                int *outcome, sm_error *err)
{
    const char *vals[] = {id, token};
    PGresult *r = smd_pg_exec(db, "event", "SELECT nevents FROM smd_jobs WHERE id = $1 AND " HELD,
                              2, vals, err);
    if (!r)
        return SM_ERR_IO;
    int64_t have = PQntuples(r) == 1 ? strtoll(PQgetvalue(r, 0, 0), NULL, 10) : -1;
    PQclear(r);
    *outcome = have < 0 ? SMD_PG_NOT_HELD : have >= expect ? SMD_PG_DUPLICATE : SMD_PG_GAP;
    return SM_OK;
}

sm_status smd_pg_append_event_at(smd_pg *db, const char *id, const smd_pg_lease *fence,
                                 const char *json, int64_t expect, int *outcome, sm_error *err)
{
    char token[24], want[24];
    fmt_i64(token, sizeof token, fence->token);
    fmt_i64(want, sizeof want, expect);
    const char *vals[] = {id, token, json, want};
    PGresult *r = smd_pg_exec(db, "event",
                              APPEND_SQL(" AND " HELD " AND nevents = $4::bigint - 1"), 4, vals,
                              err);
    if (!r)
        return SM_ERR_IO;
    int stored = PQntuples(r) == 1;
    PQclear(r);
    if (stored) {
        *outcome = SMD_PG_APPENDED;
        return SM_OK;
    }
    return append_outcome(db, id, token, expect, outcome, err);
}

static sm_status find_key(smd_pg *db, const smd_pg_job *job, char existing[SMD_ID_LEN + 1],
                          int *found, sm_error *err)
{
    const char *vals[] = {job->owner, job->idempotency_key};
    PGresult *r = smd_pg_exec(db, "idempotency key",
                              "SELECT id FROM smd_jobs WHERE owner = $1 AND idempotency_key = $2",
                              2, vals, err);
    if (!r)
        return SM_ERR_IO;
    *found = PQntuples(r) == 1;
    if (*found)
        snprintf(existing, SMD_ID_LEN + 1, "%s", PQgetvalue(r, 0, 0));
    PQclear(r);
    return SM_OK;
}

/* INSERT ... ON CONFLICT DO NOTHING: *inserted 0 when the key was taken
 * (by a retry that reached another API node at the same time). */
static sm_status insert_job(smd_pg *db, const smd_pg_job *job, int *inserted, sm_error *err)
{
    char hash[24], dim[16], max_iter[16], tol[32];
    snprintf(hash, sizeof hash, "%" PRIu64, job->request_hash);
    snprintf(dim, sizeof dim, "%d", job->dim);
    snprintf(max_iter, sizeof max_iter, "%d", job->max_iter);
    snprintf(tol, sizeof tol, "%.17g", job->tol_boundary);
    const char *key = job->idempotency_key && job->idempotency_key[0] ? job->idempotency_key : NULL;
    const char *vals[] = {job->id, job->owner ? job->owner : "", key, hash, job->params,
                          dim, max_iter, tol, job->members, job->name ? job->name : ""};
    PGresult *r = smd_pg_exec(
        db, "submit",
        "INSERT INTO smd_jobs (id, owner, idempotency_key, request_hash, state, params, dim,"
        " max_iter, tol_boundary, members, name) VALUES ($1, $2, $3, $4::numeric, 'accepted',"
        " $5::jsonb, $6::integer, $7::integer, $8::float8, $9::text[], $10)"
        " ON CONFLICT DO NOTHING RETURNING 1",
        10, vals, err);
    if (!r)
        return SM_ERR_IO;
    *inserted = PQntuples(r) == 1;
    PQclear(r);
    return SM_OK;
}

sm_status smd_pg_submit(smd_pg *db, const smd_pg_job *job, int *created,
                        char existing[SMD_ID_LEN + 1], sm_error *err)
{
    *created = 0;
    int inserted = 0, found = 0;
    int64_t seq = 0;
    if (smd_pg_begin(db, err) != SM_OK)
        return SM_ERR_IO;
    sm_status st = insert_job(db, job, &inserted, err);
    if (st == SM_OK && inserted)
        st = smd_pg_append_event(db, job->id, NULL, job->first_event, &seq, err);
    if (st == SM_OK && inserted && job->dir) {
        char path[4096], inputs[4096];
        if (smd_pathf(path, sizeof path, "%s/job.json", job->dir) != 0 ||
            smd_pathf(inputs, sizeof inputs, "%s/inputs", job->dir) != 0)
            st = sm_error_set(err, SM_ERR_IO, "%s: path too long", job->dir);
        if (st == SM_OK)
            st = smd_pg_put_file(db, job->id, "job.json", path, err);
        if (st == SM_OK)
            st = smd_pg_put_tree(db, job->id, "inputs/", inputs, err);
    }
    if (st == SM_OK)
        st = smd_pg_commit(db, err);
    if (st != SM_OK) {
        smd_pg_rollback(db);
        return st;
    }
    if (inserted) {
        *created = 1;
        return SM_OK;
    }
    if (!job->idempotency_key || !job->idempotency_key[0])
        return sm_error_set(err, SM_ERR_INVALID, "database: job id %s exists", job->id);
    st = find_key(db, job, existing, &found, err);
    if (st == SM_OK && !found)
        st = sm_error_set(err, SM_ERR_IO, "database: the job of Idempotency-Key was deleted meanwhile");
    return st;
}

sm_status smd_pg_claim(smd_pg *db, const char *node, double lease, smd_pg_lease *out, int *got,
                       sm_error *err)
{
    char secs[32];
    snprintf(secs, sizeof secs, "%.3f", lease);
    const char *vals[] = {node, secs};
    PGresult *r = smd_pg_exec(
        db, "claim",
        /* a batch's model job waits for its members (none queued or running) */
        "WITH c AS (SELECT id FROM smd_jobs s WHERE state = 'accepted' AND (s.members IS NULL"
        " OR NOT EXISTS (SELECT 1 FROM smd_jobs m WHERE m.id = ANY (s.members)"
        " AND m.state IN ('accepted', 'running'))) ORDER BY ord LIMIT 1"
        " FOR UPDATE OF s SKIP LOCKED)"
        " UPDATE smd_jobs j SET state = 'running', attempt = j.attempt + 1, lease_owner = $1,"
        " lease_expires = now() + $2::float8 * interval '1 second',"
        " lease_token = nextval('smd_lease_tokens'), started = now(), updated = now()"
        " FROM c WHERE j.id = c.id RETURNING j.id, j.attempt, j.lease_token",
        2, vals, err);
    if (!r)
        return SM_ERR_IO;
    *got = PQntuples(r) == 1;
    if (*got) {
        snprintf(out->id, sizeof out->id, "%s", PQgetvalue(r, 0, 0));
        out->attempt = atoi(PQgetvalue(r, 0, 1));
        out->token = strtoll(PQgetvalue(r, 0, 2), NULL, 10);
    }
    PQclear(r);
    return SM_OK;
}

sm_status smd_pg_renew(smd_pg *db, const smd_pg_lease *l, double lease, int *held,
                       sm_error *err)
{
    char token[24], secs[32];
    fmt_i64(token, sizeof token, l->token);
    snprintf(secs, sizeof secs, "%.3f", lease);
    const char *vals[] = {l->id, token, secs};
    PGresult *r = smd_pg_exec(db, "renew",
                              "UPDATE smd_jobs SET lease_expires = now() + $3::float8 * interval "
                              "'1 second' WHERE id = $1 AND " HELD " RETURNING cancel_requested",
                              3, vals, err);
    if (!r)
        return SM_ERR_IO;
    *held = PQntuples(r) != 1 ? 0 : strcmp(PQgetvalue(r, 0, 0), "t") == 0 ? 2 : 1;
    PQclear(r);
    return SM_OK;
}

static sm_status set_final(smd_pg *db, const smd_pg_lease *l, sm_job_state state,
                           const char *message, int *held, sm_error *err)
{
    char token[24];
    fmt_i64(token, sizeof token, l->token);
    const char *vals[] = {l->id, token, smd_pg_state_name(state), message ? message : ""};
    PGresult *r = smd_pg_exec(
        db, "complete",
        "UPDATE smd_jobs SET state = $3, message = $4, finished = now(), updated = now(),"
        " progress = CASE WHEN $3 = 'successful' THEN 100 ELSE progress END,"
        " lease_owner = NULL, lease_expires = NULL, lease_token = NULL"
        " WHERE id = $1 AND " HELD " RETURNING 1",
        4, vals, err);
    if (!r)
        return SM_ERR_IO;
    *held = PQntuples(r) == 1;
    PQclear(r);
    return SM_OK;
}

sm_status smd_pg_complete(smd_pg *db, const smd_pg_lease *l, sm_job_state state,
                          const char *message, const char *final_event, int *held,
                          sm_error *err)
{
    int64_t seq = 1;
    *held = 0;
    if (smd_pg_begin(db, err) != SM_OK)
        return SM_ERR_IO;
    sm_status st = SM_OK;
    if (final_event)
        st = smd_pg_append_event(db, l->id, l, final_event, &seq, err);
    if (st == SM_OK && seq > 0)
        st = set_final(db, l, state, message, held, err);
    if (st == SM_OK && *held)
        return smd_pg_commit(db, err) == SM_OK ? SM_OK : (*held = 0, SM_ERR_IO);
    smd_pg_rollback(db);
    *held = 0;
    return st;
}

/* One statement: lock the expired leases (SKIP LOCKED: two nodes
 * sweeping at once take different rows), requeue or end them, append the
 * final event of those that end, NOTIFY it. */
static const char expire_sql[] =
    "WITH x AS (SELECT id, CASE WHEN cancel_requested THEN 'dismissed'"
    "   WHEN attempt >= $1::integer THEN 'failed' ELSE 'accepted' END AS next"
    "   FROM smd_jobs WHERE state = 'running' AND lease_expires <= now() FOR UPDATE SKIP LOCKED),"
    " u AS (UPDATE smd_jobs j SET state = x.next, updated = now(),"
    "   message = CASE x.next WHEN 'dismissed' THEN 'cancelled (its worker node was lost)'"
    "     WHEN 'failed' THEN format('the worker node running it was lost (lease of %s expired)"
    " on each of its %s attempts (--max-attempts %s)', j.lease_owner, j.attempt, $1)"
    "     ELSE format('re-queued: the lease of worker node %s expired (attempt %s)',"
    "       j.lease_owner, j.attempt) END,"
    "   finished = CASE WHEN x.next = 'accepted' THEN NULL ELSE now() END,"
    "   nevents = j.nevents + CASE WHEN x.next = 'accepted' THEN 0 ELSE 1 END,"
    "   lease_owner = NULL, lease_expires = NULL, lease_token = NULL"
    "   FROM x WHERE j.id = x.id RETURNING j.id, j.state, j.nevents, j.message),"
    " e AS (INSERT INTO smd_events (job, seq, payload) SELECT id, nevents,"
    "   jsonb_build_object('type', CASE state WHEN 'failed' THEN 'failed' ELSE 'cancelled' END,"
    "   'jobID', id, 'seq', nevents, 'time',"
    "   to_char(now() AT TIME ZONE 'UTC', 'YYYY-MM-DD\"T\"HH24:MI:SS.MS\"Z\"'), 'message', message)"
    "   FROM u WHERE state <> 'accepted' RETURNING job, seq)"
    " SELECT u.state, CASE WHEN e.job IS NOT NULL THEN"
    "   pg_notify('" SMD_PG_CHANNEL_EVENTS "', e.job || ' ' || e.seq) END"
    " FROM u LEFT JOIN e ON e.job = u.id";

sm_status smd_pg_expire(smd_pg *db, int max_attempts, size_t *requeued, size_t *failed,
                        sm_error *err)
{
    char max[16];
    snprintf(max, sizeof max, "%d", max_attempts);
    const char *vals[] = {max};
    PGresult *r = smd_pg_exec(db, "expire leases", expire_sql, 1, vals, err);
    if (!r)
        return SM_ERR_IO;
    *requeued = *failed = 0;
    for (int i = 0; i < PQntuples(r); i++) {
        if (strcmp(PQgetvalue(r, i, 0), "accepted") == 0)
            (*requeued)++;
        else
            (*failed)++;
    }
    PQclear(r);
    return SM_OK;
}

sm_status smd_pg_expired_held(smd_pg *db, char *ids, size_t cap, size_t *n, sm_error *err)
{
    /* the sweep just took every unlocked one: what is left past its
     * expiry (by a second, not to count a lease ending right now) is a
     * row another session keeps locked */
    PGresult *r = smd_pg_exec(db, "expired leases held",
                              "SELECT id FROM smd_jobs WHERE state = 'running' AND"
                              " lease_expires <= now() - interval '1 second' ORDER BY id LIMIT 16",
                              0, NULL, err);
    if (!r)
        return SM_ERR_IO;
    *n = (size_t)PQntuples(r);
    size_t used = 0;
    if (cap)
        ids[0] = '\0';
    for (size_t i = 0; i < *n && cap; i++) {
        int k = snprintf(ids + used, cap - used, "%s%s", i ? " " : "", PQgetvalue(r, (int)i, 0));
        if (k < 0 || (size_t)k >= cap - used)
            break;
        used += (size_t)k;
    }
    PQclear(r);
    return SM_OK;
}

/* The running job's worker node is told (NOTIFY at commit); a queued one
 * ends here with its "cancelled" event. */
static const char cancel_sql[] =
    "WITH u AS (UPDATE smd_jobs SET updated = now(),"
    "   state = CASE WHEN state = 'accepted' THEN 'dismissed' ELSE state END,"
    "   cancel_requested = (state = 'running'),"
    "   finished = CASE WHEN state = 'accepted' THEN now() ELSE finished END,"
    "   message = CASE WHEN state = 'accepted' THEN 'cancelled' ELSE message END"
    "   WHERE id = $1 AND state IN ('accepted', 'running') RETURNING id, cancel_requested)"
    " SELECT cancel_requested, CASE WHEN cancel_requested THEN"
    "   pg_notify('" SMD_PG_CHANNEL_CANCEL "', id) END FROM u";

sm_status smd_pg_cancel(smd_pg *db, const char *id, int *was, sm_error *err)
{
    const char *vals[] = {id};
    int64_t seq;
    *was = 0;
    if (smd_pg_begin(db, err) != SM_OK)
        return SM_ERR_IO;
    PGresult *r = smd_pg_exec(db, "cancel", cancel_sql, 1, vals, err);
    sm_status st = r ? SM_OK : SM_ERR_IO;
    if (r && PQntuples(r) == 1)
        *was = strcmp(PQgetvalue(r, 0, 0), "t") == 0 ? 2 : 1;
    PQclear(r);
    if (st == SM_OK && *was == 1)
        st = smd_pg_append_event(db, id, NULL, "{\"type\":\"cancelled\",\"message\":\"cancelled\"}",
                                 &seq, err);
    if (st == SM_OK)
        st = smd_pg_commit(db, err);
    if (st != SM_OK) {
        smd_pg_rollback(db);
        *was = 0;
    }
    return st;
}

sm_status smd_pg_depth(smd_pg *db, int64_t *queued, int64_t *leased, sm_error *err)
{
    PGresult *r = smd_pg_exec(db, "queue depth",
                              "SELECT count(*) FILTER (WHERE state = 'accepted'),"
                              " count(*) FILTER (WHERE state = 'running') FROM smd_jobs"
                              " WHERE state IN ('accepted', 'running')",
                              0, NULL, err);
    if (!r)
        return SM_ERR_IO;
    *queued = strtoll(PQgetvalue(r, 0, 0), NULL, 10);
    *leased = strtoll(PQgetvalue(r, 0, 1), NULL, 10);
    PQclear(r);
    return SM_OK;
}

sm_status smd_pg_state(smd_pg *db, const char *id, sm_job_state *state, int *attempt,
                       int *found, sm_error *err)
{
    const char *vals[] = {id};
    PGresult *r = smd_pg_exec(db, "job state", "SELECT state, attempt FROM smd_jobs WHERE id = $1",
                              1, vals, err);
    if (!r)
        return SM_ERR_IO;
    *found = PQntuples(r) == 1;
    if (*found) {
        if (smd_pg_state_parse(PQgetvalue(r, 0, 0), state) != 0)
            *state = SM_JOB_FAILED;
        if (attempt)
            *attempt = atoi(PQgetvalue(r, 0, 1));
    }
    PQclear(r);
    return SM_OK;
}

#define INFO_COLS "id, owner, coalesce(idempotency_key, ''), request_hash, state, message," \
                  " attempt, dim, max_iter, tol_boundary, nevents, coalesce(lease_token, 0)," \
                  " members IS NOT NULL, name"

static void info_row(const PGresult *r, int i, smd_pg_info *o)
{
    memset(o, 0, sizeof *o);
    snprintf(o->id, sizeof o->id, "%s", PQgetvalue(r, i, 0));
    snprintf(o->owner, sizeof o->owner, "%s", PQgetvalue(r, i, 1));
    snprintf(o->idempotency_key, sizeof o->idempotency_key, "%s", PQgetvalue(r, i, 2));
    o->request_hash = strtoull(PQgetvalue(r, i, 3), NULL, 10);
    if (smd_pg_state_parse(PQgetvalue(r, i, 4), &o->state) != 0)
        o->state = SM_JOB_FAILED;
    snprintf(o->message, sizeof o->message, "%s", PQgetvalue(r, i, 5));
    o->attempt = atoi(PQgetvalue(r, i, 6));
    o->dim = atoi(PQgetvalue(r, i, 7));
    o->max_iter = atoi(PQgetvalue(r, i, 8));
    o->tol_boundary = strtod(PQgetvalue(r, i, 9), NULL);
    o->nevents = strtoll(PQgetvalue(r, i, 10), NULL, 10);
    o->lease_token = strtoll(PQgetvalue(r, i, 11), NULL, 10);
    o->batch_model = strcmp(PQgetvalue(r, i, 12), "t") == 0;
    snprintf(o->name, sizeof o->name, "%s", PQgetvalue(r, i, 13));
}

sm_status smd_pg_batch_done(smd_pg *db, const char *id,
                            int (*fn)(void *user, const char *member), void *user,
                            sm_error *err)
{
    const char *vals[] = {id};
    PGresult *r = smd_pg_exec(db, "batch members",
                              "SELECT m.id FROM smd_jobs s JOIN smd_jobs m ON m.id = ANY (s.members)"
                              " WHERE s.id = $1 AND m.state = 'successful'",
                              1, vals, err);
    if (!r)
        return SM_ERR_IO;
    for (int i = 0; i < PQntuples(r); i++)
        if (fn(user, PQgetvalue(r, i, 0)) != 0)
            break;
    PQclear(r);
    return SM_OK;
}

sm_status smd_pg_job_info(smd_pg *db, const char *id, smd_pg_info *out, int *found,
                          sm_error *err)
{
    const char *vals[] = {id};
    PGresult *r = smd_pg_exec(db, "job", "SELECT " INFO_COLS " FROM smd_jobs WHERE id = $1", 1,
                              vals, err);
    if (!r)
        return SM_ERR_IO;
    *found = PQntuples(r) == 1;
    if (*found)
        info_row(r, 0, out);
    PQclear(r);
    return SM_OK;
}

sm_status smd_pg_list(smd_pg *db, smd_pg_info **out, size_t *n, sm_error *err)
{
    *out = NULL;
    *n = 0;
    PGresult *r = smd_pg_exec(db, "job list", "SELECT " INFO_COLS " FROM smd_jobs ORDER BY ord", 0,
                              NULL, err);
    if (!r)
        return SM_ERR_IO;
    int rows = PQntuples(r);
    if (rows > 0 && !(*out = calloc((size_t)rows, sizeof **out))) {
        PQclear(r);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    }
    for (int i = 0; i < rows; i++)
        info_row(r, i, &(*out)[i]);
    *n = (size_t)rows;
    PQclear(r);
    return SM_OK;
}

sm_status smd_pg_events(smd_pg *db, const char *id, int64_t after, int limit,
                        int (*fn)(void *user, int64_t seq, const char *json), void *user,
                        sm_error *err)
{
    char a[24], l[16];
    fmt_i64(a, sizeof a, after);
    snprintf(l, sizeof l, "%d", limit);
    const char *vals[] = {id, a, l};
    PGresult *r = smd_pg_exec(db, "events",
                              "SELECT seq, payload::text FROM smd_events WHERE job = $1 AND"
                              " seq > $2::bigint ORDER BY seq LIMIT $3::integer",
                              3, vals, err);
    if (!r)
        return SM_ERR_IO;
    for (int i = 0; i < PQntuples(r); i++)
        if (fn(user, strtoll(PQgetvalue(r, i, 0), NULL, 10), PQgetvalue(r, i, 1)) != 0)
            break;
    PQclear(r);
    return SM_OK;
}

sm_status smd_pg_lock_held(smd_pg *db, const smd_pg_lease *l, int *held, sm_error *err)
{
    char token[24];
    fmt_i64(token, sizeof token, l->token);
    const char *vals[] = {l->id, token};
    PGresult *r = smd_pg_exec(db, "lease", "SELECT 1 FROM smd_jobs WHERE id = $1 AND " HELD
                              " FOR UPDATE", 2, vals, err);
    if (!r)
        return SM_ERR_IO;
    *held = PQntuples(r) == 1;
    PQclear(r);
    return SM_OK;
}

sm_status smd_pg_publish(smd_pg *db, const smd_pg_lease *l, sm_job_state state,
                         const char *message, const char *final_event, int64_t expect,
                         const char *results_dir, int *held, sm_error *err)
{
    *held = 0;
    int outcome = SMD_PG_APPENDED;
    const char *vals[] = {l->id};
    if (smd_pg_begin(db, err) != SM_OK)
        return SM_ERR_IO;
    sm_status st = smd_pg_lock_held(db, l, held, err);
    if (st == SM_OK && *held && results_dir) {
        st = smd_pg_run(db, "results", "DELETE FROM smd_blobs WHERE job = $1 AND"
                        " starts_with(name, 'results/')", 1, vals, err);
        if (st == SM_OK)
            st = smd_pg_put_tree(db, l->id, "results/", results_dir, err);
    }
    if (st == SM_OK && *held && final_event)
        st = smd_pg_append_event_at(db, l->id, l, final_event, expect, &outcome, err);
    int appended = outcome == SMD_PG_APPENDED;
    if (st == SM_OK && *held && appended)
        st = set_final(db, l, state, message, held, err);
    if (st == SM_OK && *held && appended)
        return smd_pg_commit(db, err) == SM_OK ? SM_OK : (*held = 0, SM_ERR_IO);
    smd_pg_rollback(db);
    /* a final event out of turn: the log would hide a gap (or the event
     * is stored already, its run published) */
    *held = st == SM_OK && *held && outcome == SMD_PG_GAP ? SMD_PG_GAP : 0;
    return st;
}

/* Queued again (dismissed when a cancel came meanwhile); undo 1: the
 * claim's attempt is given back too. */
static sm_status release_as(smd_pg *db, const smd_pg_lease *l, const char *message, int undo,
                            sm_error *err)
{
    char token[24];
    fmt_i64(token, sizeof token, l->token);
    const char *vals[] = {l->id, token, message, undo ? "1" : "0"};
    return smd_pg_run(db, "release",
                      "UPDATE smd_jobs SET state = CASE WHEN cancel_requested THEN 'dismissed'"
                      " ELSE 'accepted' END, message = $3, updated = now(), lease_owner = NULL,"
                      " lease_expires = NULL, lease_token = NULL,"
                      " attempt = greatest(attempt - $4::integer, 0) WHERE id = $1 AND " HELD,
                      4, vals, err);
}

sm_status smd_pg_release(smd_pg *db, const smd_pg_lease *l, const char *message, sm_error *err)
{
    return release_as(db, l, message, 0, err);
}

sm_status smd_pg_unclaim(smd_pg *db, const smd_pg_lease *l, const char *message, sm_error *err)
{
    return release_as(db, l, message, 1, err);
}

sm_status smd_pg_delete(smd_pg *db, const char *id, int *deleted, sm_error *err)
{
    const char *vals[] = {id};
    PGresult *r = smd_pg_exec(db, "delete",
                              "DELETE FROM smd_jobs WHERE id = $1 AND state IN"
                              " ('successful', 'failed', 'dismissed') RETURNING 1",
                              1, vals, err);
    if (!r)
        return SM_ERR_IO;
    *deleted = PQntuples(r) == 1;
    PQclear(r);
    return SM_OK;
}
