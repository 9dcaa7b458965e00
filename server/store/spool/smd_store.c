/* The job store (see smd_store.h). */
#include "store/spool/smd_store.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include "sm_json.h"
#define STATUS_FILE "status.json"
#define EVENTS_FILE "events.ndjson"
#define STATUS_MAX_BYTES (64 * 1024)

struct smd_store {
    int lock_fd;           /* SPOOL/lock, flock'ed for the daemon's life */
    char root[PATH_MAX];
    char jobs_dir[PATH_MAX];
    char tmp_dir[PATH_MAX];
    char trash_dir[PATH_MAX];
    char quarantine_dir[PATH_MAX];
    size_t nquarantined;   /* damaged records moved aside at this start */
    const smd_logger *log;
    smd_job **jobs;        /* submission order */
    size_t njobs, cap;
    smd_job **buckets;     /* hash chains by id */
    size_t nbuckets;       /* power of two */
    int64_t next_order;
};

/* The order given to the job after one of order o: saturates at
 * SMD_ORDER_MAX (see smd_store.h). */
static int64_t next_order_after(int64_t o)
{
    return o < SMD_ORDER_MAX ? o + 1 : SMD_ORDER_MAX;
}

/* ----------------------------------------------------------------- table */

static size_t id_hash(const char *id, size_t nbuckets)
{
    /* ids are random: their first 16 hex digits are a fine hash */
    uint64_t h = 0;
    for (int i = 0; i < 16; i++) {
        char c = id[i];
        h = (h << 4) | (uint64_t)(c <= '9' ? c - '0' : c - 'a' + 10);
    }
    return (size_t)(h & (nbuckets - 1));
}

static int table_grow(smd_store *s)
{
    size_t nb = s->nbuckets ? 2 * s->nbuckets : 64;
    smd_job **buckets = calloc(nb, sizeof *buckets);
    if (!buckets)
        return -1;
    for (size_t i = 0; i < s->njobs; i++) {
        smd_job *job = s->jobs[i];
        size_t h = id_hash(job->id, nb);
        job->hash_next = buckets[h];
        buckets[h] = job;
    }
    free(s->buckets);
    s->buckets = buckets;
    s->nbuckets = nb;
    return 0;
}

/* Adds job (taking the table's reference) at the end of the order. */
static int table_add(smd_store *s, smd_job *job)
{
    if (s->njobs == s->cap) {
        size_t ncap = s->cap ? 2 * s->cap : 64;
        smd_job **jobs = realloc(s->jobs, ncap * sizeof *jobs);
        if (!jobs)
            return -1;
        s->jobs = jobs;
        s->cap = ncap;
    }
    if (s->njobs + 1 > s->nbuckets && table_grow(s) != 0)
        return -1;
    s->jobs[s->njobs++] = job;
    size_t h = id_hash(job->id, s->nbuckets);
    job->hash_next = s->buckets[h];
    s->buckets[h] = job;
    job->refs++;
    return 0;
}

smd_job *smd_store_get(smd_store *s, const char *id)
{
    if (!smd_id_valid(id) || s->nbuckets == 0)
        return NULL;
    for (smd_job *job = s->buckets[id_hash(id, s->nbuckets)]; job; job = job->hash_next)
        if (memcmp(job->id, id, SMD_ID_LEN) == 0)
            return job;
    return NULL;
}

smd_job *smd_store_find_key(smd_store *s, const char *owner, const char *key)
{
    if (!key || !*key)
        return NULL;
    for (size_t i = 0; i < s->njobs; i++)
        if (strcmp(s->jobs[i]->idempotency_key, key) == 0 &&
            strcmp(s->jobs[i]->owner, owner ? owner : "") == 0)
            return s->jobs[i];
    return NULL;
}

smd_job *smd_store_get_visible(smd_store *s, const char *id, const char *tenant, int admin)
{
    smd_job *job = smd_store_get(s, id);
    return job && smd_job_visible(job, tenant, admin) ? job : NULL;
}

