/* The input stream of the readers (core/io/sm_reader.c): numbers parsed in
 * place and through the general tokenizer give the same values (bit for
 * bit, strtod's) and the same line numbers, across buffer refills and
 * next to comments; the fallbacks give the general path's errors; a small
 * plain file gets a small buffer and no zlib state; a gzip file is
 * inflated whole, and gives zlib's bytes (several members, lying sizes,
 * trailing garbage) or, through zlib's stream, its error (truncated,
 * corrupt, beyond the limit on inflated bytes). */
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

#include "io/sm_number.h"
#include "io/sm_reader.h"

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
    assert_int_equal(sm__reader_open(&r, path, &err), SM_OK);
    assert_null(r.gz);
    for (int i = 0; i < NVALUES; i++) {
        double d;
        int64_t v;
        assert_int_equal(sm__reader_real(&r, &d), SM_OK);
        assert_memory_equal(&d, &reals[i], sizeof d);
        assert_int_equal(r.token_line, lines[i]);
        assert_int_equal(sm__reader_int(&r, INT64_MIN, INT64_MAX, &v), SM_OK);
        assert_int_equal(v, ints[i]);
        assert_int_equal(r.token_line, lines[i]);
    }
    int found = 1;
    assert_int_equal(sm__reader_token(&r, &found), SM_OK);
    assert_int_equal(found, 0);
    sm__reader_close(&r);
    free(reals);
    free(ints);
    free(lines);
}

/* sm__decimal_to_double on the string s against strtod: when it
 * converts, the same double bit for bit and the same length.  Returns
 * whether it converted. */
static int check_decimal(const char *s)
{
    double got, want;
    size_t n = sm__decimal_to_double(s, s + strlen(s), &got);
    if (n == 0)
        return 0;
    char *end;
    want = strtod(s, &end);
    if (memcmp(&got, &want, sizeof got) != 0 || (size_t)(end - s) != n)
        fail_msg("%s: %.17g (%zu bytes) instead of strtod's %.17g (%zu bytes)", s, got, n, want,
                 (size_t)(end - s));
    return 1;
}

/* The in-place conversion of reals (core/io/sm_number.c) against strtod:
 * significands of 1 to 19 digits (and 20, left to strtod) at every
 * power of ten of its table and beyond it, the same in every notation;
 * exact ties between two doubles (rounded to even) and their
 * neighbours; forms it must leave to strtod or stop before. */
