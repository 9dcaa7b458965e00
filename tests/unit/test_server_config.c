/* Daemon configuration (flags over SHAPEMATCH_* variables over defaults)
 * and the bearer tokens file. */
#include <limits.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "http/smd_auth.h"
#include "base/smd_config.h"
#include "base/smd_log.h"

/* environment given as a NULL-terminated list of "NAME=value" */
static const char *table_env(const char *name, void *user)
{
    const char *const *env = user;
    size_t n = strlen(name);
    for (; env && *env; env++)
        if (strncmp(*env, name, n) == 0 && (*env)[n] == '=')
            return *env + n + 1;
    return NULL;
}

static smd_config_result parse(smd_config *c, const char *const *env, char *msg, ...)
{
    char *argv[32] = {"shapematchd"};
    int argc = 1;
    va_list ap;
    va_start(ap, msg);
    const char *a;
    while ((a = va_arg(ap, const char *)) != NULL && argc < 31)
        argv[argc++] = (char *)a;
    va_end(ap);
    return smd_config_parse(c, argc, argv, table_env, (void *)env, msg, 512);
}

static void test_defaults(void **state)
{
    (void)state;
    smd_config c;
    char msg[512];
    assert_int_equal(parse(&c, NULL, msg, NULL), SMD_CONFIG_OK);
    assert_string_equal(c.listen_host, "127.0.0.1");
    assert_int_equal(c.listen_port, 8080);
    assert_string_equal(c.spool, "./spool");
    assert_int_equal(c.workers, smd_default_workers());
    assert_true(c.max_upload == (uint64_t)256 << 20);
    assert_true(c.job_timeout == 3600);
    assert_true(c.retention == 7 * 86400);
    assert_string_equal(c.tokens_file, "");
    assert_int_equal(c.log_level, SMD_LOG_INFO);
    assert_true(c.keepalive == 15);
}

static void test_env_and_flags(void **state)
{
    (void)state;
    const char *env[] = {"SHAPEMATCH_LISTEN=0.0.0.0:9000", "SHAPEMATCH_SPOOL=/var/lib/sm",
                         "SHAPEMATCH_WORKERS=3", "SHAPEMATCH_MAX_UPLOAD=64M",
                         "SHAPEMATCH_JOB_TIMEOUT=30m", "SHAPEMATCH_RETENTION=2d",
                         "SHAPEMATCH_TOKENS_FILE=/run/secrets/tokens", "SHAPEMATCH_LOG_LEVEL=warn",
                         NULL};
    smd_config c;
    char msg[512];
    assert_int_equal(parse(&c, env, msg, NULL), SMD_CONFIG_OK);
    assert_string_equal(c.listen_host, "0.0.0.0");
    assert_int_equal(c.listen_port, 9000);
    assert_string_equal(c.spool, "/var/lib/sm");
    assert_int_equal(c.workers, 3);
    assert_true(c.max_upload == (uint64_t)64 << 20);
    assert_true(c.job_timeout == 1800);
    assert_true(c.retention == 2 * 86400);
    assert_string_equal(c.tokens_file, "/run/secrets/tokens");
    assert_int_equal(c.log_level, SMD_LOG_WARN);
    /* a flag wins over its variable; both --flag value and --flag=value */
    assert_int_equal(parse(&c, env, msg, "--workers", "5", "--spool=/tmp/s", "--listen", "[::1]:8443",
                           "--cpu-limit", "90", "--memory-limit", "1G", NULL),
                     SMD_CONFIG_OK);
    assert_int_equal(c.workers, 5);
    assert_string_equal(c.spool, "/tmp/s");
    assert_string_equal(c.listen_host, "::1");
    assert_int_equal(c.listen_port, 8443);
    assert_true(c.cpu_limit == 90);
    assert_true(c.memory_limit == (uint64_t)1 << 30);
    assert_true(c.max_upload == (uint64_t)64 << 20); /* still from the environment */
    assert_int_equal(parse(&c, NULL, msg, "--listen", ":8081", NULL), SMD_CONFIG_OK);
    assert_string_equal(c.listen_host, "0.0.0.0");
    assert_int_equal(c.listen_port, 8081);
}

