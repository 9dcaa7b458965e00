/* Inputs and results in PostgreSQL: files streamed in and out as
 * SMD_PG_CHUNK-byte bytea rows of smd_blobs (see smd_pg.h). */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <sys/stat.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "store/pg/smd_pg_int.h"

/* Locks the job's row while its lease is held (*held), or any existing
 * job when fence is NULL. */
static sm_status lock_job(smd_pg *db, const char *id, const smd_pg_lease *fence, int *held,
                          sm_error *err)
{
    char token[24] = "0";
    if (fence)
        snprintf(token, sizeof token, "%" PRId64, fence->token);
    const char *vals[] = {id, token};
    PGresult *r = smd_pg_exec(db, "blob",
                              fence ? "SELECT 1 FROM smd_jobs WHERE id = $1 AND lease_token = "
                                      "$2::bigint AND state = 'running' AND lease_expires > now() "
                                      "FOR SHARE"
                                    : "SELECT 1 FROM smd_jobs WHERE id = $1 AND $2 = '0' FOR SHARE",
                              2, vals, err);
    if (!r)
        return SM_ERR_IO;
    *held = PQntuples(r) == 1;
    PQclear(r);
    return SM_OK;
}

static sm_status put_chunks(smd_pg *db, const char *id, const char *name, int fd, sm_error *err)
{
    char *buf = malloc(SMD_PG_CHUNK);
    if (!buf)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    sm_status st = SM_OK;
    for (int chunk = 0; st == SM_OK; chunk++) {
        size_t len = 0;
        while (len < SMD_PG_CHUNK) {
            ssize_t n = read(fd, buf + len, SMD_PG_CHUNK - len);
            if (n < 0 && errno == EINTR)
                continue;
            if (n < 0) {
                st = sm_error_set(err, SM_ERR_IO, "blob %s: read: %s", name, strerror(errno));
                break;
            }
            if (n == 0)
                break;
            len += (size_t)n;
        }
        if (st != SM_OK || (len == 0 && chunk > 0))
            break;
        char c[16];
        snprintf(c, sizeof c, "%d", chunk);
        const char *vals[] = {id, name, c, buf};
        int lens[] = {0, 0, 0, (int)len};
        int fmts[] = {0, 0, 0, 1};
        PGresult *r = PQexecParams(db->conn,
                                   "INSERT INTO smd_blobs (job, name, chunk, data)"
                                   " VALUES ($1, $2, $3::integer, $4::bytea)",
                                   4, NULL, vals, lens, fmts, 0);
        if (PQresultStatus(r) != PGRES_COMMAND_OK)
            st = sm_error_set(err, SM_ERR_IO, "database: blob %s: %.200s", name,
                              PQresultErrorMessage(r));
        PQclear(r);
        if (len < SMD_PG_CHUNK)
            break;
    }
    free(buf);
    return st;
}

sm_status smd_pg_put_file(smd_pg *db, const char *id, const char *name, const char *path,
                          sm_error *err)
{
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0)
        return sm_error_set(err, SM_ERR_IO, "blob %s: %s: %s", name, path, strerror(errno));
    const char *vals[] = {id, name};
    sm_status st = smd_pg_run(db, "blob", "DELETE FROM smd_blobs WHERE job = $1 AND name = $2", 2,
                              vals, err);
    if (st == SM_OK)
        st = put_chunks(db, id, name, fd, err);
    close(fd);
    return st;
}

/* Regular files only (no links followed), names relative to the top. */
sm_status smd_pg_put_tree(smd_pg *db, const char *id, const char *prefix, const char *dir,
                          sm_error *err)
{
    DIR *d = opendir(dir);
    if (!d)
        return sm_error_set(err, SM_ERR_IO, "blob: %s: %s", dir, strerror(errno));
    sm_status st = SM_OK;
    struct dirent *e;
    while (st == SM_OK && (e = readdir(d)) != NULL) {
        if (e->d_name[0] == '.')
            continue;
        char path[PATH_MAX], name[PATH_MAX];
        struct stat sb;
        if (smd_pathf(path, sizeof path, "%s/%s", dir, e->d_name) != 0 ||
            smd_pathf(name, sizeof name, "%s%s", prefix, e->d_name) != 0 ||
            lstat(path, &sb) != 0)
            continue;
        if (S_ISREG(sb.st_mode))
            st = smd_pg_put_file(db, id, name, path, err);
        else if (S_ISDIR(sb.st_mode) && smd_pathf(name, sizeof name, "%s%s/", prefix, e->d_name) == 0)
            st = smd_pg_put_tree(db, id, name, path, err);
    }
    closedir(d);
    return st;
}

