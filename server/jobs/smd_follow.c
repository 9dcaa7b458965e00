/* Followers of jobs' events (see smd_follow.h: the lock order is there). */
#include "jobs/smd_follow.h"
#include "store/spool/smd_store.h"

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "shapematch/sm_clock.h"
#include "sm_json.h"
#include "sm_proto_events.h"

#define READ_BATCH (256 * 1024) /* log bytes formatted per refill */
#define WAKE_INLINE 32          /* connections resumed without an allocation */

typedef struct smd_follower {
    smd_server *srv;
    smd_job *job;                 /* reference held */
    void *conn;                   /* the HTTP layer's connection */
    const smd_follow_waker *waker;
    int sse;
    int fd;                       /* events.ndjson, read-only (-1: not opened yet) */
    char path[PATH_MAX];
    int64_t next_seq;
    int suspended;                /* asleep (the waker's sleep), not yet collected */
    int keepalive_due;
    int done;                     /* final status queued: end after it */
    int revoked;                  /* its token was removed (SIGHUP): end now */
    int evicted;                  /* made room for a newer stream: say so, then end */
    char *authorization, *token;  /* the credential it was opened with (copies) */
    _Atomic double last_send;     /* monotonic; written by the reader, read by the tick */
    uint64_t *bytes_out;
    const smd_follow_source *src;  /* NULL: the job's log; else its events' maker */
    void *src_state;              /* owned, freed by src->free */
    char *buf;                    /* formatted bytes not yet handed out */
    size_t len, off, cap;
    struct smd_follower *job_next, *job_prev; /* same bucket of the table by job id */
    struct smd_follower *all_next, *all_prev;
    struct smd_follower *src_next, *src_prev; /* the streams with a source */
} smd_follower;

/* The streams, by srv->lock: every one in a list (keepalives, shutdown)
 * and in a hash table by job id (wake-ups of the jobs that changed), so
 * the job record knows nothing of who follows it. */
typedef struct smd_events {
    smd_follower *all;
    size_t n;
    smd_follower *sourced; /* woken by any job their source follows */
    smd_follower **bucket;
    size_t nbucket; /* a power of two */
} smd_events;

/* Followers to wake once the lock is released. */
typedef struct wake_list {
    smd_follower *inline_conns[WAKE_INLINE];
    smd_follower **conns;
    size_t n, cap;
} wake_list;

/* ------------------------------------------------------------ formatting */

int smd_sse_format(char **buf, size_t *len, size_t *cap, int64_t seq, const char *type,
                   const char *line, size_t line_len)
{
    char head[128];
    int n;
    if (seq >= 1)
        n = snprintf(head, sizeof head, "id: %lld\nevent: %s\ndata: ", (long long)seq, type);
    else
        n = snprintf(head, sizeof head, "event: %s\ndata: ", type);
    if (n < 0 || (size_t)n >= sizeof head)
        return -1;
    if (smd_buf_append(buf, len, cap, head, (size_t)n) != 0 ||
        smd_buf_append(buf, len, cap, line, line_len) != 0 || smd_buf_append(buf, len, cap, "\n\n", 2) != 0)
        return -1;
    return 0;
}

void smd_event_line_type(const char *line, size_t len, char *type, size_t cap)
{
    static const char key[] = "\"type\":\"";
    const size_t klen = sizeof key - 1;
    snprintf(type, cap, "message");
    for (size_t i = 0; i + klen <= len; i++) {
        if (memcmp(line + i, key, klen) != 0)
            continue;
        /* only a plain lowercase word makes it into the SSE "event:" line */
        size_t j = i + klen, k = j;
        while (k < len && ((line[k] >= 'a' && line[k] <= 'z') || line[k] == '_'))
            k++;
        if (k > j && k < len && line[k] == '"' && k - j < cap)
            snprintf(type, cap, "%.*s", (int)(k - j), line + j);
        return;
    }
}

/* The last event of a stream: the final status with the statusInfo
 * members. */
