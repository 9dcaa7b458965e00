/* Connection registry and deadline sweep (see smd_conns.h). */
#include "http/smd_conns.h"

#include <arpa/inet.h>
#include <errno.h>
#include <netinet/in.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>

#include "http/smd_ratelimit.h"
#include "shapematch/sm_clock.h"

typedef enum phase { PHASE_HEADERS, PHASE_REQUEST } phase;

typedef struct conn_ctx {
    struct conn_ctx *prev, *next;
    int fd;
    phase phase;
    double since;         /* the phase began (monotonic) */
    int receiving;        /* a body is being read */
    int stream;           /* an event stream (smd_conns_stream) */
    double stream_since;  /* when it became one (monotonic): the oldest go first */
    int evicted;          /* a stream told to end for a newer one: no longer counted */
    double evicted_at;    /* monotonic: a client that does not read is cut after
                           * SMD_CONNS_BUSY_HEADERS (its final comment never leaves) */
    struct MHD_Connection *conn;
    char addr[64];        /* the client's address (smd_conn_address) */
    char key[SMD_RATELIMIT_KEY_MAX + 1]; /* what the per-address caps count it by */
    uint64_t body_bytes;
    double progress;      /* the body's last new byte (monotonic) */
    int closing;          /* shut down by us: wait for the close */
    struct smd_conns *owner;
} conn_ctx;

struct smd_conns {
    smd_conns_limits limits;
    pthread_mutex_t mutex;
    pthread_cond_t wake;
    conn_ctx *head;
    size_t open;
    smd_conns_counts counts;
    int stop;
    pthread_t sweeper;
};

/* Mutex held.  Shuts the socket down; its close comes from libmicrohttpd. */
static void cut(conn_ctx *x)
{
    x->closing = 1;
    shutdown(x->fd, SHUT_RDWR);
}

/* The oldest connection still in its headers for more than the busy
 * delay, or NULL.  Mutex held. */
static conn_ctx *oldest_slow_headers(smd_conns *c, double now)
{
    conn_ctx *best = NULL;
    for (conn_ctx *x = c->head; x; x = x->next)
        if (!x->closing && x->phase == PHASE_HEADERS && now - x->since > SMD_CONNS_BUSY_HEADERS &&
            (!best || x->since < best->since))
            best = x;
    return best;
}

/* The upload (a body being read for more than the busy delay) with the
 * lowest average rate, or NULL.  Mutex held. */
static conn_ctx *slowest_upload(smd_conns *c, double now)
{
    conn_ctx *best = NULL;
    double best_rate = 0;
    for (conn_ctx *x = c->head; x; x = x->next) {
        double age = now - x->since;
        if (x->closing || !x->receiving || age <= SMD_CONNS_BUSY_HEADERS)
            continue;
        double rate = (double)x->body_bytes / age;
        if (!best || rate < best_rate) {
            best = x;
            best_rate = rate;
        }
    }
    return best;
}

/* Frees the reserve by closing slow header senders, then the slowest
 * uploads (event streams are capped instead, smd_conns_stream: a
 * suspended one would notice a shutdown only at its next keepalive).
 * Mutex held. */
static void keep_reserve(smd_conns *c, double now)
{
    size_t busy = c->limits.max_connections - c->limits.reserved, closing = 0;
    for (conn_ctx *x = c->head; x; x = x->next)
        closing += x->closing;
    while (c->open - closing > busy) {
        conn_ctx *x = oldest_slow_headers(c, now);
        if (!x)
            x = slowest_upload(c, now);
        if (!x)
            return;
        cut(x);
        closing++;
        c->counts.evicted++;
    }
}

/* A connection over one of its deadlines (header time, body rate). */
static int overdue(const smd_conns *c, const conn_ctx *x, double now)
{
    double age = now - x->since;
    if (x->phase == PHASE_HEADERS)
        return age > c->limits.header_timeout;
    if (x->receiving && c->limits.body_stall > 0 && now - x->progress > c->limits.body_stall)
        return 1; /* a body that stopped: its average rate may still look fine */
    return x->receiving && c->limits.min_upload_rate && age > c->limits.header_timeout &&
           (double)x->body_bytes < (double)c->limits.min_upload_rate * age;
}

