/* The /metrics text (smd_metrics_render, one table of rows): each value
 * lands on its own name and label, every family has its HELP and TYPE
 * once, in the table's order, and the request counts and latency
 * histograms follow the requests recorded. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "base/smd_metrics.h"

static const char *const routes[] = {"other", "/v1/jobs", "/v1/jobs/{id}"};

/* text holds line as a whole line. */
static int has_line(const char *text, const char *line)
{
    size_t n = strlen(line);
    for (const char *p = text; (p = strstr(p, line)) != NULL; p++)
        if ((p == text || p[-1] == '\n') && p[n] == '\n')
            return 1;
    return 0;
}

static size_t count(const char *text, const char *needle)
{
    size_t k = 0;
    for (const char *p = text; (p = strstr(p, needle)) != NULL; p++)
        k++;
    return k;
}

static void test_values_on_their_rows(void **state)
{
    (void)state;
    smd_metrics m;
    assert_int_equal(smd_metrics_init(&m, routes, 3), 0);
    smd_metrics_request(&m, "/v1/jobs", "POST", 201, 0.003, 1000, 200);
    smd_metrics_request(&m, "/v1/jobs/{id}", "GET", 200, 0.0002, 0, 500);
    smd_metrics_request(&m, "no such route", "PATCH", 404, 2.0, 5, 10);
    smd_metrics_job_finished(&m, 2); /* successful */
    smd_metrics_job_finished(&m, 4); /* dismissed */
    smd_metrics_job_finished(&m, 4);
    smd_metrics_job_finished(&m, 1); /* not final: ignored */
    smd_metrics_add(&m, &m.jobs_submitted, 7);
    smd_metrics_add(&m, &m.events_appended, 99);
    smd_metrics_add(&m, &m.workers_started, 3);
    smd_gauges g = {.jobs_by_state = {1, 2, 3, 4, 5}, .queue_depth = 6, .workers_busy = 7,
                    .workers_total = 8, .followers = 9, .quarantined = 10, .connections = 11,
                    .cut_headers = 12, .cut_body = 13, .cut_reserve = 14, .checks_running = 15,
                    .checks_waiting = 16, .body_bytes = 17, .body_budget = 18,
                    .start_time = 1700000000.25, .ready = 1};
    size_t len = 0;
    char *t = smd_metrics_render(&m, &g, &len);
    assert_non_null(t);
    assert_int_equal(strlen(t), len);

    static const char *const want[] = {
        "shapematch_jobs{state=\"accepted\"} 1",
        "shapematch_jobs{state=\"dismissed\"} 5",
        "shapematch_queue_depth 6",
        "shapematch_workers_busy 7",
        "shapematch_workers 8",
        "shapematch_event_streams 9",
        "shapematch_records_quarantined 10",
        "shapematch_connections 11",
        "shapematch_connections_cut_total{reason=\"header_timeout\"} 12",
        "shapematch_connections_cut_total{reason=\"slow_body\"} 13",
        "shapematch_connections_cut_total{reason=\"reserve\"} 14",
        "shapematch_upload_checks{state=\"running\"} 15",
        "shapematch_upload_checks{state=\"waiting\"} 16",
        "shapematch_request_body_bytes 17",
        "shapematch_request_body_limit_bytes 18",
        "shapematch_ready 1",
        "process_start_time_seconds 1700000000.250",
        "shapematch_jobs_submitted_total 7",
        "shapematch_jobs_finished_total{state=\"successful\"} 1",
        "shapematch_jobs_finished_total{state=\"failed\"} 0",
        "shapematch_jobs_finished_total{state=\"dismissed\"} 2",
        "shapematch_workers_started_total 3",
        "shapematch_events_total 99",
        "shapematch_http_requests_total{route=\"/v1/jobs\",method=\"POST\",code=\"201\"} 1",
        "shapematch_http_requests_total{route=\"other\",method=\"other\",code=\"404\"} 1",
        "shapematch_http_request_duration_seconds_bucket{route=\"/v1/jobs/{id}\",le=\"0.00025\"} 1",
        "shapematch_http_request_duration_seconds_bucket{route=\"/v1/jobs/{id}\",le=\"0.0001\"} 0",
        "shapematch_http_request_duration_seconds_bucket{route=\"other\",le=\"2.5\"} 1",
        "shapematch_http_request_duration_seconds_bucket{route=\"other\",le=\"1\"} 0",
        "shapematch_http_request_duration_seconds_count{route=\"/v1/jobs\"} 1",
        "shapematch_http_received_bytes_total 1005",
        "shapematch_http_sent_bytes_total 710",
        "# TYPE shapematch_connections_cut_total counter",
        "# TYPE shapematch_jobs gauge",
    };
    for (size_t i = 0; i < sizeof want / sizeof want[0]; i++) {
        if (!has_line(t, want[i]))
            fail_msg("missing line: %s", want[i]);
    }
    /* each family once, 22 of them (the memory row when /proc is there) */
    size_t helps = count(t, "# HELP "), types = count(t, "# TYPE ");
    assert_int_equal(helps, types);
    assert_int_equal(helps, 22);
    /* the table's order: gauges, process, counters, requests, bytes */
    const char *order[] = {"# HELP shapematch_jobs ", "# HELP shapematch_ready ",
                           "# HELP process_start_time_seconds ",
                           "# HELP shapematch_jobs_submitted_total ",
                           "# HELP shapematch_http_requests_total ",
                           "# HELP shapematch_http_sent_bytes_total "};
    const char *prev = t;
    for (size_t i = 0; i < sizeof order / sizeof order[0]; i++) {
        const char *p = strstr(t, order[i]);
        assert_non_null(p);
        assert_true(p >= prev);
        prev = p;
    }
    /* no request to /v1/jobs with GET: no line for it */
    assert_null(strstr(t, "route=\"/v1/jobs\",method=\"GET\""));
    free(t);
    smd_metrics_destroy(&m);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_values_on_their_rows),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
