/* Job events on the wire (NDJSON: one compact JSON object per line) and
 * the result summary document.  Schema: proto/events.schema.json.
 *
 * Every event has "type", and when known "jobID", "seq" and "time":
 *
 *   {"type":"accepted","jobID":"9f..","seq":1,"time":"2024-05-01T12:00:00.000Z"}
 *   {"type":"started","jobID":"9f..","seq":2,"time":"...","attempt":1}
 *   {"type":"progress","jobID":"9f..","seq":3,"time":"...","iteration":1,
 *    "J":-0.12,"step":0.01,"boundary_l2":0.003,"boundary_max":0.01,
 *    "min_quality":0.41,"elapsed":0.02,"accepted":1,"rejected":0}
 *   {"type":"finished","jobID":"9f..","seq":90,"time":"...","converged":true,"result":{<summary>}}
 *   {"type":"failed","jobID":"9f..","seq":91,"time":"...","message":"worker killed by signal 9 (SIGKILL)"}
 *   {"type":"cancelled","jobID":"9f..","seq":91,"time":"...","message":"cancelled by DELETE"}
 *   {"type":"status","jobID":"9f..","seq":92,"time":"...","status":"successful","converged":true,"message":"..."}
 *   {"type":"warning","jobID":"9f..","seq":89,"time":"...","code":"outside-background",
 *    "message":"...","figure":0.12}
 *
 * "progress" carries the fields of sm_progress with the same names.
 * "finished" carries the result summary (sm_result_to_jansson) under
 * "result", and its "converged" again at the top, as "status" carries it
 * for a successful job: a job that finished without converging stays
 * "successful" (OGC's status values are fixed; docs/api.md) and says
 * "converged": false.  "status" is the last event of a stream: the job's final OGC
 * status (accepted|running|successful|failed|dismissed); the daemon may
 * add further statusInfo members to it.  "warning" is one of the run's
 * warnings (proto/job/sm_job_warnings.h) as the job runner raises it, before
 * "finished" (which still lists them all in its message); code, message
 * and figure are required.  "message" is allowed on every event
 * (required on "failed" and "warning").
 *
 * Sequence numbers: the daemon assigns seq (1, 2, 3, ... per job, no gaps)
 * when it appends an event to the job's log; a worker writes events with
 * seq 0, which the encoder leaves out.  The decoder ignores members it
 * does not know (forward compatibility) but rejects known members of the
 * wrong type or range.  Non-finite doubles are written as null and read
 * back as NaN.
 *
 * Link with libsmproto.a and -ljansson. */
#ifndef SM_PROTO_EVENTS_H
#define SM_PROTO_EVENTS_H

#include <stddef.h>
#include <stdint.h>

#include <jansson.h>

#include "shapematch/sm_error.h"
#include "sm_json.h"
#include "shapematch/sm_match.h"

/* Longest job id carried (the daemon's ids are 32 hex digits). */
#define SM_JOB_ID_MAX 64
#define SM_EVENT_MESSAGE_MAX 512
/* Longest event line accepted by sm_event_from_json (bytes). */
#define SM_EVENT_LINE_MAX (64 * 1024)
/* "YYYY-MM-DDTHH:MM:SS.mmmZ" plus NUL. */
#define SM_RFC3339_LEN 32

typedef enum sm_event_type {
    SM_EVENT_ACCEPTED = 0,
    SM_EVENT_STARTED = 1,
    SM_EVENT_PROGRESS = 2,
    SM_EVENT_FINISHED = 3,
    SM_EVENT_FAILED = 4,
    SM_EVENT_CANCELLED = 5,
    SM_EVENT_STATUS = 6,
    SM_EVENT_WARNING = 7,
    SM_EVENT_ALIGNMENT = 8
} sm_event_type;

/* SM_EVENT_ALIGNMENT: the template moved onto the target before the
 * descent (params align; summary.json's alignment has the matrix too). */
typedef struct sm_event_alignment {
    char mode[16];                  /* "rigid", "similarity" or "affine" */
    double scale, rms_before, rms_after, seconds; /* NaN = null */
    int iterations;
} sm_event_alignment;

/* Longest warning code ("outside-background"): [a-z0-9-], 1 to this. */
#define SM_WARNING_CODE_MAX 47

/* OGC API - Processes job states. */
typedef enum sm_job_state {
    SM_JOB_ACCEPTED = 0,
    SM_JOB_RUNNING = 1,
    SM_JOB_SUCCESSFUL = 2,
    SM_JOB_FAILED = 3,
    SM_JOB_DISMISSED = 4
} sm_job_state;