static void test_errors(void **state)
{
    (void)state;
    smd_config c;
    char msg[512];
    assert_int_equal(parse(&c, NULL, msg, "--help", NULL), SMD_CONFIG_HELP);
    assert_int_equal(parse(&c, NULL, msg, "--version", NULL), SMD_CONFIG_VERSION);
    assert_int_equal(parse(&c, NULL, msg, "--frobnicate", NULL), SMD_CONFIG_ERROR);
    assert_non_null(strstr(msg, "--frobnicate"));
    assert_int_equal(parse(&c, NULL, msg, "--workers", NULL), SMD_CONFIG_ERROR);
    assert_non_null(strstr(msg, "--workers: missing value"));
    assert_int_equal(parse(&c, NULL, msg, "--workers", "0", NULL), SMD_CONFIG_ERROR);
    assert_non_null(strstr(msg, "--workers"));
    assert_int_equal(parse(&c, NULL, msg, "--workers", "2x", NULL), SMD_CONFIG_ERROR);
    assert_int_equal(parse(&c, NULL, msg, "--listen", "localhost", NULL), SMD_CONFIG_ERROR);
    assert_non_null(strstr(msg, "HOST:PORT"));
    assert_int_equal(parse(&c, NULL, msg, "--listen", "1.2.3.4:99999", NULL), SMD_CONFIG_ERROR);
    assert_int_equal(parse(&c, NULL, msg, "--listen", "[::1:80", NULL), SMD_CONFIG_ERROR);
    assert_int_equal(parse(&c, NULL, msg, "--max-upload", "lots", NULL), SMD_CONFIG_ERROR);
    assert_int_equal(parse(&c, NULL, msg, "--job-timeout", "-5", NULL), SMD_CONFIG_ERROR);
    assert_int_equal(parse(&c, NULL, msg, "--log-level", "loud", NULL), SMD_CONFIG_ERROR);
    assert_int_equal(parse(&c, NULL, msg, "--spool", "", NULL), SMD_CONFIG_ERROR);
    const char *bad_env[] = {"SHAPEMATCH_WORKERS=many", NULL};
    assert_int_equal(parse(&c, bad_env, msg, NULL), SMD_CONFIG_ERROR);
    assert_non_null(strstr(msg, "SHAPEMATCH_WORKERS"));
}

/* Every numeric option of the table (not a list written here): its
 * range fits the field it is stored in, and values past it, far past
 * it (beyond 2^64, beyond a double) or malformed are refused with a
 * message naming the flag before anything is stored. */
static void test_numeric_options_bounded(void **state)
{
    (void)state;
    smd_config_number o;
    size_t rows = 0;
    for (size_t i = 0; smd_config_number_at(i, &o); i++, rows++) {
        if (o.kind == SMD_CONFIG_INTEGER)
            assert_true(o.hi <= (o.width == sizeof(int) && o.is_signed ? (double)INT_MAX
                                                                       : (double)UINT_MAX));
        else if (o.kind == SMD_CONFIG_SIZE)
            assert_true(o.hi <= 9223372036854775807.0);
        assert_true(o.lo <= o.hi && o.lo >= 0);
        char below[64] = "-1", above[64];
        if (o.kind == SMD_CONFIG_DURATION) {
            if (o.lo > 0)
                snprintf(below, sizeof below, "%.17g", o.lo / 2);
            snprintf(above, sizeof above, "%.17g", o.hi * 2);
        } else {
            if (o.lo >= 1)
                snprintf(below, sizeof below, "%.0f", o.lo - 1);
            snprintf(above, sizeof above, "%.0f", o.hi + 1 > o.hi ? o.hi + 1 : o.hi * 2);
        }
        const char *bad[] = {below, above, "18446744073709551616",
                             "123456789012345678901234567890123456789012345678901234567890",
                             "1e400", "nan", "inf", "", "0x10", " 1", "1 "};
        for (size_t k = 0; k < sizeof bad / sizeof bad[0]; k++) {
            smd_config c;
            char msg[512] = "";
            if (parse(&c, NULL, msg, o.flag, bad[k], NULL) != SMD_CONFIG_ERROR)
                fail_msg("%s %s was accepted", o.flag, bad[k]);
            if (strncmp(msg, o.flag, strlen(o.flag)) != 0)
                fail_msg("%s %s: the message does not start with the flag: %s", o.flag, bad[k], msg);
        }
    }
    assert_true(rows >= 30); /* the walk saw the table */
}

