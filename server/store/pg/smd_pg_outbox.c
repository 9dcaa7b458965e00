/* The outbox of a node on disk (see smd_pg_node_int.h): what the work
 * thread could not store in the database yet survives a kill -9 of the
 * node.  One file per item, SPOOL/outbox/<ord>.json (16 hex digits, so
 * that the names sort in the outbox's order), written with the spool's
 * durable write (temporary file, fsync, rename).  A replay is safe
 * whatever the database already holds: events are stored only as their
 * own sequence number under their own lease (smd_pg_append_event_at),
 * a run's end only while its lease is held, so each is stored once. */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <jansson.h>

#include "store/pg/smd_pg_node.h"
#include "store/pg/smd_pg_node_int.h"

#define ITEM_NAME_LEN 21 /* 16 hex digits + ".json" */

static int item_path(const smd_pg_node *n, uint64_t ord, char *buf, size_t cap)
{
    return smd_pathf(buf, cap, "%s/%016" PRIx64 ".json", n->outbox_dir, ord);
}

static const char *kind_of(const node_item *it)
{
    return it->release ? "release" : it->final ? "final" : "event";
}

static char *item_text(const node_item *it)
{
    json_t *o = json_pack("{s:I,s:s,s:i,s:I,s:I,s:s,s:s,s:s,s:s*}", "ord", (json_int_t)it->ord,
                          "job", it->id, "attempt", it->attempt, "token", (json_int_t)it->token,
                          "seq", (json_int_t)it->seq, "kind", kind_of(it), "state",
                          sm_job_state_name(it->state), "message", it->message, "event", it->json);
    char *text = o ? json_dumps(o, JSON_COMPACT) : NULL;
    json_decref(o);
    return text;
}

/* n->lock held */
static void set_full(smd_pg_node *n, int full, const char *why)
{
    int was = n->outbox_full;
    n->outbox_full = full;
    if (full)
        snprintf(n->full_why, sizeof n->full_why, "%s", why);
    if (full && !was)
        smd_logf(&n->srv->log, SMD_LOG_ERROR, "outbox_full", "%s", why);
    else if (!full && was)
        smd_logf(&n->srv->log, SMD_LOG_INFO, "outbox_space",
                 "the outbox's waiting items are all on disk again");
}

void node_outbox_spill(smd_pg_node *n, node_item *items)
{
    char why[512] = "";
    for (node_item *it = items; it; it = it->next) {
        if (it->spooled)
            continue;
        char path[PATH_MAX];
        char *text = item_text(it);
        size_t len = text ? strlen(text) : 0;
        pthread_mutex_lock(&n->lock);
        int fits = n->outbox_bytes + len <= n->srv->cfg.outbox_max;
        pthread_mutex_unlock(&n->lock);
        if (!text)
            snprintf(why, sizeof why, "out of memory writing the outbox");
        else if (!fits)
            snprintf(why, sizeof why, "the outbox on disk is full (--outbox-max %" PRIu64 " bytes): "
                     "the events and results waiting for the database are held in memory only "
                     "and a restart of this node would lose them", n->srv->cfg.outbox_max);
        else if (item_path(n, it->ord, path, sizeof path) != 0 ||
                 smd_write_file_atomic(path, text, len) != 0)
            snprintf(why, sizeof why, "the outbox cannot be written (%s): the events and results "
                     "waiting for the database are held in memory only and a restart of this "
                     "node would lose them", strerror(errno));
        free(text);
        if (why[0])
            break;
        it->spooled = len;
        pthread_mutex_lock(&n->lock);
        n->outbox_bytes += len;
        pthread_mutex_unlock(&n->lock);
    }
    pthread_mutex_lock(&n->lock);
    if (why[0] || n->outbox_full)
        set_full(n, why[0] != 0, why);
    pthread_mutex_unlock(&n->lock);
}

void node_outbox_done(smd_pg_node *n, node_item *it)
{
    if (!it->spooled)
        return;
    char path[PATH_MAX];
    /* no fsync of the folder: a file that comes back after a crash is
     * replayed and found stored already */
    if (item_path(n, it->ord, path, sizeof path) == 0 && unlink(path) != 0 && errno != ENOENT)
        smd_logf(&n->srv->log, SMD_LOG_WARN, "outbox_error", "cannot remove %s: %s", path,
                 strerror(errno));
    pthread_mutex_lock(&n->lock);
    n->outbox_bytes -= it->spooled < n->outbox_bytes ? it->spooled : n->outbox_bytes;
    pthread_mutex_unlock(&n->lock);
    it->spooled = 0;
}

