/* Decimal text of doubles for formats read and written outside the core
 * (proto's point lists): the core's own conversions (the ASCII mesh
 * readers' and writers'), exact and about ten times faster than the C
 * library's strtod and printf("%.17g").  No locale: '.' always. */
#ifndef SM_DECIMAL_H
#define SM_DECIMAL_H

#include <stddef.h>

/* The n bytes at s (no blanks, not NUL-terminated) as a plain decimal:
 * [+-] digits [. digits] [(e|E) [+-] digits] with at least one digit,
 * or the forms strtod reads from those characters ("1.", ".5").  Returns
 * 1 with *out the double strtod gives for it (bit for bit, in the
 * default rounding mode) when it is finite, 0 for anything else:
 * another character (so no "inf", "nan", hexadecimal), an empty field,
 * more than 64 bytes, a value that overflows. */
int sm_decimal_parse(const char *s, size_t n, double *out);

/* The most bytes sm_decimal_format writes. */
#define SM_DECIMAL_LEN 24

/* Writes x at out (no NUL) exactly as printf("%.17g", x) does: bitwise
 * round trip through sm_decimal_parse or strtod.  Returns the length, at
 * most SM_DECIMAL_LEN. */
size_t sm_decimal_format(double x, char *out);

#endif
