/* Daemon helpers: job ids, constant-time comparison, bounded paths,
 * durable writes, folder removal that never follows links, sizes and
 * durations, wait statuses, the job queue and the content negotiation. */
#include <dirent.h>
#include <errno.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>
#include <cmocka.h>

#include "sm_proto_text.h"
#include "base/smd_metrics.h"
#include "http/smd_negotiate.h"
#include "http/smd_reply.h"
#include "api/smd_route_table.h"
#include "api/smd_upload.h"
#include "store/spool/smd_fifo.h"
#include "base/smd_util.h"

static void test_random_ids(void **state)
{
    (void)state;
    enum { N = 2000 };
    static char ids[N][SMD_ID_LEN + 1];
    int seen_digit[16] = {0};
    for (int i = 0; i < N; i++) {
        assert_int_equal(smd_random_id(ids[i]), 0);
        assert_true(smd_id_valid(ids[i]));
        for (int k = 0; k < SMD_ID_LEN; k++) {
            char c = ids[i][k];
            seen_digit[c <= '9' ? c - '0' : c - 'a' + 10]++;
        }
    }
    for (int i = 0; i < N; i++)
        for (int j = i + 1; j < N; j++)
            assert_string_not_equal(ids[i], ids[j]);
    /* 64000 digits: each of the 16 values ~4000 times; a stuck bit
     * (half the values never seen) or a constant would show */
    for (int d = 0; d < 16; d++)
        assert_in_range(seen_digit[d], 3500, 4500);
}

static void test_id_valid(void **state)
{
    (void)state;
    assert_true(smd_id_valid("0123456789abcdef0123456789abcdef"));
    assert_false(smd_id_valid("0123456789ABCDEF0123456789abcdef"));
    assert_false(smd_id_valid("0123456789abcdef0123456789abcde"));
    assert_false(smd_id_valid("0123456789abcdef0123456789abcdef0"));
    assert_false(smd_id_valid("../../../../etc/passwd0123456789a"));
    assert_false(smd_id_valid("0123456789abcdef0123456789abcde/"));
    assert_false(smd_id_valid(""));
    assert_false(smd_id_valid(NULL));
}

static void test_secret_equal(void **state)
{
    (void)state;
    assert_true(smd_secret_equal("token", 5, "token", 5));
    assert_false(smd_secret_equal("tokem", 5, "token", 5));
    assert_false(smd_secret_equal("Token", 5, "token", 5));
    assert_false(smd_secret_equal("tok", 3, "token", 5));
    assert_false(smd_secret_equal("tokens", 6, "token", 5));
    assert_false(smd_secret_equal("", 0, "token", 5));
    /* a NUL inside the given bytes is not a terminator */
    assert_false(smd_secret_equal("tok\0n", 5, "token", 5));
    assert_true(smd_secret_equal("", 0, "", 0));
}

static void test_pathf(void **state)
{
    (void)state;
    char buf[16];
    assert_int_equal(smd_pathf(buf, sizeof buf, "%s/%s", "ab", "cd"), 0);
    assert_string_equal(buf, "ab/cd");
    assert_int_equal(smd_pathf(buf, sizeof buf, "%s/%s", "0123456789", "abcdef"), -1);
    assert_int_equal(errno, ENAMETOOLONG);
    assert_int_equal(smd_pathf(buf, sizeof buf, "%s", "012345678901234"), 0);
    assert_int_equal(smd_pathf(buf, sizeof buf, "%s", "0123456789012345"), -1);
}

