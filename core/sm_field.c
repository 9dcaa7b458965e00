/* Target field: P1 values on a background simplicial mesh.
 *
 * Point location, in order:
 *   1. visibility walk from the caller's hint (cross the facet with the
 *      most negative barycentric coordinate), skipped when the hint is far;
 *   2. the bucket grid cell of x: a walk from the cell's seed element (the
 *      one whose bounding box centre is nearest to the cell centre, or for
 *      a cell holding no box centre the seed of the nearest cell that
 *      does), a few steps at most;
 *   3. an exhaustive scan of the cell's list (elements whose bounding box
 *      meets the cell), which is the final answer: walks only stop early
 *      at gaps, overlaps, holes and concavities.
 * Outside points get value(p) + |x - p|, p the nearest point of the mesh,
 * searched over the facets without neighbour binned in the same grid.
 *
 * Per valid element we keep one record of doubles:
 *   origin (dim)          coordinates of local vertex 0
 *   inverse map (dim*dim) rows of J^-1, J = [v1-v0 | ... | vd-v0], so that
 *                         lambda_k = row_k . (x - origin), k = 1..dim
 *   value at origin (1)
 *   gradient (dim)        so that d(x) = value + gradient . (x - origin)
 * i.e. 9 doubles (72 B) per triangle and 16 doubles (128 B) per
 * tetrahedron, plus dim+1 neighbour indices and one validity byte.  With
 * the grid this comes to about 120 B per triangle and 205 B per
 * tetrahedron on Gmsh meshes (sm_field_get_stats reports it).
 * Barycentric coordinates then cost one small mat-vec with no access to
 * the mesh arrays, and the value needs no access to the vertex values.
 * Computing relative to a vertex (not in absolute affine form) keeps the
 * rounding error proportional to the element size even for boxes far from
 * the origin.
 *
 * What an evaluation costs is memory latency, not arithmetic: callers
 * sample points in no particular order, and mesh generators number
 * elements in no spatial order either, so every element a walk visits is
 * likely a cache miss (hundreds of cycles: the records of a 3D background
 * are tens of MiB).  Hence: a tetrahedron record fills exactly one aligned
 * 128-byte pair of cache lines, the records and the neighbour table sit on
 * huge pages where the system offers them (a TLB miss costs about as much
 * again, in a virtual machine at least), each walk step requests the
 * neighbours of its element before reading its record, so that the two
 * misses overlap, and the cell seeds are one array lookup.  The element
 * numbering stays the caller's: an internal renumbering would need a
 * public-to-internal map of the hint, one more miss per call.  What is
 * left is about one miss per element visited; sm_field_eval_many, for
 * many points with their own hints, keeps several walks in flight so
 * that their misses overlap.
 *
 * The construction avoids random memory traffic the same way, since the
 * vertex numbering is not spatial either: the adjacency distributes the
 * facets into buckets of their smallest vertex in two rounds of few
 * buckets each, then matches each bucket with a small hash table; whether
 * two elements sharing a facet lie on opposite sides of it comes from the
 * signs of their determinants, with no coordinate access.  The grid
 * lists are filled with the elements sorted by blocks of cells, and their
 * sizes come from a difference array.  The passes over the elements run
 * on the OpenMP threads by fixed chunks, so the structure does not depend
 * on the number of threads.  On a 345k-tetrahedron background this takes
 * about 0.2 s (before: 1 s), with the records and neighbours taking most
 * of the memory traffic.
 *
 * Orientation does not matter (barycentric coordinates are orientation
 * free), flat elements are skipped, and the structure is read-only after
 * sm_field_new: all scratch lives on the caller's stack. */
#include "sm_field.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>

/* Barycentric tolerance: a point is in an element when every coordinate is
 * >= -BARY_TOL.  Barycentric coordinates are dimensionless, so this is a
 * tolerance relative to the element size. */
#define BARY_TOL 1e-10
/* An element is degenerate when |det J| <= DEGENERATE_REL * hmax^dim. */
#define DEGENERATE_REL 1e-12
/* Element bounding boxes are inflated by this fraction of their extent
 * when binned, so points accepted within BARY_TOL are in a listed cell. */
#define BBOX_INFLATE 1e-8
/* Walk budget.  A good hint (the element of the same point at the previous
 * iteration) needs a handful of steps; past the budget the grid is
 * cheaper.  A hint whose barycentric coordinates put x more than
 * WALK_FAR_LAMBDA element heights away is not walked from at all: the walk
 * would take about that many steps, each a likely cache miss. */
#define WALK_MAX_STEPS 32
#define WALK_FAR_LAMBDA 8.0
/* Grid sizing: cells per valid element, and hard caps for hostile inputs
 * (few huge elements among tiny ones, extreme aspect ratios).  Elements are
 * binned by bounding box, and a tetrahedron's box is large compared to its
 * volume, so finer cells multiply the list entries quickly (about 25 per
 * tetrahedron at one cell per element for Gmsh meshes, 16 at one cell per
 * two); since a lookup walks from the cell's seed element, the number of
 * candidates per cell only matters for the exhaustive scan (points outside
 * the mesh but inside its box), and coarser 3D cells are the better deal. */
#define GRID_CELLS_PER_ELEM_2D 1.0
#define GRID_CELLS_PER_ELEM_3D 0.5
/* The coarse facet grid (far points) has about this many cells per
 * boundary facet: a few facets per non-empty cell. */
#define GRID_CELLS_PER_BFACET 1.0
/* Rings of the element grid searched for the nearest facet before moving
 * to the coarse facet grid. */
#define NEAR_RINGS 2
#define GRID_MAX_CELLS (1 << 24)
#define GRID_MAX_AXIS (1 << 20)
/* Arrays of at least this size are aligned to it and advised as huge pages
 * (the usual x86-64 and arm64 huge page: smaller arrays gain nothing). */
#define HUGE_PAGE_BYTES ((size_t)2 << 20)
/* Facets are matched in buckets of their smallest vertex, distributed in
 * two rounds of this fan-out: few enough write streams to stay in the
 * first-level cache, and small enough final buckets for their hash
 * tables to. */
#define ADJ_FANOUT_BITS 6
#define ADJ_FANOUT (1 << ADJ_FANOUT_BITS)
/* Elements whose vertex coordinates are requested ahead of their turn. */
#define PREFETCH_AHEAD 8
/* Values of the validity byte: usable, with det J > 0 or < 0. */
#define ELEM_VALID_POSITIVE 1
#define ELEM_VALID_NEGATIVE 2
/* Elements are sorted by blocks of cells, at most this many blocks. */
#define SORT_BLOCKS 1024
/* The parallel passes over the elements work on this many contiguous
 * chunks, whatever the number of threads (so their output does not
 * depend on it). */
#define BUILD_CHUNKS 16
/* sm_field_eval_many walks this many points together: enough misses in
 * flight to cover the memory latency, few enough to stay in registers
 * and first-level cache. */
#define EVAL_GROUP 16
/* Probes per entry a facet hash table may take before its bucket is
 * sorted instead (a fair table takes about one). */
#define HASH_PROBE_BUDGET 8

/* A uniform grid over a box; cells are numbered x fastest. */
typedef struct grid {
    int dim;
    double lo[3], hi[3], cell[3], inv_cell[3];
    int32_t n[3];
    int64_t ncells;
    double min_cell;
} grid;

struct sm_field {
    const sm_mesh *bg;
    const double *values;
    int dim;
    int stride;          /* doubles per element record */
    int32_t nelems;
    int32_t nvalid;
    double *rec;         /* nelems * stride (zeros for degenerate elements);
                          * from alloc_large (free_large) */
    uint8_t *valid;      /* nelems: 0 for a degenerate element, else
                          * ELEM_VALID_POSITIVE or _NEGATIVE (sign of det J) */
    int32_t *neigh;      /* nelems*(dim+1): across the facet opposite local
                          * vertex k, or -1 (boundary, gap, non-manifold);
                          * from alloc_large (free_large) */

    /* element grid over the bounding box of the valid elements */
    grid g;
    int32_t *cell_seed;  /* ncells: start of the walk for points of the
                          * cell, -1 when no element's box meets the cell */
    int32_t *elem_start; /* ncells+1 */
    int32_t *elem_list;  /* elements whose inflated bbox meets the cell */
    int32_t max_cell_elems;

    /* Facets without neighbour (the boundary of the union of the
     * elements, plus gaps), for the nearest point of outside points.  They
     * are binned twice: in the element grid, for points close to the mesh
     * (a couple of rings of small cells), and in a coarser grid sized by
     * their number, for points far from it (e.g. deep in a hole), where
     * rings of small cells would be mostly empty.  Cell entries index
     * bfacet_id / bfacet_xyz. */
    int32_t nbfacets;
    int32_t *bfacet_id;  /* e*(dim+1)+k */
    double *bfacet_xyz;  /* dim*dim: the facet's vertex coordinates */
    int32_t *facet_start;
    int32_t *facet_list;
    grid cg;
    int32_t *cfacet_start;
    int32_t *cfacet_list;
};

