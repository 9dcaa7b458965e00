/* Prometheus metrics (see smd_metrics.h). */
#include "base/smd_metrics.h"

#include <stdarg.h>
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

static const char *const all_states[SMD_JOB_STATES] = {"accepted", "running", "successful",
                                                       "failed", "dismissed"};

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

char *smd_metrics_render(smd_metrics *m, const smd_gauges *g, size_t *len)
{
    outbuf b = {malloc(16384), 0, 16384, 0};
    if (!b.data)
        return NULL;
    b.data[0] = '\0';
    out(&b, "# HELP shapematch_jobs Jobs in the store by state.\n# TYPE shapematch_jobs gauge\n");
    for (int s = 0; s < SMD_JOB_STATES; s++)
        out(&b, "shapematch_jobs{state=\"%s\"} %llu\n", all_states[s],
            (unsigned long long)g->jobs_by_state[s]);
    out(&b, "# HELP shapematch_queue_depth Jobs waiting for a worker.\n"
            "# TYPE shapematch_queue_depth gauge\nshapematch_queue_depth %llu\n",
        (unsigned long long)g->queue_depth);
    out(&b, "# HELP shapematch_workers_busy Worker processes running.\n"
            "# TYPE shapematch_workers_busy gauge\nshapematch_workers_busy %llu\n",
        (unsigned long long)g->workers_busy);
    out(&b, "# HELP shapematch_workers Worker slots.\n"
            "# TYPE shapematch_workers gauge\nshapematch_workers %llu\n",
        (unsigned long long)g->workers_total);
    out(&b, "# HELP shapematch_event_streams Open event streams.\n"
            "# TYPE shapematch_event_streams gauge\nshapematch_event_streams %llu\n",
        (unsigned long long)g->followers);
    out(&b, "# HELP shapematch_records_quarantined Damaged job records moved to "
            "SPOOL/quarantine/ at start.\n# TYPE shapematch_records_quarantined gauge\n"
            "shapematch_records_quarantined %llu\n",
        (unsigned long long)g->quarantined);
    out(&b, "# HELP shapematch_connections Open HTTP connections.\n"
            "# TYPE shapematch_connections gauge\nshapematch_connections %llu\n",
        (unsigned long long)g->connections);
    out(&b, "# HELP shapematch_connections_cut_total Connections closed by the daemon: headers "
            "past --header-timeout, a body under --min-upload-rate, or to keep "
            "--reserved-connections free.\n# TYPE shapematch_connections_cut_total counter\n"
            "shapematch_connections_cut_total{reason=\"header_timeout\"} %llu\n"
            "shapematch_connections_cut_total{reason=\"slow_body\"} %llu\n"
            "shapematch_connections_cut_total{reason=\"reserve\"} %llu\n",
        (unsigned long long)g->cut_headers, (unsigned long long)g->cut_body,
        (unsigned long long)g->cut_reserve);
    out(&b, "# HELP shapematch_upload_checks Acceptance checks of uploads running and waiting.\n"
            "# TYPE shapematch_upload_checks gauge\n"
            "shapematch_upload_checks{state=\"running\"} %llu\n"
            "shapematch_upload_checks{state=\"waiting\"} %llu\n",
        (unsigned long long)g->checks_running, (unsigned long long)g->checks_waiting);
    out(&b, "# HELP shapematch_ready 1 when accepting jobs.\n"
            "# TYPE shapematch_ready gauge\nshapematch_ready %d\n", g->ready);
    long rss = resident_bytes();
    if (rss >= 0)
        out(&b, "# HELP process_resident_memory_bytes Resident memory of the daemon.\n"
                "# TYPE process_resident_memory_bytes gauge\nprocess_resident_memory_bytes %ld\n",
            rss);
    out(&b, "# HELP process_start_time_seconds Start time of the daemon (Unix seconds).\n"
            "# TYPE process_start_time_seconds gauge\nprocess_start_time_seconds %.3f\n",
        g->start_time);

    pthread_mutex_lock(&m->lock);
    out(&b, "# HELP shapematch_jobs_submitted_total Jobs accepted.\n"
            "# TYPE shapematch_jobs_submitted_total counter\nshapematch_jobs_submitted_total %llu\n",
        (unsigned long long)m->jobs_submitted);
    out(&b, "# HELP shapematch_jobs_finished_total Jobs that reached a final state.\n"
            "# TYPE shapematch_jobs_finished_total counter\n");
    for (int s = 0; s < SMD_JOB_FINAL_STATES; s++)
        out(&b, "shapematch_jobs_finished_total{state=\"%s\"} %llu\n", all_states[SMD_JOB_FIRST_FINAL + s],
            (unsigned long long)m->jobs_finished[s]);
    out(&b, "# HELP shapematch_workers_started_total Worker processes started.\n"
            "# TYPE shapematch_workers_started_total counter\nshapematch_workers_started_total %llu\n",
        (unsigned long long)m->workers_started);
    out(&b, "# HELP shapematch_events_total Events appended to job logs.\n"
            "# TYPE shapematch_events_total counter\nshapematch_events_total %llu\n",
        (unsigned long long)m->events_appended);
    out(&b, "# HELP shapematch_http_requests_total HTTP requests by route, method and status.\n"
            "# TYPE shapematch_http_requests_total counter\n");
    for (size_t r = 0; r < m->nroutes; r++)
        for (size_t k = 0; k < SMD_METHODS; k++)
            for (size_t c = 0; c < SMD_STATUS_CODES; c++)
                if (REQUESTS(m, r, k, c))
                    out(&b, "shapematch_http_requests_total{route=\"%s\",method=\"%s\",code=\"%zu\"} %llu\n",
                        m->routes[r], method_labels[k], c + 100,
                        (unsigned long long)REQUESTS(m, r, k, c));
    out(&b, "# HELP shapematch_http_request_duration_seconds Time from request to the end of the "
            "response (event streams: the whole stream).\n"
            "# TYPE shapematch_http_request_duration_seconds histogram\n");
    for (size_t r = 0; r < m->nroutes; r++) {
        if (!m->latency_count[r])
            continue;
        for (size_t k = 0; k < SMD_LATENCY_BUCKETS; k++)
            out(&b, "shapematch_http_request_duration_seconds_bucket{route=\"%s\",le=\"%g\"} %llu\n",
                m->routes[r], bucket_bounds[k], (unsigned long long)BUCKET(m, r, k));
        out(&b, "shapematch_http_request_duration_seconds_bucket{route=\"%s\",le=\"+Inf\"} %llu\n",
            m->routes[r], (unsigned long long)m->latency_count[r]);
        out(&b, "shapematch_http_request_duration_seconds_sum{route=\"%s\"} %.6f\n", m->routes[r],
            m->latency_sum[r]);
        out(&b, "shapematch_http_request_duration_seconds_count{route=\"%s\"} %llu\n",
            m->routes[r], (unsigned long long)m->latency_count[r]);
    }
    out(&b, "# HELP shapematch_http_received_bytes_total Request bytes received (bodies).\n"
            "# TYPE shapematch_http_received_bytes_total counter\nshapematch_http_received_bytes_total %llu\n",
        (unsigned long long)m->bytes_in);
    out(&b, "# HELP shapematch_http_sent_bytes_total Response body bytes sent.\n"
            "# TYPE shapematch_http_sent_bytes_total counter\nshapematch_http_sent_bytes_total %llu\n",
        (unsigned long long)m->bytes_out);
    pthread_mutex_unlock(&m->lock);
    if (b.failed) {
        free(b.data);
        return NULL;
    }
    if (len)
        *len = b.len;
    return b.data;
}
