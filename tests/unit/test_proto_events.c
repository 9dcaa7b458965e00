/* Events NDJSON and the result summary: exact round trips of every event
 * type, RFC 3339 times against known instants, decoding errors naming the
 * member, forward compatibility (unknown members ignored), and the
 * events schema listing the same members as the encoder writes. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "sm_proto_events.h"
#include "sm_proto_params.h"

static int same_double(double a, double b)
{
    return (isnan(a) && isnan(b)) || memcmp(&a, &b, sizeof a) == 0;
}

static sm_result sample_result(void)
{
    sm_result r;
    memset(&r, 0, sizeof r);
    r.stop = SM_STOP_BOUNDARY;
    r.iterations = 42;
    r.J_initial = 0.123456789012345678;
    r.J = -1.0 / 3.0;
    r.boundary_l2 = 9.87654321e-4;
    r.boundary_max = 3.1e-3;
    r.min_quality = 0.4142135623730951;
    r.accepted = 42;
    r.rejected = 7;
    r.time.setup = 0.01;
    r.time.sample = 0.02;
    r.time.assembly = 0.03;
    r.time.factor = 0.04;
    r.time.solve = 0.05;
    r.time.step = 0.06;
    r.time.total = 0.21000000000000002;
    r.distance.method = SM_DISTANCE_SURFACE;
    r.distance.result_to_target = (sm_distance_side){.rms = 1.5e-3, .max = 0.1 + 0.2,
                                                     .mean = 1e-3, .p99 = NAN};
    r.distance.target_to_result = (sm_distance_side){.rms = 2.5e-3, .max = 0.75,
                                                     .mean = 1.75e-3, .p99 = 0.5};
    return r;
}

static void assert_side_equal(const sm_distance_side *a, const sm_distance_side *b, int full,
                              int p99)
{
    assert_true(same_double(a->rms, b->rms));
    assert_true(same_double(a->max, b->max));
    if (full)
        assert_true(same_double(a->mean, b->mean));
    if (p99)
        assert_true(same_double(a->p99, b->p99));
}

static void assert_result_equal(const sm_result *a, const sm_result *b)
{
    /* the two-sided distance: every figure but the result side's p99,
     * which is not on the wire */
    assert_int_equal(a->distance.method, b->distance.method);
    assert_side_equal(&a->distance.result_to_target, &b->distance.result_to_target, 1, 0);
    assert_side_equal(&a->distance.target_to_result, &b->distance.target_to_result, 1, 1);
    assert_int_equal(a->stop, b->stop);
    assert_int_equal(a->converged, b->converged);
    assert_int_equal(a->iterations, b->iterations);
    assert_true(same_double(a->J_initial, b->J_initial));
    assert_true(same_double(a->J, b->J));
    assert_true(same_double(a->boundary_l2, b->boundary_l2));
    assert_true(same_double(a->boundary_max, b->boundary_max));
    assert_true(same_double(a->min_quality, b->min_quality));
    assert_int_equal(a->accepted, b->accepted);
    assert_int_equal(a->rejected, b->rejected);
    assert_true(same_double(a->time.setup, b->time.setup));
    assert_true(same_double(a->time.sample, b->time.sample));
    assert_true(same_double(a->time.assembly, b->time.assembly));
    assert_true(same_double(a->time.factor, b->time.factor));
    assert_true(same_double(a->time.solve, b->time.solve));
    assert_true(same_double(a->time.step, b->time.step));
    assert_true(same_double(a->time.total, b->time.total));
}

static void assert_event_equal(const sm_event *a, const sm_event *b)
{
    assert_int_equal(a->type, b->type);
    assert_string_equal(a->job_id, b->job_id);
    assert_int_equal(a->seq, b->seq);
    /* times travel with millisecond precision */
    if (a->time < 0)
        assert_true(b->time < 0);
    else
        assert_true(fabs(a->time - b->time) <= 0.0005 + 1e-6);
    assert_string_equal(a->message, b->message);
    if (a->type == SM_EVENT_STARTED)
        assert_int_equal(a->attempt, b->attempt);
    if (a->type == SM_EVENT_PROGRESS) {
        const sm_progress *p = &a->progress, *q = &b->progress;
        assert_int_equal(p->iteration, q->iteration);
        assert_true(same_double(p->J, q->J));
        assert_true(same_double(p->step, q->step));
        assert_true(same_double(p->boundary_l2, q->boundary_l2));
        assert_true(same_double(p->boundary_max, q->boundary_max));
        assert_true(same_double(p->boundary_rms, q->boundary_rms));
        assert_true(same_double(p->boundary_relative, q->boundary_relative));
        assert_true(same_double(p->min_quality, q->min_quality));
        assert_true(same_double(p->elapsed, q->elapsed));
        assert_int_equal(p->accepted, q->accepted);
        assert_int_equal(p->rejected, q->rejected);
        /* the progress event's distance: rms and max, p99 on the target side */
        assert_int_equal(p->distance.method != SM_DISTANCE_NONE,
                         q->distance.method != SM_DISTANCE_NONE);
        if (p->distance.method != SM_DISTANCE_NONE) {
            assert_side_equal(&p->distance.result_to_target, &q->distance.result_to_target, 0, 0);
            assert_side_equal(&p->distance.target_to_result, &q->distance.target_to_result, 0, 1);
        }
    }
    if (a->type == SM_EVENT_FINISHED)
        assert_result_equal(&a->result, &b->result);
    if (a->type == SM_EVENT_STATUS) {
        assert_int_equal(a->state, b->state);
        assert_int_equal(a->converged, b->converged);
    }
    if (a->type == SM_EVENT_FINISHED) /* decoded from the result's */
        assert_int_equal(b->converged, a->result.converged);
    if (a->type == SM_EVENT_WARNING) {
        assert_string_equal(a->code, b->code);
        assert_true(same_double(a->figure, b->figure));
    }
    if (a->type == SM_EVENT_ALIGNMENT) {
        assert_string_equal(a->alignment.mode, b->alignment.mode);
        assert_true(same_double(a->alignment.scale, b->alignment.scale));
        assert_true(same_double(a->alignment.rms_before, b->alignment.rms_before));
        assert_true(same_double(a->alignment.rms_after, b->alignment.rms_after));
        assert_true(same_double(a->alignment.seconds, b->alignment.seconds));
        assert_int_equal(a->alignment.iterations, b->alignment.iterations);
    }
}

