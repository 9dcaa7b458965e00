/* The parameter table (sm_params_table, shapematch/sm_params.h) and its
 * three readers agree.  Every bound of every parameter is walked through
 * the CLI's option parser (args_parse_run, what `shapematch run --flag
 * value` runs), the params decoder (sm_job_params_from_json) and the
 * core's check (sm_params_validate), with values at the bound, just
 * beyond it and just inside it: the three must accept and refuse alike,
 * and as the bound's kind (open or closed) says, which this test derives
 * from the row, not from sm_param_in_range.  Also: the cross-field rule
 * step_initial <= step_max, the solver names, the reference counts, and
 * the documentation's parameter table (the blocks between
 * "<!-- params-table -->" and "<!-- /params-table -->" in README.md and
 * docs/ match job_options_markdown).
 *
 *   test_params --markdown    prints the table for the docs
 *   test_params --cli-cases   prints the bound cases for tests/cli/params.sh,
 *                             which runs them through the shapematch binary */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>
#include <glob.h>

#include "args.h"
#include "sm_proto_params.h"

static const char *root_dir(void)
{
    const char *r = getenv("SM_ROOT");
    return r && *r ? r : ".";
}

/* What one reader said about a value. */
typedef struct verdicts {
    int cli, json, core; /* 1 accepted, 0 refused, -1 not asked (core: background) */
    char why[3][ARGS_MSG_LEN];
} verdicts;

/* The other options a value needs to be judged on its own bounds:
 * step_initial <= step_max is a rule of its own (test_step_rule). */
static const char *companion_flag(const sm_param_info *f, const char **value,
                                  const char **json)
{
    if (strcmp(f->name, "step_initial") == 0) {
        *value = "1";
        *json = ", \"step_max\": 1";
        return "--step-max";
    }
    if (strcmp(f->name, "step_max") == 0) { /* the smallest positive double */
        *value = "4.9406564584124654e-324";
        *json = ", \"step_initial\": 4.9406564584124654e-324";
        return "--step-initial";
    }
    *value = *json = "";
    return NULL;
}

static int by_cli(const sm_param_info *f, int background, const char *text, char *why)
{
    const char *cvalue, *cjson;
    const char *cflag = companion_flag(f, &cvalue, &cjson);
    const char *argv[16];
    int argc = 0;
    argv[argc++] = "run";
    /* the input rows: template_size sizes a meshed template, template_label
     * selects a label map's label: a template_image takes both */
    argv[argc++] = background ? "--template-image" : "--template";
    argv[argc++] = background ? "t.nii.gz" : "t.mesh";
    if (background) { /* the background members need a generated background */
        argv[argc++] = "--target-surface";
        argv[argc++] = "s.stl";
    } else {
        argv[argc++] = "--target-mesh";
        argv[argc++] = "b.mesh";
        argv[argc++] = "--target-sol";
        argv[argc++] = "b.sol";
    }
    argv[argc++] = "-o";
    argv[argc++] = "out";
    argv[argc++] = "--no-clamp";
    if (cflag) {
        argv[argc++] = cflag;
        argv[argc++] = cvalue;
    }
    argv[argc++] = f->flag;
    argv[argc++] = text;
    argv[argc] = NULL;
    run_options o;
    args_result r = args_parse_run(argc, (char **)argv, &o, why, ARGS_MSG_LEN);
    if (r == ARGS_ERROR && !strstr(why, f->flag))
        fail_msg("the CLI's message does not name %s: %s", f->flag, why);
    return r == ARGS_OK;
}

static int by_json(const sm_param_info *f, const char *text, char *why)
{
    const char *cvalue, *cjson;
    companion_flag(f, &cvalue, &cjson);
    char doc[512];
    if (f->in_clamp)
        snprintf(doc, sizeof doc, "{\"clamp\": {\"kind\": \"none\", \"%s\": %s}%s}", f->name, text,
                 cjson);
    else
        snprintf(doc, sizeof doc, "{\"clamp\": {\"kind\": \"none\"}, \"%s\": %s%s}", f->name, text,
                 cjson);
    sm_params p;
    sm_background_params bg;
    sm_error err;
    sm_error_clear(&err);
    sm_status st = sm_job_params_from_json(doc, strlen(doc), 2, &p, &bg, &err);
    snprintf(why, ARGS_MSG_LEN, "%s", err.msg);
    if (st != SM_OK && !strstr(err.msg, f->name))
        fail_msg("the decoder's message does not name %s: %s", f->name, err.msg);
    return st == SM_OK;
}

