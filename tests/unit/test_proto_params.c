/* Job parameters JSON <-> sm_params: defaults, exact round trips, the
 * corpus of bad documents in tests/data/proto/params/bad (each error must
 * name the field), and agreement of proto/params.schema.json with the
 * decoder (defaults, bounds, field set). */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "job/sm_job_inputs.h"
#include "sm_proto_params.h"

static const char *root_dir(void)
{
    const char *r = getenv("SM_ROOT");
    return r && *r ? r : ".";
}

/* Whole file into a malloc'd buffer (NUL-terminated); NULL if unreadable. */
static char *slurp(const char *path, size_t *len)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    size_t cap = 4096, n = 0;
    char *buf = malloc(cap);
    size_t k;
    while (buf && (k = fread(buf + n, 1, cap - n - 1, f)) > 0) {
        n += k;
        if (cap - n - 1 == 0) {
            char *bigger = realloc(buf, cap * 2);
            if (!bigger) {
                free(buf);
                buf = NULL;
            }
            buf = bigger;
            cap *= 2;
        }
    }
    fclose(f);
    if (buf)
        buf[n] = '\0';
    *len = n;
    return buf;
}

static void defaults(sm_params *p)
{
    memset(p, 0, sizeof *p);
    sm_params_default(p);
}

/* Field-by-field equality; doubles compared bitwise (exact round trip). */
static int same_double(double a, double b) { return memcmp(&a, &b, sizeof a) == 0; }

static void assert_params_equal(const sm_params *a, const sm_params *b, int dim)
{
    assert_int_equal(a->clamp, b->clamp);
    if (a->clamp == SM_CLAMP_BALL) {
        for (int i = 0; i < dim; i++)
            assert_true(same_double(a->clamp_center[i], b->clamp_center[i]));
        assert_true(same_double(a->clamp_radius, b->clamp_radius));
    }
    if (a->clamp == SM_CLAMP_ELEMENTS || a->clamp == SM_CLAMP_VERTICES) {
        assert_int_equal(a->n_clamp_refs, b->n_clamp_refs);
        for (int i = 0; i < a->n_clamp_refs; i++)
            assert_int_equal(a->clamp_refs[i], b->clamp_refs[i]);
    }
    if (a->clamp == SM_CLAMP_NONE)
        assert_true(same_double(a->alpha, b->alpha));
    assert_int_equal(a->n_free_refs, b->n_free_refs);
    for (int i = 0; i < a->n_free_refs; i++)
        assert_int_equal(a->free_refs[i], b->free_refs[i]);
    assert_true(same_double(a->young, b->young));
    assert_true(same_double(a->poisson, b->poisson));
    assert_int_equal(a->max_iter, b->max_iter);
    assert_true(same_double(a->tol_step, b->tol_step));
    assert_true(same_double(a->tol_boundary, b->tol_boundary));
    assert_true(same_double(a->min_quality, b->min_quality));
    assert_int_equal(a->save_every, b->save_every);
    assert_true(same_double(a->step_initial, b->step_initial));
    assert_true(same_double(a->step_max, b->step_max));
    assert_int_equal(a->refactor_every, b->refactor_every);
    assert_int_equal(a->live_every, b->live_every);
    assert_int_equal(a->solver, b->solver);
}

static sm_status decode_str(const char *text, int dim, sm_params *p, sm_error *err)
{
    return sm_params_from_json(text, strlen(text), dim, p, err);
}

static void test_minimal_ball_is_complete(void **state)
{
    (void)state;
    sm_params p, d;
    sm_error err = {0};
    const char *text = "{\"clamp\": {\"kind\": \"ball\", \"center\": [0.5, 0.5], \"radius\": 0.04}}";
    assert_int_equal(decode_str(text, 2, &p, &err), SM_OK);
    defaults(&d);
    d.clamp = SM_CLAMP_BALL;
    d.clamp_center[0] = 0.5;
    d.clamp_center[1] = 0.5;
    d.clamp_radius = 0.04;
    assert_params_equal(&p, &d, 2);
    assert_true(p.clamp_center[2] == 0.0);
    /* the defaults are the core's, not a copy of them */
    assert_int_equal(p.max_iter, 500);
    assert_true(p.poisson == 0.3 && p.young == 1.0 && p.tol_step == 1e-6);
}

