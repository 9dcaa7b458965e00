/* Target field, adjacency: the neighbour of every element across each
 * of its facets (sm_field.c has the overview, sm_field_internal.h the
 * structure). */
#include "sm_field_internal.h"

#include <stdlib.h>
#include <string.h>

/* ------------------------------------------------------------------ */
/* Adjacency                                                           */

/* One facet of a valid element: its smallest vertex a, the others
 * ascending in key, and tag = e*(dim+1)+k (the facet opposite local vertex
 * k of element e) with SIDE_BIT set when the opposite vertex lies on the
 * negative side of the facet (orientation of the ascending facet vertices
 * followed by the opposite vertex).  Two elements sharing a facet are
 * neighbours when their opposite vertices lie on opposite sides; folded or
 * duplicated elements are not. */
typedef struct facet_key {
    uint64_t key;
    uint32_t a;
    uint32_t tag;
} facet_key;
#define SIDE_BIT 0x80000000u
#define TAG_ID(t) ((int32_t)((t) & ~SIDE_BIT))

/* Vertices of facet k (opposite local vertex k) of element e, ascending. */
void sm__field_facet_vertices(const sm_field *f, int32_t e, int k, int32_t *out)
{
    const int D = f->dim;
    const int32_t *ev = f->bg->elems + (size_t)e * (size_t)(D + 1);
    int32_t s[4];
    int loc[4], n = 0;
    sorted_vertices(ev, D + 1, s, loc);
    for (int i = 0; i <= D; i++)
        if (loc[i] != k)
            out[n++] = s[i];
}

/* The dim+1 facet keys of valid element e (negative: det J < 0).  With
 * the vertices sorted by a permutation of parity P, moving the vertex
 * opposite facet r (sorted position r) to the end takes dim - r more
 * transpositions, so the orientation of (facet ascending, opposite) is
 * sign(det J) * (-1)^(P + dim - r): exact, from the sign of a determinant
 * already computed, with no coordinate of the neighbour needed. */
static inline __attribute__((always_inline)) void
element_facet_keys(const int32_t *ev, int32_t e, const int D, int negative, facet_key *out)
{
    int32_t s[4];
    int loc[4];
    int parity = sorted_vertices(ev, D + 1, s, loc) ^ negative;
    for (int r = 0; r <= D; r++) {
        int32_t fv[3];
        int n = 0;
        for (int i = 0; i <= D; i++)
            if (i != r)
                fv[n++] = s[i];
        out[r].a = (uint32_t)fv[0];
        out[r].key = D == 2 ? (uint64_t)(uint32_t)fv[1]
                            : ((uint64_t)(uint32_t)fv[1] << 32) | (uint32_t)fv[2];
        uint32_t side = (uint32_t)((parity + D - r) & 1);
        out[r].tag = ((uint32_t)e * (uint32_t)(D + 1) + (uint32_t)loc[r]) | (side << 31);
    }
}

/* Open-addressing table matching the facets of one bucket: a slot per
 * distinct facet, with the first two entries holding it. */
typedef struct facet_slot {
    uint64_t key;
    uint32_t a;
    uint32_t stamp; /* changes with the bucket: older stamps are empty */
    int32_t first;  /* entry index */
    int32_t second; /* entry index, -1 for none yet, -2 for three or more */
} facet_slot;

static inline size_t facet_hash(uint32_t a, uint64_t key, size_t mask)
{
    uint64_t h = (key ^ ((uint64_t)a << 21)) * 0x9e3779b97f4a7c15ull;
    return (size_t)(h >> 32) & mask;
}

static void link_pair(sm_field *f, uint32_t t1, uint32_t t2)
{
    const int nv1 = f->dim + 1;
    /* a facet shared by exactly two elements is a walk edge only if they
     * lie on opposite sides of it */
    if ((t1 ^ t2) & SIDE_BIT) {
        f->neigh[TAG_ID(t1)] = TAG_ID(t2) / nv1;
        f->neigh[TAG_ID(t2)] = TAG_ID(t1) / nv1;
    }
}

static int facet_key_cmp(const void *pa, const void *pb)
{
    const facet_key *x = pa, *y = pb;
    if (x->a != y->a)
        return x->a < y->a ? -1 : 1;
    if (x->key != y->key)
        return x->key < y->key ? -1 : 1;
    return (TAG_ID(x->tag) > TAG_ID(y->tag)) - (TAG_ID(x->tag) < TAG_ID(y->tag));
}

/* Links the facets of one bucket (m entries, reordered) shared by exactly
 * two elements.  A hash table in the common case; when its probes run
 * long (vertex numbers chosen to collide), a sort, so that no input costs
 * more than O(m log m). */
static void match_bucket(sm_field *f, facet_key *bk, size_t m, facet_slot *table, size_t *occ,
                         uint32_t stamp)
{
    size_t mask = 15, nocc = 0, budget = HASH_PROBE_BUDGET * m + 64;
    while (mask + 1 < 2 * m)
        mask = 2 * mask + 1;
    for (size_t i = 0; i < m; i++) {
        size_t h = facet_hash(bk[i].a, bk[i].key, mask);
        while (table[h].stamp == stamp && (table[h].key != bk[i].key || table[h].a != bk[i].a)) {
            h = (h + 1) & mask;
            if (budget-- == 0)
                goto sort;
        }
        facet_slot *sl = &table[h];
        if (sl->stamp != stamp) {
            *sl = (facet_slot){bk[i].key, bk[i].a, stamp, (int32_t)i, -1};
            occ[nocc++] = h;
        } else {
            sl->second = sl->second == -1 ? (int32_t)i : -2;
        }
    }
    for (size_t o = 0; o < nocc; o++) {
        const facet_slot *sl = &table[occ[o]];
        if (sl->second >= 0)
            link_pair(f, bk[sl->first].tag, bk[sl->second].tag);
    }
    return;
sort:
    qsort(bk, m, sizeof *bk, facet_key_cmp);
    for (size_t i = 0; i < m;) {
        size_t j = i + 1;
        while (j < m && bk[j].a == bk[i].a && bk[j].key == bk[i].key)
            j++;
        if (j - i == 2)
            link_pair(f, bk[i].tag, bk[i + 1].tag);
        i = j;
    }
}