static void round_trip(const sm_event *ev, sm_event *back)
{
    char *line = sm_event_to_json(ev);
    assert_non_null(line);
    assert_null(strchr(line, '\n'));
    sm_error err = {0};
    if (sm_event_from_json(line, strlen(line), back, &err) != SM_OK)
        fail_msg("decoding %s: %s", line, err.msg);
    assert_event_equal(ev, back);
    /* with the NDJSON terminator too */
    size_t n = strlen(line);
    char *terminated = malloc(n + 3);
    assert_non_null(terminated);
    memcpy(terminated, line, n);
    memcpy(terminated + n, "\r\n", 3);
    assert_int_equal(sm_event_from_json(terminated, n + 2, back, &err), SM_OK);
    assert_event_equal(ev, back);
    free(terminated);
    free(line);
}

static void test_every_event_type_round_trips(void **state)
{
    (void)state;
    const double t0 = 1714564800.123; /* 2024-05-01T12:00:00.123Z */
    sm_event ev, back;
    int types = 0;
    for (int type = SM_EVENT_ACCEPTED; type <= SM_EVENT_ALIGNMENT; type++) {
        sm_event_init(&ev, (sm_event_type)type);
        snprintf(ev.job_id, sizeof ev.job_id, "0123456789abcdef0123456789abcdef");
        ev.seq = 1000000000000LL + type;
        ev.time = t0 + type;
        switch ((sm_event_type)type) {
        case SM_EVENT_STARTED:
            ev.attempt = 2;
            break;
        case SM_EVENT_PROGRESS:
            ev.progress.iteration = 17;
            ev.progress.J = -0.0123456789;
            ev.progress.step = 1e-3;
            ev.progress.boundary_l2 = 2.5e-4;
            ev.progress.boundary_max = 0.1 + 0.2;
            ev.progress.boundary_rms = 1.25e-3;
            ev.progress.boundary_relative = 6.25e-4;
            ev.progress.min_quality = 0.33;
            ev.progress.elapsed = 12.75;
            ev.progress.accepted = 17;
            ev.progress.rejected = 3;
            ev.progress.distance.method = SM_DISTANCE_LEVEL_SET;
            ev.progress.distance.result_to_target = (sm_distance_side){1.25e-3, 0.3, NAN, NAN};
            ev.progress.distance.target_to_result = (sm_distance_side){2e-3, 0.5, NAN, 0.25};
            break;
        case SM_EVENT_FINISHED:
            ev.result = sample_result();
            break;
        case SM_EVENT_FAILED:
            snprintf(ev.message, sizeof ev.message, "worker killed by signal 9 (SIGKILL)");
            break;
        case SM_EVENT_CANCELLED:
            snprintf(ev.message, sizeof ev.message, "cancelled by DELETE \"quoted\" \\ é");
            break;
        case SM_EVENT_STATUS:
            ev.state = SM_JOB_SUCCESSFUL;
            ev.converged = 0; /* finished, not converged */
            break;
        case SM_EVENT_WARNING:
            snprintf(ev.code, sizeof ev.code, "outside-background");
            snprintf(ev.message, sizeof ev.message, "12%% of the boundary lies outside");
            ev.figure = 0.125;
            break;
        case SM_EVENT_ALIGNMENT:
            snprintf(ev.alignment.mode, sizeof ev.alignment.mode, "similarity");
            ev.alignment.scale = 1000.25;
            ev.alignment.rms_before = 49.375;
            ev.alignment.rms_after = 0.1 + 0.2;
            ev.alignment.seconds = NAN;
            ev.alignment.iterations = 25;
            break;
        default:
            break;
        }
        round_trip(&ev, &back);
        types++;
    }
    assert_int_equal(types, 9);
    /* an alignment's mode is one of the three */
    sm_error err;
    const char *bad_mode = "{\"type\":\"alignment\",\"mode\":\"none\",\"scale\":1,"
                           "\"rms_before\":1,\"rms_after\":1,\"iterations\":1,\"seconds\":1}";
    assert_int_equal(sm_event_from_json(bad_mode, strlen(bad_mode), &back, &err), SM_ERR_FORMAT);
    assert_non_null(strstr(err.msg, "mode"));
    /* a warning's figure may be non-finite: null on the wire, NaN back */
    sm_event_init(&ev, SM_EVENT_WARNING);
    snprintf(ev.code, sizeof ev.code, "above-resolution");
    snprintf(ev.message, sizeof ev.message, "far");
    ev.figure = NAN;
    round_trip(&ev, &back);
    assert_true(isnan(back.figure));

    /* a worker's event: no seq, no job id, no time */
    sm_event_init(&ev, SM_EVENT_PROGRESS);
    ev.progress.iteration = 0;
    ev.progress.J = 1.5;
    char *line = sm_event_to_json(&ev);
    assert_non_null(line);
    assert_null(strstr(line, "\"seq\""));
    assert_null(strstr(line, "\"jobID\""));
    assert_null(strstr(line, "\"time\""));
    assert_non_null(strstr(line, "\"type\":\"progress\""));
    free(line);
    round_trip(&ev, &back);
}