static void test_bounded_integers(void **state)
{
    (void)state;
    uint64_t v = 7;
    assert_int_equal(smd_parse_uint("0", 0, 10, &v), SMD_NUM_OK);
    assert_true(v == 0);
    assert_int_equal(smd_parse_uint("0010", 0, 10, &v), SMD_NUM_OK);
    assert_true(v == 10);
    assert_int_equal(smd_parse_uint("11", 0, 10, &v), SMD_NUM_RANGE);
    assert_true(v == 10); /* left alone */
    assert_int_equal(smd_parse_uint("0", 1, 10, &v), SMD_NUM_RANGE);
    assert_int_equal(smd_parse_uint("", 0, 10, &v), SMD_NUM_MALFORMED);
    assert_int_equal(smd_parse_uint(NULL, 0, 10, &v), SMD_NUM_MALFORMED);
    assert_int_equal(smd_parse_uint("-1", 0, 10, &v), SMD_NUM_MALFORMED);
    assert_int_equal(smd_parse_uint("+1", 0, 10, &v), SMD_NUM_MALFORMED);
    assert_int_equal(smd_parse_uint(" 1", 0, 10, &v), SMD_NUM_MALFORMED);
    assert_int_equal(smd_parse_uint("1x", 0, 10, &v), SMD_NUM_MALFORMED);
    /* the overflow edges: INT64_MAX, UINT64_MAX and one past it */
    assert_int_equal(smd_parse_uint("9223372036854775807", 0, SMD_REQUEST_INT_MAX, &v),
                     SMD_NUM_RANGE);
    assert_int_equal(smd_parse_uint("9007199254740991", 0, SMD_REQUEST_INT_MAX, &v), SMD_NUM_OK);
    assert_true(v == 9007199254740991ULL);
    assert_int_equal(smd_parse_uint("9007199254740992", 0, SMD_REQUEST_INT_MAX, &v), SMD_NUM_RANGE);
    assert_int_equal(smd_parse_uint("18446744073709551615", 0, UINT64_MAX, &v), SMD_NUM_OK);
    assert_true(v == UINT64_MAX);
    assert_int_equal(smd_parse_uint("18446744073709551616", 0, UINT64_MAX, &v), SMD_NUM_RANGE);
    assert_int_equal(smd_parse_uint("99999999999999999999999999999999999999", 0, UINT64_MAX, &v),
                     SMD_NUM_RANGE);
    assert_int_equal(smd_parse_uint("9999999999999999999999999999999999999x", 0, UINT64_MAX, &v),
                     SMD_NUM_MALFORMED);
    assert_int_equal(smd_parse_uint("5", 0, 0, &v), SMD_NUM_RANGE);
}

static void test_sizes_and_durations(void **state)
{
    (void)state;
    uint64_t v;
    assert_int_equal(smd_parse_size("1048576", &v), 0);
    assert_true(v == 1048576);
    assert_int_equal(smd_parse_size("64K", &v), 0);
    assert_true(v == 65536);
    assert_int_equal(smd_parse_size("256M", &v), 0);
    assert_true(v == (uint64_t)256 << 20);
    assert_int_equal(smd_parse_size("2GiB", &v), 0);
    assert_true(v == (uint64_t)2 << 30);
    assert_int_equal(smd_parse_size("1.5G", &v), -1);
    assert_int_equal(smd_parse_size("-1", &v), -1);
    assert_int_equal(smd_parse_size("", &v), -1);
    assert_int_equal(smd_parse_size("12Q", &v), -1);
    assert_int_equal(smd_parse_size("99999999999999T", &v), -1);
    assert_int_equal(smd_parse_size("18446744073709551616", &v), -1);

    double d;
    assert_int_equal(smd_parse_duration("30", &d), 0);
    assert_true(d == 30);
    assert_int_equal(smd_parse_duration("0.5s", &d), 0);
    assert_true(d == 0.5);
    assert_int_equal(smd_parse_duration("15m", &d), 0);
    assert_true(d == 900);
    assert_int_equal(smd_parse_duration("2h", &d), 0);
    assert_true(d == 7200);
    assert_int_equal(smd_parse_duration("7d", &d), 0);
    assert_true(d == 7 * 86400);
    assert_int_equal(smd_parse_duration("-1", &d), -1);
    assert_int_equal(smd_parse_duration("1x", &d), -1);
    assert_int_equal(smd_parse_duration("1hh", &d), -1);
    assert_int_equal(smd_parse_duration("", &d), -1);
    assert_int_equal(smd_parse_duration("nan", &d), -1);
    assert_int_equal(smd_parse_duration("1e999", &d), -1);
}

static void test_wait_status(void **state)
{
    (void)state;
    char buf[128];
    smd_describe_wait_status(2 << 8, buf, sizeof buf);
    assert_string_equal(buf, "exited with status 2");
    smd_describe_wait_status(9, buf, sizeof buf);
    assert_string_equal(buf, "killed by signal 9 (SIGKILL)");
    smd_describe_wait_status(24, buf, sizeof buf);
    assert_string_equal(buf, "killed by signal 24 (SIGXCPU)");
    smd_describe_wait_status(11 | 0x80, buf, sizeof buf);
    assert_string_equal(buf, "killed by signal 11 (SIGSEGV), core dumped");
}

