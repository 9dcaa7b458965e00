/* Decimal numbers written without printf (core/io/sm_number.c).
 *
 * sm__double_to_decimal must write what printf("%.17g") writes, byte for
 * byte, and text that strtod (and the readers' sm__decimal_to_double)
 * reads back to the same double, bit for bit; sm__double_to_decimal_exact
 * (every rounding decided exactly) must agree with both.  Checked on
 * millions of doubles of every kind: random bit patterns over the whole
 * range (NaNs and infinities included), subnormals, every binary
 * exponent, powers of ten and their neighbours (each decimal exponent,
 * so each entry of the table of powers of ten), integers (the switch to
 * the exponent form at 1e17), multiples of 0.1 steps, the exact ties of
 * the 17th digit (rounded to even), the coordinates and values of the
 * example meshes and fields, and the special values; each with both
 * signs.  sm__int_to_decimal must write "%lld".  Neither may write more
 * than SM_DECIMAL_MAX bytes (their buffers here are exactly that long:
 * AddressSanitizer catches one more) nor depend on the locale. */
#include <float.h>
#include <locale.h>
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
#include "shapematch/sm_mesh.h"
#include "io/sm_number.h"
#include "shapematch/sm_decimal.h"

/* The random samples under the sanitizers (several times slower per
 * value): an eighth of them, so that make test's sanitized pass stays
 * short; the structured classes (every exponent, the ties, the example
 * meshes) are checked whole in both builds. */
#if defined(__SANITIZE_ADDRESS__)
#define RANDOM_SHARE 8
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define RANDOM_SHARE 8
#endif
#endif
#ifndef RANDOM_SHARE
#define RANDOM_SHARE 1
#endif

static uint64_t next(uint64_t *s)
{
    *s ^= *s << 13;
    *s ^= *s >> 7;
    *s ^= *s << 17;
    return *s;
}

static double from_bits(uint64_t bits)
{
    double x;
    memcpy(&x, &bits, sizeof x);
    return x;
}

static uint64_t to_bits(double x)
{
    uint64_t bits;
    memcpy(&bits, &x, sizeof bits);
    return bits;
}

/* Doubles checked so far, for the counts the tests print. */
static long checked;

/* x and -x: both formatters give printf's text, which reads back to the
 * same bits. */
static void check_one(double x)
{
    char *fast = malloc(SM_DECIMAL_MAX), *exact = malloc(SM_DECIMAL_MAX);
    assert_non_null(fast);
    assert_non_null(exact);
    char want[64], got[SM_DECIMAL_MAX + 1], got_exact[SM_DECIMAL_MAX + 1];
    size_t n = sm__double_to_decimal(x, fast);
    size_t ne = sm__double_to_decimal_exact(x, exact);
    int nw = snprintf(want, sizeof want, "%.17g", x);
    assert_true(n <= SM_DECIMAL_MAX && ne <= SM_DECIMAL_MAX);
    memcpy(got, fast, n);
    got[n] = '\0';
    memcpy(got_exact, exact, ne);
    got_exact[ne] = '\0';
    free(fast);
    free(exact);
    if ((size_t)nw != n || strcmp(got, want) != 0 || strcmp(got_exact, want) != 0)
        fail_msg("%016llx: \"%s\" (exact \"%s\") instead of printf's \"%s\"",
                 (unsigned long long)to_bits(x), got, got_exact, want);
    if (isfinite(x)) {
        char *end;
        double back = strtod(got, &end);
        if (to_bits(back) != to_bits(x) || *end != '\0')
            fail_msg("%016llx: \"%s\" reads back as %016llx", (unsigned long long)to_bits(x), got,
                     (unsigned long long)to_bits(back));
        double fast_back;
        if (sm__decimal_to_double(got, got + n, &fast_back) == n &&
            to_bits(fast_back) != to_bits(x))
            fail_msg("%016llx: \"%s\" reads back in place as %016llx",
                     (unsigned long long)to_bits(x), got, (unsigned long long)to_bits(fast_back));
    }
    checked++;
}

static void check_double(double x)
{
    check_one(x);
    check_one(-x);
}

/* x and its neighbours up to k units in the last place either side. */
static void check_around(double x, int k)
{
    double up = x, down = x;
    check_double(x);
    for (int i = 0; i < k; i++) {
        up = nextafter(up, INFINITY);
        down = nextafter(down, -INFINITY);
        check_double(up);
        check_double(down);
    }
}

