/* The base64 decoder of the OGC execute request (smd_ogc.h): RFC 4648
 * with optional padding and MIME line breaks; anything else (a foreign
 * character, data after padding, a lone last character, non-canonical
 * trailing bits, padding that does not fit) is refused with the offset. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>
#include <cmocka.h>

#include "api/smd_ogc.h"

/* Decodes text; the length (SIZE_MAX on refusal), the bytes into out. */
static size_t decode(const char *text, unsigned char *out, size_t *pos)
{
    *pos = 0;
    return smd_base64_decode(text, strlen(text), out, pos);
}

static void test_valid(void **state)
{
    (void)state;
    unsigned char out[64];
    size_t pos;
    assert_int_equal(decode("", out, &pos), 0);
    assert_int_equal(decode("QQ==", out, &pos), 1);
    assert_memory_equal(out, "A", 1);
    assert_int_equal(decode("QQ", out, &pos), 1); /* padding is optional */
    assert_int_equal(decode("QUI=", out, &pos), 2);
    assert_memory_equal(out, "AB", 2);
    assert_int_equal(decode("QUJD", out, &pos), 3);
    assert_memory_equal(out, "ABC", 3);
    assert_int_equal(decode("TWVz\r\nc2Fn\nZQ==", out, &pos), 7); /* line breaks skipped */
    assert_memory_equal(out, "Message", 7);
    assert_int_equal(decode("//79", out, &pos), 3);
    assert_memory_equal(out, "\xff\xfe\xfd", 3);
    assert_int_equal(decode("AAEC+/8=", out, &pos), 5);
    assert_memory_equal(out, "\x00\x01\x02\xfb\xff", 5);
}

static void test_refused(void **state)
{
    (void)state;
    unsigned char out[64];
    size_t pos;
    assert_int_equal(decode("QU*D", out, &pos), SIZE_MAX);
    assert_int_equal(pos, 2);                                /* the offending character */
    assert_int_equal(decode("QQ==QQ==", out, &pos), SIZE_MAX); /* data after padding */
    assert_int_equal(pos, 4);
    assert_int_equal(decode("Q", out, &pos), SIZE_MAX);     /* 6 bits make no byte */
    assert_int_equal(decode("QUJDR", out, &pos), SIZE_MAX);
    assert_int_equal(decode("QR==", out, &pos), SIZE_MAX);  /* trailing bits not zero */
    assert_int_equal(decode("QQ=", out, &pos), SIZE_MAX);   /* padding that does not fit */
    assert_int_equal(decode("QUJD==", out, &pos), SIZE_MAX);
    assert_int_equal(decode("====", out, &pos), SIZE_MAX);
    assert_int_equal(decode("QQ== ", out, &pos), SIZE_MAX); /* a space is no line break */
    assert_int_equal(decode("QUJD-_", out, &pos), SIZE_MAX); /* not the URL alphabet */
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_valid),
        cmocka_unit_test(test_refused),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