static char *temp_dir(void)
{
    char *d = strdup("/tmp/sm-test-server-XXXXXX");
    assert_non_null(mkdtemp(d));
    return d;
}

static int count_entries(const char *dir)
{
    DIR *d = opendir(dir);
    assert_non_null(d);
    int n = 0;
    struct dirent *de;
    while ((de = readdir(d)))
        n += de->d_name[0] != '.';
    closedir(d);
    return n;
}

static void test_atomic_write_and_read(void **state)
{
    (void)state;
    char *dir = temp_dir();
    char path[512];
    snprintf(path, sizeof path, "%s/status.json", dir);
    assert_int_equal(smd_write_file_atomic(path, "first", 5), 0);
    assert_int_equal(smd_write_file_atomic(path, "second!", 7), 0);
    char *text;
    size_t len;
    assert_int_equal(smd_read_file(path, 100, &text, &len), 0);
    assert_int_equal(len, 7);
    assert_string_equal(text, "second!");
    free(text);
    /* no temporary file left next to it */
    assert_int_equal(count_entries(dir), 1);
    /* the bound is enforced */
    assert_int_equal(smd_read_file(path, 6, &text, &len), -1);
    assert_int_equal(errno, EFBIG);
    assert_null(text);
    /* a folder cannot be read as a file */
    assert_int_equal(smd_read_file(dir, 100, &text, &len), -1);
    assert_int_equal(smd_rmtree(dir), 0);
    free(dir);
}

static void test_rmtree_keeps_link_targets(void **state)
{
    (void)state;
    char *outside = temp_dir();
    char *dir = temp_dir();
    char p[512], q[512];
    snprintf(p, sizeof p, "%s/precious", outside);
    assert_int_equal(smd_write_file_atomic(p, "keep me", 7), 0);
    snprintf(q, sizeof q, "%s/a/b/c", dir);
    assert_int_equal(smd_mkdirs(q, 0700), 0);
    snprintf(q, sizeof q, "%s/a/b/c/file", dir);
    assert_int_equal(smd_write_file_atomic(q, "x", 1), 0);
    snprintf(q, sizeof q, "%s/a/link-to-outside", dir);
    assert_int_equal(symlink(outside, q), 0);
    snprintf(q, sizeof q, "%s/a/link-to-file", dir);
    assert_int_equal(symlink(p, q), 0);
    assert_int_equal(smd_rmtree(dir), 0);
    struct stat st;
    assert_int_equal(stat(dir, &st), -1);
    assert_int_equal(stat(p, &st), 0); /* the link target survives */
    assert_int_equal(smd_rmtree(dir), 0); /* missing: fine */
    assert_int_equal(smd_rmtree(outside), 0);
    free(dir);
    free(outside);
}

static void test_queue_fifo(void **state)
{
    (void)state;
    smd_queue *q = smd_queue_local_new();
    assert_non_null(q);
    char id[SMD_ID_LEN + 1], got[SMD_ID_LEN + 1];
    /* interleaved pushes and pops wrap the ring and make it grow */
    int next_in = 0, next_out = 0;
    for (int round = 0; round < 50; round++) {
        for (int k = 0; k < 7; k++) {
            snprintf(id, sizeof id, "%032d", next_in++);
            assert_int_equal(smd_queue_push(q, id), 0);
        }
        for (int k = 0; k < 5; k++) {
            assert_int_equal(smd_queue_pop(q, got), 1);
            snprintf(id, sizeof id, "%032d", next_out++);
            assert_string_equal(got, id);
        }
    }
    assert_int_equal(smd_queue_depth(q), 100);
    /* position and removal in the middle */
    int removed = next_out + 10;
    snprintf(id, sizeof id, "%032d", removed);
    assert_int_equal(smd_queue_position(q, id), 10);
    assert_int_equal(smd_queue_remove(q, id), 1);
    assert_int_equal(smd_queue_remove(q, id), 0);
    assert_int_equal(smd_queue_position(q, id), -1);
    assert_int_equal(smd_queue_depth(q), 99);
    for (int k = 0; k < 99; k++) {
        if (next_out == removed)
            next_out++;
        assert_int_equal(smd_queue_pop(q, got), 1);
        snprintf(id, sizeof id, "%032d", next_out++);
        assert_string_equal(got, id);
    }
    assert_int_equal(next_out, next_in);
    assert_int_equal(smd_queue_pop(q, got), 0);
    smd_queue_free(q);
}