size_t smd_store_count(const smd_store *s)
{
    return s->njobs;
}

smd_job *smd_store_at(smd_store *s, size_t i)
{
    return i < s->njobs ? s->jobs[i] : NULL;
}

void smd_store_unlink(smd_store *s, smd_job *job)
{
    if (job->removed)
        return;
    size_t h = id_hash(job->id, s->nbuckets);
    for (smd_job **p = &s->buckets[h]; *p; p = &(*p)->hash_next)
        if (*p == job) {
            *p = job->hash_next;
            break;
        }
    for (size_t i = 0; i < s->njobs; i++)
        if (s->jobs[i] == job) {
            memmove(&s->jobs[i], &s->jobs[i + 1], (s->njobs - i - 1) * sizeof *s->jobs);
            s->njobs--;
            break;
        }
    job->removed = 1;
    smd_job_close_log(job);
    smd_job_unref(job);
}

const char *smd_store_root(const smd_store *s)
{
    return s->root;
}

const char *smd_store_tmp_dir(const smd_store *s)
{
    return s->tmp_dir;
}

int smd_store_path(const smd_store *s, const char *id, const char *name, char *buf, size_t cap)
{
    if (!smd_id_valid(id))
        return -1;
    if (name && *name)
        return smd_pathf(buf, cap, "%s/%s/%s", s->jobs_dir, id, name);
    return smd_pathf(buf, cap, "%s/%s", s->jobs_dir, id);
}

/* ------------------------------------------------------ status documents */

/* The persisted record: the OGC fields plus what a restart needs. */
static json_t *record_to_json(const smd_job *job)
{
    json_t *o = smd_job_status_fields(job);
    if (!o)
        return NULL;
    json_object_del(o, "lastProgress");
    json_object_set_new(o, "attempt", json_integer(job->attempt));
    json_object_set_new(o, "order", json_integer(job->order));
    json_object_set_new(o, "dimension", json_integer(job->dim));
    json_object_set_new(o, "maxIter", json_integer(job->max_iter));
    if (job->idempotency_key[0])
        json_object_set_new(o, "idempotencyKey", json_string(job->idempotency_key));
    if (job->owner[0])
        json_object_set_new(o, "owner", json_string(job->owner));
    if (job->batch_model) {
        json_object_set_new(o, "batchModel", json_true());
        json_t *m = json_array();
        for (size_t i = 0; m && i < job->nmembers; i++)
            json_array_append_new(m, json_string(job->members[i]));
        json_object_set_new(o, "members", m);
    }
    if (job->final_event_at > 0)
        json_object_set_new(o, "finalEventAt", json_integer(job->final_event_at));
    if (job->request_hash) {
        char hex[17];
        snprintf(hex, sizeof hex, "%016" PRIx64, job->request_hash);
        json_object_set_new(o, "requestHash", json_string(hex));
    }
    return o;
}

static int get_time(json_t *o, const char *key, double *out)
{
    json_t *v = json_object_get(o, key);
    *out = -1;
    if (!v)
        return 0;
    if (!json_is_string(v) || sm_time_parse_rfc3339(json_string_value(v), out) != 0)
        return -1;
    return 0;
}

static int get_int(json_t *o, const char *key, long long lo, long long hi, long long *out)
{
    json_t *v = json_object_get(o, key);
    if (!json_is_integer(v))
        return -1;
    long long x = json_integer_value(v);
    if (x < lo || x > hi)
        return -1;
    *out = x;
    return 0;
}

