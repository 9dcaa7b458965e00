#include "io/sm_number.h"

#include <math.h>
#include <stdlib.h>

#include "shapematch/sm_decimal.h"

#include <float.h>
#include <stdint.h>
#include <string.h>

#include "io/sm_number_pow10.h"

/* Significands of up to 19 digits fit a uint64_t. */
#define MAX_DIGITS 19
/* Exponents of more digits than this are left to strtod. */
#define MAX_EXPONENT 100000

/* The powers of ten Clinger's fast path multiplies or divides by: exact
 * as doubles up to 1e22. */
static const double exact_pow10[] = {
    1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,  1e8,  1e9,  1e10, 1e11,
    1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
};

/* The parser's part of the table of powers of ten (sm_number_pow10.h):
 * significands of 19 digits from about 1e-45 to 1e82 (coordinates and
 * distances in any unit), what its tests cover; beyond it strtod
 * converts. */
#define PARSE_POW10_MIN (-64)
#define PARSE_POW10_MAX 63

/* The 128-bit product a * b as (*hi, return value). */
static inline uint64_t mul_64x64(uint64_t a, uint64_t b, uint64_t *hi)
{
#ifdef __SIZEOF_INT128__
    unsigned __int128 p = (unsigned __int128)a * b;
    *hi = (uint64_t)(p >> 64);
    return (uint64_t)p;
#else
    uint64_t a0 = (uint32_t)a, a1 = a >> 32, b0 = (uint32_t)b, b1 = b >> 32;
    uint64_t p00 = a0 * b0, p01 = a0 * b1, p10 = a1 * b0, p11 = a1 * b1;
    uint64_t mid = (p00 >> 32) + (uint32_t)p01 + (uint32_t)p10;
    *hi = p11 + (p01 >> 32) + (p10 >> 32) + (mid >> 32);
    return (mid << 32) | (uint32_t)p00;
#endif
}

static inline int leading_zeros(uint64_t x)
{
    return __builtin_clzll(x); /* x != 0 */
}

/* w * 10^q (w > 0) rounded to the nearest double, ties to even, by the
 * Eisel-Lemire algorithm (Lemire, "Number parsing at a gigabyte per
 * second", 2021; Nigel Tao's write-up "The Eisel-Lemire ParseNumberF64
 * algorithm", 2020).  With m the significand shifted to a top bit of 63
 * and T = T_hi * 2^64 + T_lo the truncated 128-bit mantissa of 10^q, the
 * 128-bit product m * T_hi is below the exact m * 10^q (scaled alike) by
 * less than m + 1 units of its lowest bit.  Its top 64 bits give the 54
 * bits to round from, unless that error could carry into them; then
 * adding m * T_lo narrows the error to under two units, and if a carry
 * is still possible the rounding is left to strtod, as is a product that
 * could be an exact tie, a subnormal or an overflow.  Returns 1 with the
 * double's bits in *bits, else 0. */
static int eisel_lemire(uint64_t w, int q, uint64_t *bits)
{
    if (q < PARSE_POW10_MIN || q > PARSE_POW10_MAX)
        return 0;
    const struct sm_pow10_128 *t = &sm_pow10_128[q - SM_POW10_MIN];
    int shift = leading_zeros(w);
    uint64_t m = w << shift;
    uint64_t hi, lo = mul_64x64(m, t->hi, &hi);
    if ((hi & 0x1ff) == 0x1ff && lo + m < m) { /* the error could carry */
        uint64_t lo_hi, lo_lo = mul_64x64(m, t->lo, &lo_hi);
        uint64_t merged_lo = lo + lo_hi, merged_hi = hi + (merged_lo < lo);
        if ((merged_hi & 0x1ff) == 0x1ff && merged_lo + 1 == 0 && lo_lo + m < m)
            return 0;
        hi = merged_hi;
        lo = merged_lo;
    }
    /* 54 bits: the double's 53 and the one below, for rounding; the
     * product's top bit is 63 or 62. */
    int top = (int)(hi >> 63);
    uint64_t mantissa = hi >> (top + 9);
    if (lo == 0 && (hi & 0x1ff) == 0 && (mantissa & 3) == 1)
        return 0; /* maybe an exact tie, to be rounded to even: unknown */
    int64_t biased = (int64_t)t->exp2 + 63 + top - shift + 1023;
    mantissa += mantissa & 1;
    mantissa >>= 1;
    if (mantissa >> 53) { /* rounded up to the next power of two */
        mantissa >>= 1;
        biased++;
    }
    if (biased <= 0 || biased >= 0x7ff)
        return 0; /* subnormal or overflow */
    *bits = (uint64_t)biased << 52 | (mantissa & ((UINT64_C(1) << 52) - 1));
    return 1;
}