/* Neighbours across shared facets.  Identical facets have the same
 * smallest vertex a, so they meet in the same bucket of a: the facets are
 * written into ADJ_FANOUT buckets by the high bits of a (counted during
 * the element pass), each bucket is split by the next bits into
 * ADJ_FANOUT sub-buckets, and each sub-bucket is matched with a hash
 * table.  Every step streams through memory with few enough open write
 * positions to stay in cache, whatever the vertex numbering.  Buckets are
 * filled chunk after chunk, so their content does not depend on the
 * threads; a facet is linked when exactly two entries share it, and the
 * link is symmetric.  Each thread's scratch grows to the largest bucket
 * it meets, so it holds at most about twice the facets in all. */
static inline __attribute__((always_inline)) void
distribute_keys(const sm_field *f, int shift, size_t *pos, facet_key *keys, const int D)
{
    const int32_t ne = f->nelems;
#pragma omp parallel for schedule(static)
    for (int c = 0; c < BUILD_CHUNKS; c++) {
        size_t *my = pos + (size_t)c * ADJ_FANOUT;
        for (int32_t e = chunk_begin(ne, c); e < chunk_begin(ne, c + 1); e++) {
            if (!f->valid[e])
                continue;
            facet_key fk[4];
            element_facet_keys(f->bg->elems + (size_t)e * (size_t)(D + 1), e, D,
                               f->valid[e] == ELEM_VALID_NEGATIVE, fk);
            for (int r = 0; r <= D; r++)
                keys[my[fk[r].a >> shift]++] = fk[r];
        }
    }
}

sm_status sm__field_build_adjacency(sm_field *f, int shift, size_t *counts, sm_error *err)
{
    const int nv1 = f->dim + 1;
    const size_t nall = (size_t)f->nelems * (size_t)nv1;
    const int shift2 = shift > ADJ_FANOUT_BITS ? shift - ADJ_FANOUT_BITS : 0;
    const uint32_t low = ADJ_FANOUT - 1;
    /* bucket b holds the facets of chunk 0, then chunk 1...: counts
     * become write positions */
    size_t start[ADJ_FANOUT + 1], sum = 0;
    for (int b = 0; b < ADJ_FANOUT; b++) {
        start[b] = sum;
        for (int c = 0; c < BUILD_CHUNKS; c++) {
            size_t n = counts[(size_t)c * ADJ_FANOUT + (size_t)b];
            counts[(size_t)c * ADJ_FANOUT + (size_t)b] = sum;
            sum += n;
        }
    }
    start[ADJ_FANOUT] = sum;
    facet_key *keys = sm__alloc_large(sum * sizeof *keys);
    if (!keys)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for element adjacency");
    if (f->dim == 2)
        distribute_keys(f, shift, counts, keys, 2);
    else
        distribute_keys(f, shift, counts, keys, 3);

    int failed = 0;
#pragma omp parallel
    {
#pragma omp for schedule(static)
        for (size_t i = 0; i < nall; i++)
            f->neigh[i] = -1;
        facet_key *sub = NULL;
        facet_slot *table = NULL;
        size_t *occ = NULL, subcap = 0, cap = 0;
#pragma omp for schedule(dynamic, 1)
        for (int b = 0; b < ADJ_FANOUT; b++) {
            const facet_key *bk = keys + start[b];
            size_t m = start[b + 1] - start[b], sstart[ADJ_FANOUT + 1], sfill[ADJ_FANOUT];
            /* an empty bucket links nothing, and until a bucket holds
             * something sub is NULL, which takes no offset (not even 0) */
            if (m == 0)
                continue;
            if (m > subcap) {
                free(sub);
                sub = malloc(m * sizeof *sub);
                subcap = sub ? m : 0;
                if (!sub) {
#pragma omp atomic write
                    failed = 1;
                    continue;
                }
            }
            memset(sstart, 0, sizeof sstart);
            for (size_t i = 0; i < m; i++)
                sstart[((bk[i].a >> shift2) & low) + 1]++;
            for (int c = 0; c < ADJ_FANOUT; c++)
                sstart[c + 1] += sstart[c];
            memcpy(sfill, sstart, sizeof sfill);
            for (size_t i = 0; i < m; i++)
                sub[sfill[(bk[i].a >> shift2) & low]++] = bk[i];
            for (int c = 0; c < ADJ_FANOUT; c++) {
                size_t ms = sstart[c + 1] - sstart[c];
                if (ms == 0)
                    continue;
                if (2 * ms > cap) {
                    size_t newcap = 16;
                    while (newcap < 2 * ms)
                        newcap *= 2;
                    free(table);
                    free(occ);
                    table = calloc(newcap, sizeof *table);
                    occ = malloc(newcap * sizeof *occ);
                    cap = table && occ ? newcap : 0;
                    if (!cap) {
#pragma omp atomic write
                        failed = 1;
                        continue;
                    }
                }
                match_bucket(f, sub + sstart[c], ms, table, occ,
                             (uint32_t)(b * ADJ_FANOUT + c) + 1);
            }
        }
        free(sub);
        free(table);
        free(occ);
    }
    sm__free_large(keys, sum * sizeof *keys);
    if (failed)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for element adjacency");
    return SM_OK;
}