static int format_status(smd_follower *f)
{
    smd_job *job = f->job;
    sm_event ev;
    sm_event_init(&ev, SM_EVENT_STATUS);
    snprintf(ev.job_id, sizeof ev.job_id, "%s", job->id);
    ev.time = sm_time_now();
    ev.state = job->state;
    snprintf(ev.message, sizeof ev.message, "%s", job->removed ? "deleted" : job->message);
    json_t *o = sm_event_to_jansson(&ev);
    json_t *fields = smd_job_status_fields(job);
    if (!o || !fields) {
        json_decref(o);
        json_decref(fields);
        return -1;
    }
    const char *key;
    json_t *value;
    json_object_foreach(fields, key, value) {
        if (!json_object_get(o, key))
            json_object_set(o, key, value);
    }
    json_decref(fields);
    char *line = sm_json_dumps(o, 0);
    json_decref(o);
    if (!line)
        return -1;
    size_t n = strlen(line);
    int rc = f->sse ? smd_sse_format(&f->buf, &f->len, &f->cap, 0, "status", line, n)
                    : (smd_buf_append(&f->buf, &f->len, &f->cap, line, n) == 0 &&
                               smd_buf_append(&f->buf, &f->len, &f->cap, "\n", 1) == 0
                           ? 0
                           : -1);
    free(line);
    return rc;
}

/* Reads log bytes [from, to) and formats them into f->buf. */
static int format_events(smd_follower *f, uint64_t from, uint64_t to, int64_t first_seq)
{
    if (f->fd < 0 && (f->fd = open(f->path, O_RDONLY | O_CLOEXEC)) < 0)
        return -1; /* the log was created after the stream began */
    size_t n = (size_t)(to - from);
    char *raw = malloc(n ? n : 1);
    if (!raw)
        return -1;
    size_t got = 0;
    while (got < n) {
        ssize_t r = pread(f->fd, raw + got, n - got, (off_t)(from + got));
        if (r < 0 && errno == EINTR)
            continue;
        if (r <= 0)
            break;
        got += (size_t)r;
    }
    if (got < n) {
        free(raw);
        return -1;
    }
    int rc = 0;
    if (!f->sse) {
        rc = smd_buf_append(&f->buf, &f->len, &f->cap, raw, n);
    } else {
        int64_t seq = first_seq;
        size_t start = 0;
        for (size_t i = 0; i < n && rc == 0; i++) {
            if (raw[i] != '\n')
                continue;
            char type[32];
            smd_event_line_type(raw + start, i - start, type, sizeof type);
            rc = smd_sse_format(&f->buf, &f->len, &f->cap, seq++, type, raw + start, i - start);
            start = i + 1;
        }
    }
    free(raw);
    return rc;
}

/* ---------------------------------------------------------- the reader */

static ssize_t copy_out(smd_follower *f, char *out, size_t max)
{
    size_t n = f->len - f->off;
    if (n > max)
        n = max;
    memcpy(out, f->buf + f->off, n);
    f->off += n;
    if (f->off == f->len)
        f->off = f->len = 0;
    atomic_store(&f->last_send, sm_clock_seconds());
    if (f->bytes_out)
        *f->bytes_out += n;
    return (ssize_t)n;
}

/* Lock held (released here): the final status event, then the end. */
static ssize_t end_with_status(smd_follower *f, char *out, size_t max)
{
    int rc = format_status(f);
    pthread_mutex_unlock(&f->srv->lock);
    if (rc != 0)
        return SMD_FOLLOW_ERROR;
    f->done = 1;
    return copy_out(f, out, max);
}

/* Lock held (released here): ended to make room for a newer stream. */
static ssize_t end_evicted(smd_follower *f, char *out, size_t max)
{
    long long last = (long long)(f->next_seq - 1);
    pthread_mutex_unlock(&f->srv->lock);
    f->done = 1;
    if (!f->sse)
        return SMD_FOLLOW_END;
    char text[256];
    int n = snprintf(text, sizeof text,
                     ": evicted: this client holds more than its share of the daemon's event "
                     "streams; reconnect with Last-Event-ID: %lld\n\n", last);
    if (smd_buf_append(&f->buf, &f->len, &f->cap, text, (size_t)n) != 0)
        return SMD_FOLLOW_ERROR;
    return copy_out(f, out, max);
}

/* Lock held (released here): nothing new to send: the keepalive when due,
 * else sleep until someone collects and resumes us. */
static ssize_t idle(smd_follower *f, char *out, size_t max)
{
    smd_server *srv = f->srv;
    if (f->keepalive_due) {
        f->keepalive_due = 0;
        pthread_mutex_unlock(&srv->lock);
        const char *ka = f->sse ? ": keepalive\n\n" : "\n";
        if (smd_buf_append(&f->buf, &f->len, &f->cap, ka, strlen(ka)) != 0)
            return SMD_FOLLOW_ERROR;
        return copy_out(f, out, max);
    }
    /* nothing to send: sleep until someone collects and resumes us */
    f->suspended = 1;
    f->waker->sleep(f->conn);
    pthread_mutex_unlock(&srv->lock);
    return 0;
}