static int by_core(const sm_param_info *f, double x, char *why)
{
    sm_params p;
    sm_params_default(&p);
    p.clamp = SM_CLAMP_NONE;
    if (strcmp(f->name, "step_initial") == 0)
        p.step_max = 1;
    if (strcmp(f->name, "step_max") == 0)
        p.step_initial = nextafter(0.0, 1.0);
    char *at = (char *)&p + f->offset;
    if (f->type == SM_PARAM_INT)
        *(int *)at = (int)x;
    else
        *(double *)at = x;
    sm_error err;
    sm_error_clear(&err);
    sm_status st = sm_params_validate(&p, 2, &err);
    snprintf(why, ARGS_MSG_LEN, "%s", err.msg);
    if (st != SM_OK && !strstr(err.msg, f->name))
        fail_msg("the core's message does not name %s: %s", f->name, err.msg);
    return st == SM_OK;
}

/* With --cli-cases: the cases are printed for tests/cli/params.sh, which
 * gives them to the shapematch binary itself, instead of judged here. */
static FILE *cases_out;

/* x given to the three readers; each must answer `expect`. */
static void judge(const sm_param_info *f, int background, double x, int expect, const char *what)
{
    char text[64];
    if (f->type == SM_PARAM_INT)
        snprintf(text, sizeof text, "%.0f", x);
    else
        snprintf(text, sizeof text, "%.17g", x);
    if (cases_out) { /* "accept|refuse surface|files FLAG VALUE [FLAG VALUE]" */
        const char *cvalue, *cjson;
        const char *cflag = companion_flag(f, &cvalue, &cjson);
        fprintf(cases_out, "%s %s %s %s%s%s%s%s\n", expect ? "accept" : "refuse",
                background ? "surface" : "files", f->flag, text, cflag ? " " : "",
                cflag ? cflag : "", cflag ? " " : "", cflag ? cvalue : "");
        return;
    }
    verdicts v;
    v.cli = by_cli(f, background, text, v.why[0]);
    v.json = by_json(f, text, v.why[1]);
    v.core = background ? -1 : by_core(f, x, v.why[2]);
    if (v.cli != expect || v.json != expect || (v.core >= 0 && v.core != expect))
        fail_msg("%s = %s (%s) should be %s: CLI %s (%s), JSON %s (%s), core %s (%s)", f->name,
                 text, what, expect ? "accepted" : "refused", v.cli ? "accepts" : "refuses",
                 v.why[0], v.json ? "accepts" : "refuses", v.why[1],
                 v.core < 0 ? "-" : v.core ? "accepts" : "refuses", v.why[2]);
}

/* The values around one bound: dir is the side of the outside (-1 for a
 * minimum, +1 for a maximum). */
static int walk_bound(const sm_param_info *f, int background, double bound, int open, int dir)
{
    if (isinf(bound)) { /* no bound that side: a huge value is fine */
        double huge = f->type == SM_PARAM_INT ? (dir > 0 ? 2147483647.0 : -2147483648.0)
                                              : dir * 1e300;
        judge(f, background, huge, 1, "far out on an open side");
        return 1;
    }
    double beyond, inside;
    if (f->type == SM_PARAM_INT) {
        beyond = bound + dir;
        inside = bound - dir;
        if (bound >= 2147483647.0) /* INT_MAX: nothing beyond fits an int */
            beyond = NAN;
    } else {
        beyond = nextafter(bound, dir * INFINITY);
        inside = nextafter(bound, -dir * INFINITY);
    }
    judge(f, background, bound, !open, open ? "at an open bound" : "at a closed bound");
    judge(f, background, inside, 1, "just inside");
    if (!isnan(beyond))
        judge(f, background, beyond, 0, "just beyond");
    return 1;
}

