/* Counters and histograms of the daemon, rendered in the Prometheus text
 * exposition format (GET /metrics).  Requests are counted by route
 * template (never by raw path, so the label set stays bounded: the labels
 * are fixed at init), method and status code; latency is a histogram per
 * route. */
#ifndef SMD_METRICS_H
#define SMD_METRICS_H

#include <pthread.h>
#include <stddef.h>
#include <stdint.h>

/* The job states, in the order of proto's sm_job_state (accepted,
 * running, successful, failed, dismissed; smd_jobs.c checks the match at
 * compile time), and the final ones among them (from successful on). */
#define SMD_JOB_STATES 5
#define SMD_JOB_FIRST_FINAL 2
#define SMD_JOB_FINAL_STATES (SMD_JOB_STATES - SMD_JOB_FIRST_FINAL)

#define SMD_LATENCY_BUCKETS 15
#define SMD_METHODS 5 /* GET, POST, DELETE, HEAD, other */

#define SMD_STATUS_CODES 500 /* 100..599 */

typedef struct smd_metrics {
    pthread_mutex_t lock;
    const char *const *routes; /* route labels (the first: unknown routes) */
    size_t nroutes;
    uint64_t *requests;        /* [route][method][status - 100] */
    uint64_t *latency_bucket;  /* [route][bucket] */
    double *latency_sum;       /* [route] */
    uint64_t *latency_count;   /* [route] */
    uint64_t bytes_in, bytes_out;
    uint64_t jobs_submitted;
    uint64_t jobs_finished[SMD_JOB_FINAL_STATES]; /* successful, failed, dismissed */
    uint64_t events_appended;
    uint64_t workers_started;
} smd_metrics;

/* Values read at scrape time from the daemon's state. */
typedef struct smd_gauges {
    uint64_t jobs_by_state[SMD_JOB_STATES]; /* accepted, running, successful, failed, dismissed */
    uint64_t queue_depth;
    uint64_t workers_busy, workers_total;
    uint64_t followers;
    uint64_t quarantined;      /* damaged records moved aside at start */
    uint64_t connections;      /* open HTTP connections (smd_conns.h) */
    uint64_t cut_headers, cut_body, cut_reserve; /* closed by the daemon's deadlines */
    uint64_t checks_running, checks_waiting; /* upload checks (smd_check.h) */
    uint64_t body_bytes;       /* request bodies held in memory (smd_body.h) */
    uint64_t body_budget;      /* --max-body-memory */
    double start_time;         /* Unix seconds */
    int ready;
} smd_gauges;

/* routes: the label of each route (strings that outlive m; the daemon's
 * come from its route table, smd_route_labels), routes[0] used for any
 * label not in the list.  0, or -1 when out of memory. */
int smd_metrics_init(smd_metrics *m, const char *const *routes, size_t nroutes);
void smd_metrics_destroy(smd_metrics *m);

/* route: one of the labels given to smd_metrics_init (any other counts
 * as the first); method: "GET", ...; status: HTTP code; seconds:
 * handling time. */
void smd_metrics_request(smd_metrics *m, const char *route, const char *method,
                         unsigned status, double seconds, uint64_t bytes_in,
                         uint64_t bytes_out);
/* state index as in smd_gauges.jobs_by_state (final ones only). */
void smd_metrics_job_finished(smd_metrics *m, int state);
void smd_metrics_add(smd_metrics *m, uint64_t *counter, uint64_t n);

/* Prometheus text; malloc'd, NUL-terminated, or NULL when out of memory. */
char *smd_metrics_render(smd_metrics *m, const smd_gauges *g, size_t *len);

#endif
