/* job.json (smd_job_file.h): what the upload writes the worker reads back
 * as written; paths that would leave the job folder, a missing template
 * and params that are not an object are refused; reals keep their
 * shortest form (0.1, not 0.10000000000000001). */
#include <errno.h>
#include <limits.h>
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

#include "job/sm_job_template.h"
#include "sm_json.h"
#include "worker/smd_job_file.h"
#include "base/smd_util.h"

static smd_job_file *example(void)
{
    smd_job_file *f = calloc(1, sizeof *f);
    snprintf(f->part[SM_PART_TEMPLATE], PATH_MAX, "inputs/template.mesh");
    snprintf(f->part[SM_PART_TARGET_SURFACE], PATH_MAX, "inputs/target.stl");
    f->params = json_pack("{s:f,s:i,s:[f,f]}", "tol_boundary", 0.1, "max_iter", 30, "center", 0.3,
                          -1e-300);
    return f;
}

static void test_round_trip(void **state)
{
    (void)state;
    char dir[] = "/tmp/sm-test-jobfile-XXXXXX";
    assert_non_null(mkdtemp(dir));
    smd_job_file *f = example();
    assert_int_equal(smd_job_file_write(dir, f), 0);

    /* the file: members in part order, the reals shortest */
    char path[PATH_MAX], *text = NULL;
    size_t len = 0;
    snprintf(path, sizeof path, "%s/job.json", dir);
    assert_int_equal(smd_read_file(path, 1 << 20, &text, &len), 0);
    assert_non_null(strstr(text, "\"tol_boundary\": 0.1,"));
    assert_non_null(strstr(text, "[0.3, -1e-300]"));
    assert_true(strstr(text, "\"template\"") < strstr(text, "\"target_surface\""));
    assert_null(strstr(text, "target_mesh"));
    free(text);

    smd_job_file *g = calloc(1, sizeof *g);
    sm_error err;
    assert_int_equal(smd_job_file_read(dir, g, &err), SM_OK);
    for (int i = 0; i < SM_PART_PARAMS; i++)
        assert_string_equal(g->part[i], f->part[i]);
    assert_true(json_equal(g->params, f->params));
    /* the compact form (the database's copy) reads back the same */
    char *compact = smd_job_file_encode(g, 0);
    assert_non_null(compact);
    assert_null(strchr(compact, '\n'));
    smd_job_file h;
    assert_int_equal(smd_job_file_parse(compact, strlen(compact), &h, &err), SM_OK);
    assert_true(json_equal(h.params, f->params));
    assert_string_equal(h.part[SM_PART_TARGET_SURFACE], "inputs/target.stl");
    free(compact);
    smd_job_file_free(&h);
    smd_job_file_free(g);
    smd_job_file_free(f);
    free(g);
    free(f);
    unlink(path);
    rmdir(dir);
}

static void test_refused(void **state)
{
    (void)state;
    static const char *const bad[] = {
        "",
        "[]",
        "{\"template\": \"inputs/t.mesh\"}",                                  /* no params */
        "{\"template\": \"inputs/t.mesh\", \"params\": 3}",                   /* not an object */
        "{\"target_mesh\": \"inputs/m.mesh\", \"params\": {}}",               /* no template */
        "{\"template\": \"/etc/passwd\", \"params\": {}}",                    /* absolute */
        "{\"template\": \"../other/t.mesh\", \"params\": {}}",                /* leaves the folder */
        "{\"template\": \"inputs/t.mesh\", \"target_sol\": 1, \"params\": {}}", /* not a string */
        "{\"template\": \"\", \"params\": {}}",
        "{\"template\": \"inputs/t.mesh\", \"params\": {}",                   /* cut */
    };
    smd_job_file f;
    sm_error err;
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        assert_int_equal(smd_job_file_parse(bad[i], strlen(bad[i]), &f, &err), SM_ERR_FORMAT);
        assert_null(f.params);
        assert_string_equal(f.part[SM_PART_TEMPLATE], "");
        assert_non_null(strstr(err.msg, "not a job description"));
    }
    const char *good = "{\"template\": \"inputs/t.mesh\", \"params\": {}}";
    assert_int_equal(smd_job_file_parse(good, strlen(good), &f, &err), SM_OK);
    smd_job_file_free(&f);
    /* no file: an I/O error naming it */
    assert_int_equal(smd_job_file_read("/nonexistent-sm-dir", &f, &err), SM_ERR_IO);
    assert_non_null(strstr(err.msg, "cannot read job.json"));
    smd_job_file_free(&f);
}