/* w * 10^q as a double, when either path converts it with certainty. */
static int to_double(uint64_t w, int q, int negative, double *out)
{
    double d;
#if FLT_EVAL_METHOD == 0
    /* Clinger: w and 10^|q| exact doubles, one correctly rounded
     * operation (in double precision: FLT_EVAL_METHOD 0). */
    if (w <= (UINT64_C(1) << 53) && q >= -22 && q <= 22) {
        d = (double)w;
        d = q < 0 ? d / exact_pow10[-q] : d * exact_pow10[q];
        *out = negative ? -d : d;
        return 1;
    }
#endif
    uint64_t bits;
    if (!eisel_lemire(w, q, &bits))
        return 0;
    memcpy(&d, &bits, sizeof d);
    *out = negative ? -d : d;
    return 1;
}

/* 10^n: for the digits of a run appended to a significand (n <= 8), and
 * the length of a number written (n <= 19). */
static const uint64_t pow10_u64[] = {
    UINT64_C(1),
    UINT64_C(10),
    UINT64_C(100),
    UINT64_C(1000),
    UINT64_C(10000),
    UINT64_C(100000),
    UINT64_C(1000000),
    UINT64_C(10000000),
    UINT64_C(100000000),
    UINT64_C(1000000000),
    UINT64_C(10000000000),
    UINT64_C(100000000000),
    UINT64_C(1000000000000),
    UINT64_C(10000000000000),
    UINT64_C(100000000000000),
    UINT64_C(1000000000000000),
    UINT64_C(10000000000000000),
    UINT64_C(100000000000000000),
    UINT64_C(1000000000000000000),
    UINT64_C(10000000000000000000),
};

/* Appends the run of digits at s (before end) to the significand *w of
 * *digits digits, eight at a time.  Returns the end of the run, or NULL
 * when the significand would have more than MAX_DIGITS digits. */
static const char *digit_run(const char *s, const char *end, uint64_t *w, int *digits)
{
    for (;;) {
        unsigned n = 0;
        uint64_t v = 0;
        if (end - s >= 8) {
            uint64_t x = sm__load_le64(s);
            n = sm__leading_digits8(x);
            if (n)
                v = sm__digits8_value(x, n);
        } else {
            while (s + n < end && (unsigned)(s[n] - '0') < 10u)
                v = v * 10 + (uint64_t)(s[n++] - '0');
        }
        if (n == 0)
            return s;
        if (*digits + (int)n > MAX_DIGITS)
            return NULL;
        *w = *w * pow10_u64[n] + v;
        *digits += (int)n;
        s += n;
        if (n < 8)
            return s;
    }
}

/* Zeros at s (before end): leading zeros, which add no significant
 * digit.  Returns their end. */
static const char *skip_zeros(const char *s, const char *end)
{
    while (s < end && *s == '0')
        s++;
    return s;
}

