/* Submission limits (smd_ratelimit.h): the fixed window per key, its
 * Retry-After, independence of keys, the window's reset, and the tracked
 * unfinished jobs of an address. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <cmocka.h>

#include "http/smd_ratelimit.h"

static void test_window(void **state)
{
    (void)state;
    smd_ratelimit *rl = smd_ratelimit_new(3, 10);
    assert_non_null(rl);
    for (int i = 0; i < 3; i++)
        assert_int_equal(smd_ratelimit_take(rl, "t:alice", 100.0 + i), 0);
    /* the fourth in the window waits for its end: 100 + 10 - 102.5 */
    assert_int_equal(smd_ratelimit_take(rl, "t:alice", 102.5), 8);
    assert_int_equal(smd_ratelimit_take(rl, "t:alice", 109.9), 1);
    assert_int_equal(smd_ratelimit_take(rl, "t:bob", 103.0), 0); /* another key */
    assert_int_equal(smd_ratelimit_take(rl, "t:alice", 110.0), 0); /* a new window */
    smd_ratelimit_free(rl);
    rl = smd_ratelimit_new(0, 10); /* no rate limit */
    for (int i = 0; i < 1000; i++)
        assert_int_equal(smd_ratelimit_take(rl, "t:alice", 1.0), 0);
    smd_ratelimit_free(rl);
}

static int live_unless_b(const char *id, void *user)
{
    (void)user;
    return id[0] != 'b';
}

static void test_tracked_jobs(void **state)
{
    (void)state;
    smd_ratelimit *rl = smd_ratelimit_new(5, 60);
    char id[SMD_ID_LEN + 1];
    for (int i = 0; i < 20; i++) {
        memset(id, i % 2 ? 'b' : 'a', SMD_ID_LEN);
        id[SMD_ID_LEN] = '\0';
        smd_ratelimit_track(rl, "a:127.0.0.1", id);
    }
    assert_int_equal(smd_ratelimit_live(rl, "a:127.0.0.1", live_unless_b, NULL), 10);
    assert_int_equal(smd_ratelimit_live(rl, "a:127.0.0.1", live_unless_b, NULL), 10);
    assert_int_equal(smd_ratelimit_live(rl, "a:127.0.0.2", live_unless_b, NULL), 0);
    /* tracking does not spend the rate */
    for (int i = 0; i < 5; i++)
        assert_int_equal(smd_ratelimit_take(rl, "a:127.0.0.1", 1.0), 0);
    assert_true(smd_ratelimit_take(rl, "a:127.0.0.1", 1.0) > 0);
    smd_ratelimit_free(rl);
}

static void test_full_table(void **state)
{
    (void)state;
    smd_ratelimit *rl = smd_ratelimit_new(1, 10);
    char key[32];
    for (int i = 0; i < SMD_RATELIMIT_KEYS; i++) {
        snprintf(key, sizeof key, "a:k%d", i);
        assert_int_equal(smd_ratelimit_take(rl, key, 5.0), 0);
    }
    /* a full table of live windows (4096 throw-away addresses): a new
     * key is still taken (the least recently used makes room), never
     * refused with another key's window (before: 10 s) */
    assert_int_equal(smd_ratelimit_take(rl, "a:new", 6.0), 0);
    assert_true(smd_ratelimit_take(rl, "a:new", 6.5) > 0); /* its own rate holds */
    /* the evicted key was the oldest: k0 starts a fresh window */
    assert_int_equal(smd_ratelimit_take(rl, "a:k0", 7.0), 0);
    /* a key that tracks a job is evicted after those that track none */
    smd_ratelimit_free(rl);
    rl = smd_ratelimit_new(1, 10);
    char id[SMD_ID_LEN + 1];
    memset(id, 'a', SMD_ID_LEN);
    id[SMD_ID_LEN] = '\0';
    assert_int_equal(smd_ratelimit_take(rl, "a:owner", 1.0), 0);
    smd_ratelimit_track(rl, "a:owner", id);
    for (int i = 0; i < 2 * SMD_RATELIMIT_KEYS; i++) {
        snprintf(key, sizeof key, "a:f%d", i);
        assert_int_equal(smd_ratelimit_take(rl, key, 2.0 + i * 1e-4), 0);
    }
    assert_int_equal(smd_ratelimit_live(rl, "a:owner", live_unless_b, NULL), 1);
    smd_ratelimit_free(rl);
}

/* The key of a client address: IPv6 per /64; IPv4 per address by
 * default, per network with --submit-ipv4-prefix (the networks worked
 * out by hand), IPv4-mapped IPv6 as IPv4. */
static void test_address_keys(void **state)
{
    (void)state;
    static const struct {
        const char *addr;
        unsigned prefix;
        const char *key;
    } cases[] = {
        {"198.51.100.77", 32, "a:198.51.100.77"},
        {"198.51.100.77", 24, "a:198.51.100.0/24"},
        {"198.51.100.255", 24, "a:198.51.100.0/24"},
        {"198.51.101.1", 24, "a:198.51.101.0/24"},
        {"198.51.100.77", 16, "a:198.51.0.0/16"},
        {"198.51.100.77", 20, "a:198.51.96.0/20"}, /* 100 = 0110 0100: top 4 bits 96 */
        {"198.51.100.77", 8, "a:198.0.0.0/8"},
        {"198.51.100.77", 0, "a:198.0.0.0/8"},     /* clamped to 8..32 */
        {"::ffff:198.51.100.77", 24, "a:198.51.100.0/24"},
        {"::ffff:198.51.100.77", 32, "a:198.51.100.77"},
        {"2001:db8:1:2:3:4:5:6", 32, "a:2001:db8:1:2::/64"},
        {"2001:db8:1:2:ffff::1", 24, "a:2001:db8:1:2::/64"},
        {"?", 24, "a:?"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        char key[SMD_RATELIMIT_KEY_MAX + 1];
        smd_ratelimit_address_key(cases[i].addr, cases[i].prefix, key, sizeof key);
        assert_string_equal(key, cases[i].key);
    }
    /* two addresses of one /24 share a window only with the prefix */
    smd_ratelimit *rl = smd_ratelimit_new(1, 60);
    char k1[SMD_RATELIMIT_KEY_MAX + 1], k2[SMD_RATELIMIT_KEY_MAX + 1];
    smd_ratelimit_address_key("203.0.113.1", 24, k1, sizeof k1);
    smd_ratelimit_address_key("203.0.113.2", 24, k2, sizeof k2);
    assert_int_equal(smd_ratelimit_take(rl, k1, 1.0), 0);
    assert_true(smd_ratelimit_take(rl, k2, 1.0) > 0);
    smd_ratelimit_address_key("203.0.113.1", 32, k1, sizeof k1);
    smd_ratelimit_address_key("203.0.113.2", 32, k2, sizeof k2);
    assert_int_equal(smd_ratelimit_take(rl, k1, 1.0), 0);
    assert_int_equal(smd_ratelimit_take(rl, k2, 1.0), 0);
    smd_ratelimit_free(rl);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_window),
        cmocka_unit_test(test_tracked_jobs),
        cmocka_unit_test(test_full_table),
        cmocka_unit_test(test_address_keys),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