static void test_bounds_agree(void **state)
{
    (void)state;
    int bounds = 0, rows = 0;
    for (int background = 0; background < 2; background++) {
        size_t n;
        const sm_param_info *t =
            background ? sm_background_params_table(&n) : sm_params_table(&n);
        for (size_t i = 0; i < n; i++) {
            const sm_param_info *f = &t[i];
            if (f->type != SM_PARAM_REAL && f->type != SM_PARAM_INT)
                continue;
            if (!f->flag) { /* no option (live_every): the decoder and core only */
                char why[ARGS_MSG_LEN];
                char lo[32], hi[32];
                snprintf(lo, sizeof lo, "%.0f", f->min - 1);
                snprintf(hi, sizeof hi, "%.0f", f->min);
                assert_false(by_json(f, lo, why));
                assert_false(by_core(f, f->min - 1, why));
                assert_true(by_json(f, hi, why));
                assert_true(by_core(f, f->min, why));
                rows++;
                continue;
            }
            bounds += walk_bound(f, background, f->min, f->min_open, -1);
            bounds += walk_bound(f, background, f->max, f->max_open, +1);
            rows++;
        }
    }
    if (!cases_out)
        print_message("%d rows, %d bounds walked through CLI, JSON and core\n", rows, bounds);
    assert_true(rows >= 16);
}

/* step_initial <= step_max: equal is fine, one ulp more is refused by all. */
static void test_step_rule(void **state)
{
    (void)state;
    for (int over = 0; over < 2; over++) {
        double max = 0.05, init = over ? nextafter(max, 1) : max;
        char si[32], sm[32], why[ARGS_MSG_LEN], doc[256];
        snprintf(si, sizeof si, "%.17g", init);
        snprintf(sm, sizeof sm, "%.17g", max);
        const char *argv[] = {"run", "--template", "t", "--target-mesh", "b", "--target-sol", "s",
                              "-o", "o", "--no-clamp", "--step-initial", si, "--step-max", sm, NULL};
        run_options o;
        int cli = args_parse_run(14, (char **)argv, &o, why, sizeof why) == ARGS_OK;
        snprintf(doc, sizeof doc,
                 "{\"clamp\": {\"kind\": \"none\"}, \"step_initial\": %s, \"step_max\": %s}", si, sm);
        sm_params p;
        sm_error err;
        int json = sm_params_from_json(doc, strlen(doc), 2, &p, &err) == SM_OK;
        sm_params_default(&p);
        p.step_initial = init;
        p.step_max = max;
        int core = sm_params_validate(&p, 2, &err) == SM_OK;
        assert_int_equal(cli, !over);
        assert_int_equal(json, !over);
        assert_int_equal(core, !over);
        if (over)
            assert_non_null(strstr(err.msg, "step_initial"));
    }
}

/* Numbers in messages are the shortest text that reads back to the value
 * (issue 38: a 422 said "0.69999999999999996"), checked by strtod; and
 * the messages of the CLI, the params JSON and the core use it. */
static void test_number_text(void **state)
{
    (void)state;
    char b[SM_NUMBER_TEXT_LEN];
    struct { double x; const char *text; } cases[] = {
        {0.7, "0.7"}, {0.1 + 0.2, "0.30000000000000004"}, {1e9, "1000000000"}, {-0.0, "0"},
        {-2.5, "-2.5"}, {1e-300, "1e-300"}, {5e-324, "5e-324"},
        {1e15, "1e+15"}, {INFINITY, "inf"}, {-INFINITY, "-inf"}};
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++)
        assert_string_equal(sm_number_text(b, cases[i].x), cases[i].text);
    assert_string_equal(sm_number_text(b, NAN) + (b[0] == '-'), "nan");
    /* every finite text reads back exactly, and no shorter one would */
    srand(38);
    for (int i = 0; i < 100000; i++) {
        uint64_t bits = ((uint64_t)rand() << 42) ^ ((uint64_t)rand() << 21) ^ (uint64_t)rand();
        double x;
        memcpy(&x, &bits, sizeof x);
        if (!isfinite(x))
            continue;
        sm_number_text(b, x);
        assert_true(strtod(b, NULL) == x);
        if (fabs(x) < 1e15 && x == floor(x))
            continue; /* a whole number, in full */
        /* its significant digits: those of the mantissa past leading zeros */
        int digits = 0, leading = 1;
        for (const char *c = b; *c && *c != 'e'; c++) {
            if (*c >= '1' && *c <= '9')
                leading = 0;
            digits += !leading && *c >= '0' && *c <= '9';
        }
        if (digits > 1) {
            char shorter[320];
            snprintf(shorter, sizeof shorter, "%.*g", digits - 1, x);
            assert_true(strtod(shorter, NULL) != x);
        }
    }
    char why[ARGS_MSG_LEN];
    const char *argv[] = {"run", "--template", "t", "--target-mesh", "b", "--target-sol", "s",
                          "-o", "o", "--no-clamp", "--step-initial", "0.07", "--step-max",
                          "0.05", NULL};
    run_options o;
    assert_int_not_equal(args_parse_run(14, (char **)argv, &o, why, sizeof why), ARGS_OK);
    assert_non_null(strstr(why, "(0.07) must not exceed --step-max (0.05)"));
    const char *doc = "{\"clamp\": {\"kind\": \"none\"}, \"poisson\": 0.7}";
    sm_params p;
    sm_error err;
    assert_int_equal(sm_params_from_json(doc, strlen(doc), 2, &p, &err), SM_ERR_INVALID);
    assert_string_equal(err.msg, "params.poisson: must be < 0.5 (got 0.7)");
    sm_params_default(&p);
    p.poisson = 0.7;
    assert_int_equal(sm_params_validate(&p, 2, &err), SM_ERR_INVALID);
    assert_string_equal(err.msg, "poisson: must be in (-1, 0.5) (got 0.7)");
}