sm_status smd_pg_blob_put(smd_pg *db, const char *id, const char *name,
                          const smd_pg_lease *fence, const char *path, int *held,
                          sm_error *err)
{
    *held = 0;
    sm_status st = smd_pg_begin(db, err);
    if (st == SM_OK)
        st = lock_job(db, id, fence, held, err);
    if (st == SM_OK && *held)
        st = smd_pg_put_file(db, id, name, path, err);
    if (st == SM_OK && *held)
        st = smd_pg_commit(db, err);
    if (st != SM_OK || !*held) {
        smd_pg_rollback(db);
        *held = 0;
    }
    return st;
}

/* Writes every row of the single-row-mode query to fd. */
static sm_status get_rows(smd_pg *db, int fd, int *found, sm_error *err)
{
    sm_status st = SM_OK;
    PGresult *r;
    while ((r = PQgetResult(db->conn)) != NULL) {
        ExecStatusType s = PQresultStatus(r);
        if (s == PGRES_SINGLE_TUPLE && st == SM_OK) {
            *found = 1;
            const char *p = PQgetvalue(r, 0, 0);
            size_t len = (size_t)PQgetlength(r, 0, 0);
            while (len > 0 && st == SM_OK) {
                ssize_t n = write(fd, p, len);
                if (n < 0 && errno == EINTR)
                    continue;
                if (n < 0)
                    st = sm_error_set(err, SM_ERR_IO, "blob: write: %s", strerror(errno));
                else
                    p += n, len -= (size_t)n;
            }
        } else if (s != PGRES_SINGLE_TUPLE && s != PGRES_TUPLES_OK && st == SM_OK) {
            st = sm_error_set(err, SM_ERR_IO, "database: blob: %.200s", PQresultErrorMessage(r));
        }
        PQclear(r);
    }
    return st;
}

sm_status smd_pg_blob_get(smd_pg *db, const char *id, const char *name, const char *path,
                          int *found, sm_error *err)
{
    *found = 0;
    int fd = open(path, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd < 0)
        return sm_error_set(err, SM_ERR_IO, "blob %s: %s: %s", name, path, strerror(errno));
    const char *vals[] = {id, name};
    sm_status st = SM_OK;
    if (!PQsendQueryParams(db->conn,
                           "SELECT data FROM smd_blobs WHERE job = $1 AND name = $2 ORDER BY chunk",
                           2, NULL, vals, NULL, NULL, 1) ||
        !PQsetSingleRowMode(db->conn))
        st = sm_error_set(err, SM_ERR_IO, "database: blob %s: %.200s", name,
                          PQerrorMessage(db->conn));
    sm_status rows = get_rows(db, fd, found, err);
    if (st == SM_OK)
        st = rows;
    if (fsync(fd) != 0 && st == SM_OK)
        st = sm_error_set(err, SM_ERR_IO, "blob %s: fsync: %s", name, strerror(errno));
    close(fd);
    if (st != SM_OK || !*found)
        unlink(path);
    return st;
}

/* A stored name as a path under dir: no "..", no absolute part, parents
 * made.  -1 when refused. */
static int tree_path(const char *dir, const char *rel, char *out, size_t cap)
{
    if (!rel[0] || rel[0] == '/' || strstr(rel, "..") || smd_pathf(out, cap, "%s/%s", dir, rel) != 0)
        return -1;
    for (char *p = out + strlen(dir) + 1; (p = strchr(p, '/')) != NULL; p++) {
        *p = '\0';
        int rc = mkdir(out, 0755);
        *p = '/';
        if (rc != 0 && errno != EEXIST)
            return -1;
    }
    return 0;
}

sm_status smd_pg_blob_get_tree(smd_pg *db, const char *id, const char *prefix, const char *dir,
                               size_t *count, sm_error *err)
{
    *count = 0;
    if (mkdir(dir, 0755) != 0 && errno != EEXIST)
        return sm_error_set(err, SM_ERR_IO, "%s: %s", dir, strerror(errno));
    const char *vals[] = {id, prefix};
    PGresult *r = smd_pg_exec(db, "blob names",
                              "SELECT DISTINCT name FROM smd_blobs WHERE job = $1 AND"
                              " starts_with(name, $2) ORDER BY name",
                              2, vals, err);
    if (!r)
        return SM_ERR_IO;
    sm_status st = SM_OK;
    size_t plen = strlen(prefix);
    for (int i = 0; st == SM_OK && i < PQntuples(r); i++) {
        const char *name = PQgetvalue(r, i, 0);
        char path[PATH_MAX];
        int found;
        if (tree_path(dir, name + plen, path, sizeof path) != 0) {
            st = sm_error_set(err, SM_ERR_INVALID, "blob name '%.100s' refused", name);
            break;
        }
        st = smd_pg_blob_get(db, id, name, path, &found, err);
        *count += st == SM_OK && found;
    }
    PQclear(r);
    return st;
}