/* Allocation of the arrays every evaluation reads at random (records,
 * neighbours) and of the largest scratch arrays of the construction:
 * aligned to the 128-byte pair of cache lines the hardware fetches
 * together, and from HUGE_PAGE_BYTES on mapped directly, aligned to a
 * huge page and advised to be backed by huge pages (fewer TLB misses,
 * far fewer page faults when first written), and unmapped when freed, so
 * that the scratch goes back to the system instead of staying in the
 * allocator's heap.  Under AddressSanitizer everything goes through the
 * allocator, which checks the bounds.  Free with free_large(p, bytes). */
#if defined(__SANITIZE_ADDRESS__)
#define SM_FIELD_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define SM_FIELD_ASAN 1
#endif
#endif

static size_t round_up(size_t bytes, size_t align)
{
    size_t size = (bytes + align - 1) / align * align;
    return size < bytes ? 0 : size; /* 0: overflow */
}

static void *alloc_large(size_t bytes)
{
#if !defined(SM_FIELD_ASAN) && defined(MAP_ANONYMOUS)
    if (bytes >= HUGE_PAGE_BYTES) {
        size_t size = round_up(bytes, HUGE_PAGE_BYTES);
        if (!size || size + HUGE_PAGE_BYTES < size)
            return NULL;
        char *p = mmap(NULL, size + HUGE_PAGE_BYTES, PROT_READ | PROT_WRITE,
                       MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
        if (p == MAP_FAILED)
            return NULL;
        size_t head = (HUGE_PAGE_BYTES - (uintptr_t)p % HUGE_PAGE_BYTES) % HUGE_PAGE_BYTES;
        if (head)
            munmap(p, head);
        munmap(p + head + size, HUGE_PAGE_BYTES - head);
#ifdef MADV_HUGEPAGE
        (void)madvise(p + head, size, MADV_HUGEPAGE);
#endif
        return p + head;
    }
#endif
    size_t size = round_up(bytes ? bytes : 1, 128);
    return size ? aligned_alloc(128, size) : NULL;
}

static void free_large(void *p, size_t bytes)
{
    if (!p)
        return;
#if !defined(SM_FIELD_ASAN) && defined(MAP_ANONYMOUS)
    if (bytes >= HUGE_PAGE_BYTES) {
        munmap(p, round_up(bytes, HUGE_PAGE_BYTES));
        return;
    }
#endif
    (void)bytes;
    free(p);
}

/* First index of chunk c of n items split into BUILD_CHUNKS. */
static inline int32_t chunk_begin(int32_t n, int c)
{
    return (int32_t)((int64_t)n * c / BUILD_CHUNKS);
}

/* ------------------------------------------------------------------ */
/* Element records                                                     */

static inline __attribute__((always_inline)) void
bary_of(const double *r, const double *x, double *lam, const int D)
{
    if (D == 2) {
        double y0 = x[0] - r[0], y1 = x[1] - r[1];
        double l1 = r[2] * y0 + r[3] * y1;
        double l2 = r[4] * y0 + r[5] * y1;
        lam[0] = 1.0 - l1 - l2;
        lam[1] = l1;
        lam[2] = l2;
    } else {
        double y0 = x[0] - r[0], y1 = x[1] - r[1], y2 = x[2] - r[2];
        double l1 = r[3] * y0 + r[4] * y1 + r[5] * y2;
        double l2 = r[6] * y0 + r[7] * y1 + r[8] * y2;
        double l3 = r[9] * y0 + r[10] * y1 + r[11] * y2;
        lam[0] = 1.0 - l1 - l2 - l3;
        lam[1] = l1;
        lam[2] = l2;
        lam[3] = l3;
    }
}

static inline __attribute__((always_inline)) double
affine_value(const double *r, const double *x, const int D)
{
    const double *val = r + D + D * D;
    double v = val[0];
    for (int i = 0; i < D; i++)
        v += val[1 + i] * (x[i] - r[i]);
    return v;
}

static inline __attribute__((always_inline)) int
argmin_lam(const double *lam, const int D, double *lmin)
{
    int k = 0;
    double m = lam[0];
    for (int i = 1; i <= D; i++)
        if (lam[i] < m) {
            m = lam[i];
            k = i;
        }
    *lmin = m;
    return k;
}

static const double *vcoord(const sm_field *f, int32_t v)
{
    return f->bg->coords + (size_t)v * (size_t)f->dim;
}

/* Fills the record of element e and returns 1, with *negative set when
 * det J < 0; returns 0 (and a zero record) when the element is degenerate
 * (zero or non-finite volume, or a non-finite inverse). */
static inline __attribute__((always_inline)) int
build_record(sm_field *f, int32_t e, int *negative, const int D)
{
    const int32_t *ev = f->bg->elems + (size_t)e * (size_t)(D + 1);
    double *r = f->rec + (size_t)e * (size_t)(D + D * D + 1 + D);
    const double *p[4];
    for (int k = 0; k <= D; k++)
        p[k] = vcoord(f, ev[k]);
    double hmax2 = 0.0;
    for (int a = 0; a <= D; a++)
        for (int b = a + 1; b <= D; b++) {
            double l2 = 0.0;
            for (int i = 0; i < D; i++) {
                double t = p[b][i] - p[a][i];
                l2 += t * t;
            }
            if (l2 > hmax2)
                hmax2 = l2;
        }
    double c[3][3]; /* columns v_k - v_0 */
    for (int k = 0; k < D; k++)
        for (int i = 0; i < D; i++)
            c[k][i] = p[k + 1][i] - p[0][i];
    double M[3][3];
    double det;
    if (D == 2) {
        det = c[0][0] * c[1][1] - c[1][0] * c[0][1];
        if (!(fabs(det) > DEGENERATE_REL * hmax2))
            goto degenerate;
        M[0][0] = c[1][1] / det;
        M[0][1] = -c[1][0] / det;
        M[1][0] = -c[0][1] / det;
        M[1][1] = c[0][0] / det;
    } else {
        double x12[3] = {c[1][1] * c[2][2] - c[1][2] * c[2][1],
                         c[1][2] * c[2][0] - c[1][0] * c[2][2],
                         c[1][0] * c[2][1] - c[1][1] * c[2][0]};
        double x20[3] = {c[2][1] * c[0][2] - c[2][2] * c[0][1],
                         c[2][2] * c[0][0] - c[2][0] * c[0][2],
                         c[2][0] * c[0][1] - c[2][1] * c[0][0]};
        double x01[3] = {c[0][1] * c[1][2] - c[0][2] * c[1][1],
                         c[0][2] * c[1][0] - c[0][0] * c[1][2],
                         c[0][0] * c[1][1] - c[0][1] * c[1][0]};
        det = c[0][0] * x12[0] + c[0][1] * x12[1] + c[0][2] * x12[2];
        if (!(fabs(det) > DEGENERATE_REL * hmax2 * sqrt(hmax2)))
            goto degenerate;
        for (int i = 0; i < 3; i++) {
            M[0][i] = x12[i] / det;
            M[1][i] = x20[i] / det;
            M[2][i] = x01[i] / det;
        }
    }
    const double *val = f->values;
    double v0 = val[ev[0]];
    for (int i = 0; i < D; i++)
        r[i] = p[0][i];
    for (int k = 0; k < D; k++)
        for (int i = 0; i < D; i++)
            r[D + k * D + i] = M[k][i];
    r[D + D * D] = v0;
    for (int i = 0; i < D; i++) {
        double g = 0.0;
        for (int k = 0; k < D; k++)
            g += (val[ev[k + 1]] - v0) * M[k][i];
        r[D + D * D + 1 + i] = g;
    }
    for (int i = 0; i < D + D * D + 1 + D; i++)
        if (!isfinite(r[i]))
            goto degenerate;
    *negative = det < 0.0;
    return 1;
degenerate:
    memset(r, 0, (size_t)(D + D * D + 1 + D) * sizeof *r);
    *negative = 0;
    return 0;
}

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

/* The vertices of an element in ascending order (s) with their local
 * indices (loc); returns the parity of the permutation (1 when odd). */
static inline __attribute__((always_inline)) int
sorted_vertices(const int32_t *ev, const int nv, int32_t *s, int *loc)
{
    int parity = 0;
    for (int i = 0; i < nv; i++) {
        int32_t v = ev[i];
        int j = i;
        while (j > 0 && s[j - 1] > v) {
            s[j] = s[j - 1];
            loc[j] = loc[j - 1];
            parity ^= 1;
            j--;
        }
        s[j] = v;
        loc[j] = i;
    }
    return parity;
}

/* Vertices of facet k (opposite local vertex k) of element e, ascending. */
static void facet_vertices(const sm_field *f, int32_t e, int k, int32_t *out)
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

static sm_status build_adjacency(sm_field *f, int shift, size_t *counts, sm_error *err)
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
    facet_key *keys = alloc_large(sum * sizeof *keys);
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
    free_large(keys, sum * sizeof *keys);
    if (failed)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for element adjacency");
    return SM_OK;
}