/* Lock held (released here): the job's log from f->next_seq, then its
 * final status. */
static ssize_t log_read(smd_follower *f, char *out, size_t max)
{
    smd_server *srv = f->srv;
    smd_job *job = f->job;
    if (job->removed) /* deleted: its log is gone, its final status is not */
        return end_with_status(f, out, max);
    if (f->next_seq <= job->nevents) {
        /* next_seq >= 1 (smd_follow_subscribe): the batch walks existing
         * events only, at most READ_BATCH bytes of them */
        int64_t first = f->next_seq, last = first;
        uint64_t from = smd_job_event_offset(job, first);
        while (last < job->nevents && smd_job_event_offset(job, last + 2) - from <= READ_BATCH)
            last++;
        uint64_t to = smd_job_event_offset(job, last + 1);
        f->next_seq = last + 1;
        pthread_mutex_unlock(&srv->lock);
        /* the log is append-only and [from, to) complete: read unlocked */
        if (format_events(f, from, to, first) != 0)
            return SMD_FOLLOW_ERROR;
        return f->len ? copy_out(f, out, max) : 0;
    }
    if (smd_job_state_final(job->state) && !job->worker_active && !job->ending)
        return end_with_status(f, out, max); /* ending: its last event is still to come */
    return idle(f, out, max);
}

/* Lock held (released here), for a stream with a source: what its source
 * made, else the keepalive or the wait. */
static ssize_t source_read(smd_follower *f, char *out, size_t max)
{
    int rc = f->src->refill(f->src_state, f->srv, f->job, f->sse, &f->next_seq, &f->buf, &f->len,
                            &f->cap);
    if (rc < 0 || rc == 1 || f->len) {
        pthread_mutex_unlock(&f->srv->lock);
        if (rc < 0)
            return SMD_FOLLOW_ERROR;
        f->done = rc == 1;
        return f->len ? copy_out(f, out, max) : SMD_FOLLOW_END;
    }
    return idle(f, out, max);
}

ssize_t smd_follow_next(smd_follower *f, char *out, size_t max)
{
    smd_server *srv = f->srv;
    if (f->off < f->len)
        return copy_out(f, out, max);
    if (f->done)
        return SMD_FOLLOW_END;

    pthread_mutex_lock(&srv->lock);
    if (atomic_load(&srv->stopping) || f->revoked) {
        pthread_mutex_unlock(&srv->lock);
        return SMD_FOLLOW_END;
    }
    if (f->evicted)
        return end_evicted(f, out, max);
    return f->src ? source_read(f, out, max) : log_read(f, out, max);
}

/* ---------------------------------------------------- the table by job */

static size_t bucket_of(const smd_events *ev, const char *id)
{
    uint64_t h = 1469598103934665603ULL; /* FNV-1a */
    for (const unsigned char *p = (const unsigned char *)id; *p; p++)
        h = (h ^ *p) * 1099511628211ULL;
    return (size_t)h & (ev->nbucket - 1);
}

static void bucket_push(smd_events *ev, smd_follower *f)
{
    smd_follower **head = &ev->bucket[bucket_of(ev, f->job->id)];
    f->job_prev = NULL;
    f->job_next = *head;
    if (*head)
        (*head)->job_prev = f;
    *head = f;
}

/* Lock held: the table, created with the first stream; NULL out of
 * memory. */
static smd_events *events_of(smd_server *srv)
{
    if (!srv->events) {
        smd_events *ev = calloc(1, sizeof *ev);
        if (ev && !(ev->bucket = calloc(ev->nbucket = 64, sizeof *ev->bucket))) {
            free(ev);
            ev = NULL;
        }
        srv->events = ev;
    }
    return srv->events;
}

/* Doubles the buckets once there are more streams than buckets (out of
 * memory it keeps the longer chains). */
static void maybe_grow(smd_events *ev)
{
    if (ev->n <= ev->nbucket)
        return;
    smd_follower **b = calloc(2 * ev->nbucket, sizeof *b);
    if (!b)
        return;
    free(ev->bucket);
    ev->bucket = b;
    ev->nbucket *= 2;
    for (smd_follower *f = ev->all; f; f = f->all_next)
        bucket_push(ev, f);
}