/* The check's kept background (issue 35): "checked" written and read
 * back; its key follows the input files' bytes and the params, and is
 * the same for the same folder; a malformed member is refused. */
static void test_checked(void **state)
{
    (void)state;
    char dir[] = "/tmp/sm-test-jobfile-XXXXXX", sub[64], path[128];
    assert_non_null(mkdtemp(dir));
    snprintf(sub, sizeof sub, "%s/inputs", dir);
    assert_int_equal(mkdir(sub, 0700), 0);
    const char *names[] = {"template.mesh", "target.stl"};
    for (int i = 0; i < 2; i++) {
        snprintf(path, sizeof path, "%s/%s", sub, names[i]);
        FILE *fp = fopen(path, "w");
        assert_non_null(fp);
        fprintf(fp, "bytes of %s\n", names[i]);
        fclose(fp);
    }
    smd_job_file *f = example();
    char key[SMD_JOB_KEY_LEN + 1], again[SMD_JOB_KEY_LEN + 1];
    assert_int_equal(smd_job_file_inputs_key(dir, f, key), 0);
    assert_int_equal(strlen(key), SMD_JOB_KEY_LEN);
    assert_int_equal(smd_job_file_inputs_key(dir, f, again), 0);
    assert_string_equal(key, again);
    snprintf(f->checked_key, sizeof f->checked_key, "%s", key);
    snprintf(f->checked_background, PATH_MAX, "inputs/checked/background.meshb");
    snprintf(f->checked_distance, PATH_MAX, "inputs/checked/distance.solb");
    assert_int_equal(smd_job_file_write(dir, f), 0);
    smd_job_file g;
    sm_error err;
    assert_int_equal(smd_job_file_read(dir, &g, &err), SM_OK);
    assert_string_equal(g.checked_key, key);
    assert_string_equal(g.checked_background, "inputs/checked/background.meshb");
    assert_string_equal(g.checked_distance, "inputs/checked/distance.solb");
    assert_string_equal(g.checked_template, "");
    assert_null(g.checked_template_made);
    /* the worker's key of what it read back is the check's */
    assert_int_equal(smd_job_file_inputs_key(dir, &g, again), 0);
    assert_string_equal(again, key);
    smd_job_file_free(&g);
    /* one byte of an input, or one param, changes it */
    snprintf(path, sizeof path, "%s/target.stl", sub);
    FILE *fp = fopen(path, "a");
    fputc('x', fp);
    fclose(fp);
    assert_int_equal(smd_job_file_inputs_key(dir, f, again), 0);
    assert_string_not_equal(again, key);
    unlink(path);
    assert_int_equal(smd_job_file_inputs_key(dir, f, again), -1); /* a file gone */
    static const char *const bad[] = {
        "{\"template\": \"t\", \"params\": {}, \"checked\": 1}",
        "{\"template\": \"t\", \"params\": {}, \"checked\": {\"key\": \"00\", "
        "\"background\": \"b\", \"distance\": \"d\"}}", /* short key */
        "{\"template\": \"t\", \"params\": {}, \"checked\": {\"key\": \"000000000000000G\", "
        "\"background\": \"b\", \"distance\": \"d\"}}", /* not hexadecimal */
        "{\"template\": \"t\", \"params\": {}, \"checked\": {\"key\": \"0000000000000000\", "
        "\"background\": \"../b\", \"distance\": \"d\"}}", /* leaves the folder */
        "{\"template\": \"t\", \"params\": {}, \"checked\": {\"key\": \"0000000000000000\", "
        "\"background\": \"b\"}}", /* no distance */
        "{\"template\": \"t\", \"params\": {}, \"checked\": {\"key\": \"0000000000000000\"}}",
        "{\"template\": \"t\", \"params\": {}, \"checked\": {\"key\": \"0000000000000000\", "
        "\"template\": \"t\"}}", /* no figures */
        "{\"template\": \"t\", \"params\": {}, \"checked\": {\"key\": \"0000000000000000\", "
        "\"template\": \"t\", \"template_meshed\": 3}}",
        "{\"template\": \"t\", \"params\": {}, \"checked\": {\"key\": \"0000000000000000\", "
        "\"template\": \"/t\", \"template_meshed\": {}}}", /* absolute */
        "{\"template\": \"t\", \"params\": {}, \"checked\": {\"key\": \"0000000000000000\", "
        "\"template\": \"t\", \"template_meshed\": {}, \"other\": 1}}",
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        assert_int_equal(smd_job_file_parse(bad[i], strlen(bad[i]), &g, &err), SM_ERR_FORMAT);
        assert_string_equal(g.checked_key, "");
        assert_non_null(strstr(err.msg, "checked"));
    }
    /* with the meshed template and its figures too, and with them alone */
    sm_job_template_made made = {.source = SM_TEMPLATE_IMAGE, .label = 3};
    made.mesh.nverts = 975;
    made.mesh.size = 0.1;
    snprintf(f->checked_template, PATH_MAX, "inputs/checked/template.meshb");
    f->checked_template_made = sm_job_template_made_to_json(&made);
    assert_non_null(f->checked_template_made);
    for (int alone = 0; alone < 2; alone++) {
        if (alone)
            f->checked_background[0] = f->checked_distance[0] = '\0';
        char *text = smd_job_file_encode(f, 0);
        assert_non_null(text);
        assert_int_equal(smd_job_file_parse(text, strlen(text), &g, &err), SM_OK);
        free(text);
        assert_string_equal(g.checked_key, key);
        assert_string_equal(g.checked_background, alone ? "" : "inputs/checked/background.meshb");
        assert_string_equal(g.checked_template, "inputs/checked/template.meshb");
        assert_true(json_equal(g.checked_template_made, f->checked_template_made));
        smd_job_file_free(&g);
    }
    smd_job_file_free(f);
    free(f);
    for (int i = 0; i < 2; i++) {
        snprintf(path, sizeof path, "%s/%s", sub, names[i]);
        unlink(path);
    }
    snprintf(path, sizeof path, "%s/job.json", dir);
    unlink(path);
    rmdir(sub);
    rmdir(dir);
}