static void report(const char *what, long before)
{
    print_message("# %ld doubles (both signs): %s\n", checked - before, what);
}

static void test_random_bits(void **state)
{
    (void)state;
    long before = checked;
    uint64_t rng = 0x9e3779b97f4a7c15u;
    for (int i = 0; i < 1000000 / RANDOM_SHARE; i++)
        check_double(from_bits(next(&rng)));
    report("random bit patterns, every exponent, NaNs and infinities", before);
    before = checked;
    /* the exponents of coordinates and distances in any unit, densely */
    for (int i = 0; i < 500000 / RANDOM_SHARE; i++) {
        uint64_t r = next(&rng);
        uint64_t biased = 1023 - 60 + (r >> 52) % 120;
        check_double(from_bits(biased << 52 | (r & ((UINT64_C(1) << 52) - 1))));
    }
    report("random bit patterns from 2^-60 to 2^60", before);
}

static void test_subnormals_and_exponents(void **state)
{
    (void)state;
    long before = checked;
    uint64_t rng = 0x243f6a8885a308d3u;
    for (uint64_t m = 1; m <= 3000; m++) {
        check_double(from_bits(m));
        check_double(from_bits((UINT64_C(1) << 52) - m));
    }
    for (int i = 0; i < 100000 / RANDOM_SHARE; i++)
        check_double(from_bits(next(&rng) & ((UINT64_C(1) << 52) - 1)));
    report("subnormals: the smallest, the largest, random ones", before);
    before = checked;
    /* every binary exponent: its power of two, the largest double below
     * it, and random significands (each floor(log2 x), so each first
     * guess of the decimal exponent) */
    for (uint64_t biased = 1; biased < 2047; biased++) {
        check_around(from_bits(biased << 52), 3);
        check_double(from_bits(biased << 52 | ((UINT64_C(1) << 52) - 1)));
        for (int i = 0; i < 50; i++)
            check_double(from_bits(biased << 52 | (next(&rng) & ((UINT64_C(1) << 52) - 1))));
    }
    report("every binary exponent: 2^e and its neighbours, random significands", before);
}

static void test_powers_of_ten_and_integers(void **state)
{
    (void)state;
    long before = checked;
    /* every decimal exponent, so every entry of the table of powers of
     * ten, and each side of a carry into the next power (9.99...e p) */
    for (int p = -324; p <= 308; p++) {
        char text[32];
        snprintf(text, sizeof text, "1e%d", p);
        check_around(strtod(text, NULL), 20);
        for (int k = 1; k <= 9; k++) {
            snprintf(text, sizeof text, "%de%d", k, p);
            check_around(strtod(text, NULL), 2);
        }
        snprintf(text, sizeof text, "9.9999999999999999e%d", p);
        check_around(strtod(text, NULL), 5);
    }
    report("powers of ten 1e-324 to 1e308, k 10^p, 9.99..e p and their neighbours", before);
    before = checked;
    uint64_t rng = 0x13198a2e03707344u;
    for (int i = 0; i <= 200000; i++)
        check_double(i);
    for (int bits = 1; bits <= 64; bits++)
        for (int i = 0; i < 2000; i++)
            check_double((double)(next(&rng) >> (64 - bits)));
    /* around 10^16 and 10^17: "%f" style up to 17 digits, then "%e" */
    for (int k = -3000; k <= 3000; k++) {
        check_double(1e16 + k);
        check_double(1e17 + 16.0 * k);
    }
    report("integers: 0 to 200000, random of every bit length, around 1e16 and 1e17", before);
}

static void test_decimal_steps(void **state)
{
    (void)state;
    long before = checked;
    uint64_t rng = 0xa4093822299f31d0u;
    /* k 10^-j as strtod reads it (what a file's "0.1" becomes) */
    for (int j = 1; j <= 25; j++)
        for (int i = 0; i < 4000; i++) {
            char text[48];
            long k = i < 1000 ? i : (long)(next(&rng) % 100000000);
            snprintf(text, sizeof text, "%lde-%d", k, j);
            check_around(strtod(text, NULL), 1);
        }
    /* sums of steps, as a loop accumulates them: 0.30000000000000004 */
    double sums[4] = {0, 0, 0, 0};
    static const double steps[4] = {0.1, 0.01, 0.001, 1e-7};
    for (int i = 0; i < 100000 / RANDOM_SHARE; i++)
        for (int s = 0; s < 4; s++)
            check_double(sums[s] += steps[s]);
    report("k 10^-j for j = 1 to 25 and their neighbours, sums of 0.1 steps", before);
}