static void test_decimal_like_strtod(void **state)
{
    (void)state;
    uint64_t rng = 0x243f6a8885a308d3u;
    long converted = 0, tried = 0;
    for (int q = -80; q <= 80; q++)
        for (int digits = 1; digits <= 20; digits++)
            for (int k = 0; k < 40; k++) {
                char num[64], text[96];
                uint64_t w = next(&rng);
                int len = 0;
                for (int i = 0; i < digits; i++) /* no leading zero */
                    num[len++] = (char)('0' + (i == 0 ? 1 + (w >> 5) % 9 : (next(&rng) >> 7) % 10));
                num[len] = '\0';
                const char *sign = k % 3 == 0 ? "-" : k % 3 == 1 ? "+" : "";
                /* num * 10^q written as digits e q, and with a point */
                snprintf(text, sizeof text, "%s%se%d", sign, num, q);
                converted += check_decimal(text);
                int point = (int)((w >> 20) % (unsigned)(digits + 1));
                snprintf(text, sizeof text, "%s%.*s.%sE%+d", sign, point, num, num + point,
                         q + (digits - point));
                converted += check_decimal(text);
                if (q >= -25 && q <= 0 && -q >= digits) /* 0.000ddd */
                    snprintf(text, sizeof text, "%s0.%0*d%s", sign, -q - digits, 0, num);
                else
                    snprintf(text, sizeof text, "%s%s.0e%d", sign, num, q);
                converted += check_decimal(text);
                tried += 3;
            }
    /* Exact ties: a 54-bit odd integer M (halfway between two doubles)
     * times 2^-j written exactly (j <= 2), and M +- 1. */
    for (int k = 0; k < 20000; k++) {
        uint64_t m = (next(&rng) >> 10) | (UINT64_C(1) << 53) | 1;
        for (int j = 0; j <= 2; j++)
            for (int d = -1; d <= 1; d++) {
                uint64_t v = m + (uint64_t)d;
                for (int i = 0; i < j; i++)
                    v *= 5; /* v * 2^-j = (v * 5^j) * 10^-j */
                char text[64];
                snprintf(text, sizeof text, "%llue-%d", (unsigned long long)v, j);
                converted += check_decimal(text);
                tried++;
            }
    }
    print_message("# %ld of %ld converted in place, the others left to strtod\n", converted,
                  tried);
    assert_true(converted > tried / 2);
    static const char *const whole[] = {
        "0", "-0", "+0.0", "00012.50", ".5", "5.", "-.0e5", "0.000000000000000000000000000123",
        "1e22", "9007199254740993", "1.7976931348623157e308", "2.2250738585072014e-308",
        "123456789012345678e-70", "0e999999999", "1.5e0002",
    };
    for (size_t i = 0; i < sizeof whole / sizeof *whole; i++)
        check_decimal(whole[i]);
    /* Not its forms (or no digit): 0, for strtod or the error. */
    static const char *const refused[] = {"", "-", ".", "e5", ".e5", "inf", "nan",
                                          "12345678901234567890.5", "1e1000000"};
    for (size_t i = 0; i < sizeof refused / sizeof *refused; i++) {
        double d;
        assert_int_equal(sm__decimal_to_double(refused[i], refused[i] + strlen(refused[i]), &d),
                         0);
    }
    /* Where the number stops: before an 'e' without digits, at a second
     * point; the caller sees what follows. */
    double d;
    assert_int_equal(sm__decimal_to_double("1.5e+x", "1.5e+x" + 6, &d), 0);
    assert_int_equal(sm__decimal_to_double("2.5.1", "2.5.1" + 5, &d), 3);
    assert_true(d == 2.5);
    assert_int_equal(sm__decimal_to_double("7#c", "7#c" + 3, &d), 1);
    /* hexadecimal: "0", then an 'x' (strtod's whole token is the caller's) */
    assert_int_equal(sm__decimal_to_double("0x1p3", "0x1p3" + 5, &d), 1);
}

/* sm__decimal_to_int: in and out of its 18 digits, near the end of the
 * bytes (no word of 8 to load), digits cut by the end. */
static void test_decimal_int(void **state)
{
    (void)state;
    static const struct {
        const char *s;
        size_t n;
        int64_t v;
    } cases[] = {
        {"0", 1, 0}, {"-7 ", 2, -7}, {"+12345678", 9, 12345678}, {"123456789 1", 9, 123456789},
        {"99999999x", 8, 99999999}, {"123456789012345678", 18, 123456789012345678},
        {"-123456789012345678 ", 19, -123456789012345678}, {"1234567890123456789", 0, 0},
        {"", 0, 0}, {"-", 0, 0}, {"x1", 0, 0}, {"00000000000000000001", 0, 0},
        {"0000000000000000001 ", 0, 0}, {"000000000000000001", 18, 1},
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
        int64_t v = -1;
        size_t n = sm__decimal_to_int(cases[i].s, cases[i].s + strlen(cases[i].s), &v);
        assert_int_equal(n, cases[i].n);
        if (n)
            assert_true(v == cases[i].v);
    }
    /* every prefix of a long run, so that the end falls everywhere */
    const char *digits = "31415926535897932";
    for (size_t len = 1; len <= strlen(digits); len++) {
        int64_t v;
        char prefix[32];
        snprintf(prefix, sizeof prefix, "%.*s", (int)len, digits);
        assert_int_equal(sm__decimal_to_int(digits, digits + len, &v), len);
        assert_true(v == strtoll(prefix, NULL, 10));
    }
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
    assert_int_equal(sm__reader_open(&r, path, &err), SM_OK);
    assert_int_equal(sm__reader_int(&r, 0, 10, &v), SM_ERR_FORMAT);
    assert_non_null(strstr(r.why, "out of range [0, 10]"));
    assert_int_equal(sm__reader_int(&r, 0, 100, &v), SM_ERR_FORMAT);
    assert_non_null(strstr(r.why, "trailing characters"));
    assert_int_equal(sm__reader_real(&r, &d), SM_ERR_FORMAT);
    assert_non_null(strstr(r.why, "trailing characters"));
    assert_int_equal(sm__reader_int(&r, 0, 100, &v), SM_ERR_FORMAT);
    assert_non_null(strstr(r.why, "NUL byte"));
    assert_int_equal(sm__reader_int(&r, INT64_MIN, INT64_MAX, &v), SM_ERR_FORMAT);
    assert_non_null(strstr(r.why, "out of range"));
    assert_int_equal(sm__reader_int(&r, INT64_MIN, INT64_MAX, &v), SM_OK);
    assert_true(v == INT64_MIN + 1);
    assert_int_equal(sm__reader_int(&r, 0, 100, &v), SM_OK); /* last, no newline */
    assert_int_equal(v, 42);
    assert_int_equal(sm__reader_int(&r, 0, 100, &v), SM_ERR_FORMAT);
    assert_non_null(strstr(r.why, "end of file"));
    sm__reader_close(&r);
}