/* The named rows (solver, align) by name: every name of the table's
 * range in both; a wrong one refused by both; an enum value past the
 * range refused by core. */
static void test_named_values(void **state)
{
    (void)state;
    size_t nrows;
    const sm_param_info *rows = sm_params_table(&nrows);
    int named = 0;
    for (size_t i = 0; i < nrows; i++) {
        const sm_param_info *f = &rows[i];
        if (!sm_param_is_named(f))
            continue;
        named++;
        for (int k = (int)f->min; k <= (int)f->max + 1; k++) {
            const char *name = k <= (int)f->max ? sm_param_value_name(f, k) : "AMG";
            char quoted[32], why[ARGS_MSG_LEN];
            snprintf(quoted, sizeof quoted, "\"%s\"", name);
            int expect = k <= (int)f->max;
            const char *argv[] = {"run", "--template", "t", "--target-mesh", "b", "--target-sol",
                                  "s", "-o", "o", "--no-clamp", f->flag, name, NULL};
            run_options o;
            assert_int_equal(args_parse_run(12, (char **)argv, &o, why, sizeof why) == ARGS_OK,
                             expect);
            if (expect)
                assert_int_equal(sm_param_get_value(f, &o.job.params), k);
            assert_int_equal(by_json(f, quoted, why), expect);
            sm_params p;
            sm_error err;
            sm_params_default(&p);
            sm_param_set_value(f, &p, k);
            assert_int_equal(sm_params_validate(&p, 2, &err) == SM_OK, expect);
            if (!expect)
                assert_non_null(strstr(err.msg, f->name));
        }
    }
    assert_int_equal(named, 3);
}

/* free_boundary: the count's bounds (0 and SM_MAX_REFS) in JSON and core,
 * the upper one in the CLI (an empty list is not an option value). */
static void test_ref_counts(void **state)
{
    (void)state;
    const sm_param_info *f = sm_params_lookup("free_boundary");
    assert_non_null(f);
    assert_int_equal((int)f->max, SM_MAX_REFS);
    const int counts[] = {(int)f->min, (int)f->min + 1, (int)f->max, (int)f->max + 1};
    for (size_t c = 0; c < sizeof counts / sizeof counts[0]; c++) {
        int count = counts[c];
        char list[512] = "", json[600], why[ARGS_MSG_LEN];
        size_t used = 0;
        for (int i = 0; i < count; i++)
            used += (size_t)snprintf(list + used, sizeof list - used, "%s%d", i ? "," : "", i + 1);
        snprintf(json, sizeof json, "[%s]", list);
        int expect = count <= (int)f->max;
        if (count > 0) {
            const char *argv[] = {"run", "--template", "t", "--target-mesh", "b", "--target-sol",
                                  "s", "-o", "o", "--no-clamp", f->flag, list, NULL};
            run_options o;
            assert_int_equal(args_parse_run(12, (char **)argv, &o, why, sizeof why) == ARGS_OK,
                             expect);
        }
        assert_int_equal(by_json(f, json, why), expect);
        sm_params p;
        sm_error err;
        sm_params_default(&p);
        p.n_free_refs = count;
        assert_int_equal(sm_params_validate(&p, 2, &err) == SM_OK, expect);
    }
}