/* x = n / 2^j (n odd) with 18 significant digits exactly: its last digit
 * is 5, so the 17-digit rounding is an exact tie, rounded to even; and
 * its neighbours (n +- 1: 17 digits or fewer). */
static void test_ties(void **state)
{
    (void)state;
    long before = checked;
    uint64_t rng = 0xbe5466cf34e90c6cu;
    for (int j = 2; j <= 25; j++) {
        /* x in [10^(17-j), 10^(18-j)): n in [10^17 / 5^j, 10^18 / 5^j), and
         * below 2^53 to be exact */
        double pow5 = pow(5.0, j);
        uint64_t lo = (uint64_t)ceil(1e17 / pow5), hi = (uint64_t)(1e18 / pow5);
        if (hi > UINT64_C(1) << 53)
            hi = UINT64_C(1) << 53;
        if (lo < 1)
            lo = 1;
        for (int i = 0; i < 3000 && lo < hi; i++) {
            uint64_t n = (lo + next(&rng) % (hi - lo)) | 1;
            if (n >= hi)
                continue;
            for (int d = -1; d <= 1; d++)
                check_around(ldexp((double)(n + (uint64_t)d), -j), 1);
        }
    }
    report("exact ties of the 17th digit (n / 2^j, 18 digits ending in 5) and neighbours", before);
}

/* The values of the examples' files (what the writers print, moved a
 * little as a run moves them, and the differences, as displacements). */
static void check_mesh_file(const char *root, const char *rel)
{
    char path[4096];
    snprintf(path, sizeof path, "%s/%s", root, rel);
    sm_mesh *m = NULL;
    sm_error err;
    if (sm_mesh_read(path, &m, &err) != SM_OK)
        fail_msg("%s", err.msg);
    size_t n = (size_t)m->nverts * (size_t)m->dim;
    for (size_t i = 0; i < n; i++) {
        double x = m->coords[i], moved = x + 1e-3 * sin(37.0 * x + (double)i);
        check_double(x);
        check_double(moved);
        check_double(moved - x);
    }
    sm_mesh_free(m);
}

static void test_example_values(void **state)
{
    (void)state;
    long before = checked;
    const char *root = getenv("SM_ROOT");
    if (!root || !*root)
        root = ".";
    check_mesh_file(root, "examples/3d/template.mesh");
    check_mesh_file(root, "examples/3d/background.mesh.gz");
    check_mesh_file(root, "examples/2d/template.mesh");
    check_mesh_file(root, "examples/2d/background.mesh.gz");
    static const char *const sols[] = {"examples/3d/background.sol.gz",
                                       "examples/2d/background.sol.gz"};
    for (size_t f = 0; f < sizeof sols / sizeof *sols; f++) {
        char path[4096];
        snprintf(path, sizeof path, "%s/%s", root, sols[f]);
        sm_sol *s = NULL;
        sm_error err;
        if (sm_sol_read(path, &s, &err) != SM_OK)
            fail_msg("%s", err.msg);
        for (size_t i = 0; i < (size_t)s->nverts * (size_t)s->ncomp; i++)
            check_double(s->values[i]);
        sm_sol_free(s);
    }
    report("the examples' coordinates (moved, and the moves) and distances", before);
    before = checked;
    const double specials[] = {0.0,     DBL_MAX,  DBL_MIN,  DBL_TRUE_MIN, DBL_EPSILON,
                               INFINITY, NAN,     1e16,     1e17,         1e-4,
                               1e-5,    0.1,      0.5,      1.0 / 3.0,    123456789012345678.0,
                               1e22,    1e23,     9007199254740993.0};
    for (size_t i = 0; i < sizeof specials / sizeof *specials; i++)
        check_double(specials[i]);
    report("special values: zero, the largest and smallest, infinity, NaN", before);
    /* a few texts spelled out, as a reader of a file would see them */
    static const struct {
        double x;
        const char *text;
    } spelled[] = {
        {0.0, "0"},
        {-0.0, "-0"},
        {0.1, "0.10000000000000001"},
        {0.5, "0.5"},
        {-12.25, "-12.25"},
        {1e-4, "0.0001"},
        {1e-5, "1.0000000000000001e-05"},
        {1e16, "10000000000000000"},
        {1e17, "1e+17"},
        {1000000000000000.25, "1000000000000000.2"}, /* a tie, to even */
        {1000000000000000.75, "1000000000000000.8"}, /* a tie, to even */
        {DBL_MAX, "1.7976931348623157e+308"},
        {-DBL_MIN, "-2.2250738585072014e-308"},
        {DBL_TRUE_MIN, "4.9406564584124654e-324"},
        {-INFINITY, "-inf"},
    };
    for (size_t i = 0; i < sizeof spelled / sizeof *spelled; i++) {
        char out[SM_DECIMAL_MAX + 1];
        out[sm__double_to_decimal(spelled[i].x, out)] = '\0';
        assert_string_equal(out, spelled[i].text);
    }
}

