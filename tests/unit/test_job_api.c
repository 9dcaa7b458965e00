/* The job in one call (proto/job/shapematch_job.h, libshapematch_job.so's
 * API, which the Python package calls): the same vertices and summary as
 * the job runner it wraps (sm_job_run_exec after the inputs read as
 * `shapematch run` reads them), messages naming the file and the
 * parameter, a stop from the progress callback, the cancel flag, the
 * result set on demand, the summary's input names; every path freed (the
 * asan variant's leak check). */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <cmocka.h>

#include <jansson.h>

#include "job/shapematch_job.h"
#include "job/sm_job_inputs.h"
#include "job/sm_job_runner.h"
#include "shapematch/sm_io.h"
#include "util_mesh.h"

typedef struct fixture {
    char dir[64];
    char tpl[128], bg[128], sol[128], out[128];
} fixture;

static int setup(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    if (!f)
        return -1;
    const char *tmp = getenv("TMPDIR");
    snprintf(f->dir, sizeof f->dir, "%s/sm-test-api-XXXXXX", tmp && *tmp ? tmp : "/tmp");
    if (!mkdtemp(f->dir))
        return -1;
    snprintf(f->tpl, sizeof f->tpl, "%s/template.mesh", f->dir);
    snprintf(f->bg, sizeof f->bg, "%s/bg.mesh", f->dir);
    snprintf(f->sol, sizeof f->sol, "%s/bg.sol", f->dir);
    snprintf(f->out, sizeof f->out, "%s/out", f->dir);
    sm_error err;
    const double c[2] = {0.5, 0.5}, lo[2] = {0, 0}, hi[2] = {1, 1};
    sm_mesh *tpl = util_disk_mesh(c, 0.22, 6);
    sm_mesh *bg = util_box_mesh(2, 40, lo, hi, 0);
    sm_sol *s = NULL;
    if (!tpl || !bg || sm_mesh_write(f->tpl, tpl, &err) != SM_OK ||
        sm_mesh_write(f->bg, bg, &err) != SM_OK || sm_sol_alloc(&s, 2, bg->nverts, 1, &err) != SM_OK)
        return -1;
    for (int32_t v = 0; v < bg->nverts; v++) /* the circle of radius 0.3 */
        s->values[v] = hypot(bg->coords[2 * v] - 0.5, bg->coords[2 * v + 1] - 0.5) - 0.3;
    if (sm_sol_write(f->sol, s, &err) != SM_OK)
        return -1;
    sm_sol_free(s);
    sm_mesh_free(tpl);
    sm_mesh_free(bg);
    *state = f;
    return 0;
}

static int teardown(void **state)
{
    fixture *f = *state;
    const char *names[] = {"result.mesh", "result.vtu", "displacement.sol", "history.csv",
                           "history.json", "summary.json"};
    char path[256];
    for (size_t i = 0; i < sizeof names / sizeof *names; i++) {
        snprintf(path, sizeof path, "%s/%s", f->out, names[i]);
        unlink(path);
    }
    rmdir(f->out);
    unlink(f->tpl);
    unlink(f->bg);
    unlink(f->sol);
    rmdir(f->dir);
    free(f);
    return 0;
}

#define BALL "{\"clamp\": {\"kind\": \"ball\", \"center\": [0.5, 0.5], \"radius\": 0.05}"