static void test_accept(void **state)
{
    (void)state;
    const char *mesh[] = {"application/x-medit-mesh", "application/x-medit-meshb",
                          "application/vnd.vtk.vtu+xml", "application/vnd.shapematch.mesh"};
    assert_int_equal(smd_accept_choose(NULL, mesh, 4), 0);
    assert_int_equal(smd_accept_choose("", mesh, 4), 0);
    assert_int_equal(smd_accept_choose("*/*", mesh, 4), 0);
    assert_int_equal(smd_accept_choose("application/vnd.shapematch.mesh", mesh, 4), 3);
    assert_int_equal(smd_accept_choose("APPLICATION/X-MEDIT-MESHB", mesh, 4), 1);
    assert_int_equal(smd_accept_choose("text/html, application/vnd.vtk.vtu+xml;q=0.5", mesh, 4), 2);
    /* the higher q wins whatever the order */
    assert_int_equal(smd_accept_choose("application/x-medit-mesh;q=0.2, application/x-medit-meshb;q=0.9",
                                       mesh, 4), 1);
    /* the most specific range decides: any type at 0.5 but mesh refused */
    assert_int_equal(smd_accept_choose("application/x-medit-mesh;q=0, */*;q=0.5", mesh, 4), 1);
    assert_int_equal(smd_accept_choose("application/*", mesh, 4), 0);
    assert_int_equal(smd_accept_choose("text/html", mesh, 4), -1);
    assert_int_equal(smd_accept_choose("*/*;q=0", mesh, 4), -1);
    assert_int_equal(smd_accept_choose("application/x-medit-mesh; q=0.0", mesh, 1), -1);
    const char *events[] = {"application/x-ndjson", "text/event-stream"};
    assert_int_equal(smd_accept_choose("text/event-stream", events, 2), 1);
    assert_int_equal(smd_accept_choose("text/*", events, 2), 1);
    assert_int_equal(smd_accept_choose("*/*", events, 2), 0);
    /* garbage does not crash and matches nothing */
    assert_int_equal(smd_accept_choose(";;;,,,q=,/", events, 2), -1);

    assert_true(smd_accepts_gzip("gzip"));
    assert_true(smd_accepts_gzip("deflate, gzip;q=0.5"));
    assert_true(smd_accepts_gzip("*"));
    assert_true(smd_accepts_gzip("x-gzip"));
    assert_false(smd_accepts_gzip(NULL));
    assert_false(smd_accepts_gzip("identity"));
    assert_false(smd_accepts_gzip("gzip;q=0"));
    assert_false(smd_accepts_gzip("*, gzip;q=0"));
    assert_false(smd_accepts_gzip("*;q=0"));
}

static void test_gzip_buffer(void **state)
{
    (void)state;
    size_t n = 100000;
    char *data = malloc(n);
    assert_non_null(data);
    for (size_t i = 0; i < n; i++)
        data[i] = (char)("0123456789 ,.\n"[(i * 7 + i / 13) % 14]);
    char *z;
    size_t zlen;
    assert_int_equal(smd_gzip_buffer(data, n, &z, &zlen), 0);
    assert_true(zlen < n / 4);
    assert_int_equal((unsigned char)z[0], 0x1f);
    assert_int_equal((unsigned char)z[1], 0x8b);
    z_stream s;
    memset(&s, 0, sizeof s);
    assert_int_equal(inflateInit2(&s, 15 + 16), Z_OK);
    char *back = malloc(n + 16);
    s.next_in = (Bytef *)z;
    s.avail_in = (uInt)zlen;
    s.next_out = (Bytef *)back;
    s.avail_out = (uInt)(n + 16);
    assert_int_equal(inflate(&s, Z_FINISH), Z_STREAM_END);
    assert_int_equal(s.total_out, n);
    assert_memory_equal(back, data, n);
    inflateEnd(&s);
    free(back);
    free(z);
    free(data);
}

