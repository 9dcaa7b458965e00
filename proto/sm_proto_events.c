/* Job events (NDJSON lines) and the result summary document; see
 * proto/sm_proto_events.h and proto/events.schema.json. */
#include "sm_proto_events.h"

#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "sm_proto_json.h"
#include "sm_proto_params.h"

/* Decoding errors of a well-formed JSON document are format errors. */
static sm_status as_format(sm_error *err)
{
    if (err)
        err->code = SM_ERR_FORMAT;
    return SM_ERR_FORMAT;
}

/* ------------------------------------------------------------------ names */

static const char *const event_names[] = {"accepted", "started",   "progress", "finished",
                                          "failed",   "cancelled", "status",   "warning",
                                          "alignment"};
static const char *const state_names[] = {"accepted", "running", "successful", "failed",
                                          "dismissed"};
#define COUNT(a) (sizeof(a) / sizeof((a)[0]))

const char *sm_event_type_name(sm_event_type type)
{
    if ((int)type < 0 || (size_t)type >= COUNT(event_names))
        return NULL;
    return event_names[type];
}

int sm_event_type_from_name(const char *name, sm_event_type *out)
{
    for (size_t i = 0; name && i < COUNT(event_names); i++)
        if (strcmp(name, event_names[i]) == 0) {
            *out = (sm_event_type)i;
            return 0;
        }
    return -1;
}

const char *sm_job_state_name(sm_job_state state)
{
    if ((int)state < 0 || (size_t)state >= COUNT(state_names))
        return NULL;
    return state_names[state];
}

int sm_job_state_from_name(const char *name, sm_job_state *out)
{
    for (size_t i = 0; name && i < COUNT(state_names); i++)
        if (strcmp(name, state_names[i]) == 0) {
            *out = (sm_job_state)i;
            return 0;
        }
    return -1;
}

/* ------------------------------------------------------------------- time */

/* Days since 1970-01-01 of a proleptic Gregorian date (H. Hinnant's
 * days_from_civil), so parsing needs neither timegm nor the TZ. */
static long long days_from_civil(long long y, unsigned m, unsigned d)
{
    y -= m <= 2;
    const long long era = (y >= 0 ? y : y - 399) / 400;
    const unsigned yoe = (unsigned)(y - era * 400);
    const unsigned doy = (153 * (m + (m > 2 ? -3 : 9)) + 2) / 5 + d - 1;
    const unsigned doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    return era * 146097 + (long long)doe - 719468;
}

static void civil_from_days(long long z, int *y, unsigned *m, unsigned *d)
{
    z += 719468;
    const long long era = (z >= 0 ? z : z - 146096) / 146097;
    const unsigned doe = (unsigned)(z - era * 146097);
    const unsigned yoe = (doe - doe / 1460 + doe / 36524 - doe / 146096) / 365;
    const long long yy = (long long)yoe + era * 400;
    const unsigned doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    const unsigned mp = (5 * doy + 2) / 153;
    *d = doy - (153 * mp + 2) / 5 + 1;
    *m = mp < 10 ? mp + 3 : mp - 9;
    *y = (int)(yy + (*m <= 2));
}

#define MAX_UNIX_TIME 253402300799.0 /* 9999-12-31T23:59:59Z */

int sm_time_format_rfc3339(double t, char buf[SM_RFC3339_LEN])
{
    if (!isfinite(t) || t < 0 || t > MAX_UNIX_TIME)
        return -1;
    long long ms = llround(t * 1000.0);
    long long secs = ms / 1000;
    int millis = (int)(ms % 1000);
    long long days = secs / 86400;
    int sod = (int)(secs % 86400);
    int y;
    unsigned m, d;
    civil_from_days(days, &y, &m, &d);
    if (y > 9999)
        return -1;
    /* the modulos cannot change anything (ranges checked above); they let
     * the compiler see that the text fits */
    snprintf(buf, SM_RFC3339_LEN, "%04u-%02u-%02uT%02u:%02u:%02u.%03uZ", (unsigned)y % 10000u,
             m % 13u, d % 32u, (unsigned)sod / 3600u % 24u, (unsigned)sod / 60u % 60u,
             (unsigned)sod % 60u, (unsigned)millis % 1000u);
    return 0;
}

static int read_digits(const char **s, int n, int *out)
{
    int v = 0;
    for (int i = 0; i < n; i++) {
        char c = (*s)[i];
        if (c < '0' || c > '9')
            return -1;
        v = v * 10 + (c - '0');
    }
    *s += n;
    *out = v;
    return 0;
}

static int expect(const char **s, char c)
{
    if (**s != c)
        return -1;
    (*s)++;
    return 0;
}

