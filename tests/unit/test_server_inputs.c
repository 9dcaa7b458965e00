/* What the daemon checks before accepting a job (sm_job_inputs, proto/job/sm_job_inputs.h), the clamp
 * set rules (shared with the core), format sniffing of uploads, the SSE
 * framing of events and the Prometheus rendering. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <cmocka.h>

#include "shapematch/sm_io.h"
#include "shapematch/sm_clamp.h"
#include "job/sm_job_inputs.h"
#include "base/smd_metrics.h"
#include "api/smd_stream.h"
#include "api/smd_upload.h"
#include "base/smd_util.h"
#include "util_mesh.h"

typedef struct files {
    char dir[64];
    char tpl[128], bg[128], sol[128], bg3[128], sol3[128], small_sol[128];
} files;

/* Signed distance to the circle of radius 0.3 centred at (0.5, 0.5). */
static double circle(const double *x)
{
    return hypot(x[0] - 0.5, x[1] - 0.5) - 0.3;
}

static void write_sol(const char *path, const sm_mesh *m, int dim)
{
    sm_sol *s;
    sm_error err;
    assert_int_equal(sm_sol_alloc(&s, dim, m->nverts, 1, &err), SM_OK);
    for (int32_t v = 0; v < m->nverts; v++)
        s->values[v] = circle(m->coords + (size_t)v * (size_t)m->dim);
    assert_int_equal(sm_sol_write(path, s, &err), SM_OK);
    sm_sol_free(s);
}

static int setup(void **state)
{
    files *f = calloc(1, sizeof *f);
    snprintf(f->dir, sizeof f->dir, "/tmp/sm-test-inputs-XXXXXX");
    if (!mkdtemp(f->dir))
        return -1;
    snprintf(f->tpl, sizeof f->tpl, "%s/template.meshb", f->dir);
    snprintf(f->bg, sizeof f->bg, "%s/bg.mesh.gz", f->dir);
    snprintf(f->sol, sizeof f->sol, "%s/bg.sol", f->dir);
    snprintf(f->bg3, sizeof f->bg3, "%s/bg3.mesh", f->dir);
    snprintf(f->sol3, sizeof f->sol3, "%s/bg3.sol", f->dir);
    snprintf(f->small_sol, sizeof f->small_sol, "%s/small.solb", f->dir);
    sm_error err;
    const double lo[3] = {0.3, 0.3, 0}, hi[3] = {0.7, 0.7, 1};
    const double blo[3] = {0, 0, 0}, bhi[3] = {1, 1, 1};
    sm_mesh *tpl = util_box_mesh(2, 6, lo, hi, 0);
    sm_mesh *bg = util_box_mesh(2, 20, blo, bhi, 0);
    sm_mesh *bg3 = util_box_mesh(3, 3, blo, bhi, 0);
    if (!tpl || !bg || !bg3 || sm_mesh_write(f->tpl, tpl, &err) != SM_OK ||
        sm_mesh_write(f->bg, bg, &err) != SM_OK || sm_mesh_write(f->bg3, bg3, &err) != SM_OK)
        return -1;
    write_sol(f->sol, bg, 2);
    write_sol(f->sol3, bg3, 3);
    write_sol(f->small_sol, tpl, 2); /* a field of the wrong size */
    sm_mesh_free(tpl);
    sm_mesh_free(bg);
    sm_mesh_free(bg3);
    *state = f;
    return 0;
}

static int teardown(void **state)
{
    files *f = *state;
    smd_rmtree(f->dir);
    free(f);
    return 0;
}

static sm_status load(const char *tpl, const char *bg, const char *sol, const char *params,
                      sm_job_inputs *in, sm_error *err)
{
    sm_error_clear(err);
    sm_job_files files = {.template_mesh = tpl, .target_mesh = bg, .target_sol = sol};
    return sm_job_inputs_load(&files, params, strlen(params), in, err);
}

static void expect_error(files *f, const char *tpl, const char *bg, const char *sol,
                         const char *params, const char *prefix, const char *contains)
{
    sm_job_inputs in;
    sm_error err;
    assert_int_not_equal(load(tpl, bg, sol, params, &in, &err), SM_OK);
    if (strncmp(err.msg, prefix, strlen(prefix)) != 0 || !strstr(err.msg, contains))
        fail_msg("message '%s' should start with '%s' and contain '%s'", err.msg, prefix, contains);
    /* the server's paths never leak into what the client reads */
    if (strstr(err.msg, f->dir))
        fail_msg("message '%s' shows a server path", err.msg);
    assert_null(in.template_mesh);
    assert_null(in.field);
}