static void link_follower(smd_events *ev, smd_follower *f)
{
    f->all_prev = NULL;
    f->all_next = ev->all;
    if (ev->all)
        ev->all->all_prev = f;
    ev->all = f;
    ev->n++;
    bucket_push(ev, f);
    maybe_grow(ev);
    if (f->src) {
        f->src_prev = NULL;
        f->src_next = ev->sourced;
        if (ev->sourced)
            ev->sourced->src_prev = f;
        ev->sourced = f;
    }
}

static void unlink_follower(smd_events *ev, smd_follower *f)
{
    if (f->job_prev)
        f->job_prev->job_next = f->job_next;
    else
        ev->bucket[bucket_of(ev, f->job->id)] = f->job_next;
    if (f->job_next)
        f->job_next->job_prev = f->job_prev;
    if (f->all_prev)
        f->all_prev->all_next = f->all_next;
    else
        ev->all = f->all_next;
    if (f->all_next)
        f->all_next->all_prev = f->all_prev;
    ev->n--;
    if (f->src) {
        if (f->src_prev)
            f->src_prev->src_next = f->src_next;
        else
            ev->sourced = f->src_next;
        if (f->src_next)
            f->src_next->src_prev = f->src_prev;
    }
}

size_t smd_follow_count(const smd_server *srv)
{
    return srv->events ? srv->events->n : 0;
}

void smd_follow_free_all(smd_server *srv)
{
    if (srv->events) {
        free(srv->events->bucket);
        free(srv->events);
        srv->events = NULL;
    }
}

/* What a follower owns, and itself (not linked, or unlinked). */
static void follower_discard(smd_follower *f)
{
    if (f->fd >= 0)
        close(f->fd);
    if (f->src)
        f->src->free(f->src_state);
    free(f->buf);
    free(f->authorization);
    free(f->token);
    free(f);
}

void smd_follow_unsubscribe(smd_follower *f)
{
    smd_server *srv = f->srv;
    pthread_mutex_lock(&srv->lock);
    unlink_follower(srv->events, f);
    smd_job_unref(f->job);
    pthread_mutex_unlock(&srv->lock);
    follower_discard(f);
}

/* Lock held: the log's descriptor of a follower of job's log, opened now
 * so that a deletion of the job cannot pull the log away from a stream
 * that is replaying it.  -1 with msg set on failure. */
static int open_log(smd_follower *f, smd_server *srv, smd_job *job, char *msg, size_t cap)
{
    sm_error err;
    if (smd_store_load_events(srv->store, job, &err) != SM_OK) {
        snprintf(msg, cap, "%s", err.msg);
        return -1;
    }
    if (smd_store_path(srv->store, job->id, "events.ndjson", f->path, sizeof f->path) != 0) {
        snprintf(msg, cap, "path too long");
        return -1;
    }
    f->fd = open(f->path, O_RDONLY | O_CLOEXEC);
    if (f->fd < 0 && errno != ENOENT) {
        snprintf(msg, cap, "events.ndjson: %s", strerror(errno));
        return -1;
    }
    return 0;
}

smd_follower *smd_follow_subscribe(smd_server *srv, const smd_follow_request *rq, int *found,
                                   char *msg, size_t cap)
{
    smd_follower *f = calloc(1, sizeof *f);
    *found = 1;
    if (!f) {
        if (rq->src)
            rq->src->free(rq->src_state);
        snprintf(msg, cap, "out of memory");
        return NULL;
    }
    f->fd = -1;
    f->src = rq->src;
    f->src_state = rq->src_state;
    f->srv = srv;
    f->conn = rq->conn;
    f->waker = rq->waker;
    f->sse = rq->sse;
    /* after_seq is bounded by the caller (<= SMD_REQUEST_INT_MAX); the
     * saturation only keeps this line free of overflow whatever it gets */
    f->next_seq = rq->after_seq < 0          ? 1
                  : rq->after_seq < INT64_MAX ? rq->after_seq + 1
                                              : INT64_MAX;
    atomic_store(&f->last_send, sm_clock_seconds());
    f->bytes_out = rq->bytes_out;
    if ((rq->cred.authorization && !(f->authorization = strdup(rq->cred.authorization))) ||
        (rq->cred.token && !(f->token = strdup(rq->cred.token)))) {
        follower_discard(f);
        snprintf(msg, cap, "out of memory");
        return NULL;
    }
    pthread_mutex_lock(&srv->lock);
    smd_job *job = smd_store_get_visible(srv->store, rq->id, rq->tenant, rq->admin);
    int ok = job && events_of(srv) && (f->src || open_log(f, srv, job, msg, cap) == 0);
    if (ok) {
        /* linked only now: from here smd_follow_unsubscribe undoes it */
        f->job = job;
        smd_job_ref(job);
        link_follower(srv->events, f);
    } else if (job && !srv->events) {
        snprintf(msg, cap, "out of memory");
    }
    pthread_mutex_unlock(&srv->lock);
    if (!ok) {
        *found = job != NULL;
        follower_discard(f);
        return NULL;
    }
    return f;
}