/* Records, validity, the counts of the adjacency buckets and the bounding
 * box of the valid elements, in one pass over the elements (in parallel,
 * by chunks: every element writes only its own entries, every chunk its
 * own counts).  The coordinates of the elements a few steps ahead are
 * prefetched: the vertex numbering of mesh generators is rarely local,
 * and each element reads dim+1 scattered vertices. */
static inline __attribute__((always_inline)) void
build_elements_dim(sm_field *f, int shift, size_t *counts, double *lo, double *hi, const int D)
{
    const int32_t ne = f->nelems;
    const int32_t *elems = f->bg->elems;
    const double *coords = f->bg->coords;
    int32_t chunk_valid[BUILD_CHUNKS];
    double chunk_lo[BUILD_CHUNKS][3], chunk_hi[BUILD_CHUNKS][3];
#pragma omp parallel for schedule(static)
    for (int c = 0; c < BUILD_CHUNKS; c++) {
        size_t *my = counts + (size_t)c * ADJ_FANOUT;
        int32_t nvalid = 0, e1 = chunk_begin(ne, c + 1);
        double l[3] = {INFINITY, INFINITY, INFINITY}, h[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (int32_t e = chunk_begin(ne, c); e < e1; e++) {
            if (e + PREFETCH_AHEAD < ne) {
                const int32_t *pv = elems + (size_t)(e + PREFETCH_AHEAD) * (size_t)(D + 1);
                for (int k = 0; k <= D; k++) {
                    __builtin_prefetch(coords + (size_t)pv[k] * (size_t)D);
                    __builtin_prefetch(f->values + pv[k]);
                }
            }
            const int32_t *ev = elems + (size_t)e * (size_t)(D + 1);
            int negative;
            if (!build_record(f, e, &negative, D)) {
                f->valid[e] = 0;
                continue;
            }
            f->valid[e] = negative ? ELEM_VALID_NEGATIVE : ELEM_VALID_POSITIVE;
            nvalid++;
            /* with s0 < s1 < ... (distinct, or the element would be flat),
             * the facet opposite s0 has smallest vertex s1, the dim others
             * s0 */
            int32_t s[4];
            int loc[4];
            sorted_vertices(ev, D + 1, s, loc);
            my[(uint32_t)s[0] >> shift] += (size_t)D;
            my[(uint32_t)s[1] >> shift] += 1;
            for (int k = 0; k <= D; k++)
                for (int i = 0; i < D; i++) {
                    double x = coords[(size_t)ev[k] * (size_t)D + (size_t)i];
                    l[i] = x < l[i] ? x : l[i];
                    h[i] = x > h[i] ? x : h[i];
                }
        }
        chunk_valid[c] = nvalid;
        memcpy(chunk_lo[c], l, sizeof l);
        memcpy(chunk_hi[c], h, sizeof h);
    }
    f->nvalid = 0;
    for (int i = 0; i < 3; i++) {
        lo[i] = INFINITY;
        hi[i] = -INFINITY;
    }
    for (int c = 0; c < BUILD_CHUNKS; c++) {
        f->nvalid += chunk_valid[c];
        for (int i = 0; i < D; i++) {
            lo[i] = chunk_lo[c][i] < lo[i] ? chunk_lo[c][i] : lo[i];
            hi[i] = chunk_hi[c][i] > hi[i] ? chunk_hi[c][i] : hi[i];
        }
    }
}

/* ------------------------------------------------------------------ */
/* Grids                                                               */

static int32_t axis_cell(const grid *g, int i, double x)
{
    double t = (x - g->lo[i]) * g->inv_cell[i];
    if (!(t >= 0.0))
        return 0;
    if (t >= (double)g->n[i])
        return g->n[i] - 1;
    return (int32_t)t;
}

static int64_t cell_index(const grid *g, const int32_t *c)
{
    return c[0] + (int64_t)g->n[0] * (c[1] + (int64_t)g->n[1] * c[2]);
}

/* Cell range [c0, c1] (inclusive, per axis) covered by the box [a, b]
 * inflated by a fraction of its extent. */
static void box_cells(const grid *g, const double *a, const double *b, int32_t *c0,
                      int32_t *c1)
{
    for (int i = 0; i < g->dim; i++) {
        double pad = BBOX_INFLATE * (b[i] - a[i]) +
                     4.0 * 2.2e-16 * (fabs(a[i]) + fabs(b[i]));
        c0[i] = axis_cell(g, i, a[i] - pad);
        c1[i] = axis_cell(g, i, b[i] + pad);
    }
    for (int i = g->dim; i < 3; i++)
        c0[i] = c1[i] = 0;
}

/* Cells per axis for about `target` cells of cubic shape over the box
 * (computed in logarithms: extents may differ by many orders). */
static void grid_shape(const grid *g, double target, double *nd)
{
    const int D = g->dim;
    if (target > GRID_MAX_CELLS)
        target = GRID_MAX_CELLS;
    if (target < 1.0)
        target = 1.0;
    double logvol = 0.0;
    for (int i = 0; i < D; i++)
        logvol += log(g->hi[i] - g->lo[i]);
    double logc = (logvol - log(target)) / D;
    nd[0] = nd[1] = nd[2] = 1.0;
    for (int i = 0; i < D; i++) {
        double t = exp(log(g->hi[i] - g->lo[i]) - logc);
        nd[i] = t < 1.0 ? 1.0 : t > GRID_MAX_AXIS ? GRID_MAX_AXIS : ceil(t - 1e-9);
    }
    while (nd[0] * nd[1] * nd[2] > GRID_MAX_CELLS) {
        int big = 0;
        for (int i = 1; i < D; i++)
            if (nd[i] > nd[big])
                big = i;
        nd[big] = ceil(nd[big] / 2);
    }
}

static void grid_set_axes(grid *g, const double *nd)
{
    g->ncells = 1;
    g->min_cell = INFINITY;
    for (int i = 0; i < 3; i++) {
        if (i >= g->dim) {
            g->n[i] = 1;
            g->lo[i] = g->hi[i] = 0.0;
            g->cell[i] = g->inv_cell[i] = 1.0;
            continue;
        }
        g->n[i] = (int32_t)nd[i];
        double ext = g->hi[i] - g->lo[i];
        g->cell[i] = ext / g->n[i];
        g->inv_cell[i] = g->n[i] / ext;
        if (g->cell[i] < g->min_cell)
            g->min_cell = g->cell[i];
        g->ncells *= g->n[i];
    }
}

/* What a grid bins: the valid elements ids[0..n-1] (boxes from the
 * vertex coordinates, the lists hold the ids), or n boxes of 2*dim
 * doubles, lo then hi (the lists hold their index). */
typedef struct bin_items {
    const sm_field *f;
    const int32_t *ids;
    const double *boxes;
    int32_t n;
} bin_items;

/* Box of item j; the vertices of item j + PREFETCH_AHEAD are requested. */
static inline __attribute__((always_inline)) void
item_box(const bin_items *it, int32_t j, double *a, double *b, const int D)
{
    if (!it->ids) {
        const double *bx = it->boxes + (size_t)j * (size_t)(2 * D);
        memcpy(a, bx, (size_t)D * sizeof *a);
        memcpy(b, bx + D, (size_t)D * sizeof *b);
        return;
    }
    const int32_t *elems = it->f->bg->elems;
    const double *coords = it->f->bg->coords;
    if (j + PREFETCH_AHEAD < it->n) {
        const int32_t *pv = elems + (size_t)it->ids[j + PREFETCH_AHEAD] * (size_t)(D + 1);
        for (int k = 0; k <= D; k++)
            __builtin_prefetch(coords + (size_t)pv[k] * (size_t)D);
    }
    const int32_t *ev = elems + (size_t)it->ids[j] * (size_t)(D + 1);
    for (int i = 0; i < D; i++)
        a[i] = b[i] = coords[(size_t)ev[0] * (size_t)D + (size_t)i];
    for (int k = 1; k <= D; k++)
        for (int i = 0; i < D; i++) {
            double x = coords[(size_t)ev[k] * (size_t)D + (size_t)i];
            a[i] = x < a[i] ? x : a[i];
            b[i] = x > b[i] ? x : b[i];
        }
}

static inline __attribute__((always_inline)) int64_t
count_entries_dim(const grid *g, const bin_items *it, const int D)
{
    int64_t total = 0;
#pragma omp parallel for schedule(static) reduction(+ : total)
    for (int32_t j = 0; j < it->n; j++) {
        double a[3], b[3];
        int32_t c0[3], c1[3];
        item_box(it, j, a, b, D);
        box_cells(g, a, b, c0, c1);
        total += (int64_t)(c1[0] - c0[0] + 1) * (c1[1] - c0[1] + 1) * (c1[2] - c0[2] + 1);
    }
    return total;
}

static int64_t count_entries(const grid *g, const bin_items *it)
{
    return g->dim == 2 ? count_entries_dim(g, it, 2) : count_entries_dim(g, it, 3);
}

/* Shapes g for about `target` cells, coarsening until the lists hold at
 * most `limit` entries; returns the entry count. */
static int64_t grid_fit(grid *g, double target, const bin_items *it, int64_t limit)
{
    double nd[3];
    grid_shape(g, target, nd);
    for (;;) {
        grid_set_axes(g, nd);
        int64_t total = count_entries(g, it);
        if (total <= limit || g->ncells == 1)
            return total;
        for (int i = 0; i < g->dim; i++)
            nd[i] = nd[i] > 1 ? floor(nd[i] * 0.8) : 1;
    }
}

static sm_status grid_lists_alloc(const grid *g, int64_t total, int32_t **start, int32_t **list,
                                  sm_error *err)
{
    if (total > INT32_MAX - 1)
        return sm_error_set(err, SM_ERR_NOMEM,
                            "point location grid too large (%lld entries)", (long long)total);
    *start = calloc((size_t)g->ncells + 1, sizeof **start);
    *list = malloc((size_t)total * sizeof **list + 1);
    if (!*start || !*list)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the point location grid");
    return SM_OK;
}

/* Cell ranges of the items, in the order the lists are filled. */
typedef struct item_cells {
    int32_t c0[3], c1[3];
    int32_t id;   /* what the cell lists hold */
    int32_t cell; /* elements: the cell of the box centre */
    double d2;    /* elements: squared distance of the box centre to the
                   * centre of that cell */
} item_cells;

/* CSR lists from the cell ranges (in their order, which is also the order
 * inside each list).  start[] is zero on entry.  The counts per cell come
 * from a difference array (+-1 at the 2^dim corners of every range, then
 * running sums along each axis), so only the fill touches every entry. */
static sm_status fill_lists(const grid *g, const item_cells *it, int32_t n, int32_t *start,
                            int32_t *list, sm_error *err)
{
    const int D = g->dim;
    const int64_t m[3] = {g->n[0] + 1, g->n[1] + 1, D == 3 ? g->n[2] + 1 : 1};
    const int64_t stride[3] = {1, m[0], m[0] * m[1]};
    int32_t *diff = calloc((size_t)(m[0] * m[1] * m[2]), sizeof *diff);
    if (!diff)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the point location grid");
    for (int32_t t = 0; t < n; t++) {
        const item_cells *ic = &it[t];
        for (int corner = 0; corner < (1 << D); corner++) {
            int64_t idx = 0;
            int32_t sign = 1;
            for (int i = 0; i < D; i++)
                if (corner >> i & 1) {
                    idx += (ic->c1[i] + 1) * stride[i];
                    sign = -sign;
                } else {
                    idx += ic->c0[i] * stride[i];
                }
            diff[idx] += sign;
        }
    }
    for (int i = 0; i < D; i++) {
        int64_t idx = 0, c[3];
        for (c[2] = 0; c[2] < m[2]; c[2]++)
            for (c[1] = 0; c[1] < m[1]; c[1]++)
                for (c[0] = 0; c[0] < m[0]; c[0]++, idx++)
                    if (c[i] > 0)
                        diff[idx] += diff[idx - stride[i]];
    }
    /* start[c] = entries before cell c: the write position of cell c */
    int64_t cell = 0;
    int32_t sum = 0;
    for (int32_t z = 0; z < g->n[2]; z++)
        for (int32_t y = 0; y < g->n[1]; y++) {
            const int32_t *row = diff + z * stride[2] + y * stride[1];
            for (int32_t x = 0; x < g->n[0]; x++, cell++) {
                start[cell] = sum;
                sum += row[x];
            }
        }
    free(diff);
    for (int32_t t = 0; t < n; t++) {
        const item_cells *ic = &it[t];
        int32_t c[3];
        for (c[2] = ic->c0[2]; c[2] <= ic->c1[2]; c[2]++)
            for (c[1] = ic->c0[1]; c[1] <= ic->c1[1]; c[1]++) {
                int32_t *pos = start + cell_index(g, (int32_t[3]){ic->c0[0], c[1], c[2]});
                for (int32_t k = 0; k <= ic->c1[0] - ic->c0[0]; k++)
                    list[pos[k]++] = ic->id;
            }
    }
    /* each position now ends its cell, i.e. starts the next one */
    memmove(start + 1, start, (size_t)g->ncells * sizeof *start);
    start[0] = 0;
    return SM_OK;
}

/* Lists of the boxes meeting each cell (in increasing order). */
static sm_status bin_boxes(const grid *g, const bin_items *items, int64_t total,
                           int32_t **start, int32_t **list, sm_error *err)
{
    sm_status st = grid_lists_alloc(g, total, start, list, err);
    if (st != SM_OK)
        return st;
    item_cells *it = malloc((size_t)items->n * sizeof *it + 1);
    if (!it)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the point location grid");
    for (int32_t j = 0; j < items->n; j++) {
        const double *bx = items->boxes + (size_t)j * (size_t)(2 * g->dim);
        box_cells(g, bx, bx + g->dim, it[j].c0, it[j].c1);
        it[j].id = j;
    }
    st = fill_lists(g, it, items->n, *start, *list, err);
    free(it);
    return st;
}

/* Cells holding no box centre take the seed of the nearest cell that does
 * (L1 distance in cells, by the separable distance transform: a forward
 * and a backward sweep along each axis in turn, each visiting the cells
 * in memory order), so that a walk from the seed of any cell starts close
 * by. */
static sm_status spread_seeds(const grid *g, int32_t *seed, sm_error *err)
{
    const int64_t nc = g->ncells;
    int32_t *dist = malloc((size_t)nc * sizeof *dist + 1);
    if (!dist)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the point location grid");
    for (int64_t c = 0; c < nc; c++)
        dist[c] = seed[c] >= 0 ? 0 : INT32_MAX;
    const int64_t step[3] = {1, g->n[0], (int64_t)g->n[0] * g->n[1]};
    for (int i = 0; i < g->dim; i++) {
        for (int dir = 0; dir < 2; dir++) {
            /* t counts the steps of the sweep along each axis (cells in
             * increasing order forward, decreasing backward); the cell one
             * step back along axis i exists when t[i] > 0 */
            int64_t idx = dir == 0 ? 0 : nc - 1, back = dir == 0 ? -step[i] : step[i];
            int32_t t[3];
            for (t[2] = 0; t[2] < g->n[2]; t[2]++)
                for (t[1] = 0; t[1] < g->n[1]; t[1]++)
                    for (t[0] = 0; t[0] < g->n[0]; t[0]++) {
                        if (t[i] > 0) {
                            int64_t from = idx + back;
                            if (dist[from] != INT32_MAX && dist[from] + 1 < dist[idx]) {
                                dist[idx] = dist[from] + 1;
                                seed[idx] = seed[from];
                            }
                        }
                        idx += dir == 0 ? 1 : -1;
                    }
        }
    }
    free(dist);
    return SM_OK;
}

/* Cell ranges, centre cell and its block, for item j. */
static inline __attribute__((always_inline)) void
element_cells(const grid *g, const bin_items *items, int32_t j, int shift, const int32_t *nb,
              item_cells *ic, int32_t *block, const int D)
{
    double a[3], b[3];
    item_box(items, j, a, b, D);
    int32_t c[3] = {0, 0, 0};
    ic->d2 = 0.0;
    for (int i = 0; i < D; i++) {
        double mid = 0.5 * (a[i] + b[i]);
        c[i] = axis_cell(g, i, mid);
        double t = mid - (g->lo[i] + (c[i] + 0.5) * g->cell[i]);
        ic->d2 += t * t;
    }
    ic->cell = (int32_t)cell_index(g, c);
    ic->id = items->ids[j];
    box_cells(g, a, b, ic->c0, ic->c1);
    *block = (c[0] >> shift) + nb[0] * ((c[1] >> shift) + nb[1] * (c[2] >> shift));
}

/* The cell ranges of the elements in grid g (it[j], with the block of
 * their box centre in block_of[j] and the count of every block in every
 * chunk in pos); returns the number of list entries.  In parallel by
 * chunks of elements. */
static inline __attribute__((always_inline)) int64_t
element_ranges_dim(const grid *g, const bin_items *items, int shift, const int32_t *nb,
                   int64_t nblocks, item_cells *it, int32_t *block_of, int32_t *pos, const int D)
{
    int64_t total = 0;
#pragma omp parallel for schedule(static) reduction(+ : total)
    for (int c = 0; c < BUILD_CHUNKS; c++) {
        int32_t *my = pos + (size_t)c * (size_t)nblocks;
        for (int32_t j = chunk_begin(items->n, c); j < chunk_begin(items->n, c + 1); j++) {
            item_cells *ic = &it[j];
            element_cells(g, items, j, shift, nb, ic, &block_of[j], D);
            my[block_of[j]]++;
            total += (int64_t)(ic->c1[0] - ic->c0[0] + 1) * (ic->c1[1] - ic->c0[1] + 1) *
                     (ic->c1[2] - ic->c0[2] + 1);
        }
    }
    return total;
}

/* Element grid: shapes g (about `target` cells, coarser while the lists
 * would exceed `limit` entries), then the lists of the elements whose
 * inflated box meets each cell and the seed of each cell, the element
 * whose box centre is nearest to the cell centre (smallest id on ties).
 * The elements are sorted by blocks of cells of their box centre first (a
 * counting sort by chunks: every chunk of elements writes its own range of
 * every block, so the order is that of the elements whatever the threads,
 * with few enough blocks that the write streams stay in cache); filling
 * the lists and choosing the seeds then write to neighbouring cells in
 * turn. */
static sm_status bin_elements(sm_field *f, const bin_items *items, double target, int64_t limit,
                              sm_error *err)
{
    grid *g = &f->g;
    const int32_t n = items->n;
    sm_status st = SM_OK;
    item_cells *it = alloc_large((size_t)n * sizeof *it);
    item_cells *sorted = NULL;
    int32_t *block_of = malloc((size_t)n * sizeof *block_of + 1);
    int32_t *pos = NULL;
    double *best = NULL;
    if (!it || !block_of)
        goto nomem;
    double nd[3];
    int64_t total, nblocks;
    grid_shape(g, target, nd);
    for (;;) {
        grid_set_axes(g, nd);
        int shift = 0;
        int32_t nb[3];
        for (;;) {
            nblocks = 1;
            for (int i = 0; i < 3; i++) {
                nb[i] = ((g->n[i] - 1) >> shift) + 1;
                nblocks *= nb[i];
            }
            if (nblocks <= SORT_BLOCKS)
                break;
            shift++;
        }
        free(pos);
        pos = calloc((size_t)BUILD_CHUNKS * (size_t)nblocks, sizeof *pos);
        if (!pos)
            goto nomem;
        total = f->dim == 2 ? element_ranges_dim(g, items, shift, nb, nblocks, it, block_of, pos, 2)
                            : element_ranges_dim(g, items, shift, nb, nblocks, it, block_of, pos, 3);
        if (total <= limit || g->ncells == 1)
            break;
        for (int i = 0; i < g->dim; i++)
            nd[i] = nd[i] > 1 ? floor(nd[i] * 0.8) : 1;
    }
    int32_t sum = 0;
    for (int64_t b = 0; b < nblocks; b++)
        for (int c = 0; c < BUILD_CHUNKS; c++) {
            int32_t k = pos[(size_t)c * (size_t)nblocks + (size_t)b];
            pos[(size_t)c * (size_t)nblocks + (size_t)b] = sum;
            sum += k;
        }
    sorted = alloc_large((size_t)n * sizeof *sorted);
    if (!sorted)
        goto nomem;
#pragma omp parallel for schedule(static)
    for (int c = 0; c < BUILD_CHUNKS; c++) {
        int32_t *my = pos + (size_t)c * (size_t)nblocks;
        for (int32_t j = chunk_begin(n, c); j < chunk_begin(n, c + 1); j++)
            sorted[my[block_of[j]]++] = it[j];
    }
    free_large(it, (size_t)n * sizeof *it);
    it = NULL;
    free(block_of);
    block_of = NULL;
    free(pos);
    pos = NULL;

    const int64_t nc = g->ncells;
    best = malloc((size_t)nc * sizeof *best + 1);
    f->cell_seed = malloc((size_t)nc * sizeof *f->cell_seed + 1);
    if (!best || !f->cell_seed)
        goto nomem;
    for (int64_t c = 0; c < nc; c++) {
        f->cell_seed[c] = -1;
        best[c] = INFINITY;
    }
    for (int32_t t = 0; t < n; t++) {
        int32_t c = sorted[t].cell;
        if (sorted[t].d2 < best[c] || (sorted[t].d2 == best[c] && sorted[t].id < f->cell_seed[c])) {
            best[c] = sorted[t].d2;
            f->cell_seed[c] = sorted[t].id;
        }
    }
    free(best);
    best = NULL;
    st = spread_seeds(g, f->cell_seed, err);
    if (st == SM_OK)
        st = grid_lists_alloc(g, total, &f->elem_start, &f->elem_list, err);
    if (st == SM_OK)
        st = fill_lists(g, sorted, n, f->elem_start, f->elem_list, err);
    if (st != SM_OK)
        goto done;
    f->max_cell_elems = 0;
    for (int64_t c = 0; c < nc; c++) {
        int32_t len = f->elem_start[c + 1] - f->elem_start[c];
        if (len > f->max_cell_elems)
            f->max_cell_elems = len;
        if (len == 0)
            f->cell_seed[c] = -1; /* no element can hold a point of the cell */
    }
    goto done;
nomem:
    st = sm_error_set(err, SM_ERR_NOMEM, "out of memory for the point location grid");
done:
    free_large(it, (size_t)n * sizeof *it);
    free_large(sorted, (size_t)n * sizeof *sorted);
    free(block_of);
    free(pos);
    free(best);
    return st;
}

/* The grids, over the bounding box lo, hi of the valid elements. */
static sm_status build_grids(sm_field *f, const double *lo, const double *hi, sm_error *err)
{
    const int D = f->dim, nv1 = D + 1;
    grid *g = &f->g;
    g->dim = D;
    for (int i = 0; i < D; i++) {
        /* a hair of margin so that points on the box are inside it */
        double pad = 1e-9 * (hi[i] - lo[i]) + 4.0 * 2.2e-16 * (fabs(lo[i]) + fabs(hi[i]));
        g->lo[i] = lo[i] - pad;
        g->hi[i] = hi[i] + pad;
        double ext = g->hi[i] - g->lo[i];
        if (!(ext > 0.0) || !isfinite(ext))
            return sm_error_set(err, SM_ERR_INVALID,
                                "background bounding box has an unusable extent %g on axis %d",
                                ext, i);
    }

    /* Elements.  Hostile inputs (huge elements among tiny ones) can make
     * the lists explode: coarsen until they stay a small multiple of the
     * elements. */
    int32_t *ids = malloc((size_t)f->nvalid * sizeof *ids + 1);
    if (!ids)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the point location grid");
    int32_t nit = 0;
    for (int32_t e = 0; e < f->nelems; e++)
        if (f->valid[e])
            ids[nit++] = e;
    const bin_items elements = {f, ids, NULL, nit};
    int64_t limit = 32 * (int64_t)f->nvalid + (1 << 20);
    double per_elem = D == 2 ? GRID_CELLS_PER_ELEM_2D : GRID_CELLS_PER_ELEM_3D;
    sm_status st = bin_elements(f, &elements, per_elem * f->nvalid, limit, err);
    free(ids);
    if (st != SM_OK)
        return st;

    /* Boundary facets, their coordinates, and both facet grids. */
    int32_t nb = 0;
    for (int32_t e = 0; e < f->nelems; e++)
        if (f->valid[e])
            for (int k = 0; k <= D; k++)
                nb += f->neigh[(size_t)e * (size_t)nv1 + (size_t)k] < 0;
    f->bfacet_id = malloc((size_t)nb * sizeof *f->bfacet_id + 1);
    f->bfacet_xyz = malloc((size_t)nb * (size_t)(D * D) * sizeof(double) + 1);
    double *fboxes = malloc((size_t)nb * (size_t)(2 * D) * sizeof *fboxes + 1);
    if (!f->bfacet_id || !f->bfacet_xyz || !fboxes) {
        free(fboxes);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the boundary facets");
    }
    nb = 0;
    for (int32_t e = 0; e < f->nelems; e++)
        if (f->valid[e])
            for (int k = 0; k <= D; k++)
                if (f->neigh[(size_t)e * (size_t)nv1 + (size_t)k] < 0)
                    f->bfacet_id[nb++] = e * nv1 + k;
    f->nbfacets = nb;
    for (int32_t j = 0; j < nb; j++) {
        int32_t fv[3];
        facet_vertices(f, f->bfacet_id[j] / nv1, f->bfacet_id[j] % nv1, fv);
        double *a = fboxes + (size_t)j * (size_t)(2 * D), *b = a + D;
        for (int k = 0; k < D; k++) {
            const double *p = vcoord(f, fv[k]);
            memcpy(f->bfacet_xyz + ((size_t)j * D + k) * D, p, (size_t)D * sizeof(double));
            for (int i = 0; i < D; i++) {
                a[i] = k == 0 || p[i] < a[i] ? p[i] : a[i];
                b[i] = k == 0 || p[i] > b[i] ? p[i] : b[i];
            }
        }
    }
    const bin_items facets = {f, NULL, fboxes, nb};
    int64_t total = count_entries(g, &facets);
    st = bin_boxes(g, &facets, total, &f->facet_start, &f->facet_list, err);
    if (st == SM_OK) {
        f->cg = *g;
        total = grid_fit(&f->cg, GRID_CELLS_PER_BFACET * nb, &facets, 8 * (int64_t)nb + (1 << 16));
        st = bin_boxes(&f->cg, &facets, total, &f->cfacet_start, &f->cfacet_list, err);
    }
    free(fboxes);
    return st;
}

/* ------------------------------------------------------------------ */
/* Construction                                                        */

void sm_field_free(sm_field *f)
{
    if (!f)
        return;
    free_large(f->rec, (size_t)f->nelems * (size_t)f->stride * sizeof *f->rec);
    free(f->valid);
    free_large(f->neigh, (size_t)f->nelems * (size_t)(f->dim + 1) * sizeof *f->neigh);
    free(f->cell_seed);
    free(f->elem_start);
    free(f->elem_list);
    free(f->bfacet_id);
    free(f->bfacet_xyz);
    free(f->facet_start);
    free(f->facet_list);
    free(f->cfacet_start);
    free(f->cfacet_list);
    free(f);
}

sm_status sm_field_new(const sm_mesh *bg, const double *values, sm_field **out,
                       sm_error *err)
{
    if (!out)
        return sm_error_set(err, SM_ERR_INVALID, "sm_field_new: no output pointer");
    *out = NULL;
    if (!bg || !values)
        return sm_error_set(err, SM_ERR_INVALID, "sm_field_new: missing background mesh or values");
    if (bg->dim != 2 && bg->dim != 3)
        return sm_error_set(err, SM_ERR_INVALID,
                            "background mesh dimension %d is not 2 or 3", bg->dim);
    if (bg->nelems <= 0 || bg->nverts <= 0)
        return sm_error_set(err, SM_ERR_INVALID,
                            "background mesh is empty (%ld vertices, %ld elements)",
                            (long)bg->nverts, (long)bg->nelems);
    if (bg->nelems > SM_MAX_ENTITIES || bg->nverts > SM_MAX_ENTITIES)
        return sm_error_set(err, SM_ERR_NOMEM, "background mesh too large");
    if (!bg->coords || !bg->elems)
        return sm_error_set(err, SM_ERR_INVALID, "background mesh has no coordinates or elements");
    const int D = bg->dim;
    for (int32_t v = 0; v < bg->nverts; v++) {
        if (!isfinite(values[v]))
            return sm_error_set(err, SM_ERR_INVALID,
                                "distance value at vertex %ld is not finite (%g)",
                                (long)v + 1, values[v]);
        for (int i = 0; i < D; i++)
            if (!isfinite(bg->coords[(size_t)v * D + i]))
                return sm_error_set(err, SM_ERR_INVALID,
                                    "background vertex %ld has a non-finite coordinate",
                                    (long)v + 1);
    }
    for (size_t i = 0; i < (size_t)bg->nelems * (size_t)(D + 1); i++)
        if (bg->elems[i] < 0 || bg->elems[i] >= bg->nverts)
            return sm_error_set(err, SM_ERR_INVALID,
                                "background element %ld refers to vertex %ld (mesh has %ld)",
                                (long)(i / (size_t)(D + 1)) + 1, (long)bg->elems[i] + 1,
                                (long)bg->nverts);

    sm_field *f = calloc(1, sizeof *f);
    if (!f)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    f->bg = bg;
    f->values = values;
    f->dim = D;
    f->stride = D + D * D + 1 + D;
    f->nelems = bg->nelems;
    f->rec = alloc_large((size_t)bg->nelems * (size_t)f->stride * sizeof *f->rec);
    f->valid = calloc((size_t)bg->nelems, 1);
    f->neigh = alloc_large((size_t)bg->nelems * (size_t)(D + 1) * sizeof *f->neigh);
    if (!f->rec || !f->valid || !f->neigh) {
        sm_field_free(f);
        return sm_error_set(err, SM_ERR_NOMEM,
                            "out of memory for %ld background elements", (long)bg->nelems);
    }
    /* adjacency buckets: the top ADJ_FANOUT_BITS bits of a vertex index */
    int shift = 0;
    while (((uint32_t)(bg->nverts - 1) >> shift) >= ADJ_FANOUT)
        shift++;
    size_t counts[BUILD_CHUNKS * ADJ_FANOUT];
    memset(counts, 0, sizeof counts);
    double lo[3], hi[3];
    if (D == 2)
        build_elements_dim(f, shift, counts, lo, hi, 2);
    else
        build_elements_dim(f, shift, counts, lo, hi, 3);
    sm_status st = SM_OK;
    if (f->nvalid == 0)
        st = sm_error_set(err, SM_ERR_INVALID,
                          "background mesh has no element of non-zero volume (%ld elements, all degenerate)",
                          (long)bg->nelems);
    if (st == SM_OK)
        st = build_adjacency(f, shift, counts, err);
    if (st == SM_OK)
        st = build_grids(f, lo, hi, err);
    if (st != SM_OK) {
        sm_field_free(f);
        return st;
    }
    *out = f;
    return SM_OK;
}

int sm_field_dim(const sm_field *f)
{
    return f->dim;
}

/* ------------------------------------------------------------------ */
/* Location                                                            */

/* Visibility walk from element e: cross the facet with the most negative
 * barycentric coordinate.  Returns the element containing x (bary in lam)
 * or -1 when the walk leaves the mesh or runs out of steps.  With
 * far_lambda > 0, gives up at once when x is that many element heights
 * beyond the start element.  The neighbours of e are requested before its
 * record is read: both are cache misses, and this way they overlap. */
static inline __attribute__((always_inline)) int32_t
walk_dim(const sm_field *f, const double *x, int32_t e, double far_lambda, double *lam,
         const int D)
{
    const double *rec = f->rec;
    const int32_t *neigh = f->neigh;
    double lmin;
    for (int step = 0; step < WALK_MAX_STEPS; step++) {
        __builtin_prefetch(neigh + (size_t)e * (D + 1));
        bary_of(rec + (size_t)e * (size_t)(D + D * D + 1 + D), x, lam, D);
        int k = argmin_lam(lam, D, &lmin);
        if (lmin >= -BARY_TOL)
            return e;
        if (step == 0 && far_lambda > 0.0 && lmin < -far_lambda)
            return -1;
        e = neigh[(size_t)e * (D + 1) + k];
        if (e < 0)
            return -1;
    }
    return -1;
}

static inline __attribute__((always_inline)) int32_t
locate_dim(const sm_field *f, const double *x, int32_t hint, double *bary, const int D)
{
    double lam[4], lmin;
    int32_t e = -1;
    for (int i = 0; i < D; i++)
        if (!isfinite(x[i]))
            return -1;
    if (hint >= 0 && hint < f->nelems && f->valid[hint]) {
        e = walk_dim(f, x, hint, WALK_FAR_LAMBDA, lam, D);
        if (e >= 0)
            goto found;
    }
    for (int i = 0; i < D; i++)
        if (!(x[i] >= f->g.lo[i] && x[i] <= f->g.hi[i]))
            return -1;
    int32_t c[3] = {0, 0, 0};
    for (int i = 0; i < D; i++)
        c[i] = axis_cell(&f->g, i, x[i]);
    int64_t idx = cell_index(&f->g, c);
    int32_t seed = f->cell_seed[idx];
    if (seed < 0)
        return -1; /* no element's box meets the cell */
    e = walk_dim(f, x, seed, 0.0, lam, D);
    if (e >= 0)
        goto found;
    /* The cell lists are exhaustive: scanning one is the final answer
     * (non-convex or non-conforming parts, points outside). */
    int32_t j0 = f->elem_start[idx], j1 = f->elem_start[idx + 1];
    double best_min = -INFINITY, best_lam[4] = {0, 0, 0, 0};
    e = -1;
    for (int32_t j = j0; j < j1; j++) {
        int32_t cand = f->elem_list[j];
        bary_of(f->rec + (size_t)cand * (size_t)(D + D * D + 1 + D), x, lam, D);
        argmin_lam(lam, D, &lmin);
        if (lmin > best_min) {
            best_min = lmin;
            e = cand;
            memcpy(best_lam, lam, sizeof lam);
            if (lmin >= 0.0)
                break; /* inside or on it: no better answer */
        }
    }
    if (e < 0 || best_min < -BARY_TOL)
        return -1;
    memcpy(lam, best_lam, sizeof lam);
found:
    if (bary)
        memcpy(bary, lam, (size_t)(D + 1) * sizeof *bary);
    return e;
}

int32_t sm_field_locate(const sm_field *f, const double *x, int32_t hint, double *bary)
{
    if (f->dim == 2)
        return locate_dim(f, x, hint, bary, 2);
    return locate_dim(f, x, hint, bary, 3);
}

/* ------------------------------------------------------------------ */
/* Nearest point of the mesh for outside points                        */

static void closest_on_segment(const double *x, const double *a, const double *b,
                               double *p)
{
    double ab[2] = {b[0] - a[0], b[1] - a[1]};
    double ax[2] = {x[0] - a[0], x[1] - a[1]};
    double l2 = ab[0] * ab[0] + ab[1] * ab[1];
    double t = l2 > 0.0 ? (ax[0] * ab[0] + ax[1] * ab[1]) / l2 : 0.0;
    if (!(t > 0.0))
        t = 0.0;
    else if (t > 1.0)
        t = 1.0;
    p[0] = a[0] + t * ab[0];
    p[1] = a[1] + t * ab[1];
}

static double dot3(const double *u, const double *v)
{
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
}

/* Closest point of triangle abc to x, by the Voronoi regions of the
 * vertices, edges and face (no division by a vanishing quantity: the
 * face case divides by the sum of three positive terms). */
static void closest_on_triangle(const double *x, const double *a, const double *b,
                                const double *c, double *p)
{
    double ab[3], ac[3], ax[3], bx[3], cx[3];
    for (int i = 0; i < 3; i++) {
        ab[i] = b[i] - a[i];
        ac[i] = c[i] - a[i];
        ax[i] = x[i] - a[i];
        bx[i] = x[i] - b[i];
        cx[i] = x[i] - c[i];
    }
    double d1 = dot3(ab, ax), d2 = dot3(ac, ax);
    if (d1 <= 0.0 && d2 <= 0.0) {
        memcpy(p, a, 3 * sizeof *p);
        return;
    }
    double d3 = dot3(ab, bx), d4 = dot3(ac, bx);
    if (d3 >= 0.0 && d4 <= d3) {
        memcpy(p, b, 3 * sizeof *p);
        return;
    }
    double vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
        double t = d1 - d3 > 0.0 ? d1 / (d1 - d3) : 0.0;
        for (int i = 0; i < 3; i++)
            p[i] = a[i] + t * ab[i];
        return;
    }
    double d5 = dot3(ab, cx), d6 = dot3(ac, cx);
    if (d6 >= 0.0 && d5 <= d6) {
        memcpy(p, c, 3 * sizeof *p);
        return;
    }
    double vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
        double t = d2 - d6 > 0.0 ? d2 / (d2 - d6) : 0.0;
        for (int i = 0; i < 3; i++)
            p[i] = a[i] + t * ac[i];
        return;
    }
    double va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0) {
        double den = (d4 - d3) + (d5 - d6);
        double t = den > 0.0 ? (d4 - d3) / den : 0.0;
        for (int i = 0; i < 3; i++)
            p[i] = b[i] + t * (c[i] - b[i]);
        return;
    }
    double sum = va + vb + vc;
    double v = sum > 0.0 ? vb / sum : 0.0, w = sum > 0.0 ? vc / sum : 0.0;
    for (int i = 0; i < 3; i++)
        p[i] = a[i] + v * ab[i] + w * ac[i];
}