/* A small plain file: a buffer of its size, no zlib; gzip: inflated
 * whole at the first read (no zlib), and the same numbers. */
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
        assert_int_equal(sm__reader_open(&r, k ? gzpath : path, &err), SM_OK);
        assert_true(r.cap <= 4096);
        assert_int_equal(r.compressed, k);
        assert_true(r.gz == NULL && r.fd >= 0);
        assert_int_equal(r.inflate, k ? SM_INFLATE_WHOLE_PENDING : SM_INFLATE_STREAM);
        int64_t v;
        double d;
        assert_int_equal(sm__reader_int(&r, 0, 10, &v), SM_OK);
        assert_int_equal(r.inflate, k ? SM_INFLATE_WHOLE : SM_INFLATE_STREAM);
        assert_true(r.gz == NULL && (k ? r.fd < 0 : r.fd >= 0));
        assert_int_equal(v, 3);
        assert_int_equal(sm__reader_real(&r, &d), SM_OK);
        assert_true(d == 0.25);
        sm__reader_close(&r);
    }
}

/* ---- gzip files inflated whole, against zlib's stream ---- */

/* A gzip member of n bytes of text (zlib's gzwrite) appended to the
 * growing bytes at *buf. */
static void append_member(const char *text, size_t n, unsigned char **buf, size_t *len)
{
    char path[128];
    snprintf(path, sizeof path, "%s/member.gz", dir);
    gzFile gz = gzopen(path, "wb");
    assert_non_null(gz);
    if (n)
        assert_int_equal(gzwrite(gz, text, (unsigned)n), (int)n);
    assert_int_equal(gzclose(gz), Z_OK);
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    unsigned char tmp[1 << 16];
    size_t k;
    while ((k = fread(tmp, 1, sizeof tmp, f)) > 0) {
        *buf = realloc(*buf, *len + k);
        assert_non_null(*buf);
        memcpy(*buf + *len, tmp, k);
        *len += k;
    }
    fclose(f);
}

/* What zlib's gzread makes of path: the bytes (malloc'd, *n of them) and
 * whether it ended without an error. */
static unsigned char *zlib_read_all(const char *path, size_t *n, int *ok)
{
    gzFile gz = gzopen(path, "rb");
    assert_non_null(gz);
    unsigned char *out = NULL;
    size_t len = 0;
    int k;
    unsigned char tmp[1 << 16];
    while ((k = gzread(gz, tmp, sizeof tmp)) > 0) {
        out = realloc(out, len + (size_t)k);
        assert_non_null(out);
        memcpy(out + len, tmp, (size_t)k);
        len += (size_t)k;
    }
    int errnum;
    gzerror(gz, &errnum);
    *ok = k == 0 && errnum == Z_OK;
    gzclose(gz);
    *n = len;
    return out;
}

/* Everything the reader gives for path (with limits), through
 * sm__reader_window: the bytes, the final status and r->why, and how the
 * file was inflated. */
