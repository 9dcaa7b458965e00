/* Private to smd_pg*.c: the connection and the query helpers. */
#ifndef SMD_PG_INT_H
#define SMD_PG_INT_H

#include <libpq-fe.h>

#include "store/pg/smd_pg.h"

#define SMD_PG_LISTENS_MAX 4

struct smd_pg {
    PGconn *conn;
    char *url;
    char *password;            /* from --database-password-file, or NULL */
    char app[64];
    char listens[SMD_PG_LISTENS_MAX][32];
    int nlistens;
    int lost;                  /* a query failed for want of a connection */
    int timed_out;             /* the last failed query hit a statement or lock timeout */
    /* statement_timeout, lock_timeout, idle_in_transaction_session_timeout
     * in ms (0: the server's own), set again on every reconnect */
    long timeouts_ms[3];
};

/* Runs sql with text parameters (NULL entries are SQL NULL).  Returns the
 * result when its status is PGRES_COMMAND_OK or PGRES_TUPLES_OK, else
 * NULL with err set ("what: the server's message"). */
PGresult *smd_pg_exec(smd_pg *db, const char *what, const char *sql, int n,
                      const char *const *values, sm_error *err);
/* smd_pg_exec for statements whose result is not needed. */
sm_status smd_pg_run(smd_pg *db, const char *what, const char *sql, int n,
                     const char *const *values, sm_error *err);

/* Inside a transaction: the file at path as blob (id, name), and every
 * file under dir as "prefix<relative path>". */
sm_status smd_pg_put_file(smd_pg *db, const char *id, const char *name, const char *path,
                          sm_error *err);
sm_status smd_pg_put_tree(smd_pg *db, const char *id, const char *prefix, const char *dir,
                          sm_error *err);
/* Locks the row of a job whose lease l holds (FOR UPDATE): *held. */
sm_status smd_pg_lock_held(smd_pg *db, const smd_pg_lease *l, int *held, sm_error *err);

const char *smd_pg_state_name(sm_job_state s);
int smd_pg_state_parse(const char *name, sm_job_state *out);

#endif