/* Squared distance from x to grid cell c. */
static double cell_dist2(const grid *g, const int32_t *c, const double *x)
{
    double d2 = 0.0;
    for (int i = 0; i < g->dim; i++) {
        double a = g->lo[i] + c[i] * g->cell[i], b = a + g->cell[i];
        double t = x[i] < a ? a - x[i] : x[i] > b ? x[i] - b : 0.0;
        d2 += t * t;
    }
    return d2;
}

typedef struct nearest_state {
    double best2;   /* squared distance of the best facet so far */
    int32_t facet;  /* e*(dim+1)+k, or -1 */
    double p[3];
    int64_t cells_visited;
} nearest_state;

/* Candidate boundary facet b for the nearest point; ties go to the
 * smallest facet id, so the answer does not depend on the visiting order. */
static void try_facet(const sm_field *f, int32_t b, const double *x, nearest_state *s)
{
    const int D = f->dim;
    const double *v = f->bfacet_xyz + (size_t)b * (size_t)(D * D);
    int32_t id = f->bfacet_id[b];
    double p[3];
    if (D == 2)
        closest_on_segment(x, v, v + 2, p);
    else
        closest_on_triangle(x, v, v + 3, v + 6, p);
    double d2 = 0.0;
    for (int i = 0; i < D; i++)
        d2 += (x[i] - p[i]) * (x[i] - p[i]);
    if (d2 < s->best2 || (d2 == s->best2 && s->facet >= 0 && id < s->facet)) {
        s->best2 = d2;
        s->facet = id;
        memcpy(s->p, p, sizeof p);
    }
}