/* One file into an item; NULL (logged by the caller) when it is damaged. */
static node_item *item_read(const char *path, uint64_t max, size_t *len)
{
    char *text = NULL;
    if (smd_read_file(path, (size_t)max, &text, len) != 0)
        return NULL;
    json_t *o = json_loadb(text, *len, 0, NULL);
    free(text);
    json_int_t ord = 0, token = 0, seq = 0;
    int attempt = 0;
    const char *job = NULL, *kind = NULL, *state = NULL, *message = NULL, *event = NULL;
    node_item *it = calloc(1, sizeof *it);
    int ok = it && o &&
             json_unpack(o, "{s:I,s:s,s:i,s:I,s:I,s:s,s:s,s:s,s?s}", "ord", &ord, "job", &job,
                         "attempt", &attempt, "token", &token, "seq", &seq, "kind", &kind, "state",
                         &state, "message", &message, "event", &event) == 0 &&
             smd_id_valid(job) && sm_job_state_from_name(state, &it->state) == 0 && ord > 0 &&
             seq >= 0 && strlen(message) < sizeof it->message;
    if (ok) {
        snprintf(it->id, sizeof it->id, "%s", job);
        it->ord = (uint64_t)ord;
        it->attempt = attempt;
        it->token = token;
        it->seq = seq;
        it->release = strcmp(kind, "release") == 0;
        it->final = strcmp(kind, "final") == 0;
        snprintf(it->message, sizeof it->message, "%s", message);
        it->json = event ? strdup(event) : NULL;
        ok = (it->release || event) && (!event || it->json) &&
             (it->release || it->final || strcmp(kind, "event") == 0);
    }
    json_decref(o);
    if (!ok && it) {
        free(it->json);
        free(it);
        it = NULL;
    }
    if (it)
        it->spooled = *len;
    return it;
}

static int cmp_name(const void *a, const void *b)
{
    return strcmp(*(char *const *)a, *(char *const *)b);
}

/* The names of the outbox's items, sorted (the outbox's order). */
static sm_status list_names(smd_pg_node *n, char ***names, size_t *count, sm_error *err)
{
    *names = NULL;
    *count = 0;
    DIR *d = opendir(n->outbox_dir);
    if (!d)
        return sm_error_set(err, SM_ERR_IO, "cannot read the outbox %s: %s", n->outbox_dir,
                            strerror(errno));
    size_t cap = 0;
    sm_status st = SM_OK;
    struct dirent *de;
    while (st == SM_OK && (de = readdir(d)) != NULL) {
        size_t len = strlen(de->d_name);
        if (strncmp(de->d_name, ".tmp-", 5) == 0) {
            unlinkat(dirfd(d), de->d_name, 0); /* a durable write a kill interrupted */
            continue;
        }
        if (len != ITEM_NAME_LEN || strspn(de->d_name, "0123456789abcdef") != 16 ||
            strcmp(de->d_name + 16, ".json") != 0)
            continue; /* set aside (.damaged), or not ours */
        if (*count == cap) {
            size_t grown_cap = cap ? cap * 2 : 64;
            char **grown = realloc(*names, grown_cap * sizeof *grown);
            if (!grown) {
                st = sm_error_set(err, SM_ERR_NOMEM, "out of memory reading the outbox");
                break;
            }
            *names = grown;
            cap = grown_cap;
        }
        if (!((*names)[*count] = strdup(de->d_name)))
            st = sm_error_set(err, SM_ERR_NOMEM, "out of memory reading the outbox");
        else
            (*count)++;
    }
    closedir(d);
    if (*count)
        qsort(*names, *count, sizeof **names, cmp_name);
    return st;
}