static void test_progress_line_shape(void **state)
{
    (void)state;
    sm_event ev;
    sm_event_init(&ev, SM_EVENT_PROGRESS);
    snprintf(ev.job_id, sizeof ev.job_id, "abc");
    ev.seq = 3;
    ev.time = 0.0;
    ev.progress.iteration = 1;
    ev.progress.J = 0.5;
    ev.progress.step = 0.25;
    ev.progress.boundary_l2 = 0.125;
    ev.progress.boundary_max = 1;
    ev.progress.boundary_rms = 0.0625;
    ev.progress.boundary_relative = 0.03125;
    ev.progress.min_quality = 0.75;
    ev.progress.elapsed = 2;
    ev.progress.accepted = 1;
    ev.progress.rejected = 0;
    char *line = sm_event_to_json(&ev);
    /* the unit-free headline first, after the iteration */
    assert_string_equal(line,
                        "{\"type\":\"progress\",\"jobID\":\"abc\",\"seq\":3,"
                        "\"time\":\"1970-01-01T00:00:00.000Z\",\"iteration\":1,"
                        "\"boundary_rms\":0.0625,\"boundary_relative\":0.03125,\"J\":0.5,"
                        "\"step\":0.25,\"boundary_l2\":0.125,\"boundary_max\":1.0,"
                        "\"min_quality\":0.75,\"elapsed\":2.0,\"accepted\":1,\"rejected\":0}");
    free(line);
}

static void test_non_finite_and_long_messages(void **state)
{
    (void)state;
    sm_event ev, back;
    sm_error err = {0};
    sm_event_init(&ev, SM_EVENT_PROGRESS);
    ev.progress.J = NAN;
    ev.progress.step = INFINITY;
    char *line = sm_event_to_json(&ev);
    assert_non_null(line);
    assert_non_null(strstr(line, "\"J\":null"));
    assert_non_null(strstr(line, "\"step\":null"));
    assert_int_equal(sm_event_from_json(line, strlen(line), &back, &err), SM_OK);
    assert_true(isnan(back.progress.J) && isnan(back.progress.step));
    free(line);

    /* a message longer than the buffer is cut on a UTF-8 boundary */
    char doc[2 * SM_EVENT_MESSAGE_MAX + 100];
    int n = snprintf(doc, sizeof doc, "{\"type\":\"failed\",\"message\":\"");
    for (int i = 0; i < SM_EVENT_MESSAGE_MAX; i++) { /* 2-byte characters */
        doc[n++] = (char)0xC3;
        doc[n++] = (char)0xA9;
    }
    n += snprintf(doc + n, sizeof doc - (size_t)n, "\"}");
    assert_int_equal(sm_event_from_json(doc, (size_t)n, &back, &err), SM_OK);
    size_t kept = strlen(back.message);
    assert_true(kept < SM_EVENT_MESSAGE_MAX && kept >= SM_EVENT_MESSAGE_MAX - 2);
    assert_int_equal(kept % 2, 0); /* whole characters only */
    /* and it re-encodes (valid UTF-8) */
    line = sm_event_to_json(&back);
    assert_non_null(line);
    free(line);

    /* an unterminated job id array does not overrun */
    sm_event_init(&ev, SM_EVENT_ACCEPTED);
    memset(ev.job_id, 'a', sizeof ev.job_id);
    line = sm_event_to_json(&ev);
    assert_non_null(line);
    assert_int_equal(sm_event_from_json(line, strlen(line), &back, &err), SM_OK);
    assert_int_equal(strlen(back.job_id), SM_JOB_ID_MAX);
    free(line);

    /* invalid UTF-8 in a message becomes a placeholder, the event survives */
    sm_event_init(&ev, SM_EVENT_FAILED);
    snprintf(ev.message, sizeof ev.message, "bad \xff byte");
    line = sm_event_to_json(&ev);
    assert_non_null(line);
    assert_non_null(strstr(line, "not valid UTF-8"));
    free(line);

    /* unknown types do not encode */
    sm_event_init(&ev, (sm_event_type)99);
    assert_null(sm_event_to_json(&ev));
}