size_t sm__decimal_to_double(const char *p, const char *end, double *out)
{
    const char *s = p;
    int negative = 0;
    if (s < end && (*s == '+' || *s == '-'))
        negative = *s++ == '-';
    /* The significand w of at most MAX_DIGITS significant digits and the
     * power of ten q it is scaled by: the value is w * 10^q. */
    uint64_t w = 0;
    int digits = 0, q = 0;
    const char *first = s;
    s = digit_run(skip_zeros(s, end), end, &w, &digits);
    if (!s)
        return 0;
    int any = s > first;
    if (s < end && *s == '.') {
        const char *frac = ++s;
        if (!digits)
            s = skip_zeros(s, end);
        s = digit_run(s, end, &w, &digits);
        if (!s)
            return 0;
        any |= s > frac;
        q = -(int)(s - frac);
    }
    if (!any)
        return 0;
    if (s < end && (*s == 'e' || *s == 'E')) {
        const char *e = s + 1;
        int eneg = 0;
        if (e < end && (*e == '+' || *e == '-'))
            eneg = *e++ == '-';
        if (e == end || (unsigned)(*e - '0') >= 10u)
            return 0; /* strtod would stop before the 'e' */
        int exponent = 0;
        while (e < end && (unsigned)(*e - '0') < 10u) {
            if (exponent >= MAX_EXPONENT)
                return 0;
            exponent = exponent * 10 + (*e++ - '0');
        }
        q += eneg ? -exponent : exponent;
        s = e;
    }
    if (w == 0) {
        *out = negative ? -0.0 : 0.0;
        return (size_t)(s - p);
    }
    return to_double(w, q, negative, out) ? (size_t)(s - p) : 0;
}

/* ------------------------------------------------------------------ */
/* writing                                                             */
/* ------------------------------------------------------------------ */

/* "00" to "99": the digits of a number are written two at a time. */
static const char digit_pairs[201] =
    "00010203040506070809"
    "10111213141516171819"
    "20212223242526272829"
    "30313233343536373839"
    "40414243444546474849"
    "50515253545556575859"
    "60616263646566676869"
    "70717273747576777879"
    "80818283848586878889"
    "90919293949596979899";

/* The 2, 4 or 8 digits of v (with leading zeros) at out; the halves of
 * a number are independent, so the divisions overlap. */
static inline void put2(char *out, uint32_t v)
{
    memcpy(out, digit_pairs + 2 * v, 2);
}

static inline void put4(char *out, uint32_t v)
{
    put2(out, v / 100);
    put2(out + 2, v % 100);
}

static inline void put8(char *out, uint32_t v)
{
    put4(out, v / 10000);
    put4(out + 4, v % 10000);
}

/* The n digits of v < 10^n (n <= 20) at out, with leading zeros: eight
 * at a time from the end, then the leading ones two at a time. */
static void put_digits(char *out, uint64_t v, int n)
{
    for (; n > 8; n -= 8) {
        put8(out + n - 8, (uint32_t)(v % 100000000));
        v /= 100000000;
    }
    uint32_t rest = (uint32_t)v;
    for (; n >= 2; n -= 2) {
        put2(out + n - 2, rest % 100);
        rest /= 100;
    }
    if (n)
        out[0] = (char)('0' + rest);
}

/* How many decimal digits v has (1 for 0): from its bit length b, as
 * floor(b log10(2)) + 1 (1233 / 2^12 is log10(2) closely enough for
 * b <= 64), one fewer if v is below that power of ten. */
static int decimal_length(uint64_t v)
{
    int bits = 64 - leading_zeros(v | 1);
    int n = ((bits * 1233) >> 12) + 1;
    return n - (n > 1 && v < pow10_u64[n - 1]);
}

size_t sm__int_to_decimal(int64_t v, char *out)
{
    /* the magnitude in unsigned arithmetic: -INT64_MIN overflows */
    uint64_t u = v < 0 ? 0 - (uint64_t)v : (uint64_t)v;
    size_t sign = v < 0;
    if (sign)
        out[0] = '-';
    int n = decimal_length(u);
    put_digits(out + sign, u, n);
    return sign + (size_t)n;
}