static void test_help_lists_everything(void **state)
{
    (void)state;
    char *text = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&text, &len);
    assert_non_null(f);
    smd_config_help(f);
    fclose(f);
    const char *must[] = {"--listen", "--spool", "--workers", "--tokens-file", "--max-upload",
                          "--job-timeout", "--retention", "--cpu-limit", "--memory-limit",
                          "SHAPEMATCH_LISTEN", "SHAPEMATCH_SPOOL", "SHAPEMATCH_RETENTION",
                          "--connection-timeout", "--max-connections-per-ip"};
    for (size_t i = 0; i < sizeof must / sizeof must[0]; i++)
        assert_non_null(strstr(text, must[i]));
    free(text);
}

static void test_tokens(void **state)
{
    (void)state;
    const char *file = "# ops tokens\n\n   alpha-0123456789   \r\n# beta retired\ngamma-9876543210\n";
    smd_tokens *t;
    char msg[256];
    assert_int_equal(smd_tokens_parse(file, strlen(file), "tokens", &t, msg, sizeof msg), 0);
    assert_int_equal(smd_tokens_count(t), 2);
    assert_int_equal(smd_tokens_check(t, "Bearer alpha-0123456789"), SMD_AUTH_OK);
    assert_int_equal(smd_tokens_check(t, "bearer gamma-9876543210"), SMD_AUTH_OK);
    assert_int_equal(smd_tokens_check(t, "Bearer   gamma-9876543210  "), SMD_AUTH_OK);
    assert_int_equal(smd_tokens_check(t, NULL), SMD_AUTH_MISSING);
    assert_int_equal(smd_tokens_check(t, ""), SMD_AUTH_MISSING);
    assert_int_equal(smd_tokens_check(t, "Basic alpha-0123456789"), SMD_AUTH_MISSING);
    assert_int_equal(smd_tokens_check(t, "Beareralpha-0123456789"), SMD_AUTH_MISSING);
    assert_int_equal(smd_tokens_check(t, "Bearer alpha-012345678"), SMD_AUTH_INVALID);
    assert_int_equal(smd_tokens_check(t, "Bearer alpha-01234567890"), SMD_AUTH_INVALID);
    assert_int_equal(smd_tokens_check(t, "Bearer beta"), SMD_AUTH_INVALID);
    assert_int_equal(smd_tokens_check(t, "Bearer # ops tokens"), SMD_AUTH_INVALID);
    assert_int_equal(smd_tokens_check(t, "Bearer "), SMD_AUTH_INVALID);
    smd_tokens_free(t);

    /* "TOKEN NAME [admin]": a third word must be "admin", a name is a
     * plain word */
    const char *inner = "good-token\nbad token extra\n";
    assert_int_equal(smd_tokens_parse(inner, strlen(inner), "tokens", &t, msg, sizeof msg), -1);
    assert_non_null(strstr(msg, "tokens:2:"));
    assert_null(t);
    const char *badname = "tok-1 al/ice\n";
    assert_int_equal(smd_tokens_parse(badname, strlen(badname), "tokens", &t, msg, sizeof msg), -1);
    assert_non_null(strstr(msg, "tokens:1: a tenant name"));
    const char *ctl = "tok\x01en alice\n";
    assert_int_equal(smd_tokens_parse(ctl, strlen(ctl), "tokens", &t, msg, sizeof msg), -1);
    const char *tenants = "tok-a alice\ntok-b\tbob  admin\ntok-c\n";
    assert_int_equal(smd_tokens_parse(tenants, strlen(tenants), "tokens", &t, msg, sizeof msg), 0);
    assert_int_equal(smd_tokens_count(t), 3);
    smd_identity who;
    assert_int_equal(smd_tokens_identify(t, "Bearer tok-a", &who), SMD_AUTH_OK);
    assert_string_equal(who.tenant, "alice");
    assert_int_equal(who.admin, 0);
    assert_int_equal(smd_tokens_identify(t, "Bearer tok-b", &who), SMD_AUTH_OK);
    assert_string_equal(who.tenant, "bob");
    assert_int_equal(who.admin, 1);
    assert_int_equal(smd_tokens_identify(t, "Bearer tok-c", &who), SMD_AUTH_OK);
    assert_string_equal(who.tenant, ""); /* the original form: an unnamed admin */
    assert_int_equal(who.admin, 1);
    assert_int_equal(smd_tokens_identify(t, "Bearer alice", &who), SMD_AUTH_INVALID);
    smd_tokens_free(t);
    const char *none = "# nothing\n\n";
    assert_int_equal(smd_tokens_parse(none, strlen(none), "tokens", &t, msg, sizeof msg), -1);
    assert_non_null(strstr(msg, "no token"));
    assert_int_equal(smd_tokens_load("/nonexistent/tokens", &t, msg, sizeof msg), -1);
    assert_non_null(strstr(msg, "/nonexistent/tokens"));
}