static void check_int(int64_t v)
{
    char *out = malloc(SM_DECIMAL_MAX);
    assert_non_null(out);
    char got[SM_DECIMAL_MAX + 1], want[32];
    size_t n = sm__int_to_decimal(v, out);
    assert_true(n <= 20);
    memcpy(got, out, n);
    got[n] = '\0';
    free(out);
    snprintf(want, sizeof want, "%lld", (long long)v);
    if (strcmp(got, want) != 0)
        fail_msg("%s instead of printf's %s", got, want);
}

static void test_integers(void **state)
{
    (void)state;
    uint64_t rng = 0x082efa98ec4e6c89u;
    check_int(INT64_MIN);
    check_int(INT64_MAX);
    for (int64_t v = -100000; v <= 100000; v++)
        check_int(v);
    for (int64_t p = 1;; p *= 10) { /* 10^0 to 10^18 */
        for (int64_t d = -2; d <= 2; d++) {
            check_int(p + d);
            check_int(-(p + d));
        }
        if (p > INT64_MAX / 10)
            break;
    }
    for (int bits = 1; bits <= 63; bits++)
        for (int i = 0; i < 1000; i++) {
            int64_t v = (int64_t)(next(&rng) >> (64 - bits));
            check_int(v);
            check_int(-v);
        }
}

/* In a locale whose decimal point is ',' (when the system has one),
 * printf writes "0,5"; these still write '.', and so do the writers. */
static void test_no_locale(void **state)
{
    (void)state;
    static const char *const names[] = {"de_DE.UTF-8", "de_DE.utf8", "fr_FR.UTF-8", "fr_FR.utf8"};
    locale_t comma = (locale_t)0;
    for (size_t i = 0; i < sizeof names / sizeof *names && comma == (locale_t)0; i++)
        comma = newlocale(LC_NUMERIC_MASK, names[i], (locale_t)0);
    if (comma == (locale_t)0) {
        print_message("# skipped: no locale with a decimal comma on this system\n");
        return;
    }
    locale_t saved = uselocale(comma);
    char text[64], out[SM_DECIMAL_MAX + 1];
    snprintf(text, sizeof text, "%.17g", 0.5);
    assert_string_equal(text, "0,5"); /* the locale is in effect */
    out[sm__double_to_decimal(0.5, out)] = '\0';
    assert_string_equal(out, "0.5");
    out[sm__double_to_decimal(-1e-5, out)] = '\0';
    assert_string_equal(out, "-1.0000000000000001e-05");
    out[sm__int_to_decimal(-1234567, out)] = '\0';
    assert_string_equal(out, "-1234567");
    /* a solution written in that locale reads '.' */
    char path[] = "/tmp/sm-test-number-XXXXXX.sol";
    int fd = mkstemps(path, 4);
    assert_true(fd >= 0);
    close(fd);
    sm_sol *s;
    sm_error err;
    assert_int_equal(sm_sol_alloc(&s, 2, 1, 1, &err), SM_OK);
    s->values[0] = 0.25;
    assert_int_equal(sm_sol_write(path, s, &err), SM_OK);
    sm_sol_free(s);
    FILE *f = fopen(path, "r");
    assert_non_null(f);
    size_t n = fread(text, 1, sizeof text - 1, f);
    text[n] = '\0';
    fclose(f);
    remove(path);
    assert_non_null(strstr(text, "\n0.25\n"));
    uselocale(saved);
    freelocale(comma);
}


