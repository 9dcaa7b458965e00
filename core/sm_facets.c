/* Facets matched by their vertex sets (see sm_facets.h). */
#include "sm_facets.h"

#include <stdlib.h>
#include <string.h>

#include "sm_alloc.h"

/* One facet filed under its smallest vertex: the other vertices (the
 * larger in the high half) and its index. */
typedef struct facet_entry {
    uint64_t key;
    int32_t facet;
} facet_entry;

/* Buckets longer than this are sorted by qsort (a vertex shared by very
 * many elements, as a hostile mesh may have), shorter ones by insertion. */
#define INSERTION_MAX 256

/* The element's vertices ascending (s) and the local index of each (loc). */
static void sort_element(int nv, const int32_t *ev, int32_t *s, int *loc)
{
    for (int i = 0; i < nv; i++) {
        int j = i;
        while (j > 0 && s[j - 1] > ev[i]) {
            s[j] = s[j - 1];
            loc[j] = loc[j - 1];
            j--;
        }
        s[j] = ev[i];
        loc[j] = i;
    }
}

void sm__facet_sorted_vertices(int dim, const int32_t *ev, int k, int32_t *out)
{
    int32_t s[4];
    int loc[4], n = 0;
    sort_element(dim + 1, ev, s, loc);
    for (int r = 0; r <= dim; r++)
        if (loc[r] != k)
            out[n++] = s[r];
}

static int entry_less(const facet_entry *a, const facet_entry *b)
{
    return a->key < b->key || (a->key == b->key && a->facet < b->facet);
}

static int entry_cmp(const void *pa, const void *pb)
{
    const facet_entry *a = pa, *b = pb;
    return entry_less(a, b) ? -1 : entry_less(b, a) ? 1 : 0;
}

static void sort_bucket(facet_entry *b, size_t m)
{
    if (m > INSERTION_MAX) {
        qsort(b, m, sizeof *b, entry_cmp);
        return;
    }
    for (size_t i = 1; i < m; i++) {
        facet_entry t = b[i];
        size_t j = i;
        while (j > 0 && entry_less(&t, &b[j - 1])) {
            b[j] = b[j - 1];
            j--;
        }
        b[j] = t;
    }
}

/* Files every facet under its smallest vertex: start[a] .. start[a+1]
 * (start: nverts+1 entries, zero on entry). */
static void file_facets(int dim, int32_t nverts, int32_t nelems, const int32_t *elems,
                        int32_t *start, facet_entry *ent)
{
    const int nv = dim + 1;
    int32_t s[4];
    int loc[4];
    /* with s0 < s1 < ..., the facet opposite s0 is filed under s1, the
     * dim others under s0 */
    for (int32_t e = 0; e < nelems; e++) {
        sort_element(nv, elems + (size_t)e * (size_t)nv, s, loc);
        start[s[0]] += dim;
        start[s[1]] += 1;
    }
    int32_t sum = 0;
    for (int32_t v = 0; v < nverts; v++) {
        int32_t c = start[v];
        start[v] = sum;
        sum += c;
    }
    start[nverts] = sum;
    for (int32_t e = 0; e < nelems; e++) {
        sort_element(nv, elems + (size_t)e * (size_t)nv, s, loc);
        for (int r = 0; r <= dim; r++) {
            int32_t rest[3], n = 0;
            for (int i = 0; i <= dim; i++)
                if (i != r)
                    rest[n++] = s[i];
            uint64_t key = dim == 2 ? (uint32_t)rest[1]
                                    : ((uint64_t)(uint32_t)rest[1] << 32) | (uint32_t)rest[2];
            /* start[a] is the write position of bucket a until the end */
            ent[start[rest[0]]++] = (facet_entry){key, e * nv + loc[r]};
        }
    }
    /* each position now ends its bucket, i.e. starts the next one */
    memmove(start + 1, start, (size_t)nverts * sizeof *start);
    start[0] = 0;
}

sm_status sm__facet_match(int dim, int32_t nverts, int32_t nelems, const int32_t *elems,
                          int32_t *nbr, int32_t *boundary, sm_facet_match *out, sm_error *err)
{
    const int nv = dim + 1;
    const size_t nf = (size_t)nelems * (size_t)nv;
    out->nboundary = 0;
    out->crowded = -1;
    out->crowded_holders = 0;
    int32_t *start = calloc((size_t)nverts + 1, sizeof *start);
    facet_entry *ent = sm__alloc_large((nf ? nf : 1) * sizeof *ent);
    if (!start || !ent) {
        free(start);
        sm__free_large(ent, (nf ? nf : 1) * sizeof *ent);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory matching %ld facets", (long)nf);
    }
    file_facets(dim, nverts, nelems, elems, start, ent);
    for (int32_t a = 0; a < nverts; a++) {
        facet_entry *b = ent + start[a];
        size_t m = (size_t)(start[a + 1] - start[a]);
        sort_bucket(b, m);
        for (size_t i = 0; i < m;) {
            size_t j = i + 1;
            while (j < m && b[j].key == b[i].key)
                j++;
            if (j - i == 1) {
                nbr[b[i].facet] = -1;
                if (boundary)
                    boundary[out->nboundary] = b[i].facet;
                out->nboundary++;
            } else if (j - i == 2) {
                nbr[b[i].facet] = b[i + 1].facet / nv;
                nbr[b[i + 1].facet] = b[i].facet / nv;
            } else {
                for (size_t k = i; k < j; k++)
                    nbr[b[k].facet] = -2;
                if (out->crowded < 0) {
                    out->crowded = b[i].facet;
                    out->crowded_holders = (int32_t)(j - i);
                }
            }
            i = j;
        }
    }
    free(start);
    sm__free_large(ent, (nf ? nf : 1) * sizeof *ent);
    return SM_OK;
}