typedef struct facet_bins {
    const grid *g;
    const int32_t *start, *list;
} facet_bins;

static void scan_cell(const sm_field *f, const facet_bins *fb, const int32_t *c,
                      const double *x, nearest_state *s)
{
    s->cells_visited++;
    if (cell_dist2(fb->g, c, x) >= s->best2)
        return;
    int64_t idx = cell_index(fb->g, c);
    for (int32_t j = fb->start[idx]; j < fb->start[idx + 1]; j++)
        try_facet(f, fb->list[j], x, s);
}

/* Rings of cells around the cell of the projection p0 of x onto the grid
 * box, until the next ring cannot hold anything closer: for q in the box
 * |x-q|^2 >= |x-p0|^2 + |p0-q|^2, and a cell of ring r is at least
 * (r-1)*min_cell from p0.  Returns 1 when the answer is final, 0 when it
 * stopped at max_ring or after cell_budget cells. */
static int ring_search(const sm_field *f, const facet_bins *fb, const double *x,
                       int32_t max_ring, int64_t cell_budget, nearest_state *s)
{
    const grid *g = fb->g;
    const int D = g->dim;
    double p0[3] = {0, 0, 0}, d02 = 0.0;
    int32_t sc[3] = {0, 0, 0};
    int32_t last = 0;
    for (int i = 0; i < D; i++) {
        p0[i] = x[i] < g->lo[i] ? g->lo[i] : x[i] > g->hi[i] ? g->hi[i] : x[i];
        d02 += (x[i] - p0[i]) * (x[i] - p0[i]);
        sc[i] = axis_cell(g, i, p0[i]);
        int32_t m = sc[i] > g->n[i] - 1 - sc[i] ? sc[i] : g->n[i] - 1 - sc[i];
        if (m > last)
            last = m;
    }
    int64_t visited0 = s->cells_visited;
    for (int32_t r = 0; r <= last; r++) {
        if (r >= 1) {
            double gap = (double)(r - 1) * g->min_cell;
            if (d02 + gap * gap >= s->best2)
                return 1;
        }
        if (r > max_ring || s->cells_visited - visited0 > cell_budget)
            return 0;
        int32_t lo[3], hi[3], c[3] = {0, 0, 0};
        for (int i = 0; i < D; i++) {
            lo[i] = sc[i] - r < 0 ? 0 : sc[i] - r;
            hi[i] = sc[i] + r > g->n[i] - 1 ? g->n[i] - 1 : sc[i] + r;
        }
        if (D == 2) {
            for (c[0] = lo[0]; c[0] <= hi[0]; c[0]++) {
                if (c[0] == sc[0] - r || c[0] == sc[0] + r) {
                    for (c[1] = lo[1]; c[1] <= hi[1]; c[1]++)
                        scan_cell(f, fb, c, x, s);
                } else {
                    c[1] = sc[1] - r;
                    if (c[1] >= 0)
                        scan_cell(f, fb, c, x, s);
                    c[1] = sc[1] + r;
                    if (r > 0 && c[1] < g->n[1])
                        scan_cell(f, fb, c, x, s);
                }
            }
        } else {
            for (c[0] = lo[0]; c[0] <= hi[0]; c[0]++)
                for (c[1] = lo[1]; c[1] <= hi[1]; c[1]++) {
                    if (c[0] == sc[0] - r || c[0] == sc[0] + r || c[1] == sc[1] - r ||
                        c[1] == sc[1] + r) {
                        for (c[2] = lo[2]; c[2] <= hi[2]; c[2]++)
                            scan_cell(f, fb, c, x, s);
                    } else {
                        c[2] = sc[2] - r;
                        if (c[2] >= 0)
                            scan_cell(f, fb, c, x, s);
                        c[2] = sc[2] + r;
                        if (r > 0 && c[2] < g->n[2])
                            scan_cell(f, fb, c, x, s);
                    }
                }
        }
    }
    return 1;
}