static void test_good_corpus(void **state)
{
    (void)state;
    char path[1024];
    size_t len;
    sm_params p;
    sm_error err = {0};

    snprintf(path, sizeof path, "%s/tests/data/proto/params/good/full_3d.json", root_dir());
    char *text = slurp(path, &len);
    assert_non_null(text);
    assert_int_equal(sm_params_from_json(text, len, 3, &p, &err), SM_OK);
    free(text);
    assert_int_equal(p.clamp, SM_CLAMP_BALL);
    assert_true(p.clamp_center[0] == 0.25 && p.clamp_center[1] == -1.5 && p.clamp_center[2] == 3);
    assert_true(p.clamp_radius == 0.125);
    assert_int_equal(p.n_free_refs, 2);
    assert_int_equal(p.free_refs[0], 7);
    assert_int_equal(p.free_refs[1], 8);
    assert_true(p.young == 210.5 && p.poisson == 0.45);
    assert_int_equal(p.max_iter, 1000);
    assert_true(p.tol_step == 1e-7 && p.tol_boundary == 1e-4 && p.min_quality == 0.05);
    assert_int_equal(p.save_every, 10);
    assert_true(p.step_initial == 0.02 && p.step_max == 0.2);
    assert_int_equal(p.refactor_every, 3);

    snprintf(path, sizeof path, "%s/tests/data/proto/params/good/elements.json", root_dir());
    text = slurp(path, &len);
    assert_non_null(text);
    assert_int_equal(sm_params_from_json(text, len, 2, &p, &err), SM_OK);
    free(text);
    assert_int_equal(p.clamp, SM_CLAMP_ELEMENTS);
    assert_int_equal(p.n_clamp_refs, 3);
    assert_int_equal(p.clamp_refs[1], -2);
    assert_int_equal(p.clamp_refs[2], 2147483647);
    assert_int_equal(p.max_iter, 500); /* 500.0 is an integer for JSON Schema */

    snprintf(path, sizeof path, "%s/tests/data/proto/params/good/vertices_kind_last.json",
             root_dir());
    text = slurp(path, &len);
    assert_non_null(text);
    assert_int_equal(sm_params_from_json(text, len, 3, &p, &err), SM_OK);
    free(text);
    assert_int_equal(p.clamp, SM_CLAMP_VERTICES);
    assert_int_equal(p.n_clamp_refs, 1);
    assert_int_equal(p.n_free_refs, 0);

    snprintf(path, sizeof path, "%s/tests/data/proto/params/good/none_alpha.json", root_dir());
    text = slurp(path, &len);
    assert_non_null(text);
    assert_int_equal(sm_params_from_json(text, len, 2, &p, &err), SM_OK);
    free(text);
    assert_int_equal(p.clamp, SM_CLAMP_NONE);
    assert_true(p.alpha == 0.5 && p.poisson == -0.5 && p.step_initial == 1 && p.step_max == 1);

    snprintf(path, sizeof path, "%s/tests/data/proto/params/good/none_default_alpha.json",
             root_dir());
    text = slurp(path, &len);
    assert_non_null(text);
    assert_int_equal(sm_params_from_json(text, len, 3, &p, &err), SM_OK);
    free(text);
    assert_true(p.alpha == 0.0); /* the default: from the scale */

    snprintf(path, sizeof path, "%s/tests/data/proto/params/good/minimal_ball_2d.json",
             root_dir());
    text = slurp(path, &len);
    assert_non_null(text);
    assert_int_equal(sm_params_from_json(text, len, 2, &p, &err), SM_OK);
    free(text);

    /* the generated background's members: into bg, and accepted (then
     * dropped) by the decoder that has no bg */
    snprintf(path, sizeof path, "%s/tests/data/proto/params/good/background_3d.json", root_dir());
    text = slurp(path, &len);
    assert_non_null(text);
    sm_background_params bg = {1, 1};
    assert_int_equal(sm_job_params_from_json(text, len, 3, &p, &bg, &err), SM_OK);
    assert_true(bg.size == 0.05 && bg.padding == 0.25);
    assert_int_equal(p.clamp, SM_CLAMP_BALL);
    assert_int_equal(sm_params_from_json(text, len, 3, &p, &err), SM_OK);
    free(text);
}

/* background_size / background_padding: absent is 0 (the default), the
 * encoder writes only the given ones and reads them back exactly, a bad
 * one leaves bg zeroed. */
static void test_background_members(void **state)
{
    (void)state;
    sm_params p;
    sm_background_params bg = {7, 7};
    sm_error err = {0};
    const char *none = "{\"clamp\": {\"kind\": \"none\"}}";
    assert_int_equal(sm_job_params_from_json(none, strlen(none), 2, &p, &bg, &err), SM_OK);
    assert_true(bg.size == 0 && bg.padding == 0);
    char *text = sm_job_params_to_json(&p, &bg, 2);
    assert_non_null(text);
    assert_null(strstr(text, "background"));
    free(text);

    bg.size = 0.1 / 3;
    text = sm_job_params_to_json(&p, &bg, 2);
    assert_non_null(text);
    assert_non_null(strstr(text, "\"background_size\":"));
    assert_null(strstr(text, "background_padding"));
    sm_background_params back = {0, 0};
    assert_int_equal(sm_job_params_from_json(text, strlen(text), 2, &p, &back, &err), SM_OK);
    assert_true(same_double(back.size, bg.size) && back.padding == 0);
    free(text);

    bg.padding = SM_BACKGROUND_PADDING_MAX;
    json_t *obj = sm_job_params_to_jansson(&p, &bg, 3);
    assert_non_null(obj);
    assert_int_equal(sm_job_params_from_jansson(obj, 3, NULL, &p, &back, &err), SM_OK);
    assert_true(same_double(back.size, bg.size) && back.padding == SM_BACKGROUND_PADDING_MAX);
    json_decref(obj);

    /* what the decoder would refuse is not encoded */
    sm_background_params bad[] = {{-1, 0}, {0, -0.5}, {NAN, 0}, {INFINITY, 0},
                                  {0, SM_BACKGROUND_PADDING_MAX * 2}};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++)
        assert_null(sm_job_params_to_json(&p, &bad[i], 2));
    assert_non_null(obj = sm_job_params_to_jansson(&p, NULL, 2));
    json_decref(obj);

    const char *neg = "{\"clamp\": {\"kind\": \"none\"}, \"background_size\": 0.5, "
                      "\"background_padding\": -1}";
    bg.size = bg.padding = 3;
    assert_int_equal(sm_job_params_from_json(neg, strlen(neg), 2, &p, &bg, &err), SM_ERR_INVALID);
    assert_string_equal(err.msg, "params.background_padding: must be > 0 (got -1)");
    assert_true(bg.size == 0 && bg.padding == 0);

    /* template_label, the integer row: written as a JSON integer when
     * given, read back exactly; a real number or a value beyond an int is
     * refused naming it */
    bg = (sm_background_params){0};
    bg.template_label = 2147483647;
    assert_non_null(obj = sm_job_params_to_jansson(&p, &bg, 2));
    assert_true(json_is_integer(json_object_get(obj, "template_label")));
    assert_int_equal(json_integer_value(json_object_get(obj, "template_label")), 2147483647);
    back = (sm_background_params){0};
    assert_int_equal(sm_job_params_from_jansson(obj, 2, NULL, &p, &back, &err), SM_OK);
    assert_int_equal(back.template_label, 2147483647);
    json_decref(obj);
    bg.template_label = -1;
    assert_null(sm_job_params_to_json(&p, &bg, 2));
    const char *badlab[] = {"{\"template_label\": 2.5}", "{\"template_label\": 2147483648}",
                            "{\"template_label\": -1}", "{\"template_label\": \"3\"}"};
    for (size_t i = 0; i < sizeof badlab / sizeof badlab[0]; i++) {
        assert_int_equal(sm_job_params_from_json(badlab[i], strlen(badlab[i]), 2, &p, &back, &err),
                         SM_ERR_INVALID);
        assert_non_null(strstr(err.msg, "params.template_label: "));
    }
}