static void sweep(smd_conns *c, double now)
{
    for (conn_ctx *x = c->head; x; x = x->next) {
        if (!x->closing && x->evicted && now - x->evicted_at > SMD_CONNS_BUSY_HEADERS) {
            cut(x); /* no longer counted: it must not outlive its room */
            continue;
        }
        if (x->closing || !overdue(c, x, now))
            continue;
        if (x->phase == PHASE_HEADERS)
            c->counts.header_deadline++;
        else
            c->counts.slow_body++;
        cut(x);
    }
    keep_reserve(c, now);
}

static void *sweeper_main(void *arg)
{
    smd_conns *c = arg;
    pthread_mutex_lock(&c->mutex);
    while (!c->stop) {
        struct timespec ts;
        clock_gettime(CLOCK_REALTIME, &ts);
        long ns = ts.tv_nsec + (long)(SMD_CONNS_SWEEP * 1e9);
        ts.tv_sec += ns / 1000000000L;
        ts.tv_nsec = ns % 1000000000L;
        pthread_cond_timedwait(&c->wake, &c->mutex, &ts);
        if (!c->stop)
            sweep(c, sm_clock_seconds());
    }
    pthread_mutex_unlock(&c->mutex);
    return NULL;
}

smd_conns *smd_conns_new(const smd_conns_limits *limits, sm_error *err)
{
    smd_conns *c = calloc(1, sizeof *c);
    if (!c) {
        sm_error_set(err, SM_ERR_NOMEM, "out of memory");
        return NULL;
    }
    c->limits = *limits;
    if (c->limits.reserved >= c->limits.max_connections)
        c->limits.reserved = c->limits.max_connections ? c->limits.max_connections - 1 : 0;
    pthread_mutex_init(&c->mutex, NULL);
    pthread_cond_init(&c->wake, NULL);
    int rc = pthread_create(&c->sweeper, NULL, sweeper_main, c);
    if (rc != 0) {
        sm_error_set(err, SM_ERR_IO, "cannot start the connection sweep: %s", strerror(rc));
        pthread_cond_destroy(&c->wake);
        pthread_mutex_destroy(&c->mutex);
        free(c);
        return NULL;
    }
    return c;
}

void smd_conns_free(smd_conns *c)
{
    if (!c)
        return;
    pthread_mutex_lock(&c->mutex);
    c->stop = 1;
    pthread_cond_signal(&c->wake);
    pthread_mutex_unlock(&c->mutex);
    pthread_join(c->sweeper, NULL);
    while (c->head) { /* connections the daemon did not report closed */
        conn_ctx *x = c->head;
        c->head = x->next;
        free(x);
    }
    pthread_cond_destroy(&c->wake);
    pthread_mutex_destroy(&c->mutex);
    free(c);
}

static void opened(smd_conns *c, struct MHD_Connection *conn, void **socket_context)
{
    const union MHD_ConnectionInfo *ci = MHD_get_connection_info(conn, MHD_CONNECTION_INFO_CONNECTION_FD);
    conn_ctx *x = calloc(1, sizeof *x);
    if (!x || !ci) {
        free(x); /* untracked: libmicrohttpd's own limits still apply */
        return;
    }
    x->fd = ci->connect_fd;
    x->conn = conn;
    smd_conn_address(conn, x->addr, sizeof x->addr);
    smd_ratelimit_address_key(x->addr, c->limits.ipv4_prefix ? c->limits.ipv4_prefix : 32, x->key,
                              sizeof x->key);
    x->owner = c;
    x->phase = PHASE_HEADERS;
    x->since = sm_clock_seconds();
    pthread_mutex_lock(&c->mutex);
    x->next = c->head;
    if (c->head)
        c->head->prev = x;
    c->head = x;
    c->open++;
    keep_reserve(c, x->since);
    pthread_mutex_unlock(&c->mutex);
    *socket_context = x;
}

void smd_conns_notify(void *cls, struct MHD_Connection *conn, void **socket_context,
                      enum MHD_ConnectionNotificationCode code)
{
    smd_conns *c = cls;
    if (code == MHD_CONNECTION_NOTIFY_STARTED) {
        opened(c, conn, socket_context);
        return;
    }
    conn_ctx *x = *socket_context;
    if (!x)
        return;
    pthread_mutex_lock(&c->mutex);
    if (x->prev)
        x->prev->next = x->next;
    else
        c->head = x->next;
    if (x->next)
        x->next->prev = x->prev;
    c->open--;
    pthread_mutex_unlock(&c->mutex);
    free(x);
    *socket_context = NULL;
}