int sm_time_parse_rfc3339(const char *text, double *out)
{
    static const int mdays[] = {31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31};
    const char *s = text;
    int y, mo, d, h, mi, se;
    if (!s || read_digits(&s, 4, &y) || expect(&s, '-') || read_digits(&s, 2, &mo) ||
        expect(&s, '-') || read_digits(&s, 2, &d))
        return -1;
    if (*s != 'T' && *s != 't')
        return -1;
    s++;
    if (read_digits(&s, 2, &h) || expect(&s, ':') || read_digits(&s, 2, &mi) ||
        expect(&s, ':') || read_digits(&s, 2, &se))
        return -1;
    if (mo < 1 || mo > 12 || d < 1 || h > 23 || mi > 59 || se > 60)
        return -1;
    int leap = (y % 4 == 0 && y % 100 != 0) || y % 400 == 0;
    if (d > mdays[mo - 1] + (mo == 2 && leap))
        return -1;
    double frac = 0.0, scale = 0.1;
    if (*s == '.') {
        s++;
        if (*s < '0' || *s > '9')
            return -1;
        for (int n = 0; *s >= '0' && *s <= '9'; s++, n++) {
            if (n > 64) /* absurdly long fraction: refuse rather than loop on */
                return -1;
            frac += (*s - '0') * scale;
            scale /= 10;
        }
    }
    long offset = 0;
    if (*s == 'Z' || *s == 'z') {
        s++;
    } else if (*s == '+' || *s == '-') {
        int sign = *s == '-' ? -1 : 1, oh, om;
        s++;
        if (read_digits(&s, 2, &oh) || expect(&s, ':') || read_digits(&s, 2, &om) || oh > 23 ||
            om > 59)
            return -1;
        offset = sign * (oh * 3600L + om * 60L);
    } else {
        return -1;
    }
    if (*s != '\0')
        return -1;
    long long secs = days_from_civil(y, (unsigned)mo, (unsigned)d) * 86400LL + h * 3600LL +
                     mi * 60LL + se - offset;
    *out = (double)secs + frac;
    return 0;
}