/* Nearest point on the facets without neighbour: a few rings of the fine
 * element grid (points close to the mesh, the common case), then rings of
 * the coarse facet grid with the best distance so far as the bound, and,
 * if even those grow too many (far from a non-convex background), one
 * plain pass over the facets, which bounds the cost. */
static void nearest_facet(const sm_field *f, const double *x, nearest_state *s)
{
    s->best2 = INFINITY;
    s->facet = -1;
    s->cells_visited = 0;
    const facet_bins fine = {&f->g, f->facet_start, f->facet_list};
    if (ring_search(f, &fine, x, NEAR_RINGS, INT64_MAX, s))
        return;
    const facet_bins coarse = {&f->cg, f->cfacet_start, f->cfacet_list};
    if (ring_search(f, &coarse, x, INT32_MAX, f->nbfacets / 2 + 64, s))
        return;
    for (int32_t b = 0; b < f->nbfacets; b++)
        try_facet(f, b, x, s);
}

static double extension(const sm_field *f, const double *x, int32_t *hint, double *grad)
{
    const int D = f->dim;
    nearest_state s;
    nearest_facet(f, x, &s);
    if (s.facet < 0) {
        /* only when every distance overflows (|x| ~ 1e154 and beyond) */
        if (grad)
            for (int i = 0; i < D; i++)
                grad[i] = 0.0;
        return INFINITY;
    }
    int32_t e = s.facet / (D + 1);
    const double *r = f->rec + (size_t)e * (size_t)f->stride;
    double dist = sqrt(s.best2);
    if (hint)
        *hint = e;
    if (grad) {
        /* grad = n + (I - n n^T) g, n the unit vector from p to x */
        const double *g = r + D + D * D + 1;
        double n[3] = {0, 0, 0}, gn = 0.0;
        if (dist > 0.0)
            for (int i = 0; i < D; i++) {
                n[i] = (x[i] - s.p[i]) / dist;
                gn += g[i] * n[i];
            }
        for (int i = 0; i < D; i++)
            grad[i] = n[i] + g[i] - gn * n[i];
    }
    return (D == 2 ? affine_value(r, s.p, 2) : affine_value(r, s.p, 3)) + dist;
}

