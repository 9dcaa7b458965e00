/* Paths and folders (core/sm_path.c): the one path join and the one
 * `mkdir -p` of the tree, checked against the file system itself
 * (stat), in a fresh temporary folder. */
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

#include "shapematch/sm_path.h"

static void join_case(const char *dir, const char *name, const char *want)
{
    char *got = sm_path_join(dir, name);
    assert_non_null(got);
    assert_string_equal(got, want);
    free(got);
}

static void test_join(void **state)
{
    (void)state;
    join_case("out", "summary.json", "out/summary.json");
    join_case("out/", "summary.json", "out/summary.json"); /* no second slash */
    join_case("/", "tmp", "/tmp");
    join_case("", "file", "file");
    join_case("a/b", "", "a/b/");
}

static int is_dir(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0 && S_ISDIR(st.st_mode);
}

static void test_mkdir_p(void **state)
{
    (void)state;
    char root[] = "/tmp/sm-test-path-XXXXXX";
    assert_non_null(mkdtemp(root));
    char deep[256], file[256], under_file[256], slashes[256];
    snprintf(deep, sizeof deep, "%s/a/b/c", root);
    snprintf(file, sizeof file, "%s/a/file", root);
    snprintf(under_file, sizeof under_file, "%s/a/file/d", root);
    snprintf(slashes, sizeof slashes, "%s//x///y//", root);
    sm_error err;

    /* missing parents are made; doing it again is fine */
    assert_false(is_dir(deep));
    assert_int_equal(sm_mkdir_p(deep, &err), SM_OK);
    assert_true(is_dir(deep));
    assert_int_equal(sm_mkdir_p(deep, &err), SM_OK);

    /* repeated and trailing slashes */
    assert_int_equal(sm_mkdir_p(slashes, &err), SM_OK);
    char xy[256];
    snprintf(xy, sizeof xy, "%s/x/y", root);
    assert_true(is_dir(xy));

    /* a file in the way: SM_ERR_IO naming it */
    FILE *f = fopen(file, "w");
    assert_non_null(f);
    fclose(f);
    assert_int_equal(sm_mkdir_p(file, &err), SM_ERR_IO);
    assert_non_null(strstr(err.msg, "a file of that name exists"));
    assert_non_null(strstr(err.msg, file));
    assert_int_equal(sm_mkdir_p(under_file, &err), SM_ERR_IO);
    assert_non_null(strstr(err.msg, "/a/file"));

    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", root);
    assert_int_equal(system(cmd), 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_join),
        cmocka_unit_test(test_mkdir_p),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
