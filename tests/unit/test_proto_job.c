/* The shared job runner and what it stands on: atomic writes (core's
 * sm_atomic), the wire vocabulary, the lossy JSON string, the inputs read
 * with the user's paths, and a job run end to end through
 * sm_job_run_exec / sm_job_write_results: the outcome (finished, failed
 * when no step is possible, cancelled), the field built once, the result
 * set on disk and the summary's members. */
#include <dirent.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>
#include <cmocka.h>
#include <sched.h>
#include <omp.h>

#include "shapematch/sm_atomic.h"
#include "shapematch/sm_io.h"
#include "job/sm_job_inputs.h"
#include "job/sm_job_results.h"
#include "job/sm_job_runner.h"
#include "job/sm_job_threads.h"
#include "sm_json.h"
#include "sm_proto_vocab.h"
#include "util_mesh.h"

typedef struct fixture {
    char dir[64];
    char tpl[128], bg[128], sol[128], out[128];
} fixture;

/* Signed distance to the circle of radius 0.3 centred at (0.5, 0.5). */
static double circle(const double *x)
{
    return hypot(x[0] - 0.5, x[1] - 0.5) - 0.3;
}

static int setup(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    snprintf(f->dir, sizeof f->dir, "/tmp/sm-test-job-XXXXXX");
    if (!mkdtemp(f->dir))
        return -1;
    snprintf(f->tpl, sizeof f->tpl, "%s/template.mesh", f->dir);
    snprintf(f->bg, sizeof f->bg, "%s/bg.mesh", f->dir);
    snprintf(f->sol, sizeof f->sol, "%s/bg.sol", f->dir);
    snprintf(f->out, sizeof f->out, "%s/out", f->dir);
    sm_error err;
    const double c[2] = {0.5, 0.5};
    const double blo[2] = {0, 0}, bhi[2] = {1, 1};
    sm_mesh *tpl = util_disk_mesh(c, 0.22, 6);
    sm_mesh *bg = util_box_mesh(2, 40, blo, bhi, 0);
    sm_sol *s = NULL;
    if (!tpl || !bg || sm_mesh_write(f->tpl, tpl, &err) != SM_OK ||
        sm_mesh_write(f->bg, bg, &err) != SM_OK ||
        sm_sol_alloc(&s, 2, bg->nverts, 1, &err) != SM_OK)
        return -1;
    for (int32_t v = 0; v < bg->nverts; v++)
        s->values[v] = circle(bg->coords + 2 * (size_t)v);
    if (sm_sol_write(f->sol, s, &err) != SM_OK || mkdir(f->out, 0755) != 0)
        return -1;
    sm_sol_free(s);
    sm_mesh_free(tpl);
    sm_mesh_free(bg);
    *state = f;
    return 0;
}

static void remove_dir(const char *dir)
{
    DIR *d = opendir(dir);
    if (!d)
        return;
    struct dirent *e;
    char path[512];
    while ((e = readdir(d)) != NULL) {
        if (strcmp(e->d_name, ".") == 0 || strcmp(e->d_name, "..") == 0)
            continue;
        snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        struct stat st;
        if (lstat(path, &st) == 0 && S_ISDIR(st.st_mode))
            remove_dir(path);
        else
            unlink(path);
    }
    closedir(d);
    rmdir(dir);
}

static int teardown(void **state)
{
    fixture *f = *state;
    remove_dir(f->dir);
    free(f);
    return 0;
}

/* Entries of dir whose name starts with '.' (temporaries left behind). */
static int hidden_entries(const char *dir)
{
    DIR *d = opendir(dir);
    assert_non_null(d);
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d)) != NULL)
        if (e->d_name[0] == '.' && strcmp(e->d_name, ".") != 0 && strcmp(e->d_name, "..") != 0)
            n++;
    closedir(d);
    return n;
}

static char *slurp(const char *path, size_t *len)
{
    FILE *fp = fopen(path, "rb");
    if (!fp)
        return NULL;
    char *buf = malloc(1 << 20);
    *len = fread(buf, 1, (1 << 20) - 1, fp);
    buf[*len] = '\0';
    fclose(fp);
    return buf;
}