/* A batch's model job: no template, a batch object; encoded and read
 * back whole; a malformed batch (bad alignment, no members, a bad id, a
 * name with '/' or a control character, "..") refused. */
static void test_batch(void **state)
{
    (void)state;
    const char *id = "0123456789abcdef0123456789abcdef";
    smd_job_file f = {0}, g;
    sm_error err;
    f.params = json_object();
    f.batch = json_pack("{s:s,s:[{s:s,s:s}]}", "align", "similarity", "members", "job", id, "name",
                        "r1");
    char *text = smd_job_file_encode(&f, 0);
    assert_non_null(text);
    assert_int_equal(smd_job_file_parse(text, strlen(text), &g, &err), SM_OK);
    assert_non_null(g.batch);
    assert_true(json_equal(g.batch, f.batch));
    assert_string_equal(g.part[SM_PART_TEMPLATE], "");
    smd_job_file_free(&g);
    free(text);
    smd_job_file_free(&f);
    static const char *const bad[] = {
        "{\"params\": {}, \"batch\": {\"align\": \"affine\", \"members\": [{\"job\": \"%s\", \"name\": \"a\"}]}}",
        "{\"params\": {}, \"batch\": {\"align\": \"rigid\", \"members\": []}}",
        "{\"params\": {}, \"batch\": {\"align\": \"rigid\", \"members\": [{\"job\": \"%.31s\", \"name\": \"a\"}]}}",
        "{\"params\": {}, \"batch\": {\"align\": \"rigid\", \"members\": [{\"job\": \"%s\", \"name\": \"a/b\"}]}}",
        "{\"params\": {}, \"batch\": {\"align\": \"rigid\", \"members\": [{\"job\": \"%s\", \"name\": \"a\\u0001\"}]}}",
        "{\"params\": {}, \"batch\": {\"align\": \"rigid\", \"members\": [{\"job\": \"%s\", \"name\": \"..\"}]}}",
        "{\"params\": {}, \"batch\": []}",
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        char doc[512];
        snprintf(doc, sizeof doc, bad[i], id);
        assert_int_equal(smd_job_file_parse(doc, strlen(doc), &g, &err), SM_ERR_FORMAT);
        assert_null(g.batch);
        assert_non_null(strstr(err.msg, "batch"));
        smd_job_file_free(&g);
    }
    assert_true(smd_batch_name_valid("r-1_a.b"));
    assert_false(smd_batch_name_valid("a b"));
    assert_false(smd_batch_name_valid("a,b"));
    assert_false(smd_batch_name_valid(""));
}