/* ---- a double to 17 significant digits ----
 * x = m 2^e2 > 0 is written from N = x 10^q rounded to an integer, with
 * q chosen so that N has 17 digits: x = N 10^(X - 16) to 17 digits, X its
 * decimal exponent.  The product comes from the truncated 128-bit 10^q of
 * the table, which puts it below the exact one by less than 1.25 units
 * of 2^-64: the rounding is certain unless the fraction is within that of
 * one half.  Then it is decided exactly, with integers of up to a
 * thousand bits (tens to hundreds of ns): for the exact ties, numbers of 18
 * significant digits ending in 5 such as 1000000000000000.25 (dyadic,
 * with few bits after the point: 1 in 1300 random bit patterns), and for
 * the near-ties (2^-62 of random doubles). */

#define TEN16 UINT64_C(10000000000000000)
#define TEN17 UINT64_C(100000000000000000)

/* floor(log10(2^e)) for |e| <= 1650: 78913 / 2^18 approximates log10(2)
 * closely enough over that range (the test checks every exponent of a
 * double). */
static int floor_log10_pow2(int e)
{
    return e >= 0 ? (e * 78913) >> 18 : -((-e * 78913 + (1 << 18) - 1) >> 18);
}

/* The integer part of m 2^e2 10^q (m > 0, the product in [10^16, 10^18))
 * and its fraction in units of 2^-64 (*frac), from below: the exact
 * fraction is in [*frac, *frac + 1.25).  With M the significand shifted
 * to a top bit of 63 and T the 128-bit mantissa of 10^q, the 192-bit
 * M T lies in [2^190, 2^192) and the product is M T 2^-(128 + k) for a k
 * in [3, 10] (the product's bounds): the integer part is in the top word.
 * Leaving out T's truncation costs less than 2^-66, M T's lowest 64 + k
 * bits less than 2^-64. */
static uint64_t scale(uint64_t m, int e2, int q, uint64_t *frac)
{
    const struct sm_pow10_128 *t = &sm_pow10_128[q - SM_POW10_MIN];
    int shift = leading_zeros(m);
    uint64_t big = m << shift;
    uint64_t lo_hi, hi_hi;
    (void)mul_64x64(big, t->lo, &lo_hi);
    uint64_t hi_lo = mul_64x64(big, t->hi, &hi_hi);
    uint64_t mid = hi_lo + lo_hi, top = hi_hi + (mid < hi_lo);
    int k = shift - e2 - t->exp2 - 1;
    *frac = top << (64 - k) | mid >> k;
    return top >> k;
}

/* ---- exact arithmetic for the (near-)ties ----
 * Unsigned integers of up to BIG_WORDS 32-bit words, the least
 * significant first, n of them in use (the top one not zero).  The
 * numbers compared (compare_with_half) are below 2^844: m 5^q with
 * m < 2^53 and q <= 340, 2n + 1 < 2^58 times 5^-q (q >= -292) or 2^-(e2 +
 * q + 1) (at most 2^749, the smallest doubles): 27 words, and one more
 * for a shift. */
#define BIG_WORDS 32

typedef struct big {
    uint32_t w[BIG_WORDS];
    int n;
} big;

/* 5^0 to 5^13: 5^13 is the largest power of 5 below 2^32. */
static const uint32_t pow5_u32[14] = {
    1, 5, 25, 125, 625, 3125, 15625, 78125, 390625, 1953125, 9765625, 48828125, 244140625,
    1220703125,
};

static void big_set(big *b, uint64_t v) /* v > 0 */
{
    b->w[0] = (uint32_t)v;
    b->w[1] = (uint32_t)(v >> 32);
    b->n = b->w[1] ? 2 : 1;
}

static void big_mul32(big *b, uint32_t f)
{
    uint64_t carry = 0;
    for (int i = 0; i < b->n; i++) {
        uint64_t p = (uint64_t)b->w[i] * f + carry;
        b->w[i] = (uint32_t)p;
        carry = p >> 32;
    }
    if (carry)
        b->w[b->n++] = (uint32_t)carry;
}