static void test_atomic_write(void **state)
{
    fixture *f = *state;
    char path[192];
    snprintf(path, sizeof path, "%s/a.txt", f->out);
    sm_error err;
    assert_int_equal(sm_atomic_write_file(path, "one\n", 4, SM_ATOMIC_FSYNC, &err), SM_OK);
    assert_int_equal(sm_atomic_write_file(path, "two\n", 4, 0, &err), SM_OK);
    size_t len;
    char *text = slurp(path, &len);
    assert_non_null(text);
    assert_int_equal(len, 4);
    assert_string_equal(text, "two\n");
    free(text);
    /* a reserved temporary keeps the extension, and an abort removes it */
    sm_atomic a;
    snprintf(path, sizeof path, "%s/b.mesh", f->out);
    assert_int_equal(sm_atomic_reserve(&a, path, &err), SM_OK);
    size_t n = strlen(a.tmp_path);
    assert_true(n > 5 && strcmp(a.tmp_path + n - 5, ".mesh") == 0);
    assert_non_null(strstr(a.tmp_path, "/."));
    assert_int_equal(access(a.tmp_path, F_OK), 0);
    sm_atomic_abort(&a);
    assert_int_equal(access(path, F_OK), -1);
    /* an open stream abandoned: nothing under the final name */
    assert_int_equal(sm_atomic_open(&a, path, &err), SM_OK);
    fputs("half", a.f);
    sm_atomic_abort(&a);
    assert_int_equal(access(path, F_OK), -1);
    assert_int_equal(hidden_entries(f->out), 0);
    /* a folder that does not exist: an error naming the path */
    snprintf(path, sizeof path, "%s/no/such/c.txt", f->out);
    assert_int_equal(sm_atomic_write_file(path, "x", 1, SM_ATOMIC_FSYNC, &err), SM_ERR_IO);
    assert_non_null(strstr(err.msg, path));
}

static void test_vocabulary(void **state)
{
    (void)state;
    assert_string_equal(sm_part_name(SM_PART_TEMPLATE), "template");
    assert_string_equal(sm_part_name(SM_PART_TARGET_MESH), "target_mesh");
    assert_string_equal(sm_part_name(SM_PART_TARGET_SOL), "target_sol");
    assert_string_equal(sm_part_name(SM_PART_TARGET_SURFACE), "target_surface");
    assert_string_equal(sm_part_name(SM_PART_TEMPLATE_LANDMARKS), "template_landmarks");
    assert_string_equal(sm_part_name(SM_PART_TARGET_LANDMARKS), "target_landmarks");
    assert_string_equal(sm_part_name(SM_PART_PARAMS), "params");
    assert_null(sm_part_name(SM_NPARTS));
    static const char *const defaults[SM_NRESULT_KINDS] = {"mesh", "sol", "csv"};
    size_t total = 0;
    for (int k = 0; k < SM_NRESULT_KINDS; k++) {
        size_t n;
        const sm_result_format *f = sm_result_formats_of((sm_result_kind)k, &n);
        assert_non_null(f);
        assert_true(n >= 2);
        assert_string_equal(f[0].name, defaults[k]);
        for (size_t i = 0; i < n; i++) {
            assert_int_equal(f[i].kind, k);
            assert_ptr_equal(sm_result_format_find((sm_result_kind)k, f[i].name), &f[i]);
        }
        total += n;
    }
    assert_int_equal(total, SM_RESULT_FORMATS_N);
    /* every result file has its own name, and none is the summary */
    for (size_t i = 0; i < SM_RESULT_FORMATS_N; i++) {
        assert_string_not_equal(sm_result_formats[i].file, SM_RESULT_SUMMARY_FILE);
        for (size_t j = i + 1; j < SM_RESULT_FORMATS_N; j++)
            assert_string_not_equal(sm_result_formats[i].file, sm_result_formats[j].file);
    }
    assert_string_equal(sm_result_format_find(SM_RESULT_MESH, "binary")->file, "result.smmesh");
    assert_null(sm_result_format_find(SM_RESULT_HISTORY, "vtu"));
    assert_string_equal(sm_result_kind_name(SM_RESULT_DISPLACEMENT), "displacement");
}