/* The API's run against the runner's own, step by step as `run` does. */
static void test_same_as_the_runner(void **state)
{
    fixture *f = *state;
    sm_run_files files = {.template_mesh = f->tpl, .target_mesh = f->bg, .target_sol = f->sol};
    sm_run *r = NULL;
    sm_error err;
    assert_int_equal(sm_run_job(&files, BALL ", \"max_iter\": 12}", NULL, NULL, NULL, &r, &err),
                     SM_OK);
    assert_non_null(r);

    sm_job_files jf = {.template_mesh = f->tpl, .target_mesh = f->bg, .target_sol = f->sol};
    sm_job_inputs in;
    sm_params p;
    assert_int_equal(sm_job_inputs_read_template(&jf, SM_JOB_NAME_PATHS, &in, &err), SM_OK);
    assert_int_equal(sm_params_from_json(BALL ", \"max_iter\": 12}", strlen(BALL) + 17, 2, &p, &err),
                     SM_OK);
    assert_int_equal(sm_job_inputs_set_params(&in, &p, &err), SM_OK);
    assert_int_equal(sm_job_inputs_read_target(&jf, SM_JOB_NAME_PATHS, 1, &in, &err), SM_OK);
    sm_job_run run;
    assert_int_equal(sm_job_run_exec(&in, NULL, &run, &err), SM_OK);

    int32_t nv = sm_run_nverts(r);
    assert_int_equal(sm_run_dim(r), 2);
    assert_int_equal(nv, in.template_mesh->nverts);
    assert_int_equal(sm_run_nelems(r), in.template_mesh->nelems);
    assert_memory_equal(sm_run_coords(r), run.coords, (size_t)nv * 2 * sizeof(double));
    assert_memory_equal(sm_run_init_coords(r), in.template_mesh->coords,
                        (size_t)nv * 2 * sizeof(double));
    assert_memory_equal(sm_run_elems(r), in.template_mesh->elems,
                        (size_t)sm_run_nelems(r) * 3 * sizeof(int32_t));
    size_t nh;
    const sm_progress *h = sm_run_history(r, &nh);
    assert_int_equal(nh, run.nhistory);
    assert_int_equal(nh, 13);
    for (size_t i = 0; i < nh; i++) {
        assert_int_equal(h[i].iteration, (int)i);
        assert_true(h[i].J == run.history[i].J);
    }
    assert_string_equal(sm_run_outcome(r), "finished");
    assert_int_equal(sm_run_exit_code(r), run.exit_code);

    json_t *s = json_loads(sm_run_summary(r), 0, NULL);
    assert_non_null(s);
    assert_int_equal(json_integer_value(json_object_get(s, "iterations")), 12);
    assert_true(json_real_value(json_object_get(s, "boundary_l2")) == run.result.boundary_l2);
    assert_null(json_object_get(s, "outputs"));
    assert_string_equal(json_string_value(json_object_get(json_object_get(s, "inputs"), "template")),
                        f->tpl);
    json_decref(s);

    /* the result set, on demand, into a folder made for it */
    assert_int_equal(sm_run_write(r, f->out, NULL, &err), SM_OK);
    char path[256];
    struct stat st;
    snprintf(path, sizeof path, "%s/result.mesh", f->out);
    assert_int_equal(stat(path, &st), 0);
    assert_int_equal(sm_run_write(r, f->out, "mesh,bogus", &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "bogus"));

    sm_job_run_free(&run);
    sm_job_inputs_free(&in);
    sm_run_free(r);
}

static int stop_at_3(const sm_progress *p, void *user)
{
    (*(int *)user)++;
    return p->iteration >= 3;
}