/* The one rule of run, submit and the daemon: the background members
 * only with a target_surface and no target_mesh, the message naming the
 * params (daemon) or the flags (CLI) and what is wrong. */
static void test_background_needs_generated(void **state)
{
    (void)state;
    sm_error err = {0};
    sm_job_files f = {.template_mesh = "t.mesh", .target_surface = "s.stl"};
    assert_int_equal(sm_job_files_check_background(&f, SM_JOB_NAME_PARTS, &err), SM_OK);
    f.background_size = 0.1;
    assert_int_equal(sm_job_files_check_background(&f, SM_JOB_NAME_PARTS, &err), SM_OK);
    f.target_mesh = "b.mesh";
    assert_int_equal(sm_job_files_check_background(&f, SM_JOB_NAME_PARTS, &err), SM_ERR_INVALID);
    assert_string_equal(err.msg, "params.background_size: background_size and background_padding "
                                 "are for a generated background (target_surface without "
                                 "target_mesh): target_mesh is given");
    assert_int_equal(sm_job_files_check_background(&f, SM_JOB_NAME_PATHS, &err), SM_ERR_INVALID);
    assert_string_equal(err.msg, "--background-size and --background-padding are for a generated "
                                 "background (--target-surface without --target-mesh): "
                                 "--target-mesh is given");
    /* padding alone, and no surface at all (a sampled target) */
    sm_job_files g = {.template_mesh = "t.mesh", .target_mesh = "b.mesh", .target_sol = "b.sol",
                      .background_padding = 0.2};
    assert_int_equal(sm_job_files_check_background(&g, SM_JOB_NAME_PARTS, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "params.background_padding: "));
    assert_non_null(strstr(err.msg, "target_surface is not given"));
    /* and sm_job_inputs_read refuses before reading a file (none exist) */
    sm_job_inputs in;
    assert_int_equal(sm_job_inputs_read(&f, SM_JOB_NAME_PARTS, &in, &err), SM_ERR_INVALID);
    assert_int_equal(in.failed, SM_PART_PARAMS);
    assert_non_null(strstr(err.msg, "target_mesh is given"));
}

/* Every document of the bad corpus fails with its expected message, and
 * the output is left at the defaults. */
static void test_bad_corpus(void **state)
{
    (void)state;
    char path[1024], line[1024];
    snprintf(path, sizeof path, "%s/tests/data/proto/params/bad/cases.tsv", root_dir());
    FILE *cases = fopen(path, "r");
    assert_non_null(cases);
    int ncases = 0;
    sm_params defaults_only;
    defaults(&defaults_only);
    while (fgets(line, sizeof line, cases)) {
        if (line[0] == '#' || line[0] == '\n')
            continue;
        line[strcspn(line, "\n")] = '\0';
        char *name = strtok(line, "\t");
        char *dim_text = strtok(NULL, "\t");
        char *expected = strtok(NULL, "\t");
        assert_non_null(expected);
        snprintf(path, sizeof path, "%s/tests/data/proto/params/bad/%s.json", root_dir(), name);
        size_t len;
        char *text = slurp(path, &len);
        if (!text)
            fail_msg("missing corpus file %s", path);
        sm_params p;
        sm_error err = {0};
        sm_status st = sm_params_from_json(text, len, atoi(dim_text), &p, &err);
        free(text);
        if (st == SM_OK)
            fail_msg("case %s: accepted", name);
        if (st != SM_ERR_FORMAT && st != SM_ERR_INVALID)
            fail_msg("case %s: status %d", name, (int)st);
        if (err.code != st)
            fail_msg("case %s: err.code %d != status %d", name, (int)err.code, (int)st);
        if (!strstr(err.msg, expected))
            fail_msg("case %s: message \"%s\" lacks \"%s\"", name, err.msg, expected);
        if (strncmp(err.msg, "params", 6) != 0)
            fail_msg("case %s: message \"%s\" does not start with the path", name, err.msg);
        assert_params_equal(&p, &defaults_only, 3);
        assert_int_equal(p.clamp, defaults_only.clamp);
        ncases++;
    }
    fclose(cases);
    print_message("%d bad params documents rejected with the expected message\n", ncases);
    assert_true(ncases >= 15);
}