typedef struct read_result {
    unsigned char *bytes;
    size_t len;
    sm_status status;
    char why[SM_READER_WHY_LEN];
    int inflate;
} read_result;

static void reader_read_all(const char *path, sm_read_limits *limits, read_result *out)
{
    memset(out, 0, sizeof *out);
    sm_reader r;
    sm_error err;
    assert_int_equal(sm__reader_open(&r, path, &err), SM_OK);
    r.limits = limits;
    for (;;) {
        const unsigned char *p;
        size_t avail;
        out->status = sm__reader_window(&r, &p, &avail);
        if (out->status != SM_OK || avail == 0)
            break;
        out->bytes = realloc(out->bytes, out->len + avail);
        assert_non_null(out->bytes);
        memcpy(out->bytes + out->len, p, avail);
        out->len += avail;
        sm__reader_consume(&r, avail);
    }
    snprintf(out->why, sizeof out->why, "%s", r.why);
    out->inflate = r.inflate;
    sm__reader_close(&r);
}

/* Text of n bytes that compresses but not to nothing: numbered lines. */
static char *some_text(size_t n)
{
    char *t = malloc(n + 32);
    assert_non_null(t);
    size_t k = 0;
    for (long i = 0; k < n; i++)
        k += (size_t)snprintf(t + k, 32, "%ld %.6f\n", i, (double)i / 7);
    return t;
}

/* path holds bytes; the reader gives what zlib gives, inflated whole
 * (expect_whole 1) or, where the fast path does not take the file (0),
 * through zlib's stream with zlib's error (and a prefix of its bytes);
 * expect_whole -1: either way. */
static void check_like_zlib(const char *name, const unsigned char *bytes, size_t len,
                            int expect_whole, const char *expect_why)
{
    char path[128];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    write_text(path, bytes, len);
    size_t zlen;
    int zok;
    unsigned char *z = zlib_read_all(path, &zlen, &zok);
    read_result got;
    reader_read_all(path, NULL, &got);
    print_message("# %s: %zu bytes, status %d, %s\n", name, got.len, got.status, got.why);
    if (expect_whole >= 0)
        assert_int_equal(got.inflate, expect_whole ? SM_INFLATE_WHOLE : SM_INFLATE_STREAM);
    assert_int_equal(got.status == SM_OK, zok);
    /* Before an error, how much is handed out depends on the buffers. */
    size_t same = zok ? zlen : got.len < zlen ? got.len : zlen;
    if (zok)
        assert_int_equal(got.len, zlen);
    if (same)
        assert_memory_equal(got.bytes, z, same);
    if (expect_why)
        assert_non_null(strstr(got.why, expect_why));
    free(z);
    free(got.bytes);
}

/* Valid files the fast path takes: one member; several members whose
 * last ISIZE is far too small (the buffer grows) or larger than the
 * first members need; an empty member among them; zeros after the last
 * member (padding, ignored as zlib does).  Other trailing garbage is
 * ignored too, whichever path reads the file (its last bytes are no
 * ISIZE: a size beyond the bound sends the file to zlib's stream). */
static void test_gzip_whole_like_zlib(void **state)
{
    (void)state;
    size_t big = 300000;
    char *text = some_text(big);
    unsigned char *f = NULL;
    size_t n = 0;
    append_member(text, big, &f, &n);
    check_like_zlib("one.gz", f, n, 1, NULL);

    append_member("1 2\n", 4, &f, &n); /* ISIZE now says 4 */
    append_member("", 0, &f, &n);
    append_member("3 4\n", 4, &f, &n);
    check_like_zlib("small-isize.gz", f, n, 1, NULL);

    unsigned char *g = NULL;
    size_t m = 0;
    append_member("5 6\n", 4, &g, &m);
    append_member(text, big, &g, &m); /* ISIZE larger than the first member */
    check_like_zlib("large-isize.gz", g, m, 1, NULL);

    g = realloc(g, m + 512);
    memset(g + m, 0, 512);
    check_like_zlib("trailing-zeros.gz", g, m + 512, 1, NULL);
    memcpy(g + m, "junk!", 5);
    check_like_zlib("trailing-garbage.gz", g, m + 5, -1, NULL);
    g[m] = 0x1f; /* a lone magic byte is garbage too */
    check_like_zlib("trailing-1f.gz", g, m + 1, -1, NULL);
    /* an ISIZE beyond the bound: zlib's stream at once, the same bytes */
    memcpy(g + m, "\0\0\0\x7f", 4);
    check_like_zlib("trailing-isize-beyond.gz", g, m + 4, 0, NULL);
    free(g);
    free(f);
    free(text);
}