/* Reads a record; -1 with why filled when it is not one of ours. */
/* A model job's members (ids), within SMD_BATCH_MEMBERS_MAX. */
static int record_members(json_t *o, smd_job *job, char *why, size_t cap)
{
    json_t *m = json_object_get(o, "members"), *v;
    size_t n = json_array_size(m), i;
    char (*ids)[SMD_ID_LEN + 1] = n ? calloc(n, sizeof *ids) : NULL;
    int bad = !json_is_array(m) || n > SMD_JOB_MEMBERS_MAX || (n && !ids);
    json_array_foreach(m, i, v) {
        if (bad || !json_is_string(v) || !smd_id_valid(json_string_value(v))) {
            bad = 1;
            break;
        }
        memcpy(ids[i], json_string_value(v), SMD_ID_LEN + 1);
    }
    if (!bad)
        bad = smd_job_set_members(job, (const char (*)[SMD_ID_LEN + 1])ids, n);
    free(ids);
    if (bad)
        snprintf(why, cap, "bad members");
    return bad ? -1 : 0;
}

static int record_from_json(json_t *o, const char *id, smd_job *job, char *why, size_t cap)
{
    json_t *v = json_object_get(o, "jobID");
    if (!json_is_string(v) || strcmp(json_string_value(v), id) != 0) {
        snprintf(why, cap, "jobID does not match the folder name");
        return -1;
    }
    v = json_object_get(o, "status");
    if (!json_is_string(v) || sm_job_state_from_name(json_string_value(v), &job->state) != 0) {
        snprintf(why, cap, "bad status");
        return -1;
    }
    v = json_object_get(o, "message");
    if (json_is_string(v))
        snprintf(job->message, sizeof job->message, "%s", json_string_value(v));
    /* absent in older records (their runs passed as converged) */
    job->not_converged = job->state == SM_JOB_SUCCESSFUL && json_is_false(json_object_get(o, "converged"));
    long long x;
    if (get_int(o, "progress", 0, 100, &x) != 0) {
        snprintf(why, cap, "bad progress");
        return -1;
    }
    job->progress = (int)x;
    if (get_int(o, "attempt", 0, SMD_ATTEMPT_MAX, &x) != 0) {
        snprintf(why, cap, "bad attempt");
        return -1;
    }
    job->attempt = (int)x;
    if (get_int(o, "order", 0, SMD_ORDER_MAX, &x) != 0) {
        snprintf(why, cap, "bad order");
        return -1;
    }
    job->order = x;
    /* a model job written before it carried its targets' dimension and
     * one step had 0 for both: still a valid record */
    int model = json_is_true(json_object_get(o, "batchModel"));
    if (get_int(o, "dimension", model ? 0 : 2, 3, &x) != 0 || x == 1) {
        snprintf(why, cap, "bad dimension");
        return -1;
    }
    job->dim = (int)x;
    if (get_int(o, "maxIter", model ? 0 : 1, INT_MAX, &x) != 0) {
        snprintf(why, cap, "bad maxIter");
        return -1;
    }
    job->max_iter = (int)x;
    json_t *tol = json_object_get(o, "tolBoundary"); /* absent in older records */
    job->tol_boundary = json_is_number(tol) && json_number_value(tol) > 0 ? json_number_value(tol) : 0;
    if (get_time(o, "created", &job->created) || get_time(o, "started", &job->started) ||
        get_time(o, "finished", &job->finished) || get_time(o, "updated", &job->updated) ||
        job->created < 0) {
        snprintf(why, cap, "bad time stamp");
        return -1;
    }
    v = json_object_get(o, "owner");
    if (json_is_string(v) && strlen(json_string_value(v)) <= SMD_OWNER_MAX)
        strcpy(job->owner, json_string_value(v));
    char bad_name[96];
    v = json_object_get(o, "name"); /* a hand-edited one that is no name: none */
    if (json_is_string(v) && sm_job_name_check(json_string_value(v), json_string_length(v),
                                               bad_name, sizeof bad_name) == 0)
        strcpy(job->name, json_string_value(v));
    v = json_object_get(o, "idempotencyKey");
    if (json_is_string(v) && strlen(json_string_value(v)) <= SMD_IDEMPOTENCY_KEY_MAX)
        strcpy(job->idempotency_key, json_string_value(v));
    if (json_object_get(o, "finalEventAt")) { /* absent in older records */
        if (get_int(o, "finalEventAt", 1, INT64_MAX, &x) != 0) {
            snprintf(why, cap, "bad finalEventAt");
            return -1;
        }
        job->final_event_at = x;
    }
    job->batch_model = model;
    if (job->batch_model && record_members(o, job, why, cap) != 0)
        return -1;
    v = json_object_get(o, "requestHash");
    if (json_is_string(v) && strlen(json_string_value(v)) == 16)
        job->request_hash = strtoull(json_string_value(v), NULL, 16);
    return 0;
}