double sm_field_eval_grad(const sm_field *f, const double *x, int32_t *hint, double *grad)
{
    const int D = f->dim;
    for (int i = 0; i < D; i++)
        if (!isfinite(x[i])) {
            if (grad)
                for (int j = 0; j < D; j++)
                    grad[j] = 0.0;
            return INFINITY;
        }
    int32_t e = sm_field_locate(f, x, hint ? *hint : -1, NULL);
    if (e < 0)
        return extension(f, x, hint, grad);
    if (hint)
        *hint = e;
    const double *r = f->rec + (size_t)e * (size_t)f->stride;
    if (grad)
        memcpy(grad, r + D + D * D + 1, (size_t)D * sizeof *grad);
    return D == 2 ? affine_value(r, x, 2) : affine_value(r, x, 3);
}

double sm_field_eval(const sm_field *f, const double *x, int32_t *hint)
{
    if (f->dim == 2) {
        int32_t e = locate_dim(f, x, hint ? *hint : -1, NULL, 2);
        if (e >= 0) {
            if (hint)
                *hint = e;
            return affine_value(f->rec + (size_t)e * 9, x, 2);
        }
    } else {
        int32_t e = locate_dim(f, x, hint ? *hint : -1, NULL, 3);
        if (e >= 0) {
            if (hint)
                *hint = e;
            return affine_value(f->rec + (size_t)e * 16, x, 3);
        }
    }
    for (int i = 0; i < f->dim; i++)
        if (!isfinite(x[i]))
            return INFINITY;
    return extension(f, x, hint, NULL);
}