/* A meshed template's figures through job.json: every member back to
 * the same bits (reals of every kind: shortest digits, integral, tiny,
 * negative), and a member missing or of the wrong type refused by name. */
static void test_template_made(void **state)
{
    (void)state;
    sm_job_template_made m = {.source = SM_TEMPLATE_SURFACE, .label = -(INT64_C(1) << 40),
                              .surface_facets = 1280};
    m.mesh = (sm_template_mesh_info){.size = 0.15072970518891035, .surface_volume = 4.0,
                                     .mesh_volume = 1e-300, .min_quality = 0.1,
                                     .mean_quality = -0.0, .nverts = 975, .nelems = INT32_MAX,
                                     .passes = 2, .seconds = 2.102763793998747,
                                     .estimated_elements = INT64_MAX};
    m.health.reoriented = 7;
    m.health.open_by_volume = INT64_MIN;
    m.health.lo[0] = -1.2;
    m.health.hi[2] = 1.0 / 3.0;
    json_t *o = sm_job_template_made_to_json(&m);
    assert_non_null(o);
    char *text = sm_json_dumps(o, 0);
    json_decref(o);
    assert_non_null(text);
    json_error_t jerr;
    json_t *back = json_loads(text, 0, &jerr);
    free(text);
    assert_non_null(back);
    sm_job_template_made r;
    memset(&r, 0xff, sizeof r);
    sm_error err;
    assert_int_equal(sm_job_template_made_from_json(back, &r, &err), SM_OK);
    assert_int_equal(r.source, m.source);
    assert_int_equal(r.label, m.label);
    assert_int_equal(r.surface_facets, m.surface_facets);
    /* field by field: the struct has padding */
    assert_memory_equal(&r.mesh.size, &m.mesh.size, 5 * sizeof(double));
    assert_int_equal(r.mesh.nverts, m.mesh.nverts);
    assert_int_equal(r.mesh.nelems, m.mesh.nelems);
    assert_int_equal(r.mesh.passes, m.mesh.passes);
    assert_memory_equal(&r.mesh.seconds, &m.mesh.seconds, sizeof(double));
    assert_true(r.mesh.estimated_elements == m.mesh.estimated_elements);
    assert_true(signbit(r.mesh.mean_quality));
    assert_memory_equal(&r.health, &m.health, sizeof m.health);
    /* refusals name the member */
    json_object_set_new(back, "mesh.nverts", json_integer(INT64_C(1) << 40));
    assert_int_equal(sm_job_template_made_from_json(back, &r, &err), SM_ERR_FORMAT);
    assert_non_null(strstr(err.msg, "mesh.nverts"));
    json_object_set_new(back, "mesh.nverts", json_integer(975));
    json_object_del(back, "health.hi");
    assert_int_equal(sm_job_template_made_from_json(back, &r, &err), SM_ERR_FORMAT);
    assert_non_null(strstr(err.msg, "health.hi"));
    json_object_set_new(back, "source", json_string("given"));
    assert_int_equal(sm_job_template_made_from_json(back, &r, &err), SM_ERR_FORMAT);
    assert_non_null(strstr(err.msg, "source"));
    json_decref(back);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_round_trip),
        cmocka_unit_test(test_refused),
        cmocka_unit_test(test_batch),
        cmocka_unit_test(test_checked),
        cmocka_unit_test(test_template_made),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