static void test_huge_and_odd_inputs(void **state)
{
    (void)state;
    sm_params p;
    sm_error err = {0};
    /* a valid document padded past the limit is refused before parsing */
    size_t n = SM_PARAMS_JSON_MAX_BYTES + 10;
    char *big = malloc(n);
    assert_non_null(big);
    memset(big, ' ', n);
    const char *doc = "{\"clamp\":{\"kind\":\"none\"}}";
    memcpy(big, doc, strlen(doc));
    assert_int_equal(sm_params_from_json(big, n, 2, &p, &err), SM_ERR_FORMAT);
    assert_non_null(strstr(err.msg, "larger than the limit"));
    /* the same, inside the limit, is fine */
    assert_int_equal(sm_params_from_json(big, SM_PARAMS_JSON_MAX_BYTES, 2, &p, &err), SM_OK);
    free(big);

    /* deep nesting: jansson's depth limit, reported as a syntax error */
    size_t depth = 5000;
    char *deep = malloc(2 * depth + 1);
    assert_non_null(deep);
    memset(deep, '[', depth);
    memset(deep + depth, ']', depth);
    assert_int_equal(sm_params_from_json(deep, 2 * depth, 2, &p, &err), SM_ERR_FORMAT);
    free(deep);

    /* not NUL-terminated: only len bytes are read */
    char exact[] = {'{', '"', 'c', 'l', 'a', 'm', 'p', '"', ':', '{', '"', 'k', 'i', 'n', 'd',
                    '"', ':', '"', 'n', 'o', 'n', 'e', '"', '}', '}', 'X'};
    assert_int_equal(sm_params_from_json(exact, sizeof exact - 1, 2, &p, &err), SM_OK);
    assert_int_not_equal(sm_params_from_json(exact, sizeof exact, 2, &p, &err), SM_OK);

    /* NULL text, a bad dimension, and a NULL err do not crash */
    assert_int_equal(sm_params_from_json(NULL, 0, 2, &p, &err), SM_ERR_FORMAT);
    assert_int_equal(sm_params_from_json(doc, strlen(doc), 4, &p, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "dimension 4"));
    assert_int_equal(sm_params_from_json("{\"young\":-1}", 12, 2, &p, NULL), SM_ERR_INVALID);
    /* no clamp: the default ball, chosen on the template (kind auto) */
    assert_int_equal(sm_params_from_json("{}", 2, 2, &p, &err), SM_OK);
    assert_int_equal(p.clamp, SM_CLAMP_AUTO);

    /* invalid UTF-8 in a key is a parse error, not a crash */
    const char bad_utf8[] = "{\"clamp\":{\"kind\":\"none\"},\"\xff\xfe\":1}";
    assert_int_equal(sm_params_from_json(bad_utf8, sizeof bad_utf8 - 1, 2, &p, &err),
                     SM_ERR_FORMAT);
}

/* A long key is cut in the message; the message stays bounded. */
static void test_long_key_message(void **state)
{
    (void)state;
    char doc[2048];
    char key[1200];
    memset(key, 'k', sizeof key - 1);
    key[sizeof key - 1] = '\0';
    snprintf(doc, sizeof doc, "{\"clamp\":{\"kind\":\"none\"},\"%s\":1}", key);
    sm_params p;
    sm_error err = {0};
    assert_int_equal(decode_str(doc, 2, &p, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "params.kkkk"));
    assert_non_null(strstr(err.msg, "...: unknown field"));
}

static void test_dimension_known_later(void **state)
{
    (void)state;
    sm_params p;
    sm_error err = {0};
    const char *c2 = "{\"clamp\":{\"kind\":\"ball\",\"center\":[1,2],\"radius\":1}}";
    const char *c3 = "{\"clamp\":{\"kind\":\"ball\",\"center\":[1,2,3],\"radius\":1}}";
    assert_int_equal(decode_str(c2, 0, &p, &err), SM_OK);
    assert_true(p.clamp_center[0] == 1 && p.clamp_center[1] == 2 && p.clamp_center[2] == 0);
    assert_int_equal(decode_str(c3, 0, &p, &err), SM_OK);
    assert_true(p.clamp_center[2] == 3);
    /* once the mesh is known to be 2D, the 3-entry center is refused */
    assert_int_equal(decode_str(c3, 2, &p, &err), SM_ERR_INVALID);
    assert_string_equal(err.msg,
                        "params.clamp.center: must have 2 coordinates, the mesh dimension (got 3)");
    assert_int_equal(decode_str(c2, 3, &p, &err), SM_ERR_INVALID);
    assert_int_equal(decode_str(c2, 2, &p, &err), SM_OK);
    /* dim 0 on encode: 2 entries when z == 0 */
    char *text = sm_params_to_json(&p, 0);
    assert_non_null(text);
    assert_non_null(strstr(text, "\"center\":[1.0,2.0]"));
    free(text);
}

static void test_from_jansson_path(void **state)
{
    (void)state;
    json_error_t jerr;
    json_t *doc = json_loads("{\"inputs\":{\"params\":{\"clamp\":{\"kind\":\"none\",\"alpha\":-1}}}}",
                             0, &jerr);
    assert_non_null(doc);
    sm_params p;
    sm_error err = {0};
    json_t *params = json_object_get(json_object_get(doc, "inputs"), "params");
    assert_int_equal(sm_params_from_jansson(params, 3, "inputs.params", &p, &err), SM_ERR_INVALID);
    assert_string_equal(err.msg, "inputs.params.clamp.alpha: must be >= 0 (got -1)");
    json_decref(doc);
}

/* Deterministic pseudo-random numbers (xorshift64*), no global state. */
static uint64_t next_u64(uint64_t *s)
{
    *s ^= *s >> 12;
    *s ^= *s << 25;
    *s ^= *s >> 27;
    return *s * 2685821657736338717ULL;
}
static double uniform(uint64_t *s) { return (double)(next_u64(s) >> 11) / 9007199254740992.0; }

