/* CORS and cross-site safety (smd_cors.h) without HTTP: which origins
 * are listed (exact, case-insensitive; "*" lists all), and which are the
 * daemon's own (the Host header, or the origin of --public-url). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>
#include <cmocka.h>

#include "base/smd_config.h"
#include "http/smd_cors.h"

static void config(smd_config *c, const char *const *origins, const char *public_url)
{
    memset(c, 0, sizeof *c);
    for (; origins && *origins; origins++)
        strcpy(c->cors_origins[c->ncors_origins++], *origins);
    strcpy(c->public_url, public_url ? public_url : "");
}

static void test_listed(void **state)
{
    (void)state;
    smd_config c;
    const char *const two[] = {"https://app.example.test", "http://localhost:5173", NULL};
    config(&c, two, NULL);
    assert_true(smd_cors_listed(&c, "https://app.example.test"));
    assert_true(smd_cors_listed(&c, "HTTPS://APP.example.test"));
    assert_true(smd_cors_listed(&c, "http://localhost:5173"));
    assert_false(smd_cors_listed(&c, "http://localhost:5174"));
    assert_false(smd_cors_listed(&c, "http://app.example.test"));      /* scheme counts */
    assert_false(smd_cors_listed(&c, "https://app.example.test.evil")); /* exact, no prefix */
    assert_false(smd_cors_listed(&c, "https://app.example.tes"));
    assert_false(smd_cors_listed(&c, "null"));
    assert_false(smd_cors_listed(&c, NULL));
    config(&c, NULL, NULL);
    assert_false(smd_cors_listed(&c, "https://app.example.test"));
    const char *const star[] = {"*", NULL};
    config(&c, star, NULL);
    assert_true(smd_cors_listed(&c, "https://anything.example.test"));
    assert_false(smd_cors_listed(&c, NULL));
}

static void test_same_origin(void **state)
{
    (void)state;
    smd_config c;
    config(&c, NULL, NULL);
    assert_true(smd_cors_same_origin(&c, "http://127.0.0.1:8080", "127.0.0.1:8080"));
    /* a name in Host is the client's word: DNS rebinding sends the
     * attacker's name in both headers (issue 28) */
    assert_false(smd_cors_same_origin(&c, "http://Daemon.example.test", "daemon.example.test"));
    assert_false(smd_cors_same_origin(&c, "http://attacker.example:8080", "attacker.example:8080"));
    assert_true(smd_cors_same_origin(&c, "http://localhost:8080", "localhost:8080"));
    assert_true(smd_cors_same_origin(&c, "http://[::1]:8080", "[::1]:8080"));
    strcpy(c.allowed_hosts[0], "daemon.example.test");
    strcpy(c.allowed_hosts[1], "other.example.test:9000");
    c.nallowed_hosts = 2;
    assert_true(smd_cors_same_origin(&c, "http://Daemon.example.test", "daemon.example.test"));
    assert_true(smd_cors_trusted_host(&c, "daemon.example.test:8080"));
    assert_true(smd_cors_trusted_host(&c, "other.example.test:9000"));
    assert_false(smd_cors_trusted_host(&c, "other.example.test:9001"));
    assert_false(smd_cors_trusted_host(&c, "attacker.example"));
    assert_false(smd_cors_trusted_host(&c, ""));
    assert_true(smd_cors_trusted_host(&c, "10.1.2.3:80"));
    c.nallowed_hosts = 0;
    assert_false(smd_cors_same_origin(&c, "http://127.0.0.1:8081", "127.0.0.1:8080"));
    assert_false(smd_cors_same_origin(&c, "http://127.0.0.1:8080", NULL));
    assert_false(smd_cors_same_origin(&c, "null", "null"));
    assert_false(smd_cors_same_origin(&c, "127.0.0.1:8080", "127.0.0.1:8080")); /* no scheme */
    assert_false(smd_cors_same_origin(&c, "http://127.0.0.1:8080/x", "127.0.0.1:8080"));
    /* behind a proxy: the public URL's origin, its path aside */
    config(&c, NULL, "https://maps.example.test/shapematch/");
    assert_true(smd_cors_same_origin(&c, "https://maps.example.test", "10.0.0.5:8080"));
    assert_false(smd_cors_same_origin(&c, "http://maps.example.test", "10.0.0.5:8080"));
    assert_false(smd_cors_same_origin(&c, "https://maps.example.test:8443", "10.0.0.5:8080"));
    assert_true(smd_cors_same_origin(&c, "http://10.0.0.5:8080", "10.0.0.5:8080"));
}

/* The Host check against DNS rebinding (issue 37): the daemon's names
 * only, whatever --allowed-host holds, and nothing that merely starts or
 * ends like one. */
static void test_trusted_host(void **state)
{
    (void)state;
    smd_config c;
    config(&c, NULL, NULL);
    strcpy(c.listen_host, "0.0.0.0");
    const char *yes[] = {"127.0.0.1", "127.0.0.1:8080", "10.1.2.3:80", "[::1]", "[::1]:8080",
                         "[2001:db8::5]:443", "localhost", "LOCALHOST:8080", "localhost.:8080",
                         "app.localhost:3000", "0.0.0.0:8080"};
    for (size_t i = 0; i < sizeof yes / sizeof *yes; i++)
        assert_true(smd_cors_trusted_host(&c, yes[i]));
    const char *no[] = {"attacker.example", "attacker.example:8080", "localhost.attacker.example",
                        "evillocalhost", "127.0.0.1.attacker.example", "::1", "[::1",
                        "[::1]x", "127.0.0.1:", "127.0.0.1:80x", "127.0.0.1:123456",
                        "localhost:8080:1", "[attacker.example]", "", ":8080"};
    for (size_t i = 0; i < sizeof no / sizeof *no; i++)
        assert_false(smd_cors_trusted_host(&c, no[i]));
    /* the listen host by name, --public-url's host */
    strcpy(c.listen_host, "daemon.internal");
    assert_true(smd_cors_trusted_host(&c, "daemon.internal:8080"));
    config(&c, NULL, "https://maps.example.test:8443/shapematch/");
    assert_true(smd_cors_trusted_host(&c, "maps.example.test"));
    assert_false(smd_cors_trusted_host(&c, "example.test"));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_listed),
        cmocka_unit_test(test_same_origin),
        cmocka_unit_test(test_trusted_host),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