static void test_stop_and_cancel(void **state)
{
    fixture *f = *state;
    sm_run_files files = {.template_mesh = f->tpl, .target_mesh = f->bg, .target_sol = f->sol,
                          .template_name = "template (array)"};
    sm_run *r = NULL;
    sm_error err;
    int calls = 0;
    assert_int_equal(sm_run_job(&files, BALL ", \"max_iter\": 50}", stop_at_3, &calls, NULL, &r,
                                &err), SM_OK);
    assert_int_equal(calls, 4);
    assert_string_equal(sm_run_outcome(r), "cancelled");
    assert_int_equal(sm_run_exit_code(r), SM_JOB_EXIT_CANCELLED);
    json_t *s = json_loads(sm_run_summary(r), 0, NULL);
    assert_string_equal(json_string_value(json_object_get(json_object_get(s, "inputs"), "template")),
                        "template (array)");
    json_decref(s);
    sm_run_free(r);

    volatile int cancel = 1; /* set before the start: stops at the first check */
    assert_int_equal(sm_run_job(&files, BALL ", \"max_iter\": 50}", NULL, NULL, &cancel, &r, &err),
                     SM_OK);
    assert_string_equal(sm_run_outcome(r), "cancelled");
    size_t nh;
    sm_run_history(r, &nh);
    assert_true(nh <= 2);
    sm_run_free(r);
    /* a cancel before or during the alignment ends the run there: the
     * template unmoved, no descent (no history), what only the descent
     * measures null, the alignment not reported as done */
    assert_int_equal(sm_run_job(&files, BALL ", \"align\": \"rigid\"}", NULL, NULL, &cancel, &r,
                                &err),
                     SM_OK);
    assert_string_equal(sm_run_outcome(r), "cancelled");
    assert_int_equal(sm_run_exit_code(r), SM_JOB_EXIT_CANCELLED);
    assert_non_null(strstr(sm_run_message(r), "during the alignment"));
    sm_run_history(r, &nh);
    assert_int_equal(nh, 0);
    assert_memory_equal(sm_run_coords(r), sm_run_init_coords(r),
                        (size_t)sm_run_nverts(r) * 2 * sizeof(double));
    json_t *sum = json_loads(sm_run_summary(r), 0, NULL);
    assert_non_null(sum);
    assert_string_equal(json_string_value(json_object_get(sum, "status")), "cancelled");
    assert_string_equal(json_string_value(json_object_get(sum, "stop_reason")), "cancelled");
    assert_true(json_is_null(json_object_get(sum, "boundary_l2")));
    assert_null(json_object_get(sum, "alignment"));
    json_decref(sum);
    sm_run_free(r);
}

static void test_errors(void **state)
{
    fixture *f = *state;
    sm_run_files files = {.template_mesh = f->tpl, .target_mesh = f->bg, .target_sol = f->sol};
    sm_run *r = (sm_run *)&files; /* must come back NULL */
    sm_error err;
    assert_int_equal(sm_run_job(&files, BALL ", \"max_iter\": 0}", NULL, NULL, NULL, &r, &err),
                     SM_ERR_INVALID);
    assert_null(r);
    assert_non_null(strstr(err.msg, "params.max_iter"));
    assert_int_equal(sm_run_job(&files, BALL ", \"nope\": 1}", NULL, NULL, NULL, &r, &err),
                     SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "nope"));
    assert_int_equal(sm_run_job(&files, "{\"clamp\": ", NULL, NULL, NULL, &r, &err), SM_ERR_FORMAT);
    assert_int_equal(sm_run_job(&files, "", NULL, NULL, NULL, &r, &err), SM_ERR_INVALID);
    /* a clamp ball that holds no vertex: the clamp check, named */
    assert_int_equal(sm_run_job(&files,
                                "{\"clamp\": {\"kind\": \"ball\", \"center\": [5, 5], \"radius\": 0.01}}",
                                NULL, NULL, NULL, &r, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "params.clamp"));
    /* a broken template file: its path and line */
    char bad[160];
    snprintf(bad, sizeof bad, "%s/bad.mesh", f->dir);
    FILE *fp = fopen(bad, "w");
    assert_non_null(fp);
    fputs("MeshVersionFormatted 2\nDimension 2\nVertices\n2\n0 0 0\n1 x 0\nEnd\n", fp);
    fclose(fp);
    files.template_mesh = bad;
    assert_int_equal(sm_run_job(&files, BALL "}", NULL, NULL, NULL, &r, &err), SM_ERR_FORMAT);
    char want[200];
    snprintf(want, sizeof want, "%s:6:", bad);
    assert_non_null(strstr(err.msg, want));
    unlink(bad);
    /* a missing target: named */
    files.template_mesh = f->tpl;
    files.target_sol = NULL;
    assert_int_not_equal(sm_run_job(&files, BALL "}", NULL, NULL, NULL, &r, &err), SM_OK);
    assert_null(r);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_same_as_the_runner, setup, teardown),
        cmocka_unit_test_setup_teardown(test_stop_and_cancel, setup, teardown),
        cmocka_unit_test_setup_teardown(test_errors, setup, teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