static void test_inputs_good(void **state)
{
    files *f = *state;
    sm_job_inputs in;
    sm_error err;
    assert_int_equal(load(f->tpl, f->bg, f->sol,
                          "{\"clamp\": {\"kind\": \"ball\", \"center\": [0.5, 0.5], \"radius\": 0.07}}",
                          &in, &err),
                     SM_OK);
    assert_int_equal(in.dim, 2);
    assert_int_equal(in.template_mesh->nverts, 49);
    /* the 3x3 grid points within 0.07 of the centre: spacing 0.4/6 */
    assert_int_equal(in.nclamped, 5);
    assert_int_equal(in.params.clamp, SM_CLAMP_BALL);
    double x[2] = {0.5, 0.5};
    assert_true(fabs(sm_field_eval(in.field, x, NULL) + 0.3) < 1e-12);
    sm_job_inputs_free(&in);
    assert_int_equal(load(f->tpl, f->bg, f->sol, "{\"clamp\": {\"kind\": \"none\"}}", &in, &err), SM_OK);
    assert_int_equal(in.nclamped, 0);
    sm_job_inputs_free(&in);
}

static void test_inputs_bad(void **state)
{
    files *f = *state;
    const char *ball = "{\"clamp\": {\"kind\": \"ball\", \"center\": [0.5, 0.5], \"radius\": 0.07}}";
    char garbage[160];
    snprintf(garbage, sizeof garbage, "%s/garbage.mesh", f->dir);
    FILE *g = fopen(garbage, "w");
    fputs("MeshVersionFormatted 2\nDimension 2\nVertices\n3\n0 0 0\n1 0\n", g);
    fclose(g);
    expect_error(f, garbage, f->bg, f->sol, ball, "template: ", "");
    expect_error(f, f->tpl, garbage, f->sol, ball, "target_mesh: ", "");
    expect_error(f, f->tpl, f->bg, garbage, ball, "target_sol: ", "");
    expect_error(f, f->tpl, f->bg3, f->sol3, ball, "dimension mismatch", "2D but the target mesh is 3D");
    expect_error(f, f->tpl, f->bg, f->small_sol, ball, "target_sol: has 49 values", "441 vertices");
    expect_error(f, f->tpl, f->bg, f->sol, "{\"clamp\": ", "params", "");
    /* {}: every parameter's default, the clamp the default ball (kind auto) */
    expect_error(f, f->tpl, f->bg, f->sol, "{\"clamp\": {\"kind\": \"auto\", \"radius\": 1}}",
                 "params", "clamp");
    expect_error(f, f->tpl, f->bg, f->sol, "{\"clamp\": {\"kind\": \"ball\", \"center\": [0.5, 0.5, 0.5], \"radius\": 0.1}}",
                 "params.clamp.center", "");
    expect_error(f, f->tpl, f->bg, f->sol, "{\"clamp\": {\"kind\": \"ball\", \"center\": [3, 3], \"radius\": 0.1}}",
                 "params.clamp: the clamp set is empty", "ball");
    expect_error(f, f->tpl, f->bg, f->sol, "{\"clamp\": {\"kind\": \"vertices\", \"refs\": [42]}}",
                 "params.clamp.refs: the clamp set is empty", "");
    expect_error(f, f->tpl, f->bg, f->sol, "{\"clamp\": {\"kind\": \"ball\", \"center\": [0.5, 0.5], \"radius\": 5}}",
                 "params.clamp: every template vertex", "nothing could move");
    /* a single clamped vertex leaves rotations free */
    expect_error(f, f->tpl, f->bg, f->sol, "{\"clamp\": {\"kind\": \"ball\", \"center\": [0.5, 0.5], \"radius\": 0.01}}",
                 "params.clamp: the clamp holds only 1 vertex", "rigid rotations");
    expect_error(f, "/nonexistent.mesh", f->bg, f->sol, ball, "template: ", "");
}