static void test_forward_compatible_decode(void **state)
{
    (void)state;
    const char *line = "{\"type\":\"status\",\"jobID\":\"j1\",\"seq\":9,"
                       "\"time\":\"2024-05-01T14:00:00+02:00\",\"status\":\"dismissed\","
                       "\"progress\":40,\"links\":[{\"href\":\"/v1/jobs/j1\"}],\"future\":{}}";
    sm_event ev;
    sm_error err = {0};
    assert_int_equal(sm_event_from_json(line, strlen(line), &ev, &err), SM_OK);
    assert_int_equal(ev.type, SM_EVENT_STATUS);
    assert_int_equal(ev.state, SM_JOB_DISMISSED);
    assert_int_equal(ev.seq, 9);
    assert_string_equal(ev.job_id, "j1");
    assert_true(ev.time == 1714564800.0);
    assert_int_equal(ev.converged, -1); /* not said: not successful */
}

/* boundary_relative passed on: a decoded result encodes the same figure
 * again (the diameter behind it is not on the wire), within an ulp when
 * no diameter gives it exactly, over 20000 random pairs of RMS and
 * relative error spanning 12 decades each, and a second round changes
 * nothing (what the daemon does to the worker's finished event). */
static void test_relative_passed_on(void **state)
{
    (void)state;
    uint64_t x = 88172645463325252ULL;
    int exact = 0;
    for (int i = 0; i < 20000; i++) {
        double u[2];
        for (int k = 0; k < 2; k++) { /* xorshift64: uniform in [0, 1) */
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            u[k] = (double)(x >> 11) * 0x1.0p-53;
        }
        double rms = pow(10.0, -12 + 12 * u[0]), rel = pow(10.0, -12 + 12 * u[1]);
        sm_result r = sample_result();
        r.boundary_rms = rms;
        json_t *obj = sm_result_to_jansson(&r, NULL, 0);
        json_object_set_new(obj, "boundary_relative", json_real(rel));
        sm_result a, b;
        sm_error err;
        assert_int_equal(sm_result_from_jansson(obj, "r", &a, &err), SM_OK);
        json_decref(obj);
        json_t *once = sm_result_to_jansson(&a, NULL, 0);
        double rel1 = json_real_value(json_object_get(once, "boundary_relative"));
        assert_true(fabs(rel1 - rel) <= 2.3e-16 * rel);
        exact += rel1 == rel;
        assert_int_equal(sm_result_from_jansson(once, "r", &b, &err), SM_OK);
        json_t *twice = sm_result_to_jansson(&b, NULL, 0);
        assert_true(json_real_value(json_object_get(twice, "boundary_relative")) == rel1);
        json_decref(once);
        json_decref(twice);
    }
    print_message("%d of 20000 relative errors passed on exactly, the others within an ulp\n",
                  exact);
    assert_true(exact >= 18000);
}

/* A job that finished without converging stays successful (OGC's fixed
 * status values) and says "converged": false in its status and its
 * finished event; a status without the member (an older daemon, a state
 * that is not successful) reads as not said, and a non-boolean is
 * refused, naming the member. */
static void test_status_converged(void **state)
{
    (void)state;
    const char *no = "{\"type\":\"status\",\"status\":\"successful\",\"converged\":false}";
    const char *yes = "{\"type\":\"status\",\"status\":\"successful\",\"converged\":true}";
    const char *bad = "{\"type\":\"status\",\"status\":\"successful\",\"converged\":0}";
    sm_event ev;
    sm_error err = {0};
    assert_int_equal(sm_event_from_json(no, strlen(no), &ev, &err), SM_OK);
    assert_int_equal(ev.converged, 0);
    assert_int_equal(sm_event_from_json(yes, strlen(yes), &ev, &err), SM_OK);
    assert_int_equal(ev.converged, 1);
    assert_int_equal(sm_event_from_json(bad, strlen(bad), &ev, &err), SM_ERR_FORMAT);
    assert_non_null(strstr(err.msg, "event.status.converged"));
    /* finished: "converged" at the top is the result's */
    sm_event_init(&ev, SM_EVENT_FINISHED);
    ev.result = sample_result();
    ev.result.converged = 0;
    ev.result.boundary_rms = 0.0625;
    ev.result.diameter = 2.0; /* not on the wire: back from boundary_relative */
    char *line = sm_event_to_json(&ev);
    assert_non_null(line);
    assert_non_null(strstr(line, "{\"type\":\"finished\",\"converged\":false,"));
    sm_event back;
    assert_int_equal(sm_event_from_json(line, strlen(line), &back, &err), SM_OK);
    assert_int_equal(back.converged, 0);
    assert_int_equal(back.result.converged, 0);
    assert_true(back.result.diameter == 2.0);
    free(line);
}

