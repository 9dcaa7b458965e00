/* Fixed-window submission counters and tracked unfinished jobs per key
 * (see smd_ratelimit.h). */
#include "http/smd_ratelimit.h"

#include <math.h>
#include <arpa/inet.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct entry {
    char key[SMD_RATELIMIT_KEY_MAX + 1]; /* "" = free */
    double window_start;
    double last;                          /* its last submission: eviction order */
    unsigned count;
    char (*ids)[SMD_ID_LEN + 1];          /* tracked jobs (no tokens) */
    size_t nids, cap;
} entry;

struct smd_ratelimit {
    pthread_mutex_t mutex;
    unsigned rate;
    double window;
    entry *entries; /* SMD_RATELIMIT_KEYS */
};

smd_ratelimit *smd_ratelimit_new(unsigned rate, double window)
{
    smd_ratelimit *rl = calloc(1, sizeof *rl);
    if (!rl)
        return NULL;
    rl->entries = calloc(SMD_RATELIMIT_KEYS, sizeof *rl->entries);
    if (!rl->entries) {
        free(rl);
        return NULL;
    }
    pthread_mutex_init(&rl->mutex, NULL);
    rl->rate = rate;
    rl->window = window > 0 ? window : 60;
    return rl;
}

void smd_ratelimit_free(smd_ratelimit *rl)
{
    if (!rl)
        return;
    for (size_t i = 0; i < SMD_RATELIMIT_KEYS; i++)
        free(rl->entries[i].ids);
    free(rl->entries);
    pthread_mutex_destroy(&rl->mutex);
    free(rl);
}

/* The room a new key takes, never none: a free entry, else one whose
 * window passed and that tracks no job, else the least recently used of
 * those that track no job, else the least recently used (its tracked
 * jobs are forgotten: that address's --max-queued count starts again).
 * So a flood of throw-away keys evicts idle ones instead of shutting
 * every new key out.  Mutex held. */
static entry *victim(smd_ratelimit *rl, double now)
{
    entry *lru_free = NULL, *lru = NULL;
    for (size_t i = 0; i < SMD_RATELIMIT_KEYS; i++) {
        entry *e = &rl->entries[i];
        if (!e->key[0] || (now - e->window_start >= rl->window && e->nids == 0))
            return e;
        if (e->nids == 0 && (!lru_free || e->last < lru_free->last))
            lru_free = e;
        if (!lru || e->last < lru->last)
            lru = e;
    }
    return lru_free ? lru_free : lru;
}

/* The entry of key, or (create) a new one made its own.  Mutex held. */
static entry *find(smd_ratelimit *rl, const char *key, double now, int create)
{
    for (size_t i = 0; i < SMD_RATELIMIT_KEYS; i++) {
        entry *e = &rl->entries[i];
        if (e->key[0] && strcmp(e->key, key) == 0)
            return e;
    }
    if (!create)
        return NULL;
    entry *spare = victim(rl, now);
    snprintf(spare->key, sizeof spare->key, "%s", key);
    spare->window_start = now;
    spare->count = 0;
    spare->nids = 0;
    spare->last = now;
    return spare;
}

unsigned smd_ratelimit_take(smd_ratelimit *rl, const char *key, double now)
{
    if (!rl || rl->rate == 0)
        return 0;
    unsigned wait = 0;
    pthread_mutex_lock(&rl->mutex);
    entry *e = find(rl, key, now, 1);
    e->last = now;
    if (now - e->window_start >= rl->window) {
        e->window_start = now;
        e->count = 0;
    }
    if (e->count >= rl->rate) {
        double left = e->window_start + rl->window - now;
        wait = left < 1 ? 1 : (unsigned)ceil(left);
    } else {
        e->count++;
    }
    pthread_mutex_unlock(&rl->mutex);
    return wait;
}

void smd_ratelimit_track(smd_ratelimit *rl, const char *key, const char *id)
{
    if (!rl)
        return;
    pthread_mutex_lock(&rl->mutex);
    entry *e = find(rl, key, -1e300, 1); /* an old stamp: the rate window is not restarted */
    if (e->window_start == -1e300) /* made here (its own was evicted): idle since */
        e->last = -1e300;
    if (e->nids == e->cap) {
        size_t cap = e->cap ? 2 * e->cap : 8;
        void *p = realloc(e->ids, cap * sizeof *e->ids);
        if (p) {
            e->ids = p;
            e->cap = cap;
        }
    }
    if (e->nids < e->cap)
        snprintf(e->ids[e->nids++], sizeof e->ids[0], "%s", id);
    pthread_mutex_unlock(&rl->mutex);
}

size_t smd_ratelimit_live(smd_ratelimit *rl, const char *key, smd_ratelimit_live_fn live,
                          void *user)
{
    if (!rl)
        return 0;
    size_t n = 0;
    pthread_mutex_lock(&rl->mutex);
    entry *e = find(rl, key, 0, 0);
    for (size_t i = 0; e && i < e->nids; i++)
        if (live(e->ids[i], user))
            memmove(e->ids[n++], e->ids[i], sizeof e->ids[0]);
    if (e)
        e->nids = n;
    pthread_mutex_unlock(&rl->mutex);
    return n;
}

void smd_ratelimit_address_key(const char *addr, unsigned ipv4_prefix, char *key, size_t cap)
{
    char net[INET6_ADDRSTRLEN + 8];
    snprintf(net, sizeof net, "%s", addr);
    struct in6_addr a6;
    struct in_addr a4;
    int v4 = inet_pton(AF_INET, addr, &a4) == 1;
    if (!v4 && strchr(addr, ':') && inet_pton(AF_INET6, addr, &a6) == 1) {
        if (IN6_IS_ADDR_V4MAPPED(&a6)) {
            memcpy(&a4, a6.s6_addr + 12, 4); /* an IPv4 client on a dual-stack socket */
            v4 = 1;
        } else {
            memset(a6.s6_addr + 8, 0, 8);
            if (inet_ntop(AF_INET6, &a6, net, sizeof net))
                strncat(net, "/64", sizeof net - strlen(net) - 1);
        }
    }
    if (v4) {
        unsigned bits = ipv4_prefix < 8 ? 8 : ipv4_prefix > 32 ? 32 : ipv4_prefix;
        uint32_t mask = bits == 32 ? 0xffffffffu : ~(0xffffffffu >> bits);
        a4.s_addr = htonl(ntohl(a4.s_addr) & mask);
        if (inet_ntop(AF_INET, &a4, net, sizeof net) && bits < 32)
            snprintf(net + strlen(net), sizeof net - strlen(net), "/%u", bits);
    }
    snprintf(key, cap, "a:%s", net);
}