static void test_clamp_rank(void **state)
{
    (void)state;
    const double lo[3] = {0, 0, 0}, hi[3] = {1, 1, 1};
    sm_mesh *m = util_box_mesh(3, 2, lo, hi, 0); /* 27 vertices on a 3x3x3 grid */
    uint8_t mark[27];
    memset(mark, 0, sizeof mark);
    assert_int_equal(sm_clamp_rank(m, mark), 0);
    mark[0] = 1;
    assert_int_equal(sm_clamp_rank(m, mark), 0);
    /* the vertices with y = z = 0 lie on a line */
    int on_line = 0;
    for (int v = 0; v < 27; v++)
        if (m->coords[3 * v + 1] == 0 && m->coords[3 * v + 2] == 0) {
            mark[v] = 1;
            on_line++;
        }
    assert_int_equal(on_line, 3);
    assert_int_equal(sm_clamp_rank(m, mark), 1);
    for (int v = 0; v < 27; v++)
        if (m->coords[3 * v + 2] == 0)
            mark[v] = 1; /* the face z = 0 */
    assert_int_equal(sm_clamp_rank(m, mark), 2);
    sm_params p;
    sm_params_default(&p);
    p.clamp = SM_CLAMP_BALL;
    p.clamp_center[0] = p.clamp_center[1] = p.clamp_center[2] = 0.5;
    p.clamp_radius = 0.5; /* the centre and its 6 face neighbours, exactly on the sphere */
    assert_int_equal(sm_clamp_mark(m, &p, mark), 7);
    sm_mesh_free(m);
}

static void test_sniff(void **state)
{
    files *f = *state;
    int binary, gzip;
    assert_int_equal(smd_sniff_medit(f->tpl, &binary, &gzip), 0);
    assert_true(binary);
    assert_false(gzip);
    assert_int_equal(smd_sniff_medit(f->bg, &binary, &gzip), 0);
    assert_false(binary);
    assert_true(gzip);
    assert_int_equal(smd_sniff_medit(f->sol, &binary, &gzip), 0);
    assert_false(binary);
    assert_false(gzip);
    assert_int_equal(smd_sniff_medit(f->small_sol, &binary, &gzip), 0);
    assert_true(binary);
    assert_int_equal(smd_sniff_medit("/nonexistent", &binary, &gzip), -1);
    assert_true(smd_idempotency_key_valid("retry-7f3a"));
    assert_false(smd_idempotency_key_valid(""));
    assert_false(smd_idempotency_key_valid("with space"));
    assert_false(smd_idempotency_key_valid("tab\there"));
    assert_false(smd_idempotency_key_valid(NULL));
    char long_key[300];
    memset(long_key, 'k', sizeof long_key - 1);
    long_key[299] = '\0';
    assert_false(smd_idempotency_key_valid(long_key));
    long_key[255] = '\0';
    assert_true(smd_idempotency_key_valid(long_key));
}

static void test_sse_framing(void **state)
{
    (void)state;
    char *buf = NULL;
    size_t len = 0, cap = 0;
    const char *line = "{\"type\":\"progress\",\"seq\":7}";
    char type[32];
    smd_event_line_type(line, strlen(line), type, sizeof type);
    assert_string_equal(type, "progress");
    assert_int_equal(smd_sse_format(&buf, &len, &cap, 7, type, line, strlen(line)), 0);
    assert_int_equal(smd_sse_format(&buf, &len, &cap, 0, "status", "{}", 2), 0);
    assert_string_equal(buf, "id: 7\nevent: progress\ndata: {\"type\":\"progress\",\"seq\":7}\n\n"
                             "event: status\ndata: {}\n\n");
    assert_int_equal(len, strlen(buf));
    free(buf);
    smd_event_line_type("{\"seq\":1}", 9, type, sizeof type);
    assert_string_equal(type, "message");
    smd_event_line_type("{\"type\":\"x\nevil\"}", 16, type, sizeof type);
    assert_string_equal(type, "message"); /* never copies a newline into the frame */
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_inputs_good, setup, teardown),
        cmocka_unit_test_setup_teardown(test_inputs_bad, setup, teardown),
        cmocka_unit_test(test_clamp_rank),
        cmocka_unit_test_setup_teardown(test_sniff, setup, teardown),
        cmocka_unit_test(test_sse_framing),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