static void random_params(sm_params *p, int dim, uint64_t *s)
{
    defaults(p);
    p->clamp = (sm_clamp_kind)(next_u64(s) % 5);
    switch (p->clamp) {
    case SM_CLAMP_BALL:
        for (int i = 0; i < dim; i++)
            p->clamp_center[i] = (uniform(s) - 0.5) * 1e3;
        p->clamp_radius = uniform(s) + 1e-300;
        break;
    case SM_CLAMP_ELEMENTS:
    case SM_CLAMP_VERTICES:
        p->n_clamp_refs = 1 + (int)(next_u64(s) % SM_MAX_REFS);
        for (int i = 0; i < p->n_clamp_refs; i++)
            p->clamp_refs[i] = (int32_t)(uint32_t)next_u64(s);
        break;
    case SM_CLAMP_NONE:
        p->alpha = uniform(s) * 10 + 1e-12;
        break;
    case SM_CLAMP_AUTO:
        break;
    }
    p->n_free_refs = (int)(next_u64(s) % (SM_MAX_REFS + 1));
    for (int i = 0; i < p->n_free_refs; i++)
        p->free_refs[i] = (int32_t)(next_u64(s) % 100);
    p->young = exp((uniform(s) - 0.5) * 40);
    p->poisson = -1 + 1.5 * uniform(s) + 1e-9;
    if (p->poisson >= 0.5)
        p->poisson = 0.4999;
    p->max_iter = 1 + (int)(next_u64(s) % 1000000);
    p->tol_step = uniform(s) * 0.99 + 1e-15;
    p->tol_boundary = uniform(s) < 0.3 ? 0.0 : uniform(s);
    p->min_quality = uniform(s) * 0.99;
    p->save_every = (int)(next_u64(s) % 50);
    p->step_max = uniform(s) * 0.99 + 0.01;
    p->step_initial = p->step_max * (uniform(s) * 0.99 + 0.01);
    p->refactor_every = 1 + (int)(next_u64(s) % 10);
    p->live_every = (int)(next_u64(s) % 10);
    p->solver = (sm_solver_kind)(next_u64(s) % 3);
}

static void test_random_round_trip(void **state)
{
    (void)state;
    uint64_t seed = 0x9e3779b97f4a7c15ULL;
    int n = 0;
    for (int k = 0; k < 3000; k++) {
        int dim = 2 + k % 2;
        sm_params p, q, r;
        random_params(&p, dim, &seed);
        sm_error err = {0};
        if (sm_params_validate(&p, dim, &err) != SM_OK)
            fail_msg("generator made invalid params: %s", err.msg);
        char *text = sm_params_to_json(&p, dim);
        assert_non_null(text);
        assert_null(strchr(text, '\n')); /* one line */
        if (sm_params_from_json(text, strlen(text), dim, &q, &err) != SM_OK)
            fail_msg("round trip of %s failed: %s", text, err.msg);
        assert_params_equal(&p, &q, dim);
        /* stable encoding: decode(encode(x)) encodes to the same text */
        char *again = sm_params_to_json(&q, dim);
        assert_non_null(again);
        assert_string_equal(text, again);
        /* and the jansson variant composes */
        json_t *obj = sm_params_to_jansson(&q, dim);
        assert_non_null(obj);
        assert_int_equal(sm_params_from_jansson(obj, dim, NULL, &r, &err), SM_OK);
        assert_params_equal(&p, &r, dim);
        json_decref(obj);
        free(text);
        free(again);
        n++;
    }
    print_message("%d random params round-tripped exactly\n", n);
}

static void test_encoder_refuses_what_json_cannot_carry(void **state)
{
    (void)state;
    sm_params p;
    defaults(&p);
    p.young = NAN;
    assert_null(sm_params_to_json(&p, 2));
    defaults(&p);
    p.clamp = (sm_clamp_kind)7;
    assert_null(sm_params_to_json(&p, 2));
    defaults(&p);
    p.clamp = SM_CLAMP_VERTICES;
    p.n_clamp_refs = SM_MAX_REFS + 1;
    assert_null(sm_params_to_json(&p, 2));
    defaults(&p);
    assert_null(sm_params_to_json(&p, 5));
    assert_string_equal(sm_clamp_kind_name(SM_CLAMP_ELEMENTS), "elements");
    assert_null(sm_clamp_kind_name((sm_clamp_kind)-1));
    sm_clamp_kind k;
    assert_int_equal(sm_clamp_kind_from_name("vertices", &k), 0);
    assert_int_equal(k, SM_CLAMP_VERTICES);
    assert_int_equal(sm_clamp_kind_from_name("Vertices", &k), -1);
    assert_int_equal(sm_clamp_kind_from_name(NULL, &k), -1);
}

/* ------------------------------------------------- schema <-> decoder */

static json_t *load_schema(void)
{
    char path[1024];
    json_error_t jerr;
    snprintf(path, sizeof path, "%s/proto/params.schema.json", root_dir());
    json_t *schema = json_load_file(path, JSON_REJECT_DUPLICATES, &jerr);
    if (!schema)
        fail_msg("%s:%d: %s", path, jerr.line, jerr.text);
    return schema;
}

/* Decodes {"clamp": {"kind": "none"}, field: value}, with step_max or
 * step_initial moved out of the way so that the field's own bounds are
 * what is tested (step_initial <= step_max is checked separately). */
static sm_status try_value(const char *field, json_t *value, sm_error *err)
{
    json_t *doc = json_pack("{s:{s:s}}", "clamp", "kind", "none");
    if (strcmp(field, "step_initial") == 0)
        json_object_set_new(doc, "step_max", json_real(1.0));
    if (strcmp(field, "step_max") == 0) /* the smallest positive double */
        json_object_set_new(doc, "step_initial", json_real(nextafter(0.0, 1.0)));
    json_object_set_new(doc, field, value);
    char *text = json_dumps(doc, JSON_COMPACT | JSON_REAL_PRECISION(17));
    json_decref(doc);
    sm_params p;
    sm_status st = sm_params_from_json(text, strlen(text), 2, &p, err);
    free(text);
    return st;
}

/* A 2D mesh (one triangle) whose $PhysicalNames are "core" (elements,
 * tag 1), "cut" (facets, tag 3) and "tip" (a point, tag 9). */
