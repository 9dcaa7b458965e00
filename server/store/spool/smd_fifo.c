/* Local FIFO backend of the job queue (see smd_fifo.h): a growable ring
 * of fixed-size ids. */
#include "store/spool/smd_fifo.h"

#include <stdlib.h>
#include <string.h>

typedef struct local_queue {
    char (*ids)[SMD_ID_LEN + 1];
    size_t head;   /* index of the oldest entry */
    size_t count;
    size_t cap;
} local_queue;

static char *slot(local_queue *q, size_t i)
{
    return q->ids[(q->head + i) % q->cap];
}

static int local_push(void *impl, const char *id)
{
    local_queue *q = impl;
    if (q->count == q->cap) {
        size_t ncap = q->cap ? 2 * q->cap : 16;
        char (*ids)[SMD_ID_LEN + 1] = malloc(ncap * sizeof *ids);
        if (!ids)
            return -1;
        for (size_t i = 0; i < q->count; i++)
            memcpy(ids[i], slot(q, i), SMD_ID_LEN + 1);
        free(q->ids);
        q->ids = ids;
        q->head = 0;
        q->cap = ncap;
    }
    char *dst = q->ids[(q->head + q->count) % q->cap];
    memcpy(dst, id, SMD_ID_LEN);
    dst[SMD_ID_LEN] = '\0';
    q->count++;
    return 0;
}

static int local_pop(void *impl, char id_out[SMD_ID_LEN + 1])
{
    local_queue *q = impl;
    if (q->count == 0)
        return 0;
    memcpy(id_out, slot(q, 0), SMD_ID_LEN + 1);
    q->head = (q->head + 1) % q->cap;
    q->count--;
    return 1;
}

static long local_position(void *impl, const char *id)
{
    local_queue *q = impl;
    for (size_t i = 0; i < q->count; i++)
        if (strncmp(slot(q, i), id, SMD_ID_LEN) == 0)
            return (long)i;
    return -1;
}

static int local_remove(void *impl, const char *id)
{
    local_queue *q = impl;
    long pos = local_position(impl, id);
    if (pos < 0)
        return 0;
    for (size_t i = (size_t)pos; i + 1 < q->count; i++)
        memcpy(slot(q, i), slot(q, i + 1), SMD_ID_LEN + 1);
    q->count--;
    return 1;
}

static size_t local_depth(void *impl)
{
    return ((local_queue *)impl)->count;
}

static void local_destroy(void *impl)
{
    local_queue *q = impl;
    if (q) {
        free(q->ids);
        free(q);
    }
}

static const smd_queue_ops local_ops = {
    .name = "local",
    .push = local_push,
    .pop = local_pop,
    .remove = local_remove,
    .position = local_position,
    .depth = local_depth,
    .destroy = local_destroy,
};

smd_queue *smd_queue_local_new(void)
{
    smd_queue *q = malloc(sizeof *q);
    local_queue *impl = calloc(1, sizeof *impl);
    if (!q || !impl) {
        free(q);
        free(impl);
        return NULL;
    }
    q->ops = &local_ops;
    q->impl = impl;
    return q;
}

void smd_queue_free(smd_queue *q)
{
    if (!q)
        return;
    q->ops->destroy(q->impl);
    free(q);
}