/* Every row of the table has a name, a help and, when it has a flag, a
 * meta; the defaults are inside their own bounds. */
static void test_rows_well_formed(void **state)
{
    (void)state;
    size_t n;
    const sm_param_info *t = sm_params_table(&n);
    sm_params d;
    sm_error err;
    sm_params_default(&d);
    assert_int_equal(sm_params_validate(&d, 2, &err), SM_OK);
    for (int bg = 0; bg < 2; bg++) {
        if (bg)
            t = sm_background_params_table(&n);
        for (size_t i = 0; i < n; i++) {
            assert_non_null(t[i].name);
            assert_non_null(t[i].help);
            assert_true(!t[i].flag || t[i].meta);
            if ((t[i].type == SM_PARAM_REAL || t[i].type == SM_PARAM_INT) && !t[i].def_text &&
                !sm_param_in_range(&t[i], t[i].def))
                fail_msg("%s: default %g outside its bounds", t[i].name, t[i].def);
            /* an infinite bound is open (in range means finite) */
            assert_true(!isinf(t[i].min) || t[i].min_open);
            assert_true(!isinf(t[i].max) || t[i].max_open);
            if (!bg)
                assert_ptr_equal(sm_params_lookup(t[i].name), &t[i]);
        }
    }
}

/* ---------------------------------------------- the docs' parameter table */

static char *markdown(void)
{
    char *text = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&text, &len);
    assert_non_null(f);
    job_options_markdown(f);
    fclose(f);
    return text;
}

#define BEGIN_MARK "<!-- params-table -->\n"
#define END_MARK "<!-- /params-table -->"

/* The blocks of one file; returns how many, fails on one that differs. */
static int check_doc(const char *path, const char *want)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return 0;
    static char buf[1 << 20];
    size_t len = fread(buf, 1, sizeof buf - 1, f);
    fclose(f);
    buf[len] = '\0';
    int blocks = 0;
    for (char *at = strstr(buf, BEGIN_MARK); at; at = strstr(at, BEGIN_MARK)) {
        at += strlen(BEGIN_MARK);
        char *end = strstr(at, END_MARK);
        if (!end)
            fail_msg("%s: %s without %s", path, BEGIN_MARK, END_MARK);
        if ((size_t)(end - at) != strlen(want) || memcmp(at, want, strlen(want)) != 0)
            fail_msg("%s: the parameter table differs from the parameter table's (regenerate it: "
                     "build/release/tests/test_params --markdown)",
                     path);
        blocks++;
        at = end;
    }
    return blocks;
}

static void test_docs_table(void **state)
{
    (void)state;
    char *want = markdown();
    char pattern[1024];
    int blocks = 0;
    snprintf(pattern, sizeof pattern, "%s/README.md", root_dir());
    blocks += check_doc(pattern, want);
    snprintf(pattern, sizeof pattern, "%s/docs/*.md", root_dir());
    glob_t g;
    if (glob(pattern, 0, NULL, &g) == 0) {
        for (size_t i = 0; i < g.gl_pathc; i++)
            blocks += check_doc(g.gl_pathv[i], want);
        globfree(&g);
    }
    print_message("%d parameter table(s) in the docs match\n", blocks);
    assert_true(blocks >= 1); /* the docs have one */
    free(want);
}

int main(int argc, char **argv)
{
    if (argc == 2 && strcmp(argv[1], "--markdown") == 0) {
        job_options_markdown(stdout);
        return 0;
    }
    if (argc == 2 && strcmp(argv[1], "--cli-cases") == 0) {
        cases_out = stdout;
        test_bounds_agree(NULL);
        return 0;
    }
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_rows_well_formed),
        cmocka_unit_test(test_bounds_agree),
        cmocka_unit_test(test_step_rule),
        cmocka_unit_test(test_number_text),
        cmocka_unit_test(test_named_values),
        cmocka_unit_test(test_ref_counts),
        cmocka_unit_test(test_docs_table),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