static sm_mesh *named_mesh(void)
{
    sm_mesh *m = NULL;
    sm_error err = {0};
    assert_int_equal(sm_mesh_alloc(&m, 2, 3, 1, 0, &err), SM_OK);
    static const double xy[] = {0, 0, 1, 0, 0, 1};
    memcpy(m->coords, xy, sizeof xy);
    m->elems[0] = 0, m->elems[1] = 1, m->elems[2] = 2;
    static const struct { int32_t dim, tag; const char *name; } names[] = {
        {2, 1, "core"}, {1, 3, "cut"}, {0, 9, "tip"}};
    m->nnames = 3;
    m->names = calloc(3, sizeof *m->names);
    assert_non_null(m->names);
    for (int i = 0; i < 3; i++) {
        m->names[i].dim = names[i].dim;
        m->names[i].tag = names[i].tag;
        m->names[i].name = strdup(names[i].name);
        assert_non_null(m->names[i].name);
    }
    return m;
}

/* Physical names in reference lists: accepted by the syntax check (dim
 * 0), refused unresolved with a dimension, resolved by the dimension of
 * the group each list takes, and an unknown name listing the others. */
static void test_physical_names(void **state)
{
    (void)state;
    sm_mesh *m = named_mesh();
    sm_params p;
    sm_background_params bg;
    sm_error err = {0};
    const char *doc = "{\"clamp\": {\"kind\": \"elements\", \"refs\": [\"core\", 4]}, "
                      "\"free_boundary\": [\"cut\", 7]}";
    assert_int_equal(sm_params_from_json(doc, strlen(doc), 0, &p, &err), SM_OK);
    assert_int_equal(sm_params_from_json(doc, strlen(doc), 2, &p, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "params.clamp.refs[0]: the physical name \"core\" was not resolved"));
    assert_int_equal(sm_job_params_from_json_for(doc, strlen(doc), m, &p, &bg, &err), SM_OK);
    assert_true(p.n_clamp_refs == 2 && p.clamp_refs[0] == 1 && p.clamp_refs[1] == 4);
    assert_true(p.n_free_refs == 2 && p.free_refs[0] == 3 && p.free_refs[1] == 7);
    /* vertices: a group of any dimension */
    const char *verts = "{\"clamp\": {\"kind\": \"vertices\", \"refs\": [\"tip\", \"cut\"]}}";
    assert_int_equal(sm_job_params_from_json_for(verts, strlen(verts), m, &p, &bg, &err), SM_OK);
    assert_true(p.clamp_refs[0] == 9 && p.clamp_refs[1] == 3);
    /* elements by a name of facets: unknown among the elements' names */
    const char *wrong = "{\"clamp\": {\"kind\": \"elements\", \"refs\": [1, \"cut\"]}}";
    assert_int_equal(sm_job_params_from_json_for(wrong, strlen(wrong), m, &p, &bg, &err),
                     SM_ERR_INVALID);
    assert_string_equal(err.msg, "params.clamp.refs[1]: the template has no physical group named "
                                 "\"cut\" of elements (its names of elements: \"core\" (1))");
    const char *fb = "{\"clamp\": {\"kind\": \"none\"}, \"free_boundary\": [\"core\"]}";
    assert_int_equal(sm_job_params_from_json_for(fb, strlen(fb), m, &p, &bg, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "params.free_boundary[0]: the template has no physical group "
                                    "named \"core\" of facets (its names of facets: \"cut\" (3))"));
    /* a template without names (Medit) */
    sm_mesh_names_free(m->names, m->nnames);
    m->names = NULL, m->nnames = 0;
    assert_int_equal(sm_job_params_from_json_for(doc, strlen(doc), m, &p, &bg, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "params.clamp.refs[0]: the template has no physical names"));
    /* names that cannot be names: empty, control characters, too long */
    char longname[600];
    memset(longname, 'a', 300);
    longname[300] = '\0';
    const char *bad[] = {"\"\"", "\"a\\u0001b\"", NULL};
    for (int i = 0; bad[i]; i++) {
        char text[128];
        snprintf(text, sizeof text, "{\"clamp\": {\"kind\": \"elements\", \"refs\": [%s]}}", bad[i]);
        assert_int_equal(sm_params_from_json(text, strlen(text), 0, &p, &err), SM_ERR_INVALID);
        assert_non_null(strstr(err.msg, "params.clamp.refs[0]: a physical name has 1 to 255"));
    }
    char text[800];
    snprintf(text, sizeof text, "{\"clamp\": {\"kind\": \"none\"}, \"free_boundary\": [\"%s\"]}", longname);
    assert_int_equal(sm_params_from_json(text, strlen(text), 0, &p, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "params.free_boundary[0]: a physical name has 1 to 255"));
    longname[255] = '\0';
    snprintf(text, sizeof text, "{\"clamp\": {\"kind\": \"none\"}, \"free_boundary\": [\"%s\"]}", longname);
    assert_int_equal(sm_params_from_json(text, strlen(text), 0, &p, &err), SM_OK);
    sm_mesh_free(m);
}

