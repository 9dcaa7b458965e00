/* Prometheus metrics (see smd_metrics.h). */
#include "base/smd_metrics.h"

#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "base/smd_util.h"

static const char *const method_labels[SMD_METHODS] = {"GET", "POST", "DELETE", "HEAD", "other"};

static const double bucket_bounds[SMD_LATENCY_BUCKETS] = {
    0.0001, 0.00025, 0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025,
    0.05,   0.1,     0.25,   0.5,   1,      2.5,   10,
};

int smd_metrics_init(smd_metrics *m, const char *const *routes, size_t nroutes)
{
    memset(m, 0, sizeof *m);
    if (nroutes == 0)
        return -1;
    m->routes = routes;
    m->nroutes = nroutes;
    m->requests = calloc(nroutes * SMD_METHODS * SMD_STATUS_CODES, sizeof *m->requests);
    m->latency_bucket = calloc(nroutes * SMD_LATENCY_BUCKETS, sizeof *m->latency_bucket);
    m->latency_sum = calloc(nroutes, sizeof *m->latency_sum);
    m->latency_count = calloc(nroutes, sizeof *m->latency_count);
    if (!m->requests || !m->latency_bucket || !m->latency_sum || !m->latency_count ||
        pthread_mutex_init(&m->lock, NULL) != 0) {
        free(m->requests);
        free(m->latency_bucket);
        free(m->latency_sum);
        free(m->latency_count);
        memset(m, 0, sizeof *m);
        return -1;
    }
    return 0;
}

void smd_metrics_destroy(smd_metrics *m)
{
    pthread_mutex_destroy(&m->lock);
    free(m->requests);
    free(m->latency_bucket);
    free(m->latency_sum);
    free(m->latency_count);
}

static size_t route_index(const smd_metrics *m, const char *route)
{
    for (size_t i = 0; route && i < m->nroutes; i++)
        if (route == m->routes[i] || strcmp(route, m->routes[i]) == 0)
            return i;
    return 0;
}

#define REQUESTS(m, r, k, c) (m)->requests[((r) * SMD_METHODS + (k)) * SMD_STATUS_CODES + (c)]
#define BUCKET(m, r, b) (m)->latency_bucket[(r) * SMD_LATENCY_BUCKETS + (b)]

static int method_index(const char *method)
{
    for (int i = 0; i < SMD_METHODS - 1; i++)
        if (method && strcmp(method, method_labels[i]) == 0)
            return i;
    return SMD_METHODS - 1;
}

void smd_metrics_request(smd_metrics *m, const char *route_label, const char *method,
                         unsigned status, double seconds, uint64_t bytes_in, uint64_t bytes_out)
{
    size_t route = route_index(m, route_label);
    pthread_mutex_lock(&m->lock);
    if (status >= 100 && status <= 599)
        REQUESTS(m, route, (size_t)method_index(method), status - 100)++;
    for (int b = 0; b < SMD_LATENCY_BUCKETS; b++)
        if (seconds <= bucket_bounds[b])
            BUCKET(m, route, (size_t)b)++; /* cumulative, as Prometheus wants */
    m->latency_sum[route] += seconds;
    m->latency_count[route]++;
    m->bytes_in += bytes_in;
    m->bytes_out += bytes_out;
    pthread_mutex_unlock(&m->lock);
}

void smd_metrics_job_finished(smd_metrics *m, int state)
{
    if (state < SMD_JOB_FIRST_FINAL || state >= SMD_JOB_STATES)
        return;
    pthread_mutex_lock(&m->lock);
    m->jobs_finished[state - SMD_JOB_FIRST_FINAL]++;
    pthread_mutex_unlock(&m->lock);
}

void smd_metrics_add(smd_metrics *m, uint64_t *counter, uint64_t n)
{
    pthread_mutex_lock(&m->lock);
    *counter += n;
    pthread_mutex_unlock(&m->lock);
}

/* The exposition text: one growable buffer; the first failure sticks. */
typedef struct outbuf {
    char *data;
    size_t len, cap;
    int failed;
} outbuf;