static void big_mul_pow5(big *b, int k)
{
    for (; k >= 13; k -= 13)
        big_mul32(b, pow5_u32[13]);
    if (k > 0)
        big_mul32(b, pow5_u32[k]);
}

static void big_shift_left(big *b, int bits)
{
    int words = bits / 32, r = bits % 32;
    b->w[b->n] = 0;
    for (int i = b->n; i >= 0; i--) {
        uint32_t below = r && i > 0 ? b->w[i - 1] >> (32 - r) : 0;
        b->w[i + words] = b->w[i] << r | below;
    }
    for (int i = 0; i < words; i++)
        b->w[i] = 0;
    b->n += words + 1;
    if (b->w[b->n - 1] == 0)
        b->n--;
}

static int big_compare(const big *a, const big *b)
{
    if (a->n != b->n)
        return a->n < b->n ? -1 : 1;
    for (int i = a->n - 1; i >= 0; i--)
        if (a->w[i] != b->w[i])
            return a->w[i] < b->w[i] ? -1 : 1;
    return 0;
}

/* The sign of m 2^e2 10^q - (n + 1/2), exactly: of m 2^(e2 + q + 1) 5^q
 * against 2n + 1, each power on the side where it is a whole number. */
static int compare_with_half(uint64_t m, int e2, int q, uint64_t n)
{
    big left, right;
    big_set(&left, m);
    big_set(&right, 2 * n + 1);
    int twos = e2 + q + 1;
    big_shift_left(twos > 0 ? &left : &right, twos > 0 ? twos : -twos);
    big_mul_pow5(q > 0 ? &left : &right, q > 0 ? q : -q);
    return big_compare(&left, &right);
}

/* m 2^e2 10^q rounded to the nearest integer, ties to even (the default
 * rounding of printf), from its integer part n and fraction frac
 * (scale); exact: every time by exact arithmetic, not only when the
 * fraction is too near one half to tell. */
static uint64_t round_scaled(uint64_t m, int e2, int q, uint64_t n, uint64_t frac, int exact)
{
    const uint64_t half = UINT64_C(1) << 63;
    if (!exact && (frac > half || frac < half - 2))
        return n + (frac > half);
    /* near one half, the integer part is certain (the fraction is far
     * from 0 and 1; and if not, n + 1 is right either way) */
    int sign = compare_with_half(m, e2, q, n);
    return n + (sign > 0 || (sign == 0 && (n & 1)));
}

/* x = m 2^e2 > 0 to 17 significant digits: *digits in [10^16, 10^17) and
 * the decimal exponent *exponent, x = *digits 10^(*exponent - 16) so
 * rounded. */
static void to_17_digits(uint64_t m, int e2, int exact, uint64_t *digits, int *exponent)
{
    /* floor(log10(x)) is this or one more, 2^p <= x < 2^(p+1): the
     * product then is in [10^16, 10^18) */
    int x10 = floor_log10_pow2(e2 + 63 - leading_zeros(m));
    uint64_t frac, n = scale(m, e2, 16 - x10, &frac);
    if (n >= TEN17) {
        x10++;
        n = scale(m, e2, 16 - x10, &frac);
    }
    n = round_scaled(m, e2, 16 - x10, n, frac, exact);
    if (n == TEN17) { /* 99999999999999999.5 and above rounded up */
        n = TEN16;
        x10++;
    }
    *digits = n;
    *exponent = x10;
}

/* "e+XX": the exponent of "%e", with at least two digits. */
static char *put_exponent(char *p, int x10)
{
    *p++ = 'e';
    *p++ = x10 < 0 ? '-' : '+';
    int a = x10 < 0 ? -x10 : x10;
    if (a >= 100) {
        *p++ = (char)('0' + a / 100);
        a %= 100;
    }
    memcpy(p, digit_pairs + 2 * a, 2);
    return p + 2;
}