static void test_json_string_lossy(void **state)
{
    (void)state;
    json_t *s = sm_json_string_lossy("we\"ird\\ \xe9t\xc3\xa9\t.mesh");
    assert_non_null(s);
    assert_string_equal(json_string_value(s), "we\"ird\\ \xef\xbf\xbdt\xc3\xa9\t.mesh");
    json_decref(s);
    /* an overlong form and a truncated sequence */
    s = sm_json_string_lossy("\xc0\xaf-\xe2\x82");
    assert_string_equal(json_string_value(s), "\xef\xbf\xbd\xef\xbf\xbd-\xef\xbf\xbd\xef\xbf\xbd");
    json_decref(s);
    assert_null(sm_json_string_lossy(NULL));
}

static void read_inputs(const fixture *f, sm_job_inputs *in)
{
    sm_job_files files = {.template_mesh = f->tpl, .target_mesh = f->bg, .target_sol = f->sol};
    sm_error err;
    assert_int_equal(sm_job_inputs_read(&files, SM_JOB_NAME_PATHS, in, &err), SM_OK);
    assert_int_equal(in->field_builds, 1);
    assert_non_null(in->prepared);
    assert_non_null(in->field);
}

static void ball_params(sm_params *p)
{
    sm_params_default(p);
    p->clamp = SM_CLAMP_BALL;
    p->clamp_center[0] = p->clamp_center[1] = 0.5;
    p->clamp_radius = 0.05;
    p->max_iter = 15;
}

static void test_inputs_naming(void **state)
{
    fixture *f = *state;
    char missing[192];
    snprintf(missing, sizeof missing, "%s/nothere.mesh", f->dir);
    sm_job_files files = {.template_mesh = missing, .target_mesh = f->bg, .target_sol = f->sol};
    sm_job_inputs in;
    sm_error err;
    /* a local run names the user's file, the daemon only the part */
    assert_int_not_equal(sm_job_inputs_read(&files, SM_JOB_NAME_PATHS, &in, &err), SM_OK);
    assert_non_null(strstr(err.msg, missing));
    assert_int_equal(in.failed, SM_PART_TEMPLATE);
    assert_null(in.template_mesh);
    assert_int_not_equal(sm_job_inputs_read(&files, SM_JOB_NAME_PARTS, &in, &err), SM_OK);
    assert_null(strstr(err.msg, f->dir));
    assert_true(strncmp(err.msg, "template: ", 10) == 0);
    /* a distance of the wrong size names both files with paths */
    files.template_mesh = f->tpl;
    files.target_sol = f->tpl; /* not a .sol */
    assert_int_not_equal(sm_job_inputs_read(&files, SM_JOB_NAME_PATHS, &in, &err), SM_OK);
    assert_int_equal(in.failed, SM_PART_TARGET_SOL);
    /* parameters: the clamp set is checked against the template */
    read_inputs(f, &in);
    sm_params p;
    ball_params(&p);
    p.clamp_center[0] = 5.0;
    assert_int_equal(sm_job_inputs_set_params(&in, &p, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "clamp set is empty"));
    assert_int_equal(in.failed, SM_PART_PARAMS);
    ball_params(&p);
    assert_int_equal(sm_job_inputs_set_params(&in, &p, &err), SM_OK);
    assert_true(in.nclamped >= 1);
    sm_job_inputs_free(&in);
}

static void write_text(const char *path, const char *text)
{
    FILE *fp = fopen(path, "w");
    assert_non_null(fp);
    fputs(text, fp);
    fclose(fp);
}

/* The landmark parts: a bad file is named by its part (the daemon) or by
 * role and path (a local run); landmarks with align none are refused
 * naming template_landmarks; with an alignment they are read. */