typedef struct sm_event {
    sm_event_type type;
    char job_id[SM_JOB_ID_MAX + 1]; /* "" = not set (member omitted) */
    int64_t seq;                    /* >= 1 when assigned; 0 = omitted */
    double time;                    /* Unix seconds (UTC); < 0 = omitted */
    int attempt;                    /* started: 1 for the first run, 2 after
                                       a daemon restart, ...; 0 = omitted */
    sm_progress progress;           /* SM_EVENT_PROGRESS */
    sm_result result;               /* SM_EVENT_FINISHED */
    sm_job_state state;             /* SM_EVENT_STATUS */
    char code[SM_WARNING_CODE_MAX + 1]; /* SM_EVENT_WARNING */
    double figure;                  /* SM_EVENT_WARNING; NaN = null */
    sm_event_alignment alignment;   /* SM_EVENT_ALIGNMENT */
    char message[SM_EVENT_MESSAGE_MAX]; /* "" = omitted; longer strings are
                                           truncated (UTF-8 safe) */
    int converged;                  /* SM_EVENT_STATUS: "converged" of a
                                       successful job, 1 true, 0 false, -1
                                       omitted (not successful, an older
                                       daemon); SM_EVENT_FINISHED: decoded
                                       as result.converged, encoded from it */
} sm_event;

/* Zeroes ev, sets its type, seq 0, time -1 (omitted), converged -1
 * (omitted), everything else empty. */
void sm_event_init(sm_event *ev, sm_event_type type);

/* Wire names: "accepted", "started", "progress", "finished", "failed",
 * "cancelled", "status", "warning"; NULL for a value outside the enum.  The
 * from_name functions return 0 on success, -1 for an unknown name. */
const char *sm_event_type_name(sm_event_type type);
int sm_event_type_from_name(const char *name, sm_event_type *out);
/* "accepted", "running", "successful", "failed", "dismissed". */
const char *sm_job_state_name(sm_job_state state);
int sm_job_state_from_name(const char *name, sm_job_state *out);

/* Encodes one event as compact single-line JSON without the trailing
 * newline (NDJSON writers add "\n").  Returns a malloc'd string (caller
 * frees with free()) or NULL (bad type, out of memory). */
char *sm_event_to_json(const sm_event *ev);
json_t *sm_event_to_jansson(const sm_event *ev);

/* Decodes one line (len bytes, need not be NUL-terminated; a trailing
 * "\n" or "\r\n" is allowed).  Errors (SM_ERR_FORMAT) name the member,
 * e.g. "event.progress.iteration: must be an integer >= 0". */
sm_status sm_event_from_json(const char *line, size_t len, sm_event *out,
                             sm_error *err);
sm_status sm_event_from_jansson(const json_t *obj, sm_event *out,
                                sm_error *err);

/* Result summary: the core of summary.json, to which the job runner
 * (job/sm_job_results.h) adds status, exit_code, inverted_elements,
 * field_builds, timings.read, inputs, template, outputs and the version
 * (the daemon's GET /v1/jobs/{id}/results adds jobID and links):
 *   {"stop_reason":"step_tolerance","iterations":42,"J_initial":..,
 *    "J_final":..,"boundary_l2":..,"boundary_max":..,"min_quality":..,
 *    "accepted":..,"rejected":..,
 *    "timings":{"setup":..,"sample":..,"assembly":..,"factor":..,
 *               "solve":..,"step":..,"total":..},
 *    "parameters":{...}}          <- only when params != NULL
 * (J_final is sm_result.J.)  dim is passed to sm_params_to_json (0
 * allowed, see there).  Returns a malloc'd pretty-printed (2-space
 * indent) string ending in "\n", or NULL. */
char *sm_result_to_json(const sm_result *r, const sm_params *params, int dim);
/* Same document as a new jansson object ("parameters" only when params
 * != NULL), caller owns the reference and may add members; NULL on
 * failure. */
json_t *sm_result_to_jansson(const sm_result *r, const sm_params *params,
                             int dim);
/* Reads the summary fields back; other members (parameters, links, the
 * CLI's extras) are ignored.  path prefixes messages ("result" when
 * NULL). */
sm_status sm_result_from_jansson(const json_t *obj, const char *path,
                                 sm_result *out, sm_error *err);
sm_status sm_result_from_json(const char *text, size_t len, sm_result *out,
                              sm_error *err);
/* A progress's "distance" object as the progress event carries it
 * (result_to_target: rms, max; target_to_result: rms, max, p99), for the
 * other documents that repeat a progress (the status's lastProgress);
 * NULL when not measured (SM_DISTANCE_NONE) or out of memory. */
json_t *sm_progress_distance_to_jansson(const sm_distance *d);

/* RFC 3339 UTC with milliseconds, "2024-05-01T12:00:00.123Z".  t is Unix
 * seconds; buf has SM_RFC3339_LEN bytes.  Returns 0, or -1 when t is not
 * representable (non-finite, before 1970 or after 9999). */
int sm_time_format_rfc3339(double t, char buf[SM_RFC3339_LEN]);
/* Parses RFC 3339 date-times ("Z" or a +hh:mm/-hh:mm offset, any number
 * of fraction digits) to Unix seconds.  Returns 0, or -1 when malformed. */
int sm_time_parse_rfc3339(const char *text, double *out);
/* Current wall time as Unix seconds (CLOCK_REALTIME). */
double sm_time_now(void);

#endif