static sm_status write_record(const char *dir, const smd_job *job, sm_error *err)
{
    char path[PATH_MAX];
    if (smd_pathf(path, sizeof path, "%s/" STATUS_FILE, dir) != 0)
        return sm_error_set(err, SM_ERR_IO, "%s: path too long", dir);
    json_t *o = record_to_json(job);
    char *text = o ? sm_json_dumps(o, 2) : NULL;
    json_decref(o);
    if (!text)
        return sm_error_set(err, SM_ERR_NOMEM, "job %s: cannot encode status.json", job->id);
    size_t len = strlen(text);
    text[len] = '\n';
    int rc = smd_write_file_atomic(path, text, len + 1);
    int saved = errno;
    free(text);
    if (rc != 0)
        return sm_error_set(err, SM_ERR_IO, "%s: %s", path, strerror(saved));
    return SM_OK;
}

sm_status smd_store_save(smd_store *s, smd_job *job, sm_error *err)
{
    char dir[PATH_MAX];
    if (smd_store_path(s, job->id, "", dir, sizeof dir) != 0)
        return sm_error_set(err, SM_ERR_IO, "job %s: path too long", job->id);
    return write_record(dir, job, err);
}

/* ------------------------------------------------------------- event log */

int smd_store_final_event_missing(smd_store *s, const smd_job *job)
{
    char path[PATH_MAX];
    if (job->final_event_at <= 0 || smd_store_path(s, job->id, EVENTS_FILE, path, sizeof path) != 0)
        return 0;
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    struct stat st;
    char last = '\n';
    int missing = 0;
    if (fd >= 0 && fstat(fd, &st) == 0)
        missing = st.st_size <= job->final_event_at ||
                  pread(fd, &last, 1, st.st_size - 1) != 1 || last != '\n';
    if (fd >= 0)
        close(fd);
    return missing;
}

static int index_push(smd_job *job, uint64_t end)
{
    if ((size_t)job->nevents == job->event_cap) {
        size_t ncap = job->event_cap ? 2 * job->event_cap : 64;
        uint64_t *e = realloc(job->event_end, ncap * sizeof *e);
        if (!e)
            return -1;
        job->event_end = e;
        job->event_cap = ncap;
    }
    job->event_end[job->nevents++] = end;
    return 0;
}

sm_status smd_store_load_events(smd_store *s, smd_job *job, sm_error *err)
{
    if (job->events_loaded)
        return SM_OK;
    char path[PATH_MAX];
    if (smd_store_path(s, job->id, EVENTS_FILE, path, sizeof path) != 0)
        return sm_error_set(err, SM_ERR_IO, "job %s: path too long", job->id);
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    job->nevents = 0;
    if (fd < 0) {
        if (errno != ENOENT)
            return sm_error_set(err, SM_ERR_IO, "%s: %s", path, strerror(errno));
        job->events_loaded = 1;
        return SM_OK;
    }
    char buf[65536];
    uint64_t offset = 0;
    for (;;) {
        ssize_t n = read(fd, buf, sizeof buf);
        if (n < 0 && errno == EINTR)
            continue;
        if (n < 0) {
            int saved = errno;
            close(fd);
            return sm_error_set(err, SM_ERR_IO, "%s: %s", path, strerror(saved));
        }
        if (n == 0)
            break;
        for (ssize_t i = 0; i < n; i++)
            if (buf[i] == '\n' && index_push(job, offset + (uint64_t)i + 1) != 0) {
                close(fd);
                return sm_error_set(err, SM_ERR_NOMEM, "%s: out of memory", path);
            }
        offset += (uint64_t)n;
    }
    close(fd);
    uint64_t complete = smd_job_event_offset(job, job->nevents + 1);
    if (complete < offset) {
        /* a crash in the middle of an append: drop the torn line */
        if (truncate(path, (off_t)complete) != 0)
            return sm_error_set(err, SM_ERR_IO, "%s: cannot cut a torn last line: %s", path,
                                strerror(errno));
        smd_logf(s->log, SMD_LOG_WARN, "events_repaired", "job %s: cut a torn last event (%llu bytes)",
                 job->id, (unsigned long long)(offset - complete));
    }
    job->events_loaded = 1;
    return SM_OK;
}

