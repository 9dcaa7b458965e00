/* Morton order (see sm_morton.h). */
#include "sm_morton.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* bit b of v (v < 2^32 in 2D, < 2^21 in 3D) goes to bit dim * b */
static uint64_t spread(uint64_t v, int dim)
{
    if (dim == 2) {
        v &= 0xffffffffull;
        v = (v | v << 16) & 0x0000ffff0000ffffull;
        v = (v | v << 8) & 0x00ff00ff00ff00ffull;
        v = (v | v << 4) & 0x0f0f0f0f0f0f0f0full;
        v = (v | v << 2) & 0x3333333333333333ull;
        return (v | v << 1) & 0x5555555555555555ull;
    }
    v &= 0x1fffffull;
    v = (v | v << 32) & 0x1f00000000ffffull;
    v = (v | v << 16) & 0x1f0000ff0000ffull;
    v = (v | v << 8) & 0x100f00f00f00f00full;
    v = (v | v << 4) & 0x10c30c30c30c30c3ull;
    return (v | v << 2) & 0x1249249249249249ull;
}

typedef struct keyed {
    uint64_t key;
    int64_t i;
} keyed;

/* Sorts by key, stably (least significant digit first, 11 bits a pass:
 * six passes for 64-bit keys, fewer when the high bits are all zero),
 * back and forth between a and tmp; returns the one holding the result. */
static keyed *radix_sort(keyed *a, keyed *tmp, int64_t n, uint64_t all_bits)
{
    enum { DIGIT = 11, BUCKETS = 1 << DIGIT };
    size_t count[BUCKETS];
    for (int shift = 0; shift < 64 && (all_bits >> shift) != 0; shift += DIGIT) {
        memset(count, 0, sizeof count);
        for (int64_t i = 0; i < n; i++)
            count[(a[i].key >> shift) & (BUCKETS - 1)]++;
        size_t sum = 0;
        for (int b = 0; b < BUCKETS; b++) {
            size_t c = count[b];
            count[b] = sum;
            sum += c;
        }
        for (int64_t i = 0; i < n; i++)
            tmp[count[(a[i].key >> shift) & (BUCKETS - 1)]++] = a[i];
        keyed *t = a;
        a = tmp;
        tmp = t;
    }
    return a;
}

int64_t *sm__morton_order(int dim, int64_t n, const double *pts)
{
    keyed *k = malloc(((size_t)n + 1) * sizeof *k);
    keyed *tmp = malloc(((size_t)n + 1) * sizeof *tmp);
    int64_t *order = malloc(((size_t)n + 1) * sizeof *order);
    if (!k || !tmp || !order) {
        free(k);
        free(tmp);
        free(order);
        return NULL;
    }
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int64_t i = 0; i < n; i++)
        for (int a = 0; a < dim; a++)
            if (isfinite(pts[i * dim + a])) {
                lo[a] = fmin(lo[a], pts[i * dim + a]);
                hi[a] = fmax(hi[a], pts[i * dim + a]);
            }
    int bits = dim == 3 ? 21 : 31;
    uint64_t all_bits = 0;
    for (int64_t i = 0; i < n; i++) {
        uint64_t key = 0;
        for (int a = 0; a < dim; a++) {
            double u = hi[a] > lo[a] ? (pts[i * dim + a] - lo[a]) / (hi[a] - lo[a]) : 0;
            u = u >= 0 ? (u <= 1 ? u : 1) : 0; /* NaN too */
            key |= spread((uint64_t)(u * (double)((1u << bits) - 1)), dim) << a;
        }
        k[i] = (keyed){key, i};
        all_bits |= key;
    }
    const keyed *sorted = radix_sort(k, tmp, n, all_bits);
    for (int64_t i = 0; i < n; i++)
        order[i] = sorted[i].i;
    free(k);
    free(tmp);
    return order;
}