static void test_schema_matches_decoder(void **state)
{
    (void)state;
    json_t *schema = load_schema();
    json_t *props = json_object_get(schema, "properties");
    assert_non_null(props);
    assert_true(json_is_false(json_object_get(schema, "additionalProperties")));

    /* same field set as the encoder writes */
    sm_params d;
    defaults(&d);
    d.clamp = SM_CLAMP_NONE;
    /* written only when given: the background members (no default for
     * the size: it comes from the meshes) */
    sm_background_params bg = {0.5, SM_BACKGROUND_PADDING_DEFAULT, 0.25, 0};
    json_t *encoded = sm_job_params_to_jansson(&d, &bg, 2);
    assert_non_null(encoded);
    /* and the label-map rows (label, level, smooth, image_space, and the
     * template's template_label) only when not at their defaults */
    assert_int_equal(json_object_size(encoded) + 5, json_object_size(props));
    const char *key;
    json_t *prop;
    int bounds_checked = 0;
    json_object_foreach(props, key, prop) {
        json_t *mine = json_object_get(encoded, key), *unwritten = NULL;
        const sm_param_info *row = sm_params_lookup(key);
        if (!mine && row &&
            (!strcmp(key, "label") || !strcmp(key, "level") || !strcmp(key, "smooth") ||
             !strcmp(key, "image_space")))
            mine = unwritten = sm_param_is_named(row)
                                   ? json_string(sm_param_value_name(row, (int)row->def))
                               : row->type == SM_PARAM_INT ? json_integer((json_int_t)row->def)
                                                           : json_real(row->def);
        if (!mine && !strcmp(key, "template_label"))
            mine = unwritten = json_integer(0);
        if (!mine)
            fail_msg("schema field %s is not written by sm_params_to_json", key);
        if (strcmp(key, "clamp") == 0)
            continue;
        /* the schema's default is the core's default */
        json_t *dflt = json_object_get(prop, "default");
        /* those two: from the meshes */
        if (!dflt && strcmp(key, "background_size") != 0 && strcmp(key, "template_size") != 0)
            fail_msg("schema field %s has no default", key);
        if (dflt && !json_equal(dflt, mine) &&
            !(json_is_number(dflt) && json_is_number(mine) &&
              json_number_value(dflt) == json_number_value(mine)))
            fail_msg("schema default of %s differs from sm_params_default", key);
        json_decref(unwritten);

        const char *type = json_string_value(json_object_get(prop, "type"));
        int is_int = type && strcmp(type, "integer") == 0;
        sm_error err = {0};
        struct {
            const char *kw;
            double dir; /* direction of the invalid side */
            int inclusive;
        } kws[] = {{"minimum", -1, 1}, {"exclusiveMinimum", -1, 0},
                   {"maximum", +1, 1}, {"exclusiveMaximum", +1, 0}};
        for (size_t i = 0; i < 4; i++) {
            json_t *b = json_object_get(prop, kws[i].kw);
            if (!b)
                continue;
            double bound = json_number_value(b);
            double inside, outside;
            if (is_int) {
                inside = kws[i].inclusive ? bound : bound - kws[i].dir;
                outside = kws[i].inclusive ? bound + kws[i].dir : bound;
            } else {
                double toward_bad = kws[i].dir * INFINITY;
                inside = kws[i].inclusive ? bound : nextafter(bound, -toward_bad);
                outside = kws[i].inclusive ? nextafter(bound, toward_bad) : bound;
            }
            json_t *vin = is_int ? json_integer((json_int_t)inside) : json_real(inside);
            json_t *vout = is_int ? json_integer((json_int_t)outside) : json_real(outside);
            if (try_value(key, vin, &err) != SM_OK)
                fail_msg("%s = %.17g is inside the schema's %s but refused: %s", key, inside,
                         kws[i].kw, err.msg);
            if (try_value(key, vout, &err) != SM_ERR_INVALID)
                fail_msg("%s = %.17g is outside the schema's %s but accepted", key, outside,
                         kws[i].kw);
            char expect[64];
            snprintf(expect, sizeof expect, "params.%s: ", key);
            assert_non_null(strstr(err.msg, expect));
            bounds_checked++;
        }
        /* wrong type */
        if (try_value(key, json_string("1"), &err) != SM_ERR_INVALID)
            fail_msg("%s accepts a string", key);
    }
    json_decref(encoded);

    /* clamp kinds */
    json_t *kinds = json_object_get(
        json_object_get(json_object_get(json_object_get(json_object_get(schema, "$defs"), "clamp"),
                                        "properties"),
                        "kind"),
        "enum");
    assert_int_equal(json_array_size(kinds), 5);
    for (size_t i = 0; i < 5; i++)
        assert_string_equal(json_string_value(json_array_get(kinds, i)),
                            sm_clamp_kind_name((sm_clamp_kind)i));

    /* the examples decode, their physical names resolved against a 2D
     * template that has them */
    json_t *examples = json_object_get(schema, "examples");
    size_t i;
    json_t *ex;
    sm_mesh *named = named_mesh();
    json_array_foreach(examples, i, ex) {
        sm_params p;
        sm_error err = {0};
        json_t *copy = json_deep_copy(ex);
        if (sm_params_from_jansson(ex, 0, NULL, &p, &err) != SM_OK ||
            sm_params_resolve_names(copy, named, NULL, &err) != SM_OK ||
            sm_params_from_jansson(copy, 2, NULL, &p, &err) != SM_OK)
            fail_msg("schema example %zu refused: %s", i, err.msg);
        json_decref(copy);
    }
    sm_mesh_free(named);
    print_message("%d schema bounds checked against the decoder\n", bounds_checked);
    assert_true(bounds_checked >= 15);
    json_decref(schema);
}

/* The schema's member for row f: a top-level property, or alpha in the
 * clamp's kind "none" branch. */
static json_t *schema_member(json_t *schema, const sm_param_info *f)
{
    if (!f->in_clamp)
        return json_object_get(json_object_get(schema, "properties"), f->name);
    json_t *branches = json_object_get(
        json_object_get(json_object_get(schema, "$defs"), "clamp"), "oneOf");
    size_t i;
    json_t *b;
    json_array_foreach(branches, i, b) {
        const char *kind = json_string_value(json_object_get(
            json_object_get(json_object_get(b, "properties"), "kind"), "const"));
        if (kind && strcmp(kind, "none") == 0)
            return json_object_get(json_object_get(b, "properties"), f->name);
    }
    return NULL;
}

/* One bound of row f against the schema's keywords: a finite bound is
 * exactly one of kw_closed / kw_open with the same value; none, neither
 * (an INT's INT_MAX is written as the schema's maximum). */