static void out(outbuf *b, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void out(outbuf *b, const char *fmt, ...)
{
    if (b->failed)
        return;
    va_list ap;
    va_start(ap, fmt);
    if (smd_buf_vprintf(&b->data, &b->len, &b->cap, fmt, ap) != 0)
        b->failed = 1;
    va_end(ap);
}

static long resident_bytes(void)
{
    FILE *f = fopen("/proc/self/statm", "r");
    if (!f)
        return -1;
    long size = 0, rss = -1;
    if (fscanf(f, "%ld %ld", &size, &rss) != 2)
        rss = -1;
    fclose(f);
    return rss < 0 ? -1 : rss * sysconf(_SC_PAGESIZE);
}

/* ----------------------------------------------------------- the table
 *
 * One row a metric family: its name, help, type, and where each of its
 * values comes from.  The request counts and latency histograms, whose
 * label sets come from the route table, are rendered at their row by
 * code (ROW_HTTP). */

typedef enum {
    SRC_GAUGE,   /* a uint64_t of smd_gauges (read at scrape time) */
    SRC_COUNTER, /* a uint64_t of smd_metrics (under its lock) */
    SRC_READY,   /* smd_gauges.ready (an int) */
    SRC_START,   /* smd_gauges.start_time, seconds to the millisecond */
    SRC_RSS,     /* /proc/self/statm; the row is left out when unreadable */
    SRC_HTTP     /* the request counts and latencies by route */
} metric_source;

#define MAX_LABELED 5

typedef struct metric_row {
    const char *name, *help, *type;
    metric_source src;
    size_t n;                            /* values (0: one, unlabeled) */
    const char *label;                   /* the label's name when n > 0 */
    const char *values[MAX_LABELED];     /* the label's values */
    size_t offset[MAX_LABELED];          /* of each value (one when n == 0) */
} metric_row;

#define G(f) offsetof(smd_gauges, f)
#define C(f) offsetof(smd_metrics, f)
#define STATES "accepted", "running", "successful", "failed", "dismissed"

static const metric_row rows[] = {
    {"shapematch_jobs", "Jobs in the store by state.", "gauge", SRC_GAUGE, SMD_JOB_STATES, "state",
     {STATES},
     {G(jobs_by_state[0]), G(jobs_by_state[1]), G(jobs_by_state[2]), G(jobs_by_state[3]),
      G(jobs_by_state[4])}},
    {"shapematch_queue_depth", "Jobs waiting for a worker.", "gauge", SRC_GAUGE, 0, NULL, {NULL},
     {G(queue_depth)}},
    {"shapematch_workers_busy", "Worker processes running.", "gauge", SRC_GAUGE, 0, NULL, {NULL},
     {G(workers_busy)}},
    {"shapematch_workers", "Worker slots.", "gauge", SRC_GAUGE, 0, NULL, {NULL},
     {G(workers_total)}},
    {"shapematch_event_streams", "Open event streams.", "gauge", SRC_GAUGE, 0, NULL, {NULL},
     {G(followers)}},
    {"shapematch_records_quarantined",
     "Damaged job records moved to SPOOL/quarantine/ at start.", "gauge", SRC_GAUGE, 0, NULL,
     {NULL}, {G(quarantined)}},
    {"shapematch_connections", "Open HTTP connections.", "gauge", SRC_GAUGE, 0, NULL, {NULL},
     {G(connections)}},
    {"shapematch_connections_cut_total",
     "Connections closed by the daemon: headers past --header-timeout, a body under "
     "--min-upload-rate, or to keep --reserved-connections free.",
     "counter", SRC_GAUGE, 3, "reason", {"header_timeout", "slow_body", "reserve"},
     {G(cut_headers), G(cut_body), G(cut_reserve)}},
    {"shapematch_upload_checks", "Acceptance checks of uploads running and waiting.", "gauge",
     SRC_GAUGE, 2, "state", {"running", "waiting"}, {G(checks_running), G(checks_waiting)}},
    {"shapematch_request_body_bytes",
     "Bytes of request bodies held in memory (warp points, batch and OGC requests).", "gauge",
     SRC_GAUGE, 0, NULL, {NULL}, {G(body_bytes)}},
    {"shapematch_request_body_limit_bytes", "Their bound, --max-body-memory.", "gauge", SRC_GAUGE,
     0, NULL, {NULL}, {G(body_budget)}},
    {"shapematch_ready", "1 when accepting jobs.", "gauge", SRC_READY, 0, NULL, {NULL}, {0}},
    {"process_resident_memory_bytes", "Resident memory of the daemon.", "gauge", SRC_RSS, 0, NULL,
     {NULL}, {0}},
    {"process_start_time_seconds", "Start time of the daemon (Unix seconds).", "gauge", SRC_START,
     0, NULL, {NULL}, {0}},
    {"shapematch_jobs_submitted_total", "Jobs accepted.", "counter", SRC_COUNTER, 0, NULL, {NULL},
     {C(jobs_submitted)}},
    {"shapematch_jobs_finished_total", "Jobs that reached a final state.", "counter", SRC_COUNTER,
     SMD_JOB_FINAL_STATES, "state", {"successful", "failed", "dismissed"},
     {C(jobs_finished[0]), C(jobs_finished[1]), C(jobs_finished[2])}},
    {"shapematch_workers_started_total", "Worker processes started.", "counter", SRC_COUNTER, 0,
     NULL, {NULL}, {C(workers_started)}},
    {"shapematch_events_total", "Events appended to job logs.", "counter", SRC_COUNTER, 0, NULL,
     {NULL}, {C(events_appended)}},
    {NULL, NULL, NULL, SRC_HTTP, 0, NULL, {NULL}, {0}},
    {"shapematch_http_received_bytes_total", "Request bytes received (bodies).", "counter",
     SRC_COUNTER, 0, NULL, {NULL}, {C(bytes_in)}},
    {"shapematch_http_sent_bytes_total", "Response body bytes sent.", "counter", SRC_COUNTER, 0,
     NULL, {NULL}, {C(bytes_out)}},
};

_Static_assert(SMD_JOB_STATES == 5 && SMD_JOB_FINAL_STATES == 3,
               "the state labels of the metrics table");

/* The request counts by route, method and status, and the latency
 * histograms by route (m->lock held). */
static void render_http(outbuf *b, const smd_metrics *m)
{
    out(b, "# HELP shapematch_http_requests_total HTTP requests by route, method and status.\n"
           "# TYPE shapematch_http_requests_total counter\n");
    for (size_t r = 0; r < m->nroutes; r++)
        for (size_t k = 0; k < SMD_METHODS; k++)
            for (size_t c = 0; c < SMD_STATUS_CODES; c++)
                if (REQUESTS(m, r, k, c))
                    out(b, "shapematch_http_requests_total{route=\"%s\",method=\"%s\",code=\"%zu\"} %llu\n",
                        m->routes[r], method_labels[k], c + 100,
                        (unsigned long long)REQUESTS(m, r, k, c));
    out(b, "# HELP shapematch_http_request_duration_seconds Time from request to the end of the "
           "response (event streams: the whole stream).\n"
           "# TYPE shapematch_http_request_duration_seconds histogram\n");
    for (size_t r = 0; r < m->nroutes; r++) {
        if (!m->latency_count[r])
            continue;
        for (size_t k = 0; k < SMD_LATENCY_BUCKETS; k++)
            out(b, "shapematch_http_request_duration_seconds_bucket{route=\"%s\",le=\"%g\"} %llu\n",
                m->routes[r], bucket_bounds[k], (unsigned long long)BUCKET(m, r, k));
        out(b, "shapematch_http_request_duration_seconds_bucket{route=\"%s\",le=\"+Inf\"} %llu\n",
            m->routes[r], (unsigned long long)m->latency_count[r]);
        out(b, "shapematch_http_request_duration_seconds_sum{route=\"%s\"} %.6f\n", m->routes[r],
            m->latency_sum[r]);
        out(b, "shapematch_http_request_duration_seconds_count{route=\"%s\"} %llu\n",
            m->routes[r], (unsigned long long)m->latency_count[r]);
    }
}

static uint64_t u64_at(const void *base, size_t offset)
{
    uint64_t v;
    memcpy(&v, (const char *)base + offset, sizeof v);
    return v;
}

/* One row's HELP, TYPE and values. */
static void render_row(outbuf *b, const metric_row *row, const smd_metrics *m, const smd_gauges *g)
{
    long rss = 0;
    if (row->src == SRC_RSS && (rss = resident_bytes()) < 0)
        return;
    out(b, "# HELP %s %s\n# TYPE %s %s\n", row->name, row->help, row->name, row->type);
    const void *base = row->src == SRC_COUNTER ? (const void *)m : (const void *)g;
    switch (row->src) {
    case SRC_READY:
        out(b, "%s %d\n", row->name, g->ready);
        return;
    case SRC_START:
        out(b, "%s %.3f\n", row->name, g->start_time);
        return;
    case SRC_RSS:
        out(b, "%s %ld\n", row->name, rss);
        return;
    default:
        break;
    }
    if (row->n == 0)
        out(b, "%s %llu\n", row->name, (unsigned long long)u64_at(base, row->offset[0]));
    for (size_t i = 0; i < row->n; i++)
        out(b, "%s{%s=\"%s\"} %llu\n", row->name, row->label, row->values[i],
            (unsigned long long)u64_at(base, row->offset[i]));
}

char *smd_metrics_render(smd_metrics *m, const smd_gauges *g, size_t *len)
{
    outbuf b = {malloc(16384), 0, 16384, 0};
    if (!b.data)
        return NULL;
    b.data[0] = '\0';
    int locked = 0;
    for (size_t i = 0; i < sizeof rows / sizeof rows[0]; i++) {
        const metric_row *row = &rows[i];
        /* the gauges come first, read without the lock (the memory row
         * reads /proc); the counters and requests after, under it */
        if ((row->src == SRC_COUNTER || row->src == SRC_HTTP) && !locked) {
            pthread_mutex_lock(&m->lock);
            locked = 1;
        }
        if (row->src == SRC_HTTP)
            render_http(&b, m);
        else
            render_row(&b, row, m, g);
    }
    if (locked)
        pthread_mutex_unlock(&m->lock);
    if (b.failed) {
        free(b.data);
        return NULL;
    }
    if (len)
        *len = b.len;
    return b.data;
}