sm_status smd_store_append_event(smd_store *s, smd_job *job, sm_event *ev, sm_error *err)
{
    sm_status st = smd_store_load_events(s, job, err);
    if (st != SM_OK)
        return st;
    char path[PATH_MAX];
    if (smd_store_path(s, job->id, EVENTS_FILE, path, sizeof path) != 0)
        return sm_error_set(err, SM_ERR_IO, "job %s: path too long", job->id);
    if (job->log_fd < 0) {
        job->log_fd = open(path, O_WRONLY | O_APPEND | O_CREAT | O_CLOEXEC, 0644);
        if (job->log_fd < 0)
            return sm_error_set(err, SM_ERR_IO, "%s: %s", path, strerror(errno));
    }
    ev->seq = job->nevents + 1;
    snprintf(ev->job_id, sizeof ev->job_id, "%s", job->id);
    if (ev->time < 0)
        ev->time = sm_time_now();
    char *line = sm_event_to_json(ev);
    if (!line)
        return sm_error_set(err, SM_ERR_NOMEM, "job %s: cannot encode a %s event", job->id,
                            sm_event_type_name(ev->type));
    size_t len = strlen(line);
    char *with_nl = realloc(line, len + 2);
    if (!with_nl) {
        free(line);
        return sm_error_set(err, SM_ERR_NOMEM, "job %s: out of memory", job->id);
    }
    with_nl[len] = '\n';
    with_nl[len + 1] = '\0';
    uint64_t start = smd_job_event_offset(job, job->nevents + 1);
    ssize_t n;
    do
        n = write(job->log_fd, with_nl, len + 1);
    while (n < 0 && errno == EINTR);
    int saved = errno;
    free(with_nl);
    if (n != (ssize_t)(len + 1)) {
        /* never leave half a line: cut back to the last whole event */
        if (ftruncate(job->log_fd, (off_t)start) != 0) { /* nothing more to do */
        }
        return sm_error_set(err, SM_ERR_IO, "%s: %s", path,
                            n < 0 ? strerror(saved) : "short write");
    }
    if (index_push(job, start + len + 1) != 0) {
        if (ftruncate(job->log_fd, (off_t)start) != 0) { /* as above */
        }
        return sm_error_set(err, SM_ERR_NOMEM, "job %s: out of memory", job->id);
    }
    /* lifecycle events are rare and matter after a crash: make them durable */
    if (ev->type != SM_EVENT_PROGRESS)
        (void)fdatasync(job->log_fd);
    return SM_OK;
}

/* ---------------------------------------------------------------- commit */

