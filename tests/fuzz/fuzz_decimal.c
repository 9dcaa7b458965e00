/* Decimal numbers both ways (core/io/sm_number.c), against the C library.
 *
 * The input as text: sm__decimal_to_double, the readers' in-place
 * parser, either leaves the number to strtod (returns 0) or gives, for
 * the n bytes it says the number has, strtod's double bit for bit, strtod
 * taking the same n bytes.  The public sm_decimal_parse (the points
 * CSV's) takes the whole input as one field: accepted exactly when strtod
 * reads all of a plain decimal's characters to a finite double, its bits.
 *
 * The input as numbers, 8 bytes each: sm__double_to_decimal and its exact
 * twin write printf's "%.17g" byte for byte, in at most SM_DECIMAL_MAX
 * bytes, and strtod reads the text back to the same bits;
 * sm__int_to_decimal writes "%lld". */
#include <inttypes.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "io/sm_number.h"
#include "shapematch/sm_decimal.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static void check_parse(const uint8_t *data, size_t size)
{
    const char *text = (const char *)data;
    double got;
    size_t n = sm__decimal_to_double(text, text + size, &got);
    if (n == 0)
        return;
    if (n > size)
        abort();
    char *copy = malloc(n + 1); /* strtod needs the NUL; exactly n bytes */
    if (!copy)
        return;
    memcpy(copy, text, n);
    copy[n] = '\0';
    char *end;
    double want = strtod(copy, &end);
    int same = memcmp(&got, &want, sizeof got) == 0 && (size_t)(end - copy) == n;
    free(copy);
    if (!same)
        abort();
}

/* The public parse of the whole input as one field: accepted exactly
 * when strtod reads all of a plain decimal's characters to a finite
 * double, with its bits. */
static void check_field(const uint8_t *data, size_t size)
{
    const char *text = (const char *)data;
    double got = 0;
    int ok = sm_decimal_parse(text, size, &got);
    char buf[65];
    int want_ok = size > 0 && size <= 64;
    int digits = 0;
    for (size_t i = 0; want_ok && i < size; i++) {
        char c = text[i];
        digits += c >= '0' && c <= '9';
        want_ok = (c >= '0' && c <= '9') || c == '+' || c == '-' || c == '.' || c == 'e' ||
                  c == 'E';
        buf[i] = c;
    }
    double want = 0;
    if (want_ok && digits) {
        buf[size] = '\0';
        char *end;
        want = strtod(buf, &end);
        want_ok = end == buf + size && isfinite(want);
    } else {
        want_ok = 0;
    }
    if (ok != want_ok || (ok && memcmp(&got, &want, sizeof got) != 0))
        abort();
}

static void check_format(uint64_t bits)
{
    double x;
    memcpy(&x, &bits, sizeof x);
    char *fast = malloc(SM_DECIMAL_MAX), *exact = malloc(SM_DECIMAL_MAX);
    if (!fast || !exact) {
        free(fast);
        free(exact);
        return;
    }
    char want[64], got[SM_DECIMAL_MAX + 1];
    size_t n = sm__double_to_decimal(x, fast);
    size_t ne = sm__double_to_decimal_exact(x, exact);
    int nw = snprintf(want, sizeof want, "%.17g", x);
    int same = n <= SM_DECIMAL_MAX && n == ne && (size_t)nw == n && memcmp(fast, want, n) == 0 &&
               memcmp(exact, want, n) == 0;
    if (same) {
        memcpy(got, fast, n);
        got[n] = '\0';
    }
    free(fast);
    free(exact);
    if (!same)
        abort();
    if (isfinite(x)) {
        double back = strtod(got, NULL);
        if (memcmp(&back, &x, sizeof x) != 0)
            abort();
    }
    char ints[SM_DECIMAL_MAX + 1];
    size_t ni = sm__int_to_decimal((int64_t)bits, ints);
    ints[ni] = '\0';
    snprintf(want, sizeof want, "%" PRId64, (int64_t)bits);
    if (strcmp(ints, want) != 0)
        abort();
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    check_parse(data, size);
    check_field(data, size);
    for (size_t i = 0; i + 8 <= size; i += 8) {
        uint64_t bits;
        memcpy(&bits, data + i, sizeof bits);
        check_format(bits);
    }
    return 0;
}