/* The layout of "%.17g" for the digits d[0..n) (no trailing zero, the
 * first not zero) with the decimal exponent x10: "%e" style below 1e-4
 * and from 1e17, else "%f" style; a point only before digits. */
static char *put_g17(char *p, const char *d, int n, int x10)
{
    if (x10 < -4 || x10 >= 17) {
        *p++ = d[0];
        if (n > 1) {
            *p++ = '.';
            memcpy(p, d + 1, (size_t)(n - 1));
            p += n - 1;
        }
        return put_exponent(p, x10);
    }
    if (x10 < 0) { /* 0.000ddd */
        memcpy(p, "0.0000", (size_t)(1 - x10));
        p += 1 - x10;
        memcpy(p, d, (size_t)n);
        return p + n;
    }
    /* x10 + 1 digits before the point; d holds all 17 (zeros after n) */
    memcpy(p, d, (size_t)x10 + 1);
    p += x10 + 1;
    if (n > x10 + 1) {
        *p++ = '.';
        memcpy(p, d + x10 + 1, (size_t)(n - x10 - 1));
        p += n - x10 - 1;
    }
    return p;
}

static size_t double_to_decimal(double x, char *out, int exact)
{
    uint64_t bits;
    memcpy(&bits, &x, sizeof bits);
    char *p = out;
    if (bits >> 63)
        *p++ = '-';
    int biased = (int)(bits >> 52 & 0x7ff);
    uint64_t m = bits & ((UINT64_C(1) << 52) - 1);
    if (biased == 0x7ff) { /* printf's words */
        memcpy(p, m ? "nan" : "inf", 3);
        return (size_t)(p + 3 - out);
    }
    if (biased == 0 && m == 0) {
        *p = '0';
        return (size_t)(p + 1 - out);
    }
    int e2 = biased ? biased - 1075 : -1074; /* a subnormal's m has no hidden bit */
    if (biased)
        m |= UINT64_C(1) << 52;
    uint64_t digits;
    int x10, n = 17;
    to_17_digits(m, e2, exact, &digits, &x10);
    char d[17];
    uint32_t high = (uint32_t)(digits / 100000000);
    d[0] = (char)('0' + high / 100000000);
    put8(d + 1, high % 100000000);
    put8(d + 9, (uint32_t)(digits % 100000000));
    while (d[n - 1] == '0')
        n--;
    return (size_t)(put_g17(p, d, n, x10) - out);
}

size_t sm__double_to_decimal(double x, char *out)
{
    return double_to_decimal(x, out, 0);
}

size_t sm__double_to_decimal_exact(double x, char *out)
{
    return double_to_decimal(x, out, 1);
}

/* ---- the public face (shapematch/sm_decimal.h) ---- */

/* A field longer than this is no plain decimal anyone writes (%.17g needs
 * 24 characters); refusing it bounds the copy for strtod. */
#define DECIMAL_FIELD_MAX 64

int sm_decimal_parse(const char *s, size_t n, double *out)
{
    if (n == 0 || n > DECIMAL_FIELD_MAX)
        return 0;
    double v;
    if (sm__decimal_to_double(s, s + n, &v) == n && isfinite(v)) {
        *out = v;
        return 1;
    }
    /* the rare rest (20 or more significant digits, a rounding the fast
     * paths cannot decide, forms like "1." or "-.5"): strtod, on the
     * characters of a plain decimal only */
    char buf[DECIMAL_FIELD_MAX + 1];
    int digits = 0;
    for (size_t i = 0; i < n; i++) {
        char c = s[i];
        if (c >= '0' && c <= '9')
            digits++;
        else if (c != '+' && c != '-' && c != '.' && c != 'e' && c != 'E')
            return 0;
        buf[i] = c;
    }
    buf[n] = '\0';
    if (!digits)
        return 0;
    char *end;
    v = strtod(buf, &end);
    if (end != buf + n || !isfinite(v))
        return 0;
    *out = v;
    return 1;
}

size_t sm_decimal_format(double x, char *out)
{
    return sm__double_to_decimal(x, out);
}