double sm_time_now(void)
{
    struct timespec ts;
    if (clock_gettime(CLOCK_REALTIME, &ts) != 0)
        return (double)time(NULL);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

/* --------------------------------------------------------- result summary */

/* The two-sided distance (sm_coverage.h) as summary.json and the
 * finished event carry it (full: rms, max, mean of both sides, p99 of
 * the target's, the unit and the method) or as a progress event does
 * (rms and max, p99 of the target's side).  The meshes carry no unit,
 * so "unit" is null: the figures are in the meshes' own unit. */
static json_t *distance_to_jansson(const sm_distance *d, int full)
{
    json_t *obj = json_object(), *rt = json_object(), *tr = json_object();
    int bad = !obj || !rt || !tr;
    bad = bad || smp_set(rt, "rms", smp_real_or_null(d->result_to_target.rms));
    bad = bad || smp_set(rt, "max", smp_real_or_null(d->result_to_target.max));
    if (full)
        bad = bad || smp_set(rt, "mean", smp_real_or_null(d->result_to_target.mean));
    bad = bad || smp_set(tr, "rms", smp_real_or_null(d->target_to_result.rms));
    bad = bad || smp_set(tr, "max", smp_real_or_null(d->target_to_result.max));
    if (full)
        bad = bad || smp_set(tr, "mean", smp_real_or_null(d->target_to_result.mean));
    bad = bad || smp_set(tr, "p99", smp_real_or_null(d->target_to_result.p99));
    if (bad) {
        json_decref(obj), json_decref(rt), json_decref(tr);
        return NULL;
    }
    const char *method = sm_distance_method_name(d->method);
    if (smp_set(obj, "result_to_target", rt) || smp_set(obj, "target_to_result", tr) ||
        (full && (smp_set(obj, "unit", json_null()) ||
                  smp_set(obj, "method", method ? json_string(method) : json_null())))) {
        json_decref(obj);
        return NULL;
    }
    return obj;
}

static sm_status read_number(const json_t *obj, const char *path, const char *key,
                             double *out, sm_error *err);

/* distance_to_jansson's object back: optional (documents from before it
 * was sent read as not measured, every figure NaN); when there, its
 * figures are numbers or null. */
static sm_status read_distance(const json_t *parent, const char *path, sm_distance *d, int full,
                               sm_error *err)
{
    char sub[SMP_PATH_MAX], side[SMP_PATH_MAX];
    const sm_distance_side none = {NAN, NAN, NAN, NAN};
    d->method = SM_DISTANCE_NONE;
    d->result_to_target = d->target_to_result = none;
    const json_t *obj = json_object_get(parent, "distance");
    if (!obj)
        return SM_OK;
    smp_path_join(sub, path, "distance");
    if (!json_is_object(obj))
        return sm_error_set(err, SM_ERR_FORMAT, "%s: must be an object (got %s)", sub,
                            smp_type_name(obj));
    const char *names[2] = {"result_to_target", "target_to_result"};
    sm_distance_side *sides[2] = {&d->result_to_target, &d->target_to_result};
    for (int i = 0; i < 2; i++) {
        const json_t *o = json_object_get(obj, names[i]);
        smp_path_join(side, sub, names[i]);
        sm_status st;
        if (!o)
            return sm_error_set(err, SM_ERR_FORMAT, "%s: required member missing", side);
        if (!json_is_object(o))
            return sm_error_set(err, SM_ERR_FORMAT, "%s: must be an object (got %s)", side,
                                smp_type_name(o));
        if ((st = read_number(o, side, "rms", &sides[i]->rms, err)) ||
            (st = read_number(o, side, "max", &sides[i]->max, err)) ||
            (full && (st = read_number(o, side, "mean", &sides[i]->mean, err))) ||
            (i == 1 && (st = read_number(o, side, "p99", &sides[i]->p99, err))))
            return st;
    }
    const json_t *m = json_object_get(obj, "method");
    if (m && !json_is_null(m)) {
        const char *name = json_is_string(m) ? json_string_value(m) : "";
        if (strcmp(name, sm_distance_method_name(SM_DISTANCE_SURFACE)) == 0)
            d->method = SM_DISTANCE_SURFACE;
        else if (strcmp(name, sm_distance_method_name(SM_DISTANCE_LEVEL_SET)) == 0)
            d->method = SM_DISTANCE_LEVEL_SET;
        else
            return sm_error_set(err, SM_ERR_FORMAT, "%s.method: must be \"surface\", "
                                "\"level-set\" or null", sub);
    } else if (!full) {
        /* the progress event does not carry the method: any but none
         * marks its figures as there */
        d->method = SM_DISTANCE_LEVEL_SET;
    }
    return SM_OK;
}

json_t *sm_result_to_jansson(const sm_result *r, const sm_params *params, int dim)
{
    const char *stop = sm_stop_reason_name(r->stop);
    json_t *obj = json_object();
    json_t *timings = json_object();
    int bad = !obj || !timings || !stop;
    bad = bad || smp_set(obj, "stop_reason", json_string(stop));
    bad = bad || smp_set(obj, "converged", json_boolean(r->converged));
    bad = bad || smp_set(obj, "iterations", json_integer(r->iterations));
    bad = bad || smp_set(obj, "J_initial", smp_real_or_null(r->J_initial));
    bad = bad || smp_set(obj, "J_final", smp_real_or_null(r->J));
    bad = bad || smp_set(obj, "boundary_l2", smp_real_or_null(r->boundary_l2));
    bad = bad || smp_set(obj, "boundary_max", smp_real_or_null(r->boundary_max));
    bad = bad || smp_set(obj, "boundary_rms", smp_real_or_null(r->boundary_rms));
    bad = bad || smp_set(obj, "boundary_relative",
                         smp_real_or_null(r->diameter > 0 ? r->boundary_rms / r->diameter : 0.0));
    bad = bad || smp_set(obj, "distance", distance_to_jansson(&r->distance, 1));
    bad = bad || smp_set(obj, "min_quality", smp_real_or_null(r->min_quality));
    bad = bad || smp_set(obj, "accepted", json_integer(r->accepted));
    bad = bad || smp_set(obj, "rejected", json_integer(r->rejected));
    bad = bad || smp_set(timings, "setup", smp_real_or_null(r->time.setup));
    bad = bad || smp_set(timings, "sample", smp_real_or_null(r->time.sample));
    bad = bad || smp_set(timings, "assembly", smp_real_or_null(r->time.assembly));
    bad = bad || smp_set(timings, "factor", smp_real_or_null(r->time.factor));
    bad = bad || smp_set(timings, "solve", smp_real_or_null(r->time.solve));
    bad = bad || smp_set(timings, "step", smp_real_or_null(r->time.step));
    bad = bad || smp_set(timings, "total", smp_real_or_null(r->time.total));
    if (bad) {
        json_decref(obj);
        json_decref(timings);
        return NULL;
    }
    if (smp_set(obj, "timings", timings) != 0 ||
        (params && smp_set(obj, "parameters", sm_params_to_jansson(params, dim)) != 0)) {
        json_decref(obj);
        return NULL;
    }
    return obj;
}

char *sm_result_to_json(const sm_result *r, const sm_params *params, int dim)
{
    json_t *obj = sm_result_to_jansson(r, params, dim);
    if (!obj)
        return NULL;
    char *text = sm_json_dumps(obj, 2);
    json_decref(obj);
    if (!text)
        return NULL;
    size_t n = strlen(text);
    char *with_newline = realloc(text, n + 2);
    if (!with_newline) {
        free(text);
        return NULL;
    }
    with_newline[n] = '\n';
    with_newline[n + 1] = '\0';
    return with_newline;
}

/* Required member of obj, or an error naming it. */
static sm_status member(const json_t *obj, const char *path, const char *key,
                        const json_t **out, sm_error *err)
{
    *out = json_object_get(obj, key);
    if (!*out) {
        char sub[SMP_PATH_MAX];
        smp_path_join(sub, path, key);
        return sm_error_set(err, SM_ERR_FORMAT, "%s: required member missing", sub);
    }
    return SM_OK;
}

static sm_status read_number(const json_t *obj, const char *path, const char *key,
                             double *out, sm_error *err)
{
    const json_t *v;
    char sub[SMP_PATH_MAX];
    sm_status st = member(obj, path, key, &v, err);
    if (st != SM_OK)
        return st;
    smp_path_join(sub, path, key);
    if (smp_get_number(v, sub, 1, out, err) != SM_OK)
        return as_format(err);
    return SM_OK;
}

static sm_status read_count(const json_t *obj, const char *path, const char *key, int *out,
                            sm_error *err)
{
    const json_t *v;
    char sub[SMP_PATH_MAX];
    long long x;
    sm_status st = member(obj, path, key, &v, err);
    if (st != SM_OK)
        return st;
    smp_path_join(sub, path, key);
    if (smp_get_integer(v, sub, 0, INT_MAX, &x, err) != SM_OK)
        return as_format(err);
    *out = (int)x;
    return SM_OK;
}

/* The template's diameter is not on the wire, only boundary_relative =
 * boundary_rms / diameter: a diameter that gives that quotient exactly
 * when one is within a few ulps, so that a result passed on (the
 * daemon's finished event) encodes the same figure again; else the
 * nearest quotient (the figure moves by an ulp once, then stays: that
 * diameter gives it exactly); 0 without a figure. */
static double diameter_of(double rms, double rel)
{
    if (!(rms > 0 && rel > 0) || !isfinite(rms) || !isfinite(rel))
        return 0;
    double d = rms / rel;
    if (!(d > 0) || !isfinite(d))
        return 0;
    double lo = d, hi = d;
    for (int k = 0; k < 4; k++) { /* the quotient's rounding: a few ulps */
        if (rms / lo == rel)
            return lo;
        if (rms / hi == rel)
            return hi;
        lo = nextafter(lo, 0.0);
        hi = nextafter(hi, INFINITY);
    }
    return d;
}

sm_status sm_result_from_jansson(const json_t *obj, const char *path, sm_result *out,
                                 sm_error *err)
{
    char sub[SMP_PATH_MAX];
    const json_t *v;
    sm_result r;
    memset(&r, 0, sizeof r);
    if (!path)
        path = "result";
    if (!json_is_object(obj))
        return sm_error_set(err, SM_ERR_FORMAT, "%s: must be an object (got %s)", path,
                            obj ? smp_type_name(obj) : "nothing");
    sm_status st = member(obj, path, "stop_reason", &v, err);
    if (st != SM_OK)
        return st;
    if (!json_is_string(v) || sm_stop_reason_from_name(json_string_value(v), &r.stop) != 0) {
        smp_path_join(sub, path, "stop_reason");
        return sm_error_set(err, SM_ERR_FORMAT,
                            "%s: must be one of \"%s\", \"%s\", \"%s\", \"%s\", \"%s\", \"%s\"",
                            sub, sm_stop_reason_name(SM_STOP_STEP),
                            sm_stop_reason_name(SM_STOP_BOUNDARY),
                            sm_stop_reason_name(SM_STOP_MAX_ITER),
                            sm_stop_reason_name(SM_STOP_CANCELLED),
                            sm_stop_reason_name(SM_STOP_STALLED),
                            sm_stop_reason_name(SM_STOP_QUALITY));
    }
    if ((st = read_count(obj, path, "iterations", &r.iterations, err)) ||
        (st = read_number(obj, path, "J_initial", &r.J_initial, err)) ||
        (st = read_number(obj, path, "J_final", &r.J, err)) ||
        (st = read_number(obj, path, "boundary_l2", &r.boundary_l2, err)) ||
        (st = read_number(obj, path, "boundary_max", &r.boundary_max, err)) ||
        (st = read_number(obj, path, "min_quality", &r.min_quality, err)) ||
        (st = read_count(obj, path, "accepted", &r.accepted, err)) ||
        (st = read_count(obj, path, "rejected", &r.rejected, err)))
        return st;
    /* optional (older summaries lack it); the relative error is derived */
    const json_t *rms = json_object_get(obj, "boundary_rms");
    if (json_is_number(rms))
        r.boundary_rms = json_number_value(rms);
    const json_t *rel = json_object_get(obj, "boundary_relative");
    if (json_is_number(rel))
        r.diameter = diameter_of(r.boundary_rms, json_number_value(rel));
    /* optional too: a summary from before it was reported judged no
     * convergence, and passed as converged (its exit code was 0) */
    const json_t *conv = json_object_get(obj, "converged");
    r.converged = json_is_boolean(conv) ? json_is_true(conv) : 1;
    if ((st = read_distance(obj, path, &r.distance, 1, err)))
        return st;
    const json_t *t;
    if ((st = member(obj, path, "timings", &t, err)))
        return st;
    smp_path_join(sub, path, "timings");
    if (!json_is_object(t))
        return sm_error_set(err, SM_ERR_FORMAT, "%s: must be an object (got %s)", sub,
                            smp_type_name(t));
    if ((st = read_number(t, sub, "setup", &r.time.setup, err)) ||
        (st = read_number(t, sub, "sample", &r.time.sample, err)) ||
        (st = read_number(t, sub, "assembly", &r.time.assembly, err)) ||
        (st = read_number(t, sub, "factor", &r.time.factor, err)) ||
        (st = read_number(t, sub, "solve", &r.time.solve, err)) ||
        (st = read_number(t, sub, "step", &r.time.step, err)) ||
        (st = read_number(t, sub, "total", &r.time.total, err)))
        return st;
    *out = r;
    return SM_OK;
}

sm_status sm_result_from_json(const char *text, size_t len, sm_result *out, sm_error *err)
{
    json_t *root;
    sm_status st = smp_load(text, len, SM_EVENT_LINE_MAX, "result", &root, err);
    if (st != SM_OK)
        return st;
    st = sm_result_from_jansson(root, "result", out, err);
    json_decref(root);
    return st;
}

/* ----------------------------------------------------------------- events */

void sm_event_init(sm_event *ev, sm_event_type type)
{
    memset(ev, 0, sizeof *ev);
    ev->type = type;
    ev->time = -1.0;
    ev->converged = -1;
}

/* Copies at most cap-1 bytes of s, never cutting a UTF-8 sequence. */
static void copy_utf8(char *dst, size_t cap, const char *s)
{
    size_t n = strnlen(s, cap); /* s may be a full, unterminated array */
    if (n >= cap) {
        n = cap - 1;
        while (n > 0 && ((unsigned char)s[n] & 0xC0) == 0x80)
            n--; /* s[n] would be a continuation byte: back up to a lead */
    }
    memcpy(dst, s, n);
    dst[n] = '\0';
}

/* The members of a warning event but its message. */
static int set_warning(json_t *obj, const sm_event *ev)
{
    char code[SM_WARNING_CODE_MAX + 1];
    copy_utf8(code, sizeof code, ev->code);
    return smp_set(obj, "code", json_string(code)) ||
           smp_set(obj, "figure", smp_real_or_null(ev->figure));
}

/* The members of a job's end: finished's result, status's state, and
 * "converged" on both (status: when said). */
static int set_outcome(json_t *obj, const sm_event *ev)
{
    if (ev->type == SM_EVENT_FINISHED)
        return smp_set(obj, "converged", json_boolean(ev->result.converged)) ||
               smp_set(obj, "result", sm_result_to_jansson(&ev->result, NULL, 0));
    const char *state = sm_job_state_name(ev->state);
    return !state || smp_set(obj, "status", json_string(state)) ||
           (ev->converged >= 0 && smp_set(obj, "converged", json_boolean(ev->converged)));
}

static int set_alignment(json_t *obj, const sm_event_alignment *a)
{
    char mode[sizeof a->mode];
    copy_utf8(mode, sizeof mode, a->mode);
    return smp_set(obj, "mode", json_string(mode)) ||
           smp_set(obj, "scale", smp_real_or_null(a->scale)) ||
           smp_set(obj, "rms_before", smp_real_or_null(a->rms_before)) ||
           smp_set(obj, "rms_after", smp_real_or_null(a->rms_after)) ||
           smp_set(obj, "iterations", json_integer(a->iterations)) ||
           smp_set(obj, "seconds", smp_real_or_null(a->seconds));
}

json_t *sm_event_to_jansson(const sm_event *ev)
{
    const char *type = sm_event_type_name(ev->type);
    if (!type)
        return NULL;
    json_t *obj = json_object();
    int bad = !obj;
    bad = bad || smp_set(obj, "type", json_string(type));
    if (ev->job_id[0]) {
        char id[SM_JOB_ID_MAX + 1];
        copy_utf8(id, sizeof id, ev->job_id); /* also NUL-terminates a full array */
        bad = bad || smp_set(obj, "jobID", json_string(id));
    }
    if (ev->seq > 0)
        bad = bad || smp_set(obj, "seq", json_integer(ev->seq));
    if (ev->time >= 0) {
        char when[SM_RFC3339_LEN];
        if (sm_time_format_rfc3339(ev->time, when) != 0)
            bad = 1;
        bad = bad || smp_set(obj, "time", json_string(when));
    }
    if (ev->type == SM_EVENT_STARTED && ev->attempt > 0)
        bad = bad || smp_set(obj, "attempt", json_integer(ev->attempt));
    if (ev->type == SM_EVENT_PROGRESS) {
        const sm_progress *p = &ev->progress;
        /* the unit-free figures first: what a reader should look at */
        bad = bad || smp_set(obj, "iteration", json_integer(p->iteration));
        bad = bad || smp_set(obj, "boundary_rms", smp_real_or_null(p->boundary_rms));
        bad = bad || smp_set(obj, "boundary_relative", smp_real_or_null(p->boundary_relative));
        bad = bad || smp_set(obj, "J", smp_real_or_null(p->J));
        bad = bad || smp_set(obj, "step", smp_real_or_null(p->step));
        bad = bad || smp_set(obj, "boundary_l2", smp_real_or_null(p->boundary_l2));
        bad = bad || smp_set(obj, "boundary_max", smp_real_or_null(p->boundary_max));
        if (p->distance.method != SM_DISTANCE_NONE)
            bad = bad || smp_set(obj, "distance", distance_to_jansson(&p->distance, 0));
        bad = bad || smp_set(obj, "min_quality", smp_real_or_null(p->min_quality));
        bad = bad || smp_set(obj, "elapsed", smp_real_or_null(p->elapsed));
        bad = bad || smp_set(obj, "accepted", json_integer(p->accepted));
        bad = bad || smp_set(obj, "rejected", json_integer(p->rejected));
    }
    if (ev->type == SM_EVENT_FINISHED || ev->type == SM_EVENT_STATUS)
        bad = bad || set_outcome(obj, ev);
    if (ev->type == SM_EVENT_WARNING)
        bad = bad || set_warning(obj, ev);
    if (ev->type == SM_EVENT_ALIGNMENT)
        bad = bad || set_alignment(obj, &ev->alignment);
    if (ev->message[0] || ev->type == SM_EVENT_FAILED || ev->type == SM_EVENT_WARNING) {
        char msg[SM_EVENT_MESSAGE_MAX];
        copy_utf8(msg, sizeof msg, ev->message);
        /* json_string refuses invalid UTF-8 (e.g. a raw strerror in some
         * locale): fall back to a placeholder instead of losing the event */
        json_t *s = json_string(msg);
        if (!s)
            s = json_string("(message not valid UTF-8)");
        bad = bad || smp_set(obj, "message", s);
    }
    if (bad) {
        json_decref(obj);
        return NULL;
    }
    return obj;
}

char *sm_event_to_json(const sm_event *ev)
{
    json_t *obj = sm_event_to_jansson(ev);
    if (!obj)
        return NULL;
    char *text = sm_json_dumps(obj, 0);
    json_decref(obj);
    return text;
}

static sm_status fail(sm_error *err, const char *path, const char *key, const char *what)
{
    char sub[SMP_PATH_MAX];
    smp_path_join(sub, path, key);
    return sm_error_set(err, SM_ERR_FORMAT, "%s: %s", sub, what);
}

/* The members of a warning event: code ([a-z0-9-], 1 to 47), figure
 * (number or null), message (required). */
/* mode (an alignment's name), the four numbers (or null), iterations. */
static sm_status read_alignment(const json_t *obj, const char *sub, sm_event_alignment *a,
                                sm_error *err)
{
    const json_t *v = json_object_get(obj, "mode");
    sm_align_mode mode;
    if (!v)
        return fail(err, sub, "mode", "required member missing");
    if (!json_is_string(v) || sm_align_mode_from_name(json_string_value(v), &mode) != 0 ||
        mode == SM_ALIGN_NONE)
        return fail(err, sub, "mode", "must be \"rigid\", \"similarity\" or \"affine\"");
    snprintf(a->mode, sizeof a->mode, "%s", sm_align_mode_name(mode));
    static const char *const keys[4] = {"scale", "rms_before", "rms_after", "seconds"};
    double *vals[4] = {&a->scale, &a->rms_before, &a->rms_after, &a->seconds};
    for (int k = 0; k < 4; k++) {
        sm_status st = read_number(obj, sub, keys[k], vals[k], err);
        if (st != SM_OK)
            return st;
    }
    v = json_object_get(obj, "iterations");
    if (!v)
        return fail(err, sub, "iterations", "required member missing");
    if (!json_is_integer(v) || json_integer_value(v) < 0 || json_integer_value(v) > INT_MAX)
        return fail(err, sub, "iterations", "must be an integer >= 0");
    a->iterations = (int)json_integer_value(v);
    return SM_OK;
}

static sm_status read_warning(const json_t *obj, const char *sub, sm_event *ev, sm_error *err)
{
    const json_t *v = json_object_get(obj, "code");
    if (!v)
        return fail(err, sub, "code", "required member missing");
    const char *code = json_string_value(v);
    size_t n = code ? json_string_length(v) : 0;
    int ok = code && n >= 1 && n <= SM_WARNING_CODE_MAX && strspn(code,
             "abcdefghijklmnopqrstuvwxyz0123456789-") == n;
    if (!ok)
        return fail(err, sub, "code", "must be 1 to 47 characters a-z, 0-9 and -");
    memcpy(ev->code, code, n + 1);
    sm_status st = read_number(obj, sub, "figure", &ev->figure, err);
    if (st != SM_OK)
        return st;
    if (!json_object_get(obj, "message"))
        return fail(err, sub, "message", "required member missing (the sentence)");
    return SM_OK;
}

/* The members every event may carry: jobID, seq, time, message. */
static sm_status read_envelope(const json_t *obj, const char *path, sm_event *ev, sm_error *err)
{
    const json_t *v;
    if ((v = json_object_get(obj, "jobID"))) {
        if (!json_is_string(v))
            return fail(err, path, "jobID", "must be a string");
        if (json_string_length(v) == 0 || json_string_length(v) > SM_JOB_ID_MAX ||
            strlen(json_string_value(v)) != json_string_length(v))
            return fail(err, path, "jobID", "must be 1 to 64 characters");
        memcpy(ev->job_id, json_string_value(v), json_string_length(v) + 1);
    }
    if ((v = json_object_get(obj, "seq"))) {
        long long seq;
        if (smp_get_integer(v, "event.seq", 0, LLONG_MAX, &seq, err) != SM_OK)
            return as_format(err);
        ev->seq = seq;
    }
    if ((v = json_object_get(obj, "time"))) {
        if (!json_is_string(v) || sm_time_parse_rfc3339(json_string_value(v), &ev->time) != 0)
            return fail(err, path, "time",
                        "must be an RFC 3339 date-time string such as "
                        "\"2024-05-01T12:00:00.000Z\"");
    }
    if ((v = json_object_get(obj, "message"))) {
        if (!json_is_string(v))
            return fail(err, path, "message", "must be a string");
        copy_utf8(ev->message, sizeof ev->message, json_string_value(v));
    }
    return SM_OK;
}

static sm_status read_progress(const json_t *obj, const char *sub, sm_progress *p, sm_error *err)
{
    sm_status st;
    if ((st = read_count(obj, sub, "iteration", &p->iteration, err)) ||
        (st = read_number(obj, sub, "J", &p->J, err)) ||
        (st = read_number(obj, sub, "step", &p->step, err)) ||
        (st = read_number(obj, sub, "boundary_l2", &p->boundary_l2, err)) ||
        (st = read_number(obj, sub, "boundary_max", &p->boundary_max, err)) ||
        (st = read_number(obj, sub, "min_quality", &p->min_quality, err)) ||
        (st = read_number(obj, sub, "elapsed", &p->elapsed, err)) ||
        (st = read_count(obj, sub, "accepted", &p->accepted, err)) ||
        (st = read_count(obj, sub, "rejected", &p->rejected, err)))
        return st;
    /* optional: events from before they were sent */
    const json_t *rms = json_object_get(obj, "boundary_rms");
    const json_t *rel = json_object_get(obj, "boundary_relative");
    p->boundary_rms = json_is_number(rms) ? json_number_value(rms) : 0.0;
    p->boundary_relative = json_is_number(rel) ? json_number_value(rel) : 0.0;
    if ((st = read_distance(obj, sub, &p->distance, 0, err)))
        return st;
    if (p->distance.method != SM_DISTANCE_NONE) /* not on the wire: not a figure */
        p->distance.result_to_target.mean = p->distance.target_to_result.mean = NAN;
    return SM_OK;
}

static sm_status read_status(const json_t *obj, const char *sub, sm_event *ev, sm_error *err)
{
    const json_t *v = json_object_get(obj, "status");
    if (!v)
        return fail(err, sub, "status", "required member missing");
    if (!json_is_string(v) || sm_job_state_from_name(json_string_value(v), &ev->state) != 0)
        return fail(err, sub, "status",
                    "must be one of \"accepted\", \"running\", \"successful\", "
                    "\"failed\", \"dismissed\"");
    if ((v = json_object_get(obj, "converged"))) { /* optional */
        if (!json_is_boolean(v))
            return fail(err, sub, "converged", "must be true or false");
        ev->converged = json_is_true(v);
    }
    return SM_OK;
}

/* The members of ev->type's own (sub names it in messages). */
static sm_status read_body(const json_t *obj, const char *sub, sm_event *ev, sm_error *err)
{
    const json_t *v;
    sm_status st;
    switch (ev->type) {
    case SM_EVENT_ACCEPTED:
    case SM_EVENT_CANCELLED:
        return SM_OK;
    case SM_EVENT_STARTED:
        if ((v = json_object_get(obj, "attempt"))) {
            long long a;
            if (smp_get_integer(v, "event.started.attempt", 1, INT_MAX, &a, err) != SM_OK)
                return as_format(err);
            ev->attempt = (int)a;
        }
        return SM_OK;
    case SM_EVENT_PROGRESS:
        return read_progress(obj, sub, &ev->progress, err);
    case SM_EVENT_FINISHED: {
        char rpath[SMP_PATH_MAX];
        smp_path_join(rpath, sub, "result");
        if (!(v = json_object_get(obj, "result")))
            return fail(err, sub, "result", "required member missing");
        if ((st = sm_result_from_jansson(v, rpath, &ev->result, err)))
            return st;
        ev->converged = ev->result.converged; /* the result's says it */
        return SM_OK;
    }
    case SM_EVENT_FAILED:
        if (!json_object_get(obj, "message"))
            return fail(err, sub, "message", "required member missing (the reason)");
        return SM_OK;
    case SM_EVENT_STATUS:
        return read_status(obj, sub, ev, err);
    case SM_EVENT_WARNING:
        return read_warning(obj, sub, ev, err);
    case SM_EVENT_ALIGNMENT:
        return read_alignment(obj, sub, &ev->alignment, err);
    }
    return SM_OK;
}

sm_status sm_event_from_jansson(const json_t *obj, sm_event *out, sm_error *err)
{
    const char *path = "event";
    sm_event ev;
    sm_event_init(&ev, SM_EVENT_PROGRESS);
    sm_event_init(out, SM_EVENT_PROGRESS);
    if (!json_is_object(obj))
        return sm_error_set(err, SM_ERR_FORMAT, "%s: must be an object (got %s)", path,
                            obj ? smp_type_name(obj) : "nothing");
    const json_t *v = json_object_get(obj, "type");
    if (!v)
        return fail(err, path, "type", "required member missing");
    if (!json_is_string(v) || sm_event_type_from_name(json_string_value(v), &ev.type) != 0)
        return fail(err, path, "type",
                    "must be one of \"accepted\", \"started\", \"progress\", \"finished\", "
                    "\"failed\", \"cancelled\", \"status\", \"warning\", \"alignment\"");
    char sub[SMP_PATH_MAX];
    snprintf(sub, sizeof sub, "%s.%s", path, sm_event_type_name(ev.type));
    sm_status st = read_envelope(obj, path, &ev, err);
    if (st == SM_OK)
        st = read_body(obj, sub, &ev, err);
    if (st != SM_OK)
        return st;
    *out = ev;
    return SM_OK;
}

sm_status sm_event_from_json(const char *line, size_t len, sm_event *out, sm_error *err)
{
    json_t *root;
    sm_event_init(out, SM_EVENT_PROGRESS);
    /* NDJSON readers hand over the line with its terminator. */
    if (line && len > 0 && line[len - 1] == '\n')
        len--;
    if (line && len > 0 && line[len - 1] == '\r')
        len--;
    sm_status st = smp_load(line, len, SM_EVENT_LINE_MAX, "event", &root, err);
    if (st != SM_OK)
        return st;
    st = sm_event_from_jansson(root, out, err);
    json_decref(root);
    return st;
}

json_t *sm_progress_distance_to_jansson(const sm_distance *d)
{
    return d->method == SM_DISTANCE_NONE ? NULL : distance_to_jansson(d, 0);
}