static void test_decode_errors_name_the_member(void **state)
{
    (void)state;
    static const struct {
        const char *line, *expect;
    } cases[] = {
        {"", "event: invalid JSON"},
        {"{\"type\":\"progress\"", "event: invalid JSON"},
        {"[]", "event: must be an object (got array)"},
        {"{}", "event.type: required member missing"},
        {"{\"type\":\"exploded\"}", "event.type: must be one of"},
        {"{\"type\":7}", "event.type: must be one of"},
        {"{\"type\":\"accepted\",\"jobID\":5}", "event.jobID: must be a string"},
        {"{\"type\":\"accepted\",\"jobID\":\"\"}", "event.jobID: must be 1 to 64 characters"},
        {"{\"type\":\"accepted\",\"seq\":-1}", "event.seq: must be an integer in"},
        {"{\"type\":\"accepted\",\"seq\":\"1\"}", "event.seq: must be an integer (got string)"},
        {"{\"type\":\"accepted\",\"time\":\"yesterday\"}", "event.time: must be an RFC 3339"},
        {"{\"type\":\"accepted\",\"time\":\"2024-02-30T00:00:00Z\"}", "event.time: must be"},
        {"{\"type\":\"accepted\",\"time\":12}", "event.time: must be"},
        {"{\"type\":\"accepted\",\"message\":[]}", "event.message: must be a string"},
        {"{\"type\":\"started\",\"attempt\":0}", "event.started.attempt: must be an integer in [1,"},
        {"{\"type\":\"progress\"}", "event.progress.iteration: required member missing"},
        {"{\"type\":\"progress\",\"iteration\":-1}", "event.progress.iteration: must be an integer in [0,"},
        {"{\"type\":\"progress\",\"iteration\":1,\"J\":\"x\"}", "event.progress.J: must be a number or null (got string)"},
        {"{\"type\":\"progress\",\"iteration\":1,\"J\":1,\"step\":1,\"boundary_l2\":1,"
         "\"boundary_max\":1,\"min_quality\":1,\"elapsed\":1,\"accepted\":1}",
         "event.progress.rejected: required member missing"},
        {"{\"type\":\"progress\",\"iteration\":1,\"J\":1,\"step\":1,\"boundary_l2\":1,"
         "\"boundary_max\":1,\"min_quality\":1,\"elapsed\":1,\"accepted\":1,\"rejected\":0,\"distance\":5}",
         "event.progress.distance: must be an object (got integer)"},
        {"{\"type\":\"progress\",\"iteration\":1,\"J\":1,\"step\":1,\"boundary_l2\":1,"
         "\"boundary_max\":1,\"min_quality\":1,\"elapsed\":1,\"accepted\":1,\"rejected\":0,\"distance\":{\"result_to_target\":{\"rms\":1,\"max\":1}}}",
         "event.progress.distance.target_to_result: required member missing"},
        {"{\"type\":\"progress\",\"iteration\":1,\"J\":1,\"step\":1,\"boundary_l2\":1,"
         "\"boundary_max\":1,\"min_quality\":1,\"elapsed\":1,\"accepted\":1,\"rejected\":0,\"distance\":{\"result_to_target\":{\"rms\":1,\"max\":1},"
         "\"target_to_result\":{\"rms\":1,\"max\":\"far\",\"p99\":1}}}",
         "event.progress.distance.target_to_result.max: must be a number or null"},
        {"{\"type\":\"progress\",\"iteration\":1,\"J\":1,\"step\":1,\"boundary_l2\":1,"
         "\"boundary_max\":1,\"min_quality\":1,\"elapsed\":1,\"accepted\":1,\"rejected\":0,\"distance\":{\"result_to_target\":{\"rms\":1,\"max\":1},"
         "\"target_to_result\":{\"rms\":1,\"max\":1,\"p99\":1},\"method\":\"guess\"}}",
         "event.progress.distance.method: must be \"surface\", \"level-set\" or null"},
        {"{\"type\":\"finished\"}", "event.finished.result: required member missing"},
        {"{\"type\":\"finished\",\"result\":3}", "event.finished.result: must be an object"},
        {"{\"type\":\"finished\",\"result\":{\"stop_reason\":\"bored\"}}",
         "event.finished.result.stop_reason: must be one of"},
        {"{\"type\":\"finished\",\"result\":{\"stop_reason\":\"cancelled\",\"iterations\":1,"
         "\"J_initial\":1,\"J_final\":1,\"boundary_l2\":1,\"boundary_max\":1,\"min_quality\":1,"
         "\"accepted\":1,\"rejected\":1,\"timings\":{\"setup\":1}}}",
         "event.finished.result.timings.sample: required member missing"},
        {"{\"type\":\"failed\"}", "event.failed.message: required member missing"},
        {"{\"type\":\"status\"}", "event.status.status: required member missing"},
        {"{\"type\":\"warning\",\"figure\":1,\"message\":\"m\"}",
         "event.warning.code: required member missing"},
        {"{\"type\":\"warning\",\"code\":\"Bad Code\",\"figure\":1,\"message\":\"m\"}",
         "event.warning.code: must be 1 to 47 characters"},
        {"{\"type\":\"warning\",\"code\":\"\",\"figure\":1,\"message\":\"m\"}",
         "event.warning.code: must be 1 to 47 characters"},
        {"{\"type\":\"warning\",\"code\":\"a-aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa\","
         "\"figure\":1,\"message\":\"m\"}",
         "event.warning.code: must be 1 to 47 characters"},
        {"{\"type\":\"warning\",\"code\":7,\"figure\":1,\"message\":\"m\"}",
         "event.warning.code: must be 1 to 47 characters"},
        {"{\"type\":\"warning\",\"code\":\"alpha-small\",\"message\":\"m\"}",
         "event.warning.figure: required member missing"},
        {"{\"type\":\"warning\",\"code\":\"alpha-small\",\"figure\":\"x\",\"message\":\"m\"}",
         "event.warning.figure: must be a number or null"},
        {"{\"type\":\"warning\",\"code\":\"alpha-small\",\"figure\":1}",
         "event.warning.message: required member missing"},
        {"{\"type\":\"status\",\"status\":\"done\"}", "event.status.status: must be one of"},
        {"{\"type\":\"accepted\",\"type\":\"failed\"}", "duplicate object key"},
    };
    int n = 0;
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        sm_event ev;
        sm_error err = {0};
        sm_status st = sm_event_from_json(cases[i].line, strlen(cases[i].line), &ev, &err);
        if (st != SM_ERR_FORMAT)
            fail_msg("case %zu (%s): status %d", i, cases[i].line, (int)st);
        if (err.code != SM_ERR_FORMAT)
            fail_msg("case %zu: err.code %d", i, (int)err.code);
        if (!strstr(err.msg, cases[i].expect))
            fail_msg("case %zu (%s): \"%s\" lacks \"%s\"", i, cases[i].line, err.msg,
                     cases[i].expect);
        n++;
    }
    print_message("%d malformed event lines rejected with the member named\n", n);

    /* an oversized line is refused before parsing */
    size_t big = SM_EVENT_LINE_MAX + 1;
    char *line = malloc(big);
    assert_non_null(line);
    memset(line, ' ', big);
    sm_event ev;
    sm_error err = {0};
    assert_int_equal(sm_event_from_json(line, big, &ev, &err), SM_ERR_FORMAT);
    assert_non_null(strstr(err.msg, "larger than the limit"));
    free(line);
}