static void check_bound(const char *name, json_t *m, double bound, int open, const char *kw_closed,
                        const char *kw_open)
{
    json_t *closed = json_object_get(m, kw_closed), *excl = json_object_get(m, kw_open);
    if (isinf(bound)) {
        if (closed || excl)
            fail_msg("%s: the schema has a %s the table does not", name, closed ? kw_closed : kw_open);
        return;
    }
    json_t *have = open ? excl : closed;
    if (!have || (open ? closed : excl))
        fail_msg("%s: the table's bound %g is %s, the schema says otherwise", name, bound,
                 open ? kw_open : kw_closed);
    if (json_number_value(have) != bound)
        fail_msg("%s: %s is %.17g in the schema, %.17g in the table", name, open ? kw_open : kw_closed,
                 json_number_value(have), bound);
}

/* proto/params.schema.json against the parameter table (the served
 * schema is written by hand for its descriptions; this keeps its names,
 * types, bounds and defaults those of the table). */
static void test_schema_matches_table(void **state)
{
    (void)state;
    json_t *schema = load_schema();
    json_t *props = json_object_get(schema, "properties");
    size_t n_core, n_bg, rows_checked = 0;
    const sm_param_info *core = sm_params_table(&n_core);
    const sm_param_info *bg = sm_background_params_table(&n_bg);
    for (size_t i = 0; i < n_core + n_bg; i++) {
        const sm_param_info *f = i < n_core ? &core[i] : &bg[i - n_core];
        json_t *m = schema_member(schema, f);
        if (!m)
            fail_msg("%s: in the table, not in the schema", f->name);
        /* the form's section (the web app groups its fields by it): the
         * table's, one of the schema's x-groups; alpha goes with the clamp */
        const char *group = f->group ? f->group : "advanced";
        const char *shown = json_string_value(
            json_object_get(f->in_clamp ? json_object_get(props, "clamp") : m, "x-group"));
        if (!shown || strcmp(shown, group) != 0)
            fail_msg("%s: x-group %s in the schema, group %s in the table", f->name,
                     shown ? shown : "missing", group);
        int listed = 0;
        size_t g;
        json_t *entry;
        json_array_foreach(json_object_get(schema, "x-groups"), g, entry)
            listed |= strcmp(json_string_value(json_object_get(entry, "name")), group) == 0;
        if (!listed)
            fail_msg("%s: group %s is not one of the schema's x-groups", f->name, group);
        if (f->type == SM_PARAM_CLAMP)
            continue; /* its own $defs, checked by test_schema_matches_decoder */
        const char *type = json_string_value(json_object_get(m, "type"));
        const char *want = f->type == SM_PARAM_REAL ? "number"
                           : f->type == SM_PARAM_INT ? "integer"
                           : sm_param_is_named(f) ? "string" : NULL;
        if (f->type == SM_PARAM_REFS) {
            /* a list of refs: $ref to #/$defs/refs, count bounds */
            assert_string_equal(json_string_value(json_object_get(m, "$ref")), "#/$defs/refs");
            assert_int_equal(json_integer_value(json_object_get(m, "minItems")), (json_int_t)f->min);
            assert_int_equal(json_integer_value(json_object_get(
                                 json_object_get(json_object_get(schema, "$defs"), "refs"), "maxItems")),
                             (json_int_t)f->max);
        } else if (!type || strcmp(type, want) != 0) {
            fail_msg("%s: type %s in the schema, %s in the table", f->name, type ? type : "none", want);
        }
        if (f->type == SM_PARAM_REAL || f->type == SM_PARAM_INT) {
            check_bound(f->name, m, f->min, f->min_open, "minimum", "exclusiveMinimum");
            check_bound(f->name, m, f->max, f->max_open, "maximum", "exclusiveMaximum");
        }
        if (sm_param_is_named(f)) {
            json_t *names = json_object_get(m, "enum");
            assert_int_equal(json_array_size(names), (size_t)f->max + 1);
            for (int k = (int)f->min; k <= (int)f->max; k++)
                assert_string_equal(json_string_value(json_array_get(names, (size_t)k)),
                                    sm_param_value_name(f, k));
        }
        /* the default: none in the schema when it comes from the meshes */
        json_t *d = json_object_get(m, "default");
        if (f->type == SM_PARAM_REAL && f->def_text)
            assert_null(d);
        else if (sm_param_is_named(f))
            assert_string_equal(json_string_value(d), sm_param_value_name(f, (int)f->def));
        else if (f->type == SM_PARAM_REFS)
            assert_int_equal(json_array_size(d), 0);
        else if (!d || json_number_value(d) != f->def)
            fail_msg("%s: default %s in the schema, %.17g in the table", f->name,
                     d ? "differs" : "missing", f->def);
        rows_checked++;
    }
    /* and no schema member without a row */
    const char *key;
    json_t *prop;
    json_object_foreach(props, key, prop) {
        int found = sm_params_lookup(key) != NULL;
        for (size_t i = 0; i < n_bg; i++)
            found = found || strcmp(bg[i].name, key) == 0;
        if (!found)
            fail_msg("%s: in the schema, not in the table", key);
    }
    print_message("%zu rows checked against the schema\n", rows_checked);
    assert_true(rows_checked == n_core + n_bg - 1);
    json_decref(schema);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_minimal_ball_is_complete),
        cmocka_unit_test(test_good_corpus),
        cmocka_unit_test(test_background_members),
        cmocka_unit_test(test_background_needs_generated),
        cmocka_unit_test(test_bad_corpus),
        cmocka_unit_test(test_huge_and_odd_inputs),
        cmocka_unit_test(test_long_key_message),
        cmocka_unit_test(test_dimension_known_later),
        cmocka_unit_test(test_from_jansson_path),
        cmocka_unit_test(test_random_round_trip),
        cmocka_unit_test(test_encoder_refuses_what_json_cannot_carry),
        cmocka_unit_test(test_physical_names),
        cmocka_unit_test(test_schema_matches_decoder),
        cmocka_unit_test(test_schema_matches_table),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