static void test_metrics(void **state)
{
    (void)state;
    smd_metrics m;
    static const char *const labels[] = {"other", "/v1/jobs", "/v1/jobs/{id}"};
    assert_int_equal(smd_metrics_init(&m, labels, 3), 0);
    smd_metrics_request(&m, "/v1/jobs/{id}", "GET", 200, 0.0003, 0, 100);
    smd_metrics_request(&m, labels[2], "GET", 200, 0.02, 0, 100);
    smd_metrics_request(&m, "/v1/jobs/{id}", "GET", 404, 5.0, 0, 50);
    smd_metrics_request(&m, "/v1/jobs", "POST", 201, 0.5, 123456, 600);
    smd_metrics_request(&m, "/nowhere", "GET", 404, 0.001, 0, 0); /* counted as "other" */
    smd_metrics_job_finished(&m, 2);
    smd_gauges g = {.jobs_by_state = {1, 2, 3, 4, 5}, .queue_depth = 1, .workers_busy = 2,
                    .workers_total = 4, .start_time = 1700000000, .ready = 1};
    size_t len;
    char *text = smd_metrics_render(&m, &g, &len);
    assert_non_null(text);
    assert_int_equal(len, strlen(text));
    const char *must[] = {
        "shapematch_jobs{state=\"running\"} 2\n",
        "shapematch_queue_depth 1\n",
        "shapematch_workers_busy 2\n",
        "shapematch_http_requests_total{route=\"/v1/jobs/{id}\",method=\"GET\",code=\"200\"} 2\n",
        "shapematch_http_requests_total{route=\"/v1/jobs/{id}\",method=\"GET\",code=\"404\"} 1\n",
        "shapematch_http_requests_total{route=\"/v1/jobs\",method=\"POST\",code=\"201\"} 1\n",
        "shapematch_http_request_duration_seconds_bucket{route=\"/v1/jobs/{id}\",le=\"0.0005\"} 1\n",
        "shapematch_http_request_duration_seconds_bucket{route=\"/v1/jobs/{id}\",le=\"0.025\"} 2\n",
        "shapematch_http_request_duration_seconds_bucket{route=\"/v1/jobs/{id}\",le=\"10\"} 3\n",
        "shapematch_http_request_duration_seconds_bucket{route=\"/v1/jobs/{id}\",le=\"+Inf\"} 3\n",
        "shapematch_http_request_duration_seconds_count{route=\"/v1/jobs/{id}\"} 3\n",
        "shapematch_http_received_bytes_total 123456\n",
        "shapematch_http_sent_bytes_total 850\n",
        "shapematch_jobs_finished_total{state=\"successful\"} 1\n",
        "shapematch_http_requests_total{route=\"other\",method=\"GET\",code=\"404\"} 1\n",
        "# TYPE shapematch_http_request_duration_seconds histogram\n",
    };
    for (size_t i = 0; i < sizeof must / sizeof must[0]; i++)
        if (!strstr(text, must[i]))
            fail_msg("missing: %s", must[i]);
    /* buckets are cumulative: never decreasing along a route */
    const char *p = text;
    long prev = -1;
    while ((p = strstr(p, "route=\"/v1/jobs/{id}\",le=\"")) != NULL) {
        const char *close = strstr(p, "} ");
        long v = strtol(close + 2, NULL, 10);
        assert_true(v >= prev);
        prev = v;
        p = close;
    }
    assert_int_equal(prev, 3);
    free(text);
    smd_metrics_destroy(&m);
}