static void test_rfc3339(void **state)
{
    (void)state;
    char buf[SM_RFC3339_LEN];
    static const struct {
        double t;
        const char *text;
    } known[] = {
        {0.0, "1970-01-01T00:00:00.000Z"},
        {951782400.0, "2000-02-29T00:00:00.000Z"},     /* leap day of a 400-year */
        {951868799.999, "2000-02-29T23:59:59.999Z"},
        {1234567890.5, "2009-02-13T23:31:30.500Z"},
        {4107542400.0, "2100-03-01T00:00:00.000Z"},    /* 2100 is not a leap year */
        {253402300799.0, "9999-12-31T23:59:59.000Z"},
        {1714564799.9996, "2024-05-01T12:00:00.000Z"}, /* rounds up across a second */
    };
    for (size_t i = 0; i < sizeof known / sizeof known[0]; i++) {
        assert_int_equal(sm_time_format_rfc3339(known[i].t, buf), 0);
        assert_string_equal(buf, known[i].text);
        double back;
        assert_int_equal(sm_time_parse_rfc3339(known[i].text, &back), 0);
        assert_true(fabs(back - known[i].t) < 0.0005 + 1e-6);
    }
    /* against the C library for a sweep of instants */
    for (long long t = 0; t < 253402300799LL; t += 86399LL * 37 + 12345) {
        struct tm tm;
        time_t tt = (time_t)t;
        char expect[64];
        gmtime_r(&tt, &tm);
        strftime(expect, sizeof expect, "%Y-%m-%dT%H:%M:%S.000Z", &tm);
        assert_int_equal(sm_time_format_rfc3339((double)t, buf), 0);
        assert_string_equal(buf, expect);
        double back;
        assert_int_equal(sm_time_parse_rfc3339(buf, &back), 0);
        assert_true(back == (double)t);
    }
    double t;
    assert_int_equal(sm_time_parse_rfc3339("2024-05-01T12:00:00Z", &t), 0);
    assert_true(t == 1714564800.0);
    assert_int_equal(sm_time_parse_rfc3339("2024-05-01t07:30:00.25-04:30", &t), 0);
    assert_true(t == 1714564800.25);
    assert_int_equal(sm_time_parse_rfc3339("2024-05-01T12:00:00.123456789z", &t), 0);
    static const char *bad[] = {"", "2024-05-01", "2024-05-01T12:00:00", "2024-13-01T00:00:00Z",
                                "2023-02-29T00:00:00Z", "2024-05-01T24:00:00Z",
                                "2024-05-01T12:00:00.Z", "2024-05-01T12:00:00Zjunk",
                                "2024-05-01 12:00:00Z", "2024-05-01T12:00:00+2:00", "+2024-05-01T12:00:00Z"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++)
        if (sm_time_parse_rfc3339(bad[i], &t) == 0)
            fail_msg("accepted \"%s\"", bad[i]);
    assert_int_equal(sm_time_parse_rfc3339(NULL, &t), -1);
    assert_int_equal(sm_time_format_rfc3339(-1.0, buf), -1);
    assert_int_equal(sm_time_format_rfc3339(NAN, buf), -1);
    assert_int_equal(sm_time_format_rfc3339(1e12, buf), -1);
    /* now is after this code was written and formats */
    assert_true(sm_time_now() > 1700000000.0);
    assert_int_equal(sm_time_format_rfc3339(sm_time_now(), buf), 0);
}

