/* The daemon operations that several commands share (daemon_ops.c):
 * following a job's events to its end (`watch`, `submit --wait`) and
 * downloading its results (`fetch`, `submit --wait -o`), so that no
 * command calls into another command's file. */
#ifndef CLI_DAEMON_OPS_H
#define CLI_DAEMON_OPS_H

#include "http.h"
#include "remote.h"

/* ---- watch ---- */

typedef struct watch_options {
    int quiet;                 /* no progress display, no lifecycle lines */
    int json;                  /* every event as one JSON line on stdout */
    double reconnect_timeout;  /* seconds to keep reconnecting after a drop */
} watch_options;

/* --reconnect-timeout: seconds in [0, REMOTE_RECONNECT_MAX]. */
int watch_parse_reconnect(const char *flag, const char *value, double *out, char *msg,
                          size_t cap);

/* Follows the job's events to its end.  Returns 0 (successful),
 * CLI_EXIT_JOB_FAILED, CLI_EXIT_CANCELLED (dismissed), or the exit code
 * of a request that failed (reported). */
int remote_watch(http_client *c, const char *cmd, int token_given, const char *id,
                 const watch_options *o);

/* ---- fetch ---- */

enum {
    FETCH_MESH = 1u << 0,
    FETCH_MESHB = 1u << 1,
    FETCH_VTU = 1u << 2,
    FETCH_BINARY = 1u << 3,
    FETCH_SOL = 1u << 4,      /* displacement.sol (also when neither is named) */
    FETCH_SOLB = 1u << 5
};
#define FETCH_DEFAULT_FORMATS (FETCH_MESH | FETCH_VTU)
#define FETCH_DEFAULT_FORMATS_TEXT "mesh,vtu"

/* "mesh,vtu" -> bit set.  Returns 0, or -1 with a message. */
int fetch_parse_formats(const char *flag, const char *text, unsigned *out, char *msg,
                        size_t cap);

typedef struct fetch_options {
    const char *outdir;
    unsigned formats;
    int quiet;
    int show_result;           /* also print the result's one-line summary */
} fetch_options;

/* GET path into outdir/name (atomically: complete or absent), its
 * Content-Type checked against media.  0, or an exit code (reported). */
int remote_download(http_client *c, const char *cmd, int token_given, const char *path,
                    const char *outdir, const char *name, const char *media);

/* doc as indented JSON into outdir/name (atomically).  0, or
 * CLI_EXIT_OUTPUT (reported). */
int remote_write_json(const char *cmd, const char *outdir, const char *name, const json_t *doc);

/* Downloads the results of a successful job into outdir (see
 * daemon_ops.c).  Returns 0, or an exit code (reported). */
int remote_fetch(http_client *c, const char *cmd, int token_given, const char *id,
                 const fetch_options *o);

#endif