static void test_route_table(void **state)
{
    (void)state;
    smd_request req;
    unsigned allowed;
    const smd_route *route, *first;
    const char *id = "0123456789abcdef0123456789abcdef";
    char path[128];

    memset(&req, 0, sizeof req);
    first = smd_route_find("/v1/jobs", SMD_METHOD_POST, &req, &allowed, &route);
    assert_non_null(first);
    assert_non_null(route);
    assert_true(route->handler == smd_upload_begin);
    assert_int_equal(allowed, SMD_METHOD_GET | SMD_METHOD_HEAD | SMD_METHOD_POST);
    assert_string_equal(first->label, "/v1/jobs");

    snprintf(path, sizeof path, "/v1/jobs/%s", id);
    first = smd_route_find(path, smd_method_bit("PUT"), &req, &allowed, &route);
    assert_non_null(first);
    assert_null(route); /* 405 */
    assert_string_equal(req.id, id);
    assert_int_equal(req.bad_id, 0);
    char allow[64];
    smd_methods_format(allowed, allow, sizeof allow);
    assert_string_equal(allow, "GET, HEAD, DELETE");

    /* a malformed id matches (404 no-such-job) but is never kept */
    first = smd_route_find("/v1/jobs/../../etc/events", SMD_METHOD_GET, &req, &allowed, &route);
    assert_null(first);
    first = smd_route_find("/v1/jobs/XYZ/events", SMD_METHOD_GET, &req, &allowed, &route);
    assert_non_null(first);
    assert_int_equal(req.bad_id, 1);
    assert_string_equal(req.id, "");
    first = smd_route_find("/v1/jobs/", SMD_METHOD_GET, &req, &allowed, &route);
    assert_non_null(first);
    assert_int_equal(req.bad_id, 1);

    /* snapshots: counted under /results; the iteration segment is bounded */
    snprintf(path, sizeof path, "/v1/jobs/%s/results/snapshots/12", id);
    first = smd_route_find(path, SMD_METHOD_GET, &req, &allowed, &route);
    assert_non_null(route);
    assert_string_equal(req.arg, "12");
    assert_string_equal(route->label, "/v1/jobs/{id}/results");
    snprintf(path, sizeof path, "/v1/jobs/%s/results/snapshots/12345678901234567", id);
    assert_null(smd_route_find(path, SMD_METHOD_GET, &req, &allowed, &route));
    snprintf(path, sizeof path, "/v1/jobs/%s/results/snapshots/", id);
    assert_null(smd_route_find(path, SMD_METHOD_GET, &req, &allowed, &route));

    first = smd_route_find("/v1/processes/match", SMD_METHOD_HEAD, &req, &allowed, &route);
    assert_non_null(route);
    assert_string_equal(req.pid, "match");
    assert_null(smd_route_find("/v1/processes/", SMD_METHOD_GET, &req, &allowed, &route));
    assert_null(smd_route_find("/v1/processes/match/x", SMD_METHOD_GET, &req, &allowed, &route));
    first = smd_route_find("/healthz", SMD_METHOD_GET, &req, &allowed, &route);
    assert_true(first && first->public);
    first = smd_route_find("/metrics", SMD_METHOD_GET, &req, &allowed, &route);
    assert_true(first && !first->public);
    assert_null(smd_route_find("/v1/jobsx", SMD_METHOD_GET, &req, &allowed, &route));
    assert_null(smd_route_find("/healthz/", SMD_METHOD_GET, &req, &allowed, &route));
    /* the live mesh has its own label; a preflight reads its methods */
    snprintf(path, sizeof path, "/v1/jobs/%s/mesh/latest", id);
    first = smd_route_find(path, SMD_METHOD_GET, &req, &allowed, &route);
    assert_true(route && strcmp(route->label, "/v1/jobs/{id}/mesh/latest") == 0);
    assert_int_equal(allowed, SMD_METHOD_READ);
    snprintf(path, sizeof path, "/v1/jobs/%s", id);
    smd_route_find(path, 0, &req, &allowed, &route);
    assert_int_equal(allowed, SMD_METHOD_READ | SMD_METHOD_DELETE);

    /* a batch's model file: {file} into arg, counted under the model */
    snprintf(path, sizeof path, "/v1/batches/%s/model/mode_12.sol", id);
    first = smd_route_find(path, SMD_METHOD_GET, &req, &allowed, &route);
    assert_true(route && strcmp(route->label, "/v1/batches/{id}/model") == 0);
    assert_string_equal(req.arg, "mode_12.sol");
    assert_string_equal(req.id, id);
    snprintf(path, sizeof path, "/v1/batches/%s", id);
    smd_route_find(path, 0, &req, &allowed, &route);
    assert_int_equal(allowed, SMD_METHOD_READ | SMD_METHOD_DELETE);
    /* a batch's event stream: its own label, read only */
    snprintf(path, sizeof path, "/v1/batches/%s/events", id);
    first = smd_route_find(path, SMD_METHOD_GET, &req, &allowed, &route);
    assert_true(route && strcmp(route->label, "/v1/batches/{id}/events") == 0);
    assert_int_equal(allowed, SMD_METHOD_READ);
    assert_string_equal(req.id, id);

    /* the labels: "other" first, each once */
    const char *labels[64];
    size_t n = smd_route_labels(labels, 64);
    assert_string_equal(labels[0], "other");
    assert_int_equal(n, 29); /* with mesh/latest, the two schemas, /v1/conformance, the app files and the OGC execute route (issue 11), the job's inputs and one input (issue 27), the warp route (issue 24), the batches, a batch, its events and its model (issue 25), the meshed template (issue 34) */
    for (size_t i = 0; i < n; i++)
        for (size_t k = i + 1; k < n; k++)
            assert_true(strcmp(labels[i], labels[k]) != 0);
    /* every row has a handler and methods */
    for (size_t i = 0; i < smd_route_table_len; i++) {
        assert_non_null(smd_route_table[i].handler);
        assert_true(smd_route_table[i].methods != 0);
    }
}

