/* The input stream of the readers (core/sm_reader.c): numbers parsed in
 * place and through the general tokenizer give the same values (bit for
 * bit, strtod's) and the same line numbers, across buffer refills and
 * next to comments; the fallbacks give the general path's errors; a small
 * plain file gets a small buffer and no zlib state, a gzip file gets
 * zlib. */
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
#include <zlib.h>

#include "sm_reader.h"

static char dir[64];

static int setup(void **state)
{
    (void)state;
    snprintf(dir, sizeof dir, "/tmp/sm-test-reader-XXXXXX");
    return mkdtemp(dir) ? 0 : -1;
}

static int teardown(void **state)
{
    (void)state;
    char cmd[128];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    return system(cmd) == 0 ? 0 : -1;
}

static uint64_t next(uint64_t *s)
{
    *s ^= *s << 13;
    *s ^= *s >> 7;
    *s ^= *s << 17;
    return *s;
}

/* A finite double of any exponent and mantissa. */
static double random_double(uint64_t *s)
{
    for (;;) {
        uint64_t bits = next(s);
        double d;
        memcpy(&d, &bits, sizeof d);
        if (isfinite(d))
            return d;
    }
}

enum { NVALUES = 60000 };

/* Writes NVALUES records "real int" with varied formats and separators
 * (more than one 64 KiB buffer), remembering what strtod and the integer
 * give; every 7th record ends in a comment glued to the number. */
static void write_numbers(const char *path, double *reals, int64_t *ints, long *lines)
{
    static const char *const fmt[] = {"%.17g", "%.6e", "%g", "%.3f", "%+.10g"};
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    uint64_t s = 0x9e3779b97f4a7c15u;
    long line = 1;
    for (int i = 0; i < NVALUES; i++) {
        char num[64];
        double d = i % 3 ? random_double(&s) : (double)(int64_t)(next(&s) % 2000001) / 1000 - 1000;
        snprintf(num, sizeof num, fmt[i % 5], d);
        reals[i] = strtod(num, NULL);
        ints[i] = (int64_t)(next(&s) % 4000000001u) - 2000000000;
        if (i % 11 == 0)
            ints[i] = i % 2 ? INT64_MAX : INT64_MIN + 1;
        lines[i] = line;
        fprintf(f, "%s%s%s%lld", num, i % 4 ? " " : "\t ", i % 5 == 0 && ints[i] >= 0 ? "+" : "",
                (long long)ints[i]);
        if (i % 7 == 0)
            fputs("#c 1 2", f);
        fputs(i % 3 ? "\n" : "\r\n", f);
        line++;
    }
    fclose(f);
}

static void test_numbers_in_place_and_general(void **state)
{
    (void)state;
    char path[128];
    snprintf(path, sizeof path, "%s/numbers.txt", dir);
    double *reals = malloc(NVALUES * sizeof *reals);
    int64_t *ints = malloc(NVALUES * sizeof *ints);
    long *lines = malloc(NVALUES * sizeof *lines);
    assert_non_null(reals);
    assert_non_null(ints);
    assert_non_null(lines);
    write_numbers(path, reals, ints, lines);
    sm_reader r;
    sm_error err;
    assert_int_equal(sm_reader_open(&r, path, &err), SM_OK);
    assert_null(r.gz);
    for (int i = 0; i < NVALUES; i++) {
        double d;
        int64_t v;
        assert_int_equal(sm_reader_real(&r, &d), SM_OK);
        assert_memory_equal(&d, &reals[i], sizeof d);
        assert_int_equal(r.token_line, lines[i]);
        assert_int_equal(sm_reader_int(&r, INT64_MIN, INT64_MAX, &v), SM_OK);
        assert_int_equal(v, ints[i]);
        assert_int_equal(r.token_line, lines[i]);
    }
    int found = 1;
    assert_int_equal(sm_reader_token(&r, &found), SM_OK);
    assert_int_equal(found, 0);
    sm_reader_close(&r);
    free(reals);
    free(ints);
    free(lines);
}

static void write_text(const char *path, const void *text, size_t n)
{
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(text, 1, n, f), n);
    fclose(f);
}

/* The fallbacks: out of range, trailing characters, a NUL byte, a
 * number at the very end of the file, overlong digit strings. */
static void test_fallback_errors(void **state)
{
    (void)state;
    char path[128];
    snprintf(path, sizeof path, "%s/errors.txt", dir);
    static const char text[] = "11 12x 1.5e 7\0 123456789012345678901 -9223372036854775807 42";
    write_text(path, text, sizeof text - 1);
    sm_reader r;
    sm_error err;
    int64_t v;
    double d;
    assert_int_equal(sm_reader_open(&r, path, &err), SM_OK);
    assert_int_equal(sm_reader_int(&r, 0, 10, &v), SM_ERR_FORMAT);
    assert_non_null(strstr(r.why, "out of range [0, 10]"));
    assert_int_equal(sm_reader_int(&r, 0, 100, &v), SM_ERR_FORMAT);
    assert_non_null(strstr(r.why, "trailing characters"));
    assert_int_equal(sm_reader_real(&r, &d), SM_ERR_FORMAT);
    assert_non_null(strstr(r.why, "trailing characters"));
    assert_int_equal(sm_reader_int(&r, 0, 100, &v), SM_ERR_FORMAT);
    assert_non_null(strstr(r.why, "NUL byte"));
    assert_int_equal(sm_reader_int(&r, INT64_MIN, INT64_MAX, &v), SM_ERR_FORMAT);
    assert_non_null(strstr(r.why, "out of range"));
    assert_int_equal(sm_reader_int(&r, INT64_MIN, INT64_MAX, &v), SM_OK);
    assert_true(v == INT64_MIN + 1);
    assert_int_equal(sm_reader_int(&r, 0, 100, &v), SM_OK); /* last, no newline */
    assert_int_equal(v, 42);
    assert_int_equal(sm_reader_int(&r, 0, 100, &v), SM_ERR_FORMAT);
    assert_non_null(strstr(r.why, "end of file"));
    sm_reader_close(&r);
}

/* A small plain file: a buffer of its size, no zlib; gzip: zlib, and the
 * same numbers. */
static void test_buffers_and_zlib(void **state)
{
    (void)state;
    char path[128], gzpath[128];
    snprintf(path, sizeof path, "%s/small.txt", dir);
    snprintf(gzpath, sizeof gzpath, "%s/small.txt.gz", dir);
    static const char text[] = "3 0.25\n";
    write_text(path, text, sizeof text - 1);
    gzFile gz = gzopen(gzpath, "wb");
    assert_non_null(gz);
    assert_int_equal(gzwrite(gz, text, sizeof text - 1), (int)(sizeof text - 1));
    assert_int_equal(gzclose(gz), Z_OK);
    for (int k = 0; k < 2; k++) {
        sm_reader r;
        sm_error err;
        assert_int_equal(sm_reader_open(&r, k ? gzpath : path, &err), SM_OK);
        assert_true(r.cap <= 4096);
        assert_int_equal(r.compressed, k);
        assert_true(k ? r.gz != NULL && r.fd < 0 : r.gz == NULL && r.fd >= 0);
        int64_t v;
        double d;
        assert_int_equal(sm_reader_int(&r, 0, 10, &v), SM_OK);
        assert_int_equal(v, 3);
        assert_int_equal(sm_reader_real(&r, &d), SM_OK);
        assert_true(d == 0.25);
        sm_reader_close(&r);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_numbers_in_place_and_general),
        cmocka_unit_test(test_fallback_errors),
        cmocka_unit_test(test_buffers_and_zlib),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