static void test_landmark_parts(void **state)
{
    fixture *f = *state;
    char good[192], bad[192];
    snprintf(good, sizeof good, "%s/lm_good.csv", f->dir);
    snprintf(bad, sizeof bad, "%s/lm_bad.csv", f->dir);
    write_text(good, "x,y\n0.5,0.5\n0.6,0.5\n0.5,0.6\n");
    write_text(bad, "0.5,0.5\n0.6,zero\n0.5,0.6\n");
    sm_job_files files = {.template_mesh = f->tpl, .target_mesh = f->bg, .target_sol = f->sol,
                          .landmarks_template = good, .landmarks_target = bad};
    sm_job_inputs in;
    sm_error err;
    assert_int_equal(sm_job_inputs_read(&files, SM_JOB_NAME_PARTS, &in, &err), SM_ERR_FORMAT);
    assert_int_equal(in.failed, SM_PART_TARGET_LANDMARKS);
    assert_true(strncmp(err.msg, "target_landmarks: line 2, ", 26) == 0);
    assert_null(strstr(err.msg, f->dir));
    assert_int_not_equal(sm_job_inputs_read(&files, SM_JOB_NAME_PATHS, &in, &err), SM_OK);
    assert_true(strncmp(err.msg, "landmarks (target): ", 20) == 0);
    assert_non_null(strstr(err.msg, bad));
    files.landmarks_target = good;
    static const char none[] = "{\"clamp\": {\"kind\": \"ball\", \"center\": [0.5, 0.5], \"radius\": 0.05}}";
    assert_int_equal(sm_job_inputs_load(&files, none, strlen(none), &in, &err), SM_ERR_INVALID);
    assert_int_equal(in.failed, SM_PART_TEMPLATE_LANDMARKS);
    assert_true(strncmp(err.msg, "template_landmarks: landmarks need an alignment", 47) == 0);
    assert_null(in.template_mesh);
    static const char rigid[] = "{\"clamp\": {\"kind\": \"ball\", \"center\": [0.5, 0.5], \"radius\": 0.05}, "
                                "\"align\": \"rigid\"}";
    assert_int_equal(sm_job_inputs_load(&files, rigid, strlen(rigid), &in, &err), SM_OK);
    assert_int_equal(in.nlandmarks, 3);
    assert_true(in.landmarks[1][3] == 0.5 && in.landmarks[1][2] == 0.6);
    sm_job_inputs_free(&in);
}

static int count_progress(const sm_progress *p, void *user)
{
    (void)p;
    (*(int *)user)++;
    return 0;
}

static void test_run_and_results(void **state)
{
    fixture *f = *state;
    sm_job_inputs in;
    read_inputs(f, &in);
    sm_params p;
    ball_params(&p);
    p.save_every = 5;
    sm_error err;
    assert_int_equal(sm_job_inputs_set_params(&in, &p, &err), SM_OK);
    int reports = 0;
    sm_job_hooks hooks = {.progress = count_progress, .user = &reports, .snapshot_dir = f->out};
    sm_job_run run;
    assert_int_equal(sm_job_run_exec(&in, &hooks, &run, &err), SM_OK);
    assert_int_equal(run.outcome, SM_JOB_OUTCOME_FINISHED);
    assert_int_equal(run.exit_code, SM_JOB_EXIT_OK);
    assert_int_equal(run.result.iterations, 15);
    assert_int_equal(run.nhistory, 16);
    assert_int_equal(reports, 16);
    assert_int_equal(run.history[15].iteration, 15);
    assert_int_equal(run.inverted, 0);
    sm_job_files names = {.template_mesh = "t.mesh", .target_mesh = "b.mesh", .target_sol = "b.sol"};
    assert_int_equal(sm_job_write_results(&in, &run, &names, f->out, SM_ATOMIC_FSYNC, &err), SM_OK);
    char path[192];
    for (size_t i = 0; i < SM_RESULT_FORMATS_N; i++) {
        snprintf(path, sizeof path, "%s/%s", f->out, sm_result_formats[i].file);
        struct stat st;
        assert_int_equal(stat(path, &st), 0);
        assert_true(st.st_size > 0);
    }
    for (int it = 5; it <= 15; it += 5) {
        char name[32];
        snprintf(name, sizeof name, SM_SNAPSHOT_FORMAT, it);
        snprintf(path, sizeof path, "%s/%s", f->out, name);
        assert_int_equal(access(path, F_OK), 0);
    }
    assert_int_equal(hidden_entries(f->out), 0);
    /* the summary: the result members and the runner's own */
    snprintf(path, sizeof path, "%s/" SM_RESULT_SUMMARY_FILE, f->out);
    json_error_t jerr;
    json_t *doc = json_load_file(path, 0, &jerr);
    assert_non_null(doc);
    static const char *const keys[] = {"shapematch_version", "status", "exit_code", "stop_reason",
                                       "iterations", "J_initial", "J_final", "boundary_l2",
                                       "boundary_max", "min_quality", "accepted", "rejected",
                                       "timings", "parameters", "inverted_elements",
                                       "field_builds", "inputs", "template", "outputs"};
    for (size_t k = 0; k < sizeof keys / sizeof keys[0]; k++)
        if (!json_object_get(doc, keys[k]))
            fail_msg("summary.json has no %s", keys[k]);
    assert_string_equal(json_string_value(json_object_get(doc, "status")), "finished");
    assert_int_equal(json_integer_value(json_object_get(doc, "field_builds")), 1);
    assert_int_equal(json_integer_value(json_object_get(doc, "iterations")), 15);
    json_t *timings = json_object_get(doc, "timings");
    assert_non_null(json_object_get(timings, "read"));
    assert_non_null(json_object_get(timings, "field_build"));
    assert_non_null(json_object_get(timings, "total"));
    assert_string_equal(json_string_value(json_object_get(json_object_get(doc, "inputs"), "target_sol")),
                        "b.sol");
    json_t *mesh = json_object_get(json_object_get(doc, "outputs"), "mesh");
    assert_string_equal(json_string_value(json_object_get(mesh, "binary")), "result.smmesh");
    assert_int_equal(json_integer_value(json_object_get(json_object_get(doc, "template"), "vertices")),
                     in.template_mesh->nverts);
    json_decref(doc);
    sm_job_run_free(&run);
    sm_job_inputs_free(&in);
}