sm_status smd_store_commit(smd_store *s, const char *upload_dir, smd_job *job, sm_event *first,
                           sm_error *err)
{
    const char *id = job->id;
    char path[PATH_MAX], final_dir[PATH_MAX];
    sm_status st = SM_OK;
    job->order = s->next_order;
    first->seq = 1;
    if (first->time < 0)
        first->time = job->created;
    snprintf(first->job_id, sizeof first->job_id, "%s", id);
    char *line = sm_event_to_json(first);
    if (!line) {
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory");
        goto fail;
    }
    size_t len = strlen(line);
    line[len] = '\n'; /* replaces the NUL; written with its length */
    if (smd_pathf(path, sizeof path, "%s/" EVENTS_FILE, upload_dir) != 0 ||
        smd_store_path(s, id, "", final_dir, sizeof final_dir) != 0) {
        free(line);
        st = sm_error_set(err, SM_ERR_IO, "%s: path too long", upload_dir);
        goto fail;
    }
    int rc = smd_write_file_atomic(path, line, len + 1);
    free(line);
    if (rc != 0) {
        st = sm_error_set(err, SM_ERR_IO, "%s: %s", path, strerror(errno));
        goto fail;
    }
    if (index_push(job, len + 1) != 0) {
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory");
        goto fail;
    }
    job->events_loaded = 1;
    if ((st = write_record(upload_dir, job, err)) != SM_OK)
        goto fail;
    if (rename(upload_dir, final_dir) != 0) {
        st = sm_error_set(err, SM_ERR_IO, "cannot move %s to %s: %s", upload_dir, final_dir,
                          strerror(errno));
        goto fail;
    }
    (void)smd_fsync_dir(s->jobs_dir);
    (void)smd_fsync_dir(s->tmp_dir);
    if (table_add(s, job) != 0) {
        /* the job is durable; it will be picked up at the next start */
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory");
        goto fail;
    }
    s->next_order = next_order_after(s->next_order);
    return SM_OK;
fail:
    smd_job_free(job);
    return st;
}

void smd_store_remove_results(smd_store *s, const smd_job *job, int partial_only)
{
    char path[PATH_MAX];
    if (smd_store_path(s, job->id, "results.tmp", path, sizeof path) == 0)
        smd_rmtree(path);
    if (!partial_only && smd_store_path(s, job->id, "results", path, sizeof path) == 0)
        smd_rmtree(path);
}

int smd_store_trash(smd_store *s, const char *id, char *trash_path, size_t cap)
{
    char dir[PATH_MAX], suffix[SMD_ID_LEN + 1];
    if (smd_store_path(s, id, "", dir, sizeof dir) != 0 || smd_random_id(suffix) != 0 ||
        smd_pathf(trash_path, cap, "%s/%s-%.8s", s->trash_dir, id, suffix) != 0)
        return -1;
    if (rename(dir, trash_path) != 0)
        return errno == ENOENT ? (trash_path[0] = '\0', 0) : -1;
    /* the rename is the delete: on disk before the caller says "deleted"
     * (an unsynced rename can come back after a crash) */
    (void)smd_fsync_dir(s->jobs_dir);
    (void)smd_fsync_dir(s->trash_dir);
    return 0;
}

int smd_store_writable(const smd_store *s)
{
    return access(s->root, W_OK) == 0;
}

int smd_store_can_trash(const smd_store *s)
{
    return access(s->jobs_dir, W_OK) == 0 && access(s->trash_dir, W_OK) == 0;
}

/* ------------------------------------------------------------ open/close */

/* Submission order, then (for orders that reached SMD_ORDER_MAX) the
 * creation time, then the id: a total order, whatever the records say. */
static int cmp_order(const void *a, const void *b)
{
    const smd_job *x = *(smd_job *const *)a, *y = *(smd_job *const *)b;
    if (x->order != y->order)
        return (x->order > y->order) - (x->order < y->order);
    if (x->created != y->created)
        return (x->created > y->created) - (x->created < y->created);
    return strcmp(x->id, y->id);
}

/* A record that cannot be read: jobs/<id> moves to quarantine/<id>-<8 hex>
 * (kept for a post-mortem, fsync'ed), and jobs/<id> gets a new record of
 * a failed job saying so: the job answers "failed, record damaged" and
 * can be deleted, instead of vanishing (404).  dimension and maxIter of
 * the new record are placeholders (record fields, not in the status
 * document).  NULL (logged) when the spool refuses. */