/* sm_field_eval_many keeps EVAL_GROUP walks in flight: each visit of a
 * slot does one step of its walk, whose record and neighbours were
 * requested one round earlier, then requests the next element's (or, when
 * the walk ends, the next point's hint's).  The misses of all the slots
 * overlap instead of following each other.  Each walk is exactly
 * walk_dim's from the point's hint (same steps, same exits); a point whose
 * walk fails, or that cannot use its hint, gets sm_field_eval, so every
 * result is that of sm_field_eval. */
typedef struct eval_slot {
    int64_t point; /* -1: free */
    int32_t elem;
    int step;
} eval_slot;

static inline __attribute__((always_inline)) void
request_elem(const sm_field *f, int32_t e, const int D)
{
    const double *r = f->rec + (size_t)e * (size_t)(D + D * D + 1 + D);
    __builtin_prefetch(r);
    __builtin_prefetch(r + 8);
    __builtin_prefetch(f->neigh + (size_t)e * (size_t)(D + 1));
}

/* Next point from *next on that can start a walk from its hint (the
 * others are evaluated at once); -1 when none is left. */
static inline __attribute__((always_inline)) int64_t
next_walk(const sm_field *f, int64_t n, const double *xs, int32_t *hints, double *values,
          int64_t *next, const int D)
{
    while (*next < n) {
        int64_t i = (*next)++;
        const double *x = xs + (size_t)i * (size_t)D;
        int32_t h = hints ? hints[i] : -1;
        int ok = h >= 0 && h < f->nelems;
        for (int k = 0; k < D; k++)
            ok = ok && isfinite(x[k]);
        if (ok && f->valid[h]) {
            request_elem(f, h, D);
            return i;
        }
        values[i] = sm_field_eval(f, x, hints ? &hints[i] : NULL);
    }
    return -1;
}

static inline __attribute__((always_inline)) void
eval_many_dim(const sm_field *f, int64_t n, const double *xs, int32_t *hints, double *values,
              const int D)
{
    eval_slot slot[EVAL_GROUP];
    int64_t next = 0;
    int busy = 0;
    for (int s = 0; s < EVAL_GROUP; s++) {
        slot[s].point = next_walk(f, n, xs, hints, values, &next, D);
        if (slot[s].point >= 0) {
            slot[s].elem = hints[slot[s].point];
            slot[s].step = 0;
            busy++;
        }
    }
    while (busy > 0) {
        for (int s = 0; s < EVAL_GROUP; s++) {
            eval_slot *sl = &slot[s];
            if (sl->point < 0)
                continue;
            const double *x = xs + (size_t)sl->point * (size_t)D;
            const double *r = f->rec + (size_t)sl->elem * (size_t)(D + D * D + 1 + D);
            double lam[4], lmin;
            bary_of(r, x, lam, D);
            int k = argmin_lam(lam, D, &lmin);
            int done = 1;
            if (lmin >= -BARY_TOL) {
                values[sl->point] = affine_value(r, x, D);
                hints[sl->point] = sl->elem;
            } else {
                int32_t e = sl->step == 0 && lmin < -WALK_FAR_LAMBDA
                                ? -1
                                : f->neigh[(size_t)sl->elem * (size_t)(D + 1) + (size_t)k];
                if (e >= 0 && ++sl->step < WALK_MAX_STEPS) {
                    sl->elem = e;
                    request_elem(f, e, D);
                    done = 0;
                } else {
                    values[sl->point] = sm_field_eval(f, x, &hints[sl->point]);
                }
            }
            if (done) {
                sl->point = next_walk(f, n, xs, hints, values, &next, D);
                if (sl->point >= 0) {
                    sl->elem = hints[sl->point];
                    sl->step = 0;
                } else {
                    busy--;
                }
            }
        }
    }
}

void sm_field_eval_many(const sm_field *f, int64_t n, const double *xs, int32_t *hints,
                        double *values)
{
    if (f->dim == 2)
        eval_many_dim(f, n, xs, hints, values, 2);
    else
        eval_many_dim(f, n, xs, hints, values, 3);
}

int32_t sm_field_nearest(const sm_field *f, const double *x, double *nearest,
                         double *distance)
{
    const int D = f->dim;
    for (int i = 0; i < D; i++)
        if (!isfinite(x[i]))
            return -1;
    int32_t e = sm_field_locate(f, x, -1, NULL);
    if (e >= 0) {
        if (nearest)
            memcpy(nearest, x, (size_t)D * sizeof *nearest);
        if (distance)
            *distance = 0.0;
        return e;
    }
    nearest_state s;
    nearest_facet(f, x, &s);
    if (s.facet < 0)
        return -1;
    if (nearest)
        memcpy(nearest, s.p, (size_t)D * sizeof *nearest);
    if (distance)
        *distance = sqrt(s.best2);
    return s.facet / (D + 1);
}


void sm_field_get_stats(const sm_field *f, sm_field_stats *st)
{
    memset(st, 0, sizeof *st);
    for (int i = 0; i < 3; i++) {
        st->grid[i] = f->g.n[i];
        st->lo[i] = f->g.lo[i];
        st->hi[i] = f->g.hi[i];
    }
    st->ncells = f->g.ncells;
    st->elem_entries = f->elem_start[f->g.ncells];
    st->max_cell_elems = f->max_cell_elems;
    st->nboundary_facets = f->nbfacets;
    st->facet_entries = f->facet_start[f->g.ncells];
    st->coarse_cells = f->cg.ncells;
    st->coarse_facet_entries = f->cfacet_start[f->cg.ncells];
    st->ndegenerate = f->nelems - f->nvalid;
    size_t ne = (size_t)f->nelems;
    st->bytes = sizeof *f + ne * (size_t)f->stride * sizeof(double) + ne +
                ne * (size_t)(f->dim + 1) * sizeof(int32_t) +
                (size_t)f->nbfacets * (sizeof(int32_t) + (size_t)(f->dim * f->dim) * sizeof(double)) +
                (3 * ((size_t)f->g.ncells + 1) + (size_t)f->cg.ncells + 1) * sizeof(int32_t) +
                (size_t)(st->elem_entries + st->facet_entries + st->coarse_facet_entries) *
                    sizeof(int32_t);
}