static void test_result_summary(void **state)
{
    (void)state;
    sm_result r = sample_result(), back;
    sm_error err = {0};
    sm_params p;
    memset(&p, 0, sizeof p);
    sm_params_default(&p);
    p.clamp = SM_CLAMP_BALL;
    p.clamp_center[0] = 0.5;
    p.clamp_center[1] = 0.25;
    p.clamp_radius = 0.1;
    char *text = sm_result_to_json(&r, &p, 2);
    assert_non_null(text);
    size_t n = strlen(text);
    assert_true(n > 2 && text[n - 1] == '\n' && text[n - 2] == '}');
    assert_non_null(strstr(text, "\"stop_reason\": \"boundary_tolerance\""));
    assert_int_equal(sm_result_from_json(text, n, &back, &err), SM_OK);
    assert_result_equal(&r, &back);

    /* the embedded params decode to the same params */
    json_error_t jerr;
    json_t *doc = json_loadb(text, n, 0, &jerr);
    assert_non_null(doc);
    sm_params q;
    assert_int_equal(sm_params_from_jansson(json_object_get(doc, "parameters"), 2, NULL, &q, &err),
                     SM_OK);
    assert_int_equal(q.clamp, SM_CLAMP_BALL);
    assert_true(q.clamp_center[1] == 0.25 && q.clamp_radius == 0.1);
    json_decref(doc);
    free(text);

    /* without params, and every stop reason, converged or not */
    for (int s = SM_STOP_STEP; s <= SM_STOP_QUALITY; s++) {
        r.stop = (sm_stop_reason)s;
        r.converged = s % 2;
        json_t *obj = sm_result_to_jansson(&r, NULL, 0);
        assert_non_null(obj);
        assert_null(json_object_get(obj, "parameters"));
        assert_int_equal(sm_result_from_jansson(obj, NULL, &back, &err), SM_OK);
        assert_result_equal(&r, &back);
        json_decref(obj);
        sm_stop_reason sr;
        assert_int_equal(sm_stop_reason_from_name(sm_stop_reason_name((sm_stop_reason)s), &sr), 0);
        assert_int_equal(sr, s);
    }
    sm_stop_reason sr;
    assert_int_equal(sm_stop_reason_from_name("nope", &sr), -1);
    r.stop = (sm_stop_reason)42;
    text = sm_result_to_json(&r, NULL, 0);
    /* the core names unknown reasons "unknown", which no decoder accepts */
    if (text) {
        assert_int_not_equal(sm_result_from_json(text, strlen(text), &back, &err), SM_OK);
        free(text);
    }
}

static void test_names(void **state)
{
    (void)state;
    for (int i = 0; i <= SM_EVENT_ALIGNMENT; i++) {
        sm_event_type t;
        assert_int_equal(sm_event_type_from_name(sm_event_type_name((sm_event_type)i), &t), 0);
        assert_int_equal(t, i);
    }
    for (int i = 0; i <= SM_JOB_DISMISSED; i++) {
        sm_job_state s;
        assert_int_equal(sm_job_state_from_name(sm_job_state_name((sm_job_state)i), &s), 0);
        assert_int_equal(s, i);
    }
    assert_string_equal(sm_job_state_name(SM_JOB_SUCCESSFUL), "successful");
    assert_string_equal(sm_event_type_name(SM_EVENT_CANCELLED), "cancelled");
    assert_string_equal(sm_event_type_name(SM_EVENT_WARNING), "warning");
    assert_string_equal(sm_event_type_name(SM_EVENT_ALIGNMENT), "alignment");
    assert_null(sm_event_type_name((sm_event_type)9));
    assert_null(sm_job_state_name((sm_job_state)-1));
    sm_job_state s;
    assert_int_equal(sm_job_state_from_name("SUCCESSFUL", &s), -1);
}

/* proto/events.schema.json lists the members the encoder writes. */
static void test_schema_lists_the_members(void **state)
{
    (void)state;
    char path[1024];
    const char *root = getenv("SM_ROOT");
    snprintf(path, sizeof path, "%s/proto/events.schema.json", root && *root ? root : ".");
    json_error_t jerr;
    json_t *schema = json_load_file(path, JSON_REJECT_DUPLICATES, &jerr);
    if (!schema)
        fail_msg("%s:%d: %s", path, jerr.line, jerr.text);
    json_t *defs = json_object_get(schema, "$defs");
    assert_non_null(defs);
    int checked = 0;
    for (int type = 0; type <= SM_EVENT_ALIGNMENT; type++) {
        sm_event ev;
        sm_event_init(&ev, (sm_event_type)type);
        snprintf(ev.code, sizeof ev.code, "alpha-small");
        snprintf(ev.alignment.mode, sizeof ev.alignment.mode, "rigid");
        snprintf(ev.job_id, sizeof ev.job_id, "j");
        ev.seq = 1;
        ev.time = 1.0;
        ev.attempt = 1;
        ev.converged = 0; /* status: written when said */
        snprintf(ev.message, sizeof ev.message, "m");
        ev.result = sample_result();
        json_t *obj = sm_event_to_jansson(&ev);
        assert_non_null(obj);
        json_t *def = json_object_get(defs, sm_event_type_name((sm_event_type)type));
        if (!def)
            fail_msg("schema has no $defs/%s", sm_event_type_name((sm_event_type)type));
        json_t *props = json_object_get(def, "properties");
        json_t *common = json_object_get(json_object_get(defs, "common"), "properties");
        const char *key;
        json_t *v;
        json_object_foreach(obj, key, v) {
            if (!json_object_get(props, key) && !json_object_get(common, key))
                fail_msg("event %s: member %s is not in the schema",
                         sm_event_type_name((sm_event_type)type), key);
            checked++;
        }
        /* every required member of the schema is written */
        json_t *req = json_object_get(def, "required");
        size_t i;
        json_t *name;
        json_array_foreach(req, i, name) {
            if (!json_object_get(obj, json_string_value(name)))
                fail_msg("event %s: required %s not written",
                         sm_event_type_name((sm_event_type)type), json_string_value(name));
        }
        json_decref(obj);
    }
    /* the result summary */
    sm_result r = sample_result();
    json_t *obj = sm_result_to_jansson(&r, NULL, 0);
    json_t *props = json_object_get(json_object_get(defs, "result"), "properties");
    const char *key;
    json_t *v;
    json_object_foreach(obj, key, v) {
        if (!json_object_get(props, key))
            fail_msg("result member %s is not in the schema", key);
        checked++;
    }
    json_decref(obj);
    print_message("%d encoded members found in events.schema.json\n", checked);
    json_decref(schema);
}