static smd_job *quarantine_job(smd_store *s, const char *id, const char *why)
{
    char dir[PATH_MAX], dest[PATH_MAX], suffix[SMD_ID_LEN + 1];
    sm_error err;
    smd_job *job = NULL;
    if (smd_store_path(s, id, "", dir, sizeof dir) != 0 || smd_random_id(suffix) != 0 ||
        smd_pathf(dest, sizeof dest, "%s/%s-%.8s", s->quarantine_dir, id, suffix) != 0)
        return NULL;
    if (rename(dir, dest) != 0 || mkdir(dir, 0750) != 0 || (job = smd_job_new(id)) == NULL) {
        smd_logf(s->log, SMD_LOG_ERROR, "store_error", "job %s: cannot quarantine its damaged record: %s",
                 id, strerror(errno));
        return NULL;
    }
    (void)smd_fsync_dir(s->quarantine_dir);
    job->state = SM_JOB_FAILED;
    job->created = job->updated = job->finished = sm_time_now();
    job->dim = 2;
    job->max_iter = 1;
    snprintf(job->message, sizeof job->message, "record damaged (%s); moved to quarantine/%s-%.8s",
             why, id, suffix);
    if (write_record(dir, job, &err) != SM_OK) {
        smd_logf(s->log, SMD_LOG_ERROR, "store_error", "job %s: %s", id, err.msg);
        free(job);
        return NULL;
    }
    (void)smd_fsync_dir(s->jobs_dir);
    s->nquarantined++;
    smd_log(s->log, SMD_LOG_WARN, "job_quarantined",
            json_pack("{s:s,s:s,s:s}", "job", id, "why", why, "moved_to", dest));
    return job;
}

size_t smd_store_quarantined(const smd_store *s)
{
    return s->nquarantined;
}

/* Loads jobs/<id>; a record that cannot be read is quarantined. */
static smd_job *load_job(smd_store *s, const char *id)
{
    char path[PATH_MAX], why[256];
    if (smd_store_path(s, id, STATUS_FILE, path, sizeof path) != 0)
        return NULL;
    char *text = NULL;
    size_t len = 0;
    if (smd_read_file(path, STATUS_MAX_BYTES, &text, &len) != 0) {
        snprintf(why, sizeof why, "status.json: %s", strerror(errno));
        return quarantine_job(s, id, why);
    }
    json_error_t jerr;
    json_t *o = json_loadb(text, len, JSON_REJECT_DUPLICATES, &jerr);
    free(text);
    smd_job *job = smd_job_new(id);
    if (!o || !job || record_from_json(o, id, job, why, sizeof why) != 0) {
        if (!job) {
            smd_logf(s->log, SMD_LOG_WARN, "job_skipped", "%s: out of memory", path);
            json_decref(o);
            return NULL;
        }
        if (!o)
            snprintf(why, sizeof why, "status.json: %s", jerr.text);
        json_decref(o);
        free(job);
        return quarantine_job(s, id, why);
    }
    json_decref(o);
    return job;
}

static int empty_dir(const char *dir)
{
    DIR *d = opendir(dir);
    if (!d)
        return -1;
    struct dirent *de;
    char path[PATH_MAX];
    while ((de = readdir(d)) != NULL) {
        if (strcmp(de->d_name, ".") == 0 || strcmp(de->d_name, "..") == 0)
            continue;
        if (smd_pathf(path, sizeof path, "%s/%s", dir, de->d_name) == 0)
            smd_rmtree(path);
    }
    closedir(d);
    return 0;
}