/* The record of conn (NULL if untracked). */
static conn_ctx *ctx_of(struct MHD_Connection *conn)
{
    const union MHD_ConnectionInfo *ci = MHD_get_connection_info(conn, MHD_CONNECTION_INFO_SOCKET_CONTEXT);
    return ci ? ci->socket_context : NULL;
}

/* 1 when y holds a long-lived request (a body, a stream) that counts. */
static int long_lived(const conn_ctx *y)
{
    return !y->closing && !y->evicted && (y->receiving || y->stream);
}

/* The long-lived requests of key, x aside.  Mutex held. */
static size_t long_of(const smd_conns *c, const conn_ctx *x, const char *key)
{
    size_t n = 0;
    for (const conn_ctx *y = c->head; y; y = y->next)
        n += y != x && long_lived(y) && strcmp(y->key, key) == 0;
    return n;
}

/* 1 when x may not become long-lived (a body, a stream): its address
 * holds max_long_per_ip of them, or all hold max_connections - reserved.
 * Mutex held. */
static int long_full(const smd_conns *c, const conn_ctx *x)
{
    size_t all = 0;
    for (const conn_ctx *y = c->head; y; y = y->next)
        all += y != x && long_lived(y);
    return (c->limits.max_long_per_ip && long_of(c, x, x->key) >= c->limits.max_long_per_ip) ||
           all >= c->limits.max_connections - c->limits.reserved;
}

int smd_conns_request(struct MHD_Connection *conn, int receiving)
{
    conn_ctx *x = ctx_of(conn);
    if (!x)
        return 0;
    pthread_mutex_lock(&x->owner->mutex);
    int refused = receiving && long_full(x->owner, x);
    if (refused)
        x->owner->counts.long_refused++;
    x->phase = PHASE_REQUEST;
    x->since = sm_clock_seconds();
    x->receiving = receiving && !refused;
    x->body_bytes = 0;
    x->progress = x->since;
    pthread_mutex_unlock(&x->owner->mutex);
    return refused ? -1 : 0;
}

/* The oldest stream of key, x aside; NULL when it has none. */
static conn_ctx *oldest_of(const smd_conns *c, const conn_ctx *x, const char *key)
{
    conn_ctx *best = NULL;
    for (conn_ctx *y = c->head; y; y = y->next)
        if (y != x && y->stream && long_lived(y) && strcmp(y->key, key) == 0 &&
            (!best || y->stream_since < best->stream_since))
            best = y;
    return best;
}

/* One address's long-lived requests (x counted with its own) and its
 * oldest stream. */
typedef struct tally {
    const char *key;
    size_t n;
    conn_ctx *oldest;
} tally;

/* The tallies of the addresses holding long-lived requests, x's among
 * them, into t (room for every open connection + 1); how many.  Mutex
 * held; linear in the connections times the addresses. */
static size_t tally_addresses(const smd_conns *c, const conn_ctx *x, tally *t)
{
    size_t k = 1;
    t[0] = (tally){x->key, 1, NULL};
    for (conn_ctx *y = c->head; y; y = y->next) {
        if (y == x || !long_lived(y))
            continue;
        size_t i = 0;
        while (i < k && strcmp(t[i].key, y->key) != 0)
            i++;
        if (i == k)
            t[k++] = (tally){y->key, 0, NULL};
        t[i].n++;
        if (y->stream && (!t[i].oldest || y->stream_since < t[i].oldest->stream_since))
            t[i].oldest = y;
    }
    return k;
}

/* The stream whose end makes room for x: at its address's cap, that
 * address's oldest; else the oldest of the address most over its fair
 * share (the total cap over the addresses holding long-lived requests,
 * x's counted; at least 1), x counted with its own; ties: the older
 * stream.  NULL when none would (no address over its share, or it holds
 * only bodies).  Mutex held. */