static void test_outcomes(void **state)
{
    fixture *f = *state;
    sm_job_inputs in;
    read_inputs(f, &in);
    sm_params p;
    ball_params(&p);
    p.tol_step = 0.5; /* the first step (1% of the diameter) is below it */
    sm_error err;
    assert_int_equal(sm_job_inputs_set_params(&in, &p, &err), SM_OK);
    sm_job_run run;
    assert_int_equal(sm_job_run_exec(&in, NULL, &run, &err), SM_OK);
    assert_int_equal(run.result.stop, SM_STOP_STEP);
    assert_int_equal(run.result.iterations, 0);
    assert_int_equal(run.outcome, SM_JOB_OUTCOME_FAILED);
    assert_int_equal(run.exit_code, SM_JOB_EXIT_NUMERIC);
    assert_non_null(strstr(run.message, "no valid step"));
    assert_string_equal(sm_job_outcome_name(run.outcome), "failed");
    sm_job_run_free(&run);
    /* the cancel flag: the state reached, outcome cancelled */
    ball_params(&p);
    assert_int_equal(sm_job_inputs_set_params(&in, &p, &err), SM_OK);
    volatile int cancel = 1;
    sm_job_hooks hooks = {.cancel = &cancel};
    assert_int_equal(sm_job_run_exec(&in, &hooks, &run, &err), SM_OK);
    assert_int_equal(run.outcome, SM_JOB_OUTCOME_CANCELLED);
    assert_int_equal(run.exit_code, SM_JOB_EXIT_CANCELLED);
    assert_int_equal(run.result.stop, SM_STOP_CANCELLED);
    assert_memory_equal(run.coords, in.template_mesh->coords,
                        sizeof(double) * 2 * (size_t)in.template_mesh->nverts);
    sm_job_run_free(&run);
    /* a snapshot folder that does not exist: SM_ERR_IO naming the snapshot */
    char bad[192];
    snprintf(bad, sizeof bad, "%s/no-such-folder", f->dir);
    p.save_every = 2;
    assert_int_equal(sm_job_inputs_set_params(&in, &p, &err), SM_OK);
    sm_job_hooks snap = {.snapshot_dir = bad};
    assert_int_equal(sm_job_run_exec(&in, &snap, &run, &err), SM_ERR_IO);
    assert_non_null(strstr(err.msg, "snapshot of iteration 0")); /* the first state is one */
    sm_job_run_free(&run);
    sm_job_inputs_free(&in);
}

/* The thread limit seen from inside the run (the progress hook runs on
 * the calling thread, whose OpenMP limit the runner sets). */