/* --cors-origin: repeatable, the variable a comma list that the first
 * flag replaces; exact origins only; '*' refused with tokens. */
static void test_cors_origins(void **state)
{
    (void)state;
    smd_config c;
    char msg[512];
    const char *env[] = {"SHAPEMATCH_CORS_ORIGINS=http://a.test, https://b.test:8443", NULL};
    assert_int_equal(parse(&c, env, msg, NULL), SMD_CONFIG_OK);
    assert_int_equal(c.ncors_origins, 2);
    assert_string_equal(c.cors_origins[0], "http://a.test");
    assert_string_equal(c.cors_origins[1], "https://b.test:8443");
    assert_int_equal(parse(&c, env, msg, "--cors-origin", "http://c.test", "--cors-origin=*", NULL),
                     SMD_CONFIG_OK);
    assert_int_equal(c.ncors_origins, 2);
    assert_string_equal(c.cors_origins[0], "http://c.test");
    assert_string_equal(c.cors_origins[1], "*");
    const char *bad[] = {"https://a.test/", "a.test", "ftp://a.test", "http://", "http://u@a.test",
                         "http://a.test?x", ""};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        assert_int_equal(parse(&c, NULL, msg, "--cors-origin", bad[i], NULL), SMD_CONFIG_ERROR);
        assert_non_null(strstr(msg, "--cors-origin"));
    }
    assert_int_equal(parse(&c, NULL, msg, "--tokens-file", "t", "--cors-origin", "*", NULL),
                     SMD_CONFIG_ERROR);
    assert_non_null(strstr(msg, "refused with --tokens-file"));
    assert_int_equal(parse(&c, NULL, msg, "--public-url", "https://x.test/p", NULL), SMD_CONFIG_OK);
    assert_string_equal(c.public_url, "https://x.test/p");
    assert_int_equal(parse(&c, NULL, msg, "--public-url", "x.test", NULL), SMD_CONFIG_ERROR);
    /* --allowed-host: the same list rules, host names with an optional port */
    const char *henv[] = {"SHAPEMATCH_ALLOWED_HOSTS=maps.example.test, [::1]:8080", NULL};
    assert_int_equal(parse(&c, henv, msg, NULL), SMD_CONFIG_OK);
    assert_int_equal(c.nallowed_hosts, 2);
    assert_string_equal(c.allowed_hosts[1], "[::1]:8080");
    assert_int_equal(parse(&c, henv, msg, "--allowed-host", "a.test:9000", NULL), SMD_CONFIG_OK);
    assert_int_equal(c.nallowed_hosts, 1);
    assert_string_equal(c.allowed_hosts[0], "a.test:9000");
    const char *badh[] = {"http://a.test", "a.test/", "a.test:", "a.test:x", "[::1", "a b", ":80", ""};
    for (size_t i = 0; i < sizeof badh / sizeof badh[0]; i++) {
        assert_int_equal(parse(&c, NULL, msg, "--allowed-host", badh[i], NULL), SMD_CONFIG_ERROR);
        assert_non_null(strstr(msg, "--allowed-host"));
    }
}