/* The public pair (shapematch/sm_decimal.h, proto's point lists):
 * sm_decimal_parse accepts exactly the fields made of digits, signs, '.'
 * and exponents that strtod reads whole to a finite double, and gives
 * strtod's bits; sm_decimal_format writes "%.17g".  The reference is the
 * C library itself on every text: random doubles at every precision from
 * 1 to 25 digits in both styles (more than 19 digits: strtod's share of
 * the path), and the edges (forms strtod reads that the fast path leaves
 * to it, overflow, underflow to zero and subnormals, words, too long). */
static int reference_parse(const char *s, size_t n, double *out)
{
    if (n == 0 || n > 64 || strspn(s, "0123456789+-.eE") != n || strcspn(s, "0123456789") == n)
        return 0;
    char buf[65], *end;
    memcpy(buf, s, n);
    buf[n] = '\0';
    double v = strtod(buf, &end);
    if (end != buf + n || !isfinite(v))
        return 0;
    *out = v;
    return 1;
}

static void check_parse_text(const char *s)
{
    size_t n = strlen(s);
    double got = 0, want = 0;
    int ok = sm_decimal_parse(s, n, &got), ok_want = reference_parse(s, n, &want);
    if (ok != ok_want || (ok && to_bits(got) != to_bits(want)))
        fail_msg("sm_decimal_parse(\"%s\"): %s %016llx, strtod: %s %016llx", s,
                 ok ? "accepted" : "refused", (unsigned long long)to_bits(got),
                 ok_want ? "accepted" : "refused", (unsigned long long)to_bits(want));
    checked++;
}

static void test_public_pair(void **state)
{
    (void)state;
    long before = checked;
    static const char *const edges[] = {
        "0", "-0", "+0", "1.", ".5", "-.5", "+.5e1", "1e", "1e+", "e5", ".", "-", "+", "--1",
        "1.2.3", "1e5e5", "0x1p3", "inf", "-inf", "nan", "infinity", "1,5", " 1", "1 ", "",
        "1e308", "1.7976931348623157e308", "1.7976931348623159e308", "1e309", "-1e400",
        "4.9406564584124654e-324", "2.4703282292062327e-324", "2.4703282292062328e-324",
        "1e-400", "2.2250738585072011e-308", "2.2250738585072014e-308",
        "9007199254740993", "9007199254740992.5", "123456789012345678901234567890",
        "0.1000000000000000055511151231257827021181583404541015625",
        "00000000000000000000000000000000000000000000000000000000000001.5",
        "000000000000000000000000000000000000000000000000000000000000001.5",
        "1e0000000000000000000000000000000000000000000000000000000000010"};
    for (size_t i = 0; i < sizeof edges / sizeof *edges; i++)
        check_parse_text(edges[i]);
    uint64_t seed = 0x5eed5eed1234ull;
    long samples = 200000 / RANDOM_SHARE;
    char text[64], out[SM_DECIMAL_LEN + 1], want[64];
    for (long k = 0; k < samples; k++) {
        double x = from_bits(next(&seed));
        if (!isfinite(x))
            continue;
        int digits = 1 + (int)(k % 25);
        snprintf(text, sizeof text, k & 1 ? "%.*e" : "%.*g", digits, x);
        check_parse_text(text);
        size_t n = sm_decimal_format(x, out);
        assert_true(n <= SM_DECIMAL_LEN);
        out[n] = '\0';
        snprintf(want, sizeof want, "%.17g", x);
        assert_string_equal(out, want);
        double back;
        assert_true(sm_decimal_parse(out, n, &back));
        assert_true(to_bits(back) == to_bits(x));
    }
    report("sm_decimal_parse and sm_decimal_format against strtod and printf", before);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_random_bits),
        cmocka_unit_test(test_subnormals_and_exponents),
        cmocka_unit_test(test_powers_of_ten_and_integers),
        cmocka_unit_test(test_decimal_steps),
        cmocka_unit_test(test_ties),
        cmocka_unit_test(test_example_values),
        cmocka_unit_test(test_integers),
        cmocka_unit_test(test_no_locale),
        cmocka_unit_test(test_public_pair),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