static int note_threads(const sm_progress *p, void *user)
{
    (void)p;
    int *seen = user;
    int t = omp_get_max_threads();
    if (t > *seen)
        *seen = t;
    return 0;
}

static void test_thread_policy(void **state)
{
    fixture *f = *state;
    assert_int_equal(sm_job_threads_for(0, 4, 4), 1);
    assert_int_equal(sm_job_threads_for(SM_JOB_THREADS_IDLE_MIN_ELEMENTS - 1, 4, 4), 1);
    /* between the two sizes: the idle cores, within the limit */
    assert_int_equal(sm_job_threads_for(SM_JOB_THREADS_IDLE_MIN_ELEMENTS, 4, 4), 4);
    assert_int_equal(sm_job_threads_for(SM_JOB_THREADS_IDLE_MIN_ELEMENTS, 4, 2), 2);
    assert_int_equal(sm_job_threads_for(SM_JOB_THREADS_IDLE_MIN_ELEMENTS, 2, 8), 2);
    assert_int_equal(sm_job_threads_for(SM_JOB_THREADS_MIN_ELEMENTS - 1, 4, 1), 1);
    assert_int_equal(sm_job_threads_for(SM_JOB_THREADS_MIN_ELEMENTS - 1, 4, 0), 1);
    assert_int_equal(sm_job_threads_for(SM_JOB_THREADS_MIN_ELEMENTS - 1, 4, -1), 1);
    /* from the larger one on: the limit, busy or not */
    assert_int_equal(sm_job_threads_for(SM_JOB_THREADS_MIN_ELEMENTS, 4, 0), 4);
    assert_int_equal(sm_job_threads_for(SM_JOB_THREADS_MIN_ELEMENTS, 1, 4), 1);
    assert_int_equal(sm_job_threads_for(10 * SM_JOB_THREADS_MIN_ELEMENTS, 0, 4), 1);
    /* the idle cores: at most the cores this process may use */
    int idle = sm_job_idle_cores();
    cpu_set_t set;
    assert_int_equal(sched_getaffinity(0, sizeof set, &set), 0);
    assert_true(idle >= 0 && idle <= CPU_COUNT(&set));
    /* a process that keeps a core busy is seen, whenever its samples fall
     * (a spinning child is runnable all along, running or queued) */
    pid_t busy = fork();
    assert_true(busy >= 0);
    if (busy == 0)
        for (;;)
            __asm__ volatile("" ::: "memory");
    usleep(20000);
    int idle_busy = sm_job_idle_cores();
    kill(busy, SIGKILL);
    waitpid(busy, NULL, 0);
    assert_true(idle_busy >= 0 && idle_busy <= CPU_COUNT(&set) - 1);
    /* a small template runs on one thread, and the limit is back after */
    int saved = omp_get_max_threads();
    omp_set_num_threads(3);
    sm_job_inputs in;
    read_inputs(f, &in);
    sm_params p;
    ball_params(&p);
    sm_error err;
    assert_int_equal(sm_job_inputs_set_params(&in, &p, &err), SM_OK);
    int seen = 0;
    sm_job_hooks hooks = {.progress = note_threads, .user = &seen};
    sm_job_run run;
    assert_int_equal(sm_job_run_exec(&in, &hooks, &run, &err), SM_OK);
    assert_true(in.template_mesh->nelems < SM_JOB_THREADS_MIN_ELEMENTS);
    assert_int_equal(seen, 1);
    assert_int_equal(omp_get_max_threads(), 3);
    sm_job_run_free(&run);
    sm_job_inputs_free(&in);
    omp_set_num_threads(saved);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_atomic_write, setup, teardown),
        cmocka_unit_test(test_vocabulary),
        cmocka_unit_test(test_json_string_lossy),
        cmocka_unit_test_setup_teardown(test_inputs_naming, setup, teardown),
        cmocka_unit_test_setup_teardown(test_landmark_parts, setup, teardown),
        cmocka_unit_test_setup_teardown(test_run_and_results, setup, teardown),
        cmocka_unit_test_setup_teardown(test_outcomes, setup, teardown),
        cmocka_unit_test_setup_teardown(test_thread_policy, setup, teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