/* sm_json_dumps: shortest exact reals, escapes, both layouts; every output
 * parses back (jansson) to an equal value. */
static void test_json_dumps(void **state)
{
    (void)state;
    json_t *doc = json_pack("{s:f,s:f,s:f,s:f,s:I,s:s,s:[b,b,n,{}],s:{}}", "a", 0.3, "b", 1.0, "c",
                            -0.0, "d", 1e-300, "e", (json_int_t)-9007199254740993LL, "s",
                            "q\"b\\s/\n\t\x01 \xc3\xa9", "arr", 1, 0, "o");
    assert_non_null(doc);
    char *text = sm_json_dumps(doc, 0);
    assert_non_null(text);
    assert_string_equal(text, "{\"a\":0.3,\"b\":1.0,\"c\":-0.0,\"d\":1e-300,\"e\":-9007199254740993,"
                              "\"s\":\"q\\\"b\\\\s/\\n\\t\\u0001 \xc3\xa9\",\"arr\":[true,false,null,{}],"
                              "\"o\":{}}");
    json_error_t jerr;
    json_t *back = json_loads(text, 0, &jerr);
    assert_non_null(back);
    assert_true(json_equal(doc, back));
    json_decref(back);
    free(text);
    text = sm_json_dumps(doc, 2);
    assert_non_null(strstr(text, "{\n  \"a\": 0.3,\n  \"b\": 1.0,"));
    assert_non_null(strstr(text, "\"arr\": [true, false, null, {}],\n  \"o\": {}\n}"));
    back = json_loads(text, 0, &jerr);
    assert_true(json_equal(doc, back));
    json_decref(back);
    free(text);
    json_decref(doc);
    assert_null(sm_json_dumps(NULL, 0));

    /* random doubles: the text reads back to the same bits, and is never
     * longer than jansson's 17 digits */
    uint64_t s = 88172645463325252ULL;
    for (int i = 0; i < 100000; i++) {
        s ^= s << 13, s ^= s >> 7, s ^= s << 17;
        double x;
        memcpy(&x, &s, sizeof x);
        if (!isfinite(x))
            continue;
        json_t *r = json_real(x);
        char *t = sm_json_dumps(r, 0);
        assert_non_null(t);
        double y = strtod(t, NULL);
        if (memcmp(&x, &y, sizeof x) != 0)
            fail_msg("%.17g printed as %s", x, t);
        char *j = json_dumps(r, JSON_ENCODE_ANY | JSON_REAL_PRECISION(17));
        assert_true(strlen(t) <= strlen(j) + 2);
        free(j);
        free(t);
        json_decref(r);
    }
}

/* The CLI's summary.json (more members, same names) reads as a result. */
static void test_cli_summary_reads(void **state)
{
    (void)state;
    const char *cli =
        "{\"shapematch_version\":\"0.1.0\",\"status\":\"finished\",\"stop_reason\":\"max_iterations\","
        "\"exit_code\":0,\"iterations\":3,\"J_initial\":0.5,\"J_final\":0.25,\"boundary_l2\":0.001,"
        "\"boundary_max\":0.01,\"min_quality\":0.3,\"inverted_elements\":0,\"accepted\":3,"
        "\"rejected\":1,\"timings\":{\"read\":0.1,\"setup\":0.01,\"sample\":0.02,\"assembly\":0.03,"
        "\"factor\":0.04,\"solve\":0.05,\"step\":0.06,\"total\":0.2},\"inputs\":{},\"template\":{},"
        "\"parameters\":{\"clamp\":{\"kind\":\"none\",\"alpha\":0.01}},\"outputs\":{}}";
    sm_result r;
    sm_error err = {0};
    assert_int_equal(sm_result_from_json(cli, strlen(cli), &r, &err), SM_OK);
    assert_int_equal(r.stop, SM_STOP_MAX_ITER);
    assert_int_equal(r.iterations, 3);
    assert_true(r.J == 0.25 && r.J_initial == 0.5 && r.time.total == 0.2);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_every_event_type_round_trips),
        cmocka_unit_test(test_progress_line_shape),
        cmocka_unit_test(test_non_finite_and_long_messages),
        cmocka_unit_test(test_forward_compatible_decode),
        cmocka_unit_test(test_status_converged),
        cmocka_unit_test(test_relative_passed_on),
        cmocka_unit_test(test_decode_errors_name_the_member),
        cmocka_unit_test(test_rfc3339),
        cmocka_unit_test(test_result_summary),
        cmocka_unit_test(test_names),
        cmocka_unit_test(test_schema_lists_the_members),
        cmocka_unit_test(test_json_dumps),
        cmocka_unit_test(test_cli_summary_reads),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