/* Several machines: --database, --role, --max-attempts, --lease. */
static void test_cluster(void **state)
{
    (void)state;
    smd_config c;
    char msg[512];
    assert_int_equal(parse(&c, NULL, msg, NULL), SMD_CONFIG_OK);
    assert_string_equal(c.database, "");
    assert_int_equal(c.role, SMD_ROLE_ALL);
    assert_int_equal(c.max_attempts, 3);
    assert_true(c.lease == 30);
    const char *env[] = {"SHAPEMATCH_DATABASE_URL=postgresql://db.test/sm?sslmode=require",
                         "SHAPEMATCH_ROLE=worker", NULL};
    assert_int_equal(parse(&c, env, msg, "--max-attempts", "5", "--lease", "1m", NULL), SMD_CONFIG_OK);
    assert_string_equal(c.database, "postgresql://db.test/sm?sslmode=require");
    assert_int_equal(c.role, SMD_ROLE_WORKER);
    assert_int_equal(c.max_attempts, 5);
    assert_true(c.lease == 60);
    /* the database sessions' timeouts: defaults, flags, bounds */
    assert_true(c.db_statement_timeout == 30 && c.db_lock_timeout == 5 && c.db_idle_timeout == 15);
    assert_int_equal(parse(&c, env, msg, "--database-lock-timeout", "0.5",
                           "--database-statement-timeout", "2m", "--database-idle-timeout", "10",
                           NULL), SMD_CONFIG_OK);
    assert_true(c.db_lock_timeout == 0.5 && c.db_statement_timeout == 120 && c.db_idle_timeout == 10);
    assert_int_equal(parse(&c, env, msg, "--database-lock-timeout", "0", NULL), SMD_CONFIG_ERROR);
    assert_non_null(strstr(msg, "--database-lock-timeout"));
    assert_int_equal(parse(&c, env, msg, "--role", "api", "--database", "host=/s dbname=x", NULL),
                     SMD_CONFIG_OK);
    assert_int_equal(c.role, SMD_ROLE_API);
    assert_string_equal(c.database, "host=/s dbname=x");
    assert_int_equal(parse(&c, NULL, msg, "--role", "api", NULL), SMD_CONFIG_ERROR);
    assert_non_null(strstr(msg, "--role api needs --database"));
    assert_int_equal(parse(&c, NULL, msg, "--role", "boss", NULL), SMD_CONFIG_ERROR);
    assert_non_null(strstr(msg, "expected all, api or worker"));
    assert_int_equal(parse(&c, NULL, msg, "--database-password-file", "/p", NULL), SMD_CONFIG_ERROR);
    assert_non_null(strstr(msg, "needs --database"));
    assert_int_equal(parse(&c, NULL, msg, "--max-attempts", "0", NULL), SMD_CONFIG_ERROR);
    char longurl[SMD_DATABASE_URL_MAX + 8];
    memset(longurl, 'h', sizeof longurl - 1);
    longurl[sizeof longurl - 1] = '\0';
    assert_int_equal(parse(&c, NULL, msg, "--database", longurl, NULL), SMD_CONFIG_ERROR);
    assert_non_null(strstr(msg, "--database: at most"));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_defaults),
        cmocka_unit_test(test_env_and_flags),
        cmocka_unit_test(test_errors),
        cmocka_unit_test(test_numeric_options_bounded),
        cmocka_unit_test(test_help_lists_everything),
        cmocka_unit_test(test_tokens),
        cmocka_unit_test(test_cors_origins),
        cmocka_unit_test(test_cluster),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