static conn_ctx *stream_to_evict(const smd_conns *c, const conn_ctx *x)
{
    if (c->limits.max_long_per_ip && long_of(c, x, x->key) >= c->limits.max_long_per_ip)
        return oldest_of(c, x, x->key);
    tally *t = malloc((c->open + 1) * sizeof *t);
    if (!t)
        return NULL;
    size_t k = tally_addresses(c, x, t);
    size_t share = (c->limits.max_connections - c->limits.reserved) / k;
    if (share == 0)
        share = 1;
    const tally *best = NULL;
    for (size_t i = 0; i < k; i++) {
        if (t[i].n <= share || !t[i].oldest)
            continue; /* within its share: never evicted for another */
        if (!best || t[i].n > best->n ||
            (t[i].n == best->n && t[i].oldest->stream_since < best->oldest->stream_since))
            best = &t[i];
    }
    conn_ctx *old = best ? best->oldest : NULL;
    free(t);
    return old;
}

int smd_conns_stream(struct MHD_Connection *conn, struct MHD_Connection **evict)
{
    *evict = NULL;
    conn_ctx *x = ctx_of(conn);
    if (!x)
        return 0;
    pthread_mutex_lock(&x->owner->mutex);
    int refused = long_full(x->owner, x);
    if (refused) {
        /* the newest client is served: the oldest stream is told to end
         * (it reconnects with Last-Event-ID and loses nothing) */
        conn_ctx *old = stream_to_evict(x->owner, x);
        if (old) {
            old->evicted = 1;
            old->evicted_at = sm_clock_seconds();
            *evict = old->conn;
            x->owner->counts.streams_evicted++;
            refused = long_full(x->owner, x);
        }
    }
    if (refused) {
        x->owner->counts.long_refused++;
    } else {
        x->stream = 1;
        x->stream_since = sm_clock_seconds();
    }
    pthread_mutex_unlock(&x->owner->mutex);
    return refused ? -1 : 0;
}

void smd_conns_body(struct MHD_Connection *conn, uint64_t bytes)
{
    conn_ctx *x = ctx_of(conn);
    if (!x)
        return;
    pthread_mutex_lock(&x->owner->mutex);
    if (bytes > x->body_bytes)
        x->progress = sm_clock_seconds();
    x->body_bytes = bytes;
    pthread_mutex_unlock(&x->owner->mutex);
}

void smd_conns_body_done(struct MHD_Connection *conn)
{
    conn_ctx *x = ctx_of(conn);
    if (!x)
        return;
    pthread_mutex_lock(&x->owner->mutex);
    x->receiving = 0;
    pthread_mutex_unlock(&x->owner->mutex);
}

void smd_conns_idle(struct MHD_Connection *conn)
{
    conn_ctx *x = ctx_of(conn);
    if (!x)
        return;
    pthread_mutex_lock(&x->owner->mutex);
    x->phase = PHASE_HEADERS;
    x->since = sm_clock_seconds();
    x->receiving = 0;
    x->stream = 0;
    if (x->evicted && !x->closing)
        cut(x); /* an evicted stream's socket goes too: its client reconnects anyway */
    x->evicted = 0;
    pthread_mutex_unlock(&x->owner->mutex);
}

void smd_conns_get_counts(smd_conns *c, smd_conns_counts *out)
{
    memset(out, 0, sizeof *out);
    if (!c)
        return;
    pthread_mutex_lock(&c->mutex);
    *out = c->counts;
    out->open = c->open;
    pthread_mutex_unlock(&c->mutex);
}

void smd_conn_address(struct MHD_Connection *conn, char *buf, size_t cap)
{
    snprintf(buf, cap, "?");
    const union MHD_ConnectionInfo *ci = MHD_get_connection_info(conn, MHD_CONNECTION_INFO_CLIENT_ADDRESS);
    if (!ci || !ci->client_addr || cap < INET6_ADDRSTRLEN)
        return;
    const struct sockaddr *sa = ci->client_addr;
    if (sa->sa_family == AF_INET)
        inet_ntop(AF_INET, &((const struct sockaddr_in *)sa)->sin_addr, buf, (socklen_t)cap);
    else if (sa->sa_family == AF_INET6)
        inet_ntop(AF_INET6, &((const struct sockaddr_in6 *)sa)->sin6_addr, buf, (socklen_t)cap);
}
