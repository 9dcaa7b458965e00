/* Decimal numbers, read and written without the C library (internal,
 * not part of the public API): the fast path of the ASCII readers' reals
 * (sm__reader_real) and the numbers of the ASCII writers (sm__writer_int,
 * sm__writer_real).
 *
 * Reading.  Decimal numbers converted in place, bit for bit as strtod
 * converts them.  glibc's strtod costs about 1000 instructions a number
 * (it handles every form, with multi-precision arithmetic), which was
 * most of the time of an ASCII mesh's Vertices section.  The common forms
 * are converted here instead, exactly: a significand of at most 19 digits
 * and a power of ten by Clinger's fast path (both exact doubles, one
 * rounding) where it applies, else by the Eisel-Lemire algorithm (a
 * 128-bit product with a truncated power of ten, which knows when its
 * rounding could be wrong).  Whatever they cannot convert with certainty
 * is left to strtod.
 *
 * Writing.  Doubles as printf's "%.17g" writes them and integers as
 * "%lld", byte for byte, for a tenth of the cost (glibc's vsnprintf:
 * 200 ns a double, 35 ns an integer; a result of the paper's size prints
 * 95k of the first and 400k of the second, bench/write_bench.c).  The
 * same 128-bit powers of ten give the 17 digits, and exact integer
 * arithmetic the rare roundings they cannot tell.  No locale: the
 * decimal point is always '.'. */
#ifndef SM_NUMBER_H
#define SM_NUMBER_H

#include <stddef.h>
#include <stdint.h>
#include <string.h>

/* ---- runs of decimal digits, eight bytes at a time ----
 * The digits of a number are found and converted eight at a time in a
 * 64-bit word (two masks and three multiplications) rather than one
 * byte at a time (a compare, a branch, a multiply-add each): the integers
 * of an element section and the 14 to 17 digits of a coordinate are one
 * or two words. */

/* The 8 bytes at p as a little-endian word: p[0] in the low byte. */
static inline uint64_t sm__load_le64(const void *p)
{
    uint64_t x;
    memcpy(&x, p, sizeof x);
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__
    x = __builtin_bswap64(x);
#endif
    return x;
}

/* How many of the bytes of x (from its low byte) are ASCII digits before
 * the first that is not (8: all).  A byte's high nibble must be 3, and
 * stay 3 when 6 is added ('0'-'9' are 0x30-0x39); a carry out of a byte
 * of 0xfa or more only disturbs the bytes after it, which do not count. */
static inline unsigned sm__leading_digits8(uint64_t x)
{
    const uint64_t high = 0xf0f0f0f0f0f0f0f0u, three = 0x3030303030303030u;
    uint64_t bad = ((x & high) ^ three) | (((x + 0x0606060606060606u) & high) ^ three);
    return bad ? (unsigned)__builtin_ctzll(bad) / 8 : 8;
}

/* The value of the first n (1 to 8) digits of x, the first the most
 * significant: the digits are moved to the top bytes (the low ones
 * becoming leading zeros), then pairs, fours and eights are combined. */
static inline uint64_t sm__digits8_value(uint64_t x, unsigned n)
{
    uint64_t d = (x - 0x3030303030303030u) << (8 * (8 - n));
    d = (d * 10 + (d >> 8)) & 0x00ff00ff00ff00ffu;
    d = (d * 100 + (d >> 16)) & 0x0000ffff0000ffffu;
    return (d * 10000 + (d >> 32)) & 0xffffffffu;
}

/* The decimal integer [+-] digits at p (before end), of at most 18
 * digits (so it cannot overflow), as *out; returns its length, or 0 when
 * there is no digit or more than 18 (the caller then takes the general
 * path).  Where it ends, the caller checks. */
static inline size_t sm__decimal_to_int(const char *p, const char *end, int64_t *out)
{
    const char *s = p;
    int negative = 0;
    if (s < end && (*s == '-' || *s == '+'))
        negative = *s++ == '-';
    size_t left = (size_t)(end - s), n = 0;
    uint64_t v = 0;
    if (left >= 8) {
        uint64_t x = sm__load_le64(s);
        n = sm__leading_digits8(x);
        if (n)
            v = sm__digits8_value(x, (unsigned)n);
    }
    if (n == 8 || left < 8) /* more digits, or too close to the end for a word */
        while (n < left && (unsigned)(s[n] - '0') < 10u) {
            if (n == 18)
                return 0; /* a 19th digit */
            v = v * 10 + (uint64_t)(s[n++] - '0');
        }
    if (n == 0)
        return 0;
    *out = negative ? -(int64_t)v : (int64_t)v;
    return (size_t)(s + n - p);
}

/* Converts the decimal number at p (before end): [+-] digits [. digits]
 * [(e|E) [+-] digits], with at least one digit before the exponent.
 * Returns the length of the number, with the double strtod would give
 * for it in *out (in the default rounding mode); 0 when it leaves the
 * number to strtod: another form (hexadecimal, inf, nan, no digit), more
 * than 19 significant digits, an exponent out of its table, or a
 * rounding it cannot decide.  The number ends where these forms end (a
 * hexadecimal number is read as its leading 0); the caller checks what
 * follows. */
size_t sm__decimal_to_double(const char *p, const char *end, double *out);

/* The most bytes sm__double_to_decimal and sm__int_to_decimal write:
 * "-2.2250738585072014e-308", "-9223372036854775808". */
#define SM_DECIMAL_MAX 24

/* Writes x at out (no NUL) exactly as printf("%.17g", x) does in the
 * default rounding mode, whatever the locale: 17 significant digits
 * rounded to nearest, ties to even, trailing zeros dropped; "%e" style
 * ("1.0000000000000001e-05", "1e+17") below 1e-4 and from 1e17, else "%f"
 * style ("0.10000000000000001", "-0", "12.5"); "inf", "-inf", "nan",
 * "-nan".  Seventeen digits identify a double: strtod (or
 * sm__decimal_to_double) reads the text back to x bit for bit.  Returns
 * the length, at most SM_DECIMAL_MAX. */
size_t sm__double_to_decimal(double x, char *out);
/* The same, every rounding decided by exact integer arithmetic instead of
 * the 128-bit product first: slower, the reference its tests hold
 * sm__double_to_decimal to. */
size_t sm__double_to_decimal_exact(double x, char *out);
/* Writes v at out (no NUL) as printf("%lld", v) does; returns the length,
 * at most 20. */
size_t sm__int_to_decimal(int64_t v, char *out);

#endif