sm_status smd_store_open(const char *spool, const smd_logger *log, smd_store **out,
                         sm_error *err)
{
    *out = NULL;
    smd_store *s = calloc(1, sizeof *s);
    if (!s)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    s->lock_fd = -1;
    s->log = log;
    if (smd_pathf(s->root, sizeof s->root, "%s", spool) != 0 ||
        smd_pathf(s->jobs_dir, sizeof s->jobs_dir, "%s/jobs", spool) != 0 ||
        smd_pathf(s->tmp_dir, sizeof s->tmp_dir, "%s/tmp", spool) != 0 ||
        smd_pathf(s->trash_dir, sizeof s->trash_dir, "%s/trash", spool) != 0 ||
        smd_pathf(s->quarantine_dir, sizeof s->quarantine_dir, "%s/quarantine", spool) != 0) {
        free(s);
        return sm_error_set(err, SM_ERR_INVALID, "spool path too long: %s", spool);
    }
    const char *dirs[] = {s->root, s->jobs_dir, s->tmp_dir, s->trash_dir, s->quarantine_dir};
    for (int i = 0; i < 5; i++)
        if (smd_mkdirs(dirs[i], 0750) != 0) {
            sm_status st = sm_error_set(err, SM_ERR_IO, "cannot create %s: %s", dirs[i],
                                        strerror(errno));
            free(s);
            return st;
        }
    if (access(s->jobs_dir, W_OK) != 0) {
        sm_status st = sm_error_set(err, SM_ERR_IO, "%s is not writable: %s", s->jobs_dir,
                                    strerror(errno));
        free(s);
        return st;
    }
    /* one daemon per spool: two would run the same jobs.  The kernel drops
     * the lock when the holder dies, kill -9 included. */
    char lock_path[PATH_MAX];
    if (smd_pathf(lock_path, sizeof lock_path, "%s/lock", spool) != 0 ||
        (s->lock_fd = open(lock_path, O_RDWR | O_CREAT | O_CLOEXEC, 0640)) < 0) {
        sm_status st = sm_error_set(err, SM_ERR_IO, "cannot open %s/lock: %s", spool, strerror(errno));
        free(s);
        return st;
    }
    if (flock(s->lock_fd, LOCK_EX | LOCK_NB) != 0) {
        char owner[32] = "";
        ssize_t n = pread(s->lock_fd, owner, sizeof owner - 1, 0);
        owner[n > 0 ? n : 0] = '\0';
        owner[strcspn(owner, "\n")] = '\0';
        sm_status st = sm_error_set(err, SM_ERR_IO, "%s is in use by another shapematchd%s%s%s", spool,
                                    owner[0] ? " (pid " : "", owner, owner[0] ? ")" : "");
        close(s->lock_fd);
        free(s);
        return st;
    }
    char pid[32];
    int len = snprintf(pid, sizeof pid, "%ld\n", (long)getpid());
    if (ftruncate(s->lock_fd, 0) != 0 || pwrite(s->lock_fd, pid, (size_t)len, 0) != len) {
        /* only informative */
    }
    empty_dir(s->tmp_dir);
    empty_dir(s->trash_dir);

    DIR *d = opendir(s->jobs_dir);
    if (!d) {
        sm_status st = sm_error_set(err, SM_ERR_IO, "%s: %s", s->jobs_dir, strerror(errno));
        smd_store_close(s);
        return st;
    }
    struct dirent *de;
    while ((de = readdir(d)) != NULL) {
        if (de->d_name[0] == '.')
            continue;
        if (!smd_id_valid(de->d_name)) {
            smd_logf(s->log, SMD_LOG_WARN, "spool_stray", "%s/%s is not a job folder: left alone",
                     s->jobs_dir, de->d_name);
            continue;
        }
        smd_job *job = load_job(s, de->d_name);
        if (!job)
            continue;
        if (table_add(s, job) != 0) {
            smd_job_free(job);
            closedir(d);
            smd_store_close(s);
            return sm_error_set(err, SM_ERR_NOMEM, "out of memory loading the spool");
        }
        if (job->order >= s->next_order)
            s->next_order = next_order_after(job->order);
    }
    closedir(d);
    if (s->njobs > 1)
        qsort(s->jobs, s->njobs, sizeof *s->jobs, cmp_order);
    *out = s;
    return SM_OK;
}

void smd_store_close(smd_store *s)
{
    if (!s)
        return;
    if (s->lock_fd >= 0)
        close(s->lock_fd); /* releases the spool */
    for (size_t i = 0; i < s->njobs; i++)
        smd_job_free(s->jobs[i]);
    free(s->jobs);
    free(s->buckets);
    free(s);
}