static void test_text_and_buffers(void **state)
{
    (void)state;
    char s[] = "a\tb\x7f\xc3\xa9 \"q\"";
    assert_string_equal(sm_text_make_printable(s, NULL), "a?b??? \"q\"");
    char t[] = "GET /a b";
    assert_string_equal(sm_text_make_printable(t, " "), "GET?/a?b");
    char d[8];
    assert_string_equal(sm_text_printable_copy(d, sizeof d, "ab\"c", "\""), "ab?c");
    assert_string_equal(sm_text_printable_copy(d, sizeof d, "abcdefghij", NULL), "abcd...");
    assert_string_equal(sm_text_printable_copy(d, sizeof d, NULL, NULL), "");

    char *buf = NULL;
    size_t len = 0, cap = 0;
    assert_int_equal(smd_buf_append(&buf, &len, &cap, "abc", 3), 0);
    assert_int_equal(smd_buf_printf(&buf, &len, &cap, "-%d-%s", 42, "x"), 0);
    assert_string_equal(buf, "abc-42-x");
    assert_int_equal(len, 8);
    for (int i = 0; i < 2000; i++) /* grows past the first 4 KiB */
        assert_int_equal(smd_buf_printf(&buf, &len, &cap, "%04d", i), 0);
    assert_int_equal(len, 8 + 8000);
    assert_int_equal(strlen(buf), len);
    assert_true(cap > len);
    assert_int_equal(smd_buf_append(&buf, &len, &cap, "x", SIZE_MAX), -1); /* no overflow */
    assert_int_equal(len, 8008);
    free(buf);
}

static void test_unroot(void **state)
{
    (void)state;
    char m[256];
    snprintf(m, sizeof m, "cannot read /srv/sp/jobs/0123/inputs/source.msh: no such file");
    smd_unroot(m, "/srv/sp/");
    assert_string_equal(m, "cannot read source.msh: no such file");
    snprintf(m, sizeof m, "'/srv/spool/tmp/up-1/inputs/a.msh' and \"/srv/spool/jobs/x/b.sol\", in /srv/spool");
    smd_unroot(m, "/srv/spool");
    assert_string_equal(m, "'a.msh' and \"b.sol\", in the spool");
    /* a longer folder of the same prefix, or a path that only contains
     * root, is not under root */
    snprintf(m, sizeof m, "/srv/spool2/x.msh /home/srv/spool/y.msh");
    smd_unroot(m, "/srv/spool");
    assert_string_equal(m, "/srv/spool2/x.msh /home/srv/spool/y.msh");
    snprintf(m, sizeof m, "/a/b.msh (/a)");
    smd_unroot(m, "/a");
    assert_string_equal(m, "b.msh (.)"); /* "the spool" would not fit in "/a" */
    snprintf(m, sizeof m, "/x/y");
    smd_unroot(m, "");
    assert_string_equal(m, "/x/y");
    smd_unroot(m, "/");
    assert_string_equal(m, "/x/y");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_random_ids),
        cmocka_unit_test(test_id_valid),
        cmocka_unit_test(test_bounded_integers),
        cmocka_unit_test(test_metrics),
        cmocka_unit_test(test_route_table),
        cmocka_unit_test(test_text_and_buffers),
        cmocka_unit_test(test_secret_equal),
        cmocka_unit_test(test_pathf),
        cmocka_unit_test(test_unroot),
        cmocka_unit_test(test_sizes_and_durations),
        cmocka_unit_test(test_wait_status),
        cmocka_unit_test(test_atomic_write_and_read),
        cmocka_unit_test(test_rmtree_keeps_link_targets),
        cmocka_unit_test(test_queue_fifo),
        cmocka_unit_test(test_accept),
        cmocka_unit_test(test_gzip_buffer),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
