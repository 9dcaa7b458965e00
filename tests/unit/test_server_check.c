/* The upload check pool's fair shares (smd_check.h, issue 37), without
 * HTTP: the checks of one client wait on a gate file (they run in forked
 * children in the release build, in the check threads under the
 * sanitizers), so which of them run and which wait is a state, not a
 * race.  One client holds at most --check-threads - 1 slots and another
 * client's check runs at once; waiting checks start in arrival order; one
 * client may keep SMD_CHECK_WAITING_PER_CLIENT waiting, and no more. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "jobs/smd_check.h"
#include "shapematch/sm_clock.h"

#define NTASKS (SMD_CHECK_WAITING_PER_CLIENT + 8)

typedef struct harness {
    char gate[64];
    pthread_mutex_t mutex;
    pthread_cond_t cond;
    int done[NTASKS];  /* completion rank + 1, 0 while not done */
    int ndone;
    smd_check_result out[NTASKS];
} harness;

typedef struct task_arg {
    harness *h;
    int index;
    int gated;
} task_arg;

static task_arg args[NTASKS];

/* The check: a gated one waits for the gate file (30 s at most). */
static void check_fn(void *arg, smd_check_result *out)
{
    task_arg *a = arg;
    double until = sm_clock_seconds() + 30;
    while (a->gated && access(a->h->gate, F_OK) != 0 && sm_clock_seconds() < until)
        usleep(5000);
    out->status = SM_OK;
    out->nverts = a->index;
}

static void done_fn(void *user)
{
    task_arg *a = user;
    harness *h = a->h;
    pthread_mutex_lock(&h->mutex);
    h->done[a->index] = ++h->ndone;
    pthread_cond_broadcast(&h->cond);
    pthread_mutex_unlock(&h->mutex);
}

static int submit(smd_check_pool *p, harness *h, int i, const char *key, int gated)
{
    args[i] = (task_arg){h, i, gated};
    return smd_check_submit_from(p, key, check_fn, &args[i], &h->out[i], done_fn, &args[i]);
}

/* Waits (10 s at most) until task i is done; 1 when it is. */
static int wait_done(harness *h, int i)
{
    double until = sm_clock_seconds() + 10;
    pthread_mutex_lock(&h->mutex);
    while (!h->done[i] && sm_clock_seconds() < until) {
        pthread_mutex_unlock(&h->mutex);
        usleep(5000);
        pthread_mutex_lock(&h->mutex);
    }
    int d = h->done[i];
    pthread_mutex_unlock(&h->mutex);
    return d != 0;
}

/* Waits (10 s at most) for the pool's counts. */
static int wait_counts(smd_check_pool *p, uint64_t running, uint64_t waiting)
{
    double until = sm_clock_seconds() + 10;
    uint64_t r, w;
    for (;;) {
        smd_check_counts(p, &r, &w);
        if ((r == running && w == waiting) || sm_clock_seconds() > until)
            return r == running && w == waiting;
        usleep(5000);
    }
}

static void harness_init(harness *h)
{
    memset(h, 0, sizeof *h);
    snprintf(h->gate, sizeof h->gate, "/tmp/sm-check-gate-%d", (int)getpid());
    unlink(h->gate);
    pthread_mutex_init(&h->mutex, NULL);
    pthread_cond_init(&h->cond, NULL);
}

static void open_gate(harness *h)
{
    FILE *f = fopen(h->gate, "w");
    assert_non_null(f);
    fclose(f);
}

static void test_shares(void **state)
{
    (void)state;
    static harness h;
    harness_init(&h);
    sm_error err;
    sm_error_clear(&err);
    smd_check_pool *p = smd_check_pool_new(2, 60, 0, &err);
    assert_non_null(p);
    /* three slow checks of one client: one runs, two wait (before: two ran) */
    for (int i = 0; i < 3; i++)
        assert_int_equal(submit(p, &h, i, "a:192.0.2.1", 1), 0);
    assert_true(wait_counts(p, 1, 2));
    /* another client's check runs at once, on the slot kept free */
    assert_int_equal(submit(p, &h, 3, "a:2001:db8:1:2::/64", 0), 0);
    assert_true(wait_done(&h, 3));
    assert_int_equal(h.ndone, 1);
    assert_int_equal(h.out[3].nverts, 3);
    assert_true(wait_counts(p, 1, 2));
    open_gate(&h);
    for (int i = 0; i < 3; i++)
        assert_true(wait_done(&h, i));
    /* the client's own checks in their order */
    assert_true(h.done[0] < h.done[1] && h.done[1] < h.done[2]);
    for (int i = 0; i < 4; i++)
        smd_check_settled(p);
    smd_check_pool_stop(p, 5);
    smd_check_pool_free(p);
    unlink(h.gate);
}

static void test_waiting_per_client(void **state)
{
    (void)state;
    static harness h;
    harness_init(&h);
    sm_error err;
    sm_error_clear(&err);
    smd_check_pool *p = smd_check_pool_new(2, 60, 0, &err);
    assert_non_null(p);
    int n = 0;
    assert_int_equal(submit(p, &h, n++, "t:flood", 1), 0);
    assert_true(wait_counts(p, 1, 0));
    for (int i = 0; i < SMD_CHECK_WAITING_PER_CLIENT; i++)
        assert_int_equal(submit(p, &h, n++, "t:flood", 1), 0);
    assert_int_equal(submit(p, &h, n, "t:flood", 1), -2); /* its waiting share is full */
    assert_int_equal(submit(p, &h, n++, "t:other", 0), 0);  /* another's is not */
    assert_true(wait_done(&h, n - 1));
    open_gate(&h);
    for (int i = 0; i < n; i++) {
        assert_true(wait_done(&h, i));
        smd_check_settled(p);
    }
    smd_check_pool_stop(p, 5);
    smd_check_pool_free(p);
    unlink(h.gate);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_shares),
        cmocka_unit_test(test_waiting_per_client),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