/* ------------------------------------------------------------- wake-ups */

static void collect(smd_follower *f, wake_list *w)
{
    if (!f->suspended)
        return;
    if (w->n == w->cap) {
        size_t ncap = 2 * w->cap;
        smd_follower **c = w->conns == w->inline_conns ? malloc(ncap * sizeof *c)
                                                                 : realloc(w->conns, ncap * sizeof *c);
        if (!c)
            return; /* stays suspended; the keepalive tick retries */
        if (w->conns == w->inline_conns)
            memcpy(c, w->inline_conns, sizeof w->inline_conns);
        w->conns = c;
        w->cap = ncap;
    }
    f->suspended = 0;
    w->conns[w->n++] = f;
}

/* Lock NOT held: wakes what was collected (each still asleep, so still
 * there). */
static void resume_all(wake_list *w)
{
    for (size_t i = 0; i < w->n; i++)
        w->conns[i]->waker->wake(w->conns[i]->conn);
    if (w->conns != w->inline_conns)
        free(w->conns);
}

void smd_follow_jobs_changed(smd_server *srv, const char (*ids)[SMD_ID_LEN + 1], size_t n,
                             int keepalive)
{
    wake_list w = {.n = 0, .cap = WAKE_INLINE};
    w.conns = w.inline_conns;
    pthread_mutex_lock(&srv->lock);
    smd_events *ev = srv->events;
    for (size_t i = 0; ev && ev->n > 0 && i < n; i++)
        for (smd_follower *f = ev->bucket[bucket_of(ev, ids[i])]; f; f = f->job_next)
            if (strcmp(f->job->id, ids[i]) == 0)
                collect(f, &w);
    /* a stream with a source follows other jobs too (a batch: its members) */
    for (smd_follower *f = ev ? ev->sourced : NULL; f; f = f->src_next)
        for (size_t i = 0; f->suspended && i < n; i++)
            if (f->src->follows(f->src_state, ids[i]))
                collect(f, &w); /* clears f->suspended: the loop ends */
    if (ev && keepalive) {
        double now = sm_clock_seconds();
        for (smd_follower *f = ev->all; f; f = f->all_next)
            if (f->suspended && now - atomic_load(&f->last_send) >= srv->cfg.keepalive) {
                f->keepalive_due = 1;
                collect(f, &w);
            }
    }
    pthread_mutex_unlock(&srv->lock);
    resume_all(&w);
}

void smd_follow_end_all(smd_server *srv)
{
    wake_list w = {.n = 0, .cap = WAKE_INLINE};
    w.conns = w.inline_conns;
    pthread_mutex_lock(&srv->lock);
    for (smd_follower *f = srv->events ? srv->events->all : NULL; f; f = f->all_next)
        collect(f, &w);
    pthread_mutex_unlock(&srv->lock);
    resume_all(&w);
}

void smd_follow_revoke(smd_server *srv,
                       int (*valid)(void *ctx, const char *authorization, const char *token),
                       void *ctx)
{
    wake_list w = {.n = 0, .cap = WAKE_INLINE};
    w.conns = w.inline_conns;
    pthread_mutex_lock(&srv->lock);
    for (smd_follower *f = srv->events ? srv->events->all : NULL; f; f = f->all_next) {
        if (!f->authorization && !f->token)
            continue; /* opened without tokens */
        if (!valid(ctx, f->authorization, f->token)) {
            f->revoked = 1;
            collect(f, &w); /* a sleeping one reads, and ends */
        }
    }
    pthread_mutex_unlock(&srv->lock);
    resume_all(&w);
}

void smd_follow_evict(smd_server *srv, void *conn)
{
    wake_list w = {.n = 0, .cap = WAKE_INLINE};
    w.conns = w.inline_conns;
    pthread_mutex_lock(&srv->lock);
    for (smd_follower *f = srv->events ? srv->events->all : NULL; f; f = f->all_next)
        if (f->conn == conn) {
            f->evicted = 1;
            collect(f, &w); /* a sleeping one reads, and ends */
            break;
        }
    pthread_mutex_unlock(&srv->lock);
    resume_all(&w);
}
