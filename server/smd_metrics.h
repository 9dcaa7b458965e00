/* Counters and histograms of the daemon, rendered in the Prometheus text
 * exposition format (GET /metrics).  Requests are counted by route
 * template (never by raw path, so the label set stays bounded), method
 * and status code; latency is a histogram per route. */
#ifndef SMD_METRICS_H
#define SMD_METRICS_H

#include <pthread.h>
#include <stddef.h>
#include <stdint.h>

typedef enum smd_route {
    SMD_ROUTE_OTHER = 0,
    SMD_ROUTE_ROOT,
    SMD_ROUTE_OPENAPI,
    SMD_ROUTE_HEALTHZ,
    SMD_ROUTE_READYZ,
    SMD_ROUTE_METRICS,
    SMD_ROUTE_PROCESSES,
    SMD_ROUTE_PROCESS,
    SMD_ROUTE_JOBS,
    SMD_ROUTE_JOB,
    SMD_ROUTE_EVENTS,
    SMD_ROUTE_RESULTS,
    SMD_ROUTE_RESULT_MESH,
    SMD_ROUTE_RESULT_DISPLACEMENT,
    SMD_ROUTE_RESULT_HISTORY,
    SMD_ROUTE_COUNT
} smd_route;

/* Route template, e.g. "/v1/jobs/{id}/events"; "other" for unknown. */
const char *smd_route_label(smd_route r);

#define SMD_LATENCY_BUCKETS 15
#define SMD_METHODS 5 /* GET, POST, DELETE, HEAD, other */

typedef struct smd_metrics {
    pthread_mutex_t lock;
    uint64_t requests[SMD_ROUTE_COUNT][SMD_METHODS][500]; /* status 100..599 */
    uint64_t latency_bucket[SMD_ROUTE_COUNT][SMD_LATENCY_BUCKETS];
    double latency_sum[SMD_ROUTE_COUNT];
    uint64_t latency_count[SMD_ROUTE_COUNT];
    uint64_t bytes_in, bytes_out;
    uint64_t jobs_submitted;
    uint64_t jobs_finished[3]; /* successful, failed, dismissed */
    uint64_t events_appended;
    uint64_t workers_started;
} smd_metrics;

/* Values read at scrape time from the daemon's state. */
typedef struct smd_gauges {
    uint64_t jobs_by_state[5]; /* accepted, running, successful, failed, dismissed */
    uint64_t queue_depth;
    uint64_t workers_busy, workers_total;
    uint64_t followers;
    double start_time;         /* Unix seconds */
    int ready;
} smd_gauges;

int smd_metrics_init(smd_metrics *m);
void smd_metrics_destroy(smd_metrics *m);

/* method: "GET", ...; status: HTTP code; seconds: handling time. */
void smd_metrics_request(smd_metrics *m, smd_route route, const char *method,
                         unsigned status, double seconds, uint64_t bytes_in,
                         uint64_t bytes_out);
/* state index as in smd_gauges.jobs_by_state (2..4 for the final ones). */
void smd_metrics_job_finished(smd_metrics *m, int state);
void smd_metrics_add(smd_metrics *m, uint64_t *counter, uint64_t n);

/* Prometheus text; malloc'd, NUL-terminated, or NULL when out of memory. */
char *smd_metrics_render(smd_metrics *m, const smd_gauges *g, size_t *len);

#endif