/* Files the fast path does not take go through zlib's stream and give
 * zlib's bytes and error: truncated (in the deflate data, in the
 * trailer), a CRC or ISIZE that does not match, a corrupt second member,
 * garbage right after the header. */
static void test_gzip_errors_like_zlib(void **state)
{
    (void)state;
    size_t big = 200000;
    char *text = some_text(big);
    unsigned char *f = NULL;
    size_t n = 0;
    append_member(text, big, &f, &n);
    check_like_zlib("truncated.gz", f, n / 2, 0, "truncated or corrupt gzip stream");
    check_like_zlib("truncated-trailer.gz", f, n - 3, 0, "truncated or corrupt gzip stream");

    unsigned char *bad = malloc(n + 64);
    assert_non_null(bad);
    memcpy(bad, f, n);
    bad[n - 8] ^= 1; /* CRC32 */
    check_like_zlib("bad-crc.gz", bad, n, 0, "incorrect data check");
    memcpy(bad, f, n);
    bad[n - 1] ^= 0x40; /* ISIZE lies: a file of 1 GiB more */
    check_like_zlib("lying-isize.gz", bad, n, 0, "incorrect length check");

    memcpy(bad, f, n);
    static const unsigned char second[] = {0x1f, 0x8b, 8, 0, 0, 0, 0, 0, 0, 3, 0xff, 0xff, 0xff};
    memcpy(bad + n, second, sizeof second);
    check_like_zlib("bad-second-member.gz", bad, n + sizeof second, 0, "gzip");

    memcpy(bad, f, 10);
    memset(bad + 10, 0xff, 20);
    check_like_zlib("garbage-after-header.gz", bad, 30, 0, "corrupt gzip data");
    free(bad);
    free(f);
    free(text);
}

/* The limit on inflated bytes holds on the fast path: a file of exactly
 * the limit is inflated whole, one byte more is refused (SM_ERR_NOMEM,
 * SM_LIMIT_INFLATED) as zlib's stream refuses it. */
static void test_gzip_whole_limit(void **state)
{
    (void)state;
    size_t big = 100000;
    char *text = some_text(big);
    unsigned char *f = NULL;
    size_t n = 0;
    append_member(text, big, &f, &n);
    char path[128];
    snprintf(path, sizeof path, "%s/limit.gz", dir);
    write_text(path, f, n);
    sm_read_limits lim = {.max_inflated = big};
    read_result got;
    reader_read_all(path, &lim, &got);
    assert_int_equal(got.status, SM_OK);
    assert_int_equal(got.inflate, SM_INFLATE_WHOLE);
    assert_int_equal(got.len, big);
    assert_int_equal(lim.hit, SM_LIMIT_NONE);
    free(got.bytes);

    lim.max_inflated = big - 1;
    reader_read_all(path, &lim, &got);
    assert_int_equal(got.status, SM_ERR_NOMEM);
    assert_int_equal(got.inflate, SM_INFLATE_STREAM);
    assert_int_equal(lim.hit, SM_LIMIT_INFLATED);
    assert_non_null(strstr(got.why, "decompresses to more than the limit of 99999 bytes"));
    free(got.bytes);
    free(f);
    free(text);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_numbers_in_place_and_general),
        cmocka_unit_test(test_fallback_errors),
        cmocka_unit_test(test_decimal_like_strtod),
        cmocka_unit_test(test_decimal_int),
        cmocka_unit_test(test_buffers_and_zlib),
        cmocka_unit_test(test_gzip_whole_like_zlib),
        cmocka_unit_test(test_gzip_errors_like_zlib),
        cmocka_unit_test(test_gzip_whole_limit),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