/* The lease an item was made under, held again by this node. */
static int adopt(smd_pg_node *n, const node_item *it)
{
    node_lease *l = node_find_lease(n, it->id);
    if (l) {
        /* items come in order: a later lease of the job is the one held
         * now; the earlier one's items are dropped by the work thread */
        l->lease.attempt = it->attempt;
        l->lease.token = it->token;
        return 0;
    }
    if (!(l = calloc(1, sizeof *l)))
        return -1;
    snprintf(l->lease.id, sizeof l->lease.id, "%s", it->id);
    l->lease.attempt = it->attempt;
    l->lease.token = it->token;
    l->known = INT64_MAX; /* the run is not here: nothing more is forwarded */
    l->renewed = 0;       /* renewed at once */
    l->next = n->leases;
    n->leases = l;
    n->nleases++;
    return 0;
}

static void push_loaded(smd_pg_node *n, node_item *it)
{
    it->next = NULL;
    *n->out_tail = it;
    n->out_tail = &it->next;
    if (it->ord >= n->next_ord)
        n->next_ord = it->ord + 1;
}

/* After the loaded items: a release for each adopted lease whose items
 * do not end its run (the node was killed while the job ran). */
static size_t release_unended(smd_pg_node *n)
{
    size_t added = 0;
    for (node_lease *l = n->leases; l; l = l->next) {
        const node_item *last = NULL;
        for (const node_item *it = n->out_head; it; it = it->next)
            if (strcmp(it->id, l->lease.id) == 0)
                last = it;
        if (!last || last->final || last->release)
            continue;
        node_item *rel = calloc(1, sizeof *rel);
        if (!rel)
            continue; /* the lease expires instead */
        memcpy(rel->id, l->lease.id, sizeof rel->id);
        rel->ord = n->next_ord;
        rel->attempt = l->lease.attempt;
        rel->token = l->lease.token;
        rel->release = 1;
        snprintf(rel->message, sizeof rel->message,
                 "queued again: node %.100s restarted while run %d ran", n->name, l->lease.attempt);
        push_loaded(n, rel);
        added++;
    }
    return added;
}

sm_status node_outbox_open(smd_pg_node *n, sm_error *err)
{
    if (smd_pathf(n->outbox_dir, sizeof n->outbox_dir, "%s/outbox", n->srv->cfg.spool) != 0 ||
        smd_mkdirs(n->outbox_dir, 0700) != 0)
        return sm_error_set(err, SM_ERR_IO, "cannot make the outbox %s/outbox: %s",
                            n->srv->cfg.spool, strerror(errno));
    n->next_ord = 1;
    char **names;
    size_t count;
    sm_status st = list_names(n, &names, &count, err);
    size_t loaded = 0;
    for (size_t i = 0; st == SM_OK && i < count; i++) {
        char path[PATH_MAX];
        size_t len = 0;
        node_item *it = NULL;
        if (smd_pathf(path, sizeof path, "%s/%s", n->outbox_dir, names[i]) == 0)
            it = item_read(path, n->srv->cfg.outbox_max, &len);
        if (!it) {
            /* kept for a person to look at, under a name never replayed */
            char aside[PATH_MAX];
            if (smd_pathf(aside, sizeof aside, "%s.damaged", path) == 0)
                rename(path, aside);
            smd_logf(&n->srv->log, SMD_LOG_ERROR, "outbox_damaged",
                     "the outbox item %s cannot be read: set aside as %s.damaged", names[i],
                     names[i]);
            continue;
        }
        if (adopt(n, it) != 0)
            st = sm_error_set(err, SM_ERR_NOMEM, "out of memory reading the outbox");
        n->outbox_bytes += len;
        push_loaded(n, it);
        loaded++;
    }
    for (size_t i = 0; i < count; i++)
        free(names[i]);
    free(names);
    if (st != SM_OK || !loaded)
        return st;
    size_t released = release_unended(n);
    n->outbox_held = 1; /* unready until the replay is stored */
    snprintf(n->held_why, sizeof n->held_why,
             "the events or results of a previous run of this node wait to be stored in the "
             "database (%zu items)", loaded);
    smd_log(&n->srv->log, SMD_LOG_WARN, "outbox_replay",
            json_pack("{s:I,s:I,s:I,s:I}", "items", (json_int_t)loaded, "jobs",
                      (json_int_t)n->nleases, "released", (json_int_t)released, "bytes",
                      (json_int_t)n->outbox_bytes));
    return SM_OK;
}
