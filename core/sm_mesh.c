#include "shapematch/sm_mesh.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sm_alloc.h"
#include "sm_facets.h"

static void *alloc_array(size_t count, size_t size)
{
    /* calloc of 0 elements may return NULL; keep a valid pointer so that
     * "NULL means failure" holds everywhere. */
    return calloc(count ? count : 1, size);
}

sm_status sm_mesh_alloc(sm_mesh **out, int dim, int32_t nverts,
                        int32_t nelems, int32_t nfacets, sm_error *err)
{
    *out = NULL;
    if (dim != 2 && dim != 3)
        return sm_error_set(err, SM_ERR_INVALID, "dimension %d is not 2 or 3", dim);
    if (nverts < 0 || nelems < 0 || nfacets < 0 || nverts > SM_MAX_ENTITIES ||
        nelems > SM_MAX_ENTITIES || nfacets > SM_MAX_ENTITIES)
        return sm_error_set(err, SM_ERR_NOMEM,
                            "entity counts out of range (vertices %ld, elements %ld, facets %ld; limit %d)",
                            (long)nverts, (long)nelems, (long)nfacets, SM_MAX_ENTITIES);
    sm_mesh *m = calloc(1, sizeof *m);
    if (!m)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    m->dim = dim;
    m->nverts = nverts;
    m->nelems = nelems;
    m->nfacets = nfacets;
    m->coords = alloc_array((size_t)nverts * (size_t)dim, sizeof(double));
    m->vert_refs = alloc_array((size_t)nverts, sizeof(int32_t));
    m->elems = alloc_array((size_t)nelems * (size_t)(dim + 1), sizeof(int32_t));
    m->elem_refs = alloc_array((size_t)nelems, sizeof(int32_t));
    m->facets = alloc_array((size_t)nfacets * (size_t)dim, sizeof(int32_t));
    m->facet_refs = alloc_array((size_t)nfacets, sizeof(int32_t));
    if (!m->coords || !m->vert_refs || !m->elems || !m->elem_refs || !m->facets ||
        !m->facet_refs) {
        sm_mesh_free(m);
        return sm_error_set(err, SM_ERR_NOMEM,
                            "out of memory for a mesh of %ld vertices and %ld elements",
                            (long)nverts, (long)nelems);
    }
    *out = m;
    return SM_OK;
}

static void free_boundary(sm_mesh *m)
{
    free(m->bfacets);
    free(m->bfacet_refs);
    free(m->bfacet_elem);
    free(m->on_boundary);
    m->bfacets = m->bfacet_refs = m->bfacet_elem = NULL;
    m->on_boundary = NULL;
    m->nbfacets = 0;
}

void sm_mesh_free(sm_mesh *m)
{
    if (!m)
        return;
    free(m->coords);
    free(m->vert_refs);
    free(m->elems);
    free(m->elem_refs);
    free(m->facets);
    free(m->facet_refs);
    free_boundary(m);
    sm_mesh_names_free(m->names, m->nnames);
    free(m);
}

void sm_mesh_names_free(sm_mesh_name *names, int32_t n)
{
    for (int32_t i = 0; names && i < n; i++)
        free(names[i].name);
    free(names);
}

/* Copies the name table of m into c. */
static int clone_names(const sm_mesh *m, sm_mesh *c)
{
    if (m->nnames <= 0)
        return 0;
    c->names = calloc((size_t)m->nnames, sizeof *c->names);
    if (!c->names)
        return -1;
    c->nnames = m->nnames;
    for (int32_t i = 0; i < m->nnames; i++) {
        c->names[i] = m->names[i];
        c->names[i].name = strdup(m->names[i].name);
        if (!c->names[i].name)
            return -1;
    }
    return 0;
}

static void *dup_array(const void *src, size_t bytes)
{
    void *p = malloc(bytes ? bytes : 1);
    if (p && bytes)
        memcpy(p, src, bytes);
    return p;
}

sm_status sm_mesh_clone(const sm_mesh *m, sm_mesh **out, sm_error *err)
{
    sm_status st = sm_mesh_alloc(out, m->dim, m->nverts, m->nelems, m->nfacets, err);
    if (st != SM_OK)
        return st;
    sm_mesh *c = *out;
    size_t nv = (size_t)m->nverts, ne = (size_t)m->nelems, nf = (size_t)m->nfacets;
    memcpy(c->coords, m->coords, nv * (size_t)m->dim * sizeof(double));
    memcpy(c->vert_refs, m->vert_refs, nv * sizeof(int32_t));
    memcpy(c->elems, m->elems, ne * (size_t)(m->dim + 1) * sizeof(int32_t));
    memcpy(c->elem_refs, m->elem_refs, ne * sizeof(int32_t));
    memcpy(c->facets, m->facets, nf * (size_t)m->dim * sizeof(int32_t));
    memcpy(c->facet_refs, m->facet_refs, nf * sizeof(int32_t));
    if (clone_names(m, c) != 0) {
        sm_mesh_free(c);
        *out = NULL;
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory copying a mesh");
    }
    if (m->bfacets) {
        size_t nb = (size_t)m->nbfacets;
        c->nbfacets = m->nbfacets;
        c->bfacets = dup_array(m->bfacets, nb * (size_t)m->dim * sizeof(int32_t));
        c->bfacet_refs = dup_array(m->bfacet_refs, nb * sizeof(int32_t));
        c->bfacet_elem = dup_array(m->bfacet_elem, nb * sizeof(int32_t));
        c->on_boundary = dup_array(m->on_boundary, nv);
        if (!c->bfacets || !c->bfacet_refs || !c->bfacet_elem || !c->on_boundary) {
            sm_mesh_free(c);
            *out = NULL;
            return sm_error_set(err, SM_ERR_NOMEM, "out of memory copying a mesh");
        }
    }
    return SM_OK;
}

/* ---- geometry ---------------------------------------------------------- */

static inline const double *vertex(const double *coords, int dim, int32_t v)
{
    return coords + (size_t)v * (size_t)dim;
}

double sm_elem_volume(const sm_mesh *m, const double *coords, int32_t e)
{
    const int32_t *ev = m->elems + (size_t)e * (size_t)(m->dim + 1);
    if (m->dim == 2) {
        const double *a = vertex(coords, 2, ev[0]), *b = vertex(coords, 2, ev[1]),
                     *c = vertex(coords, 2, ev[2]);
        return 0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]));
    }
    const double *a = vertex(coords, 3, ev[0]), *b = vertex(coords, 3, ev[1]),
                 *c = vertex(coords, 3, ev[2]), *d = vertex(coords, 3, ev[3]);
    double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    double v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    double w[3] = {d[0] - a[0], d[1] - a[1], d[2] - a[2]};
    return (u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0]) +
            u[2] * (v[0] * w[1] - v[1] * w[0])) / 6.0;
}

static double squared_edge_sum(const sm_mesh *m, const double *coords, int32_t e)
{
    int nv = m->dim + 1;
    const int32_t *ev = m->elems + (size_t)e * (size_t)nv;
    double sum = 0.0;
    for (int i = 0; i < nv; i++)
        for (int j = i + 1; j < nv; j++) {
            const double *p = vertex(coords, m->dim, ev[i]), *q = vertex(coords, m->dim, ev[j]);
            for (int c = 0; c < m->dim; c++)
                sum += (q[c] - p[c]) * (q[c] - p[c]);
        }
    return sum;
}

double sm_elem_quality(const sm_mesh *m, const double *coords, int32_t e)
{
    double vol = sm_elem_volume(m, coords, e);
    double l2 = squared_edge_sum(m, coords, e);
    if (!(l2 > 0.0))
        return 0.0;
    if (m->dim == 2)
        return 4.0 * sqrt(3.0) * vol / l2;
    double v3 = 3.0 * fabs(vol);
    double q = 12.0 * cbrt(v3 * v3) / l2;
    return vol < 0 ? -q : q;
}

/* A number that orders the elements as their quality does: the quality
 * is a positive power of |volume| / sum(l^2)^(dim/2) with the sign of the
 * volume, so in 3D (3V)^2 / sum(l^2)^3 with that sign orders them without
 * the cube root, in 2D area / sum(l^2). */
static inline double quality_key(const sm_mesh *m, const double *coords, int32_t e)
{
    double vol = sm_elem_volume(m, coords, e);
    double l2 = squared_edge_sum(m, coords, e);
    if (!(l2 > 0.0))
        return 0.0;
    if (m->dim == 2)
        return vol / l2;
    double v3 = 3.0 * vol;
    double key = v3 * v3 / (l2 * l2 * l2);
    return vol < 0 ? -key : key;
}

/* Folds key k of element e into the two smallest keys so far (k1 of
 * element e1, then k2), the first element on ties. */
static void keep_two_smallest(double k, int32_t e, double *k1, int32_t *e1, double *k2)
{
    if (k < *k1 || (k == *k1 && e < *e1)) {
        *k2 = *k1;
        *k1 = k;
        *e1 = e;
    } else if (k < *k2) {
        *k2 = k;
    }
}

double sm_mesh_min_quality(const sm_mesh *m, const double *coords, int32_t *worst)
{
    /* The smallest key; when no other key is within rounding of it, its
     * element has the smallest quality, otherwise sm_elem_quality decides
     * among the elements that are: either way exactly the minimum, and
     * the first element reaching it, of sm_elem_quality over all. */
    double k1 = INFINITY, k2 = INFINITY, best_q = INFINITY;
    int32_t e1 = -1, best = -1;
#pragma omp parallel
    {
        double my_k1 = INFINITY, my_k2 = INFINITY;
        int32_t my_e1 = -1;
#pragma omp for schedule(static) nowait
        for (int32_t e = 0; e < m->nelems; e++)
            keep_two_smallest(quality_key(m, coords, e), e, &my_k1, &my_e1, &my_k2);
#pragma omp critical
        if (my_e1 >= 0) {
            keep_two_smallest(my_k1, my_e1, &k1, &e1, &k2);
            if (my_k2 < k2)
                k2 = my_k2;
        }
    }
    if (e1 < 0) {
        if (worst)
            *worst = -1;
        return 0.0;
    }
    const double bound = k1 + 1e-9 * fabs(k1) + 1e-300;
    if (!(k2 <= bound)) {
        if (worst)
            *worst = e1;
        return sm_elem_quality(m, coords, e1);
    }
#pragma omp parallel
    {
        double my_q = INFINITY;
        int32_t mine = -1;
#pragma omp for schedule(static) nowait
        for (int32_t e = 0; e < m->nelems; e++) {
            if (!(quality_key(m, coords, e) <= bound))
                continue;
            double q = sm_elem_quality(m, coords, e);
            if (q < my_q) {
                my_q = q;
                mine = e;
            }
        }
#pragma omp critical
        if (mine >= 0 && (my_q < best_q || (my_q == best_q && mine < best))) {
            best_q = my_q;
            best = mine;
        }
    }
    if (worst)
        *worst = best;
    return best_q;
}

void sm_mesh_quality(const sm_mesh *m, const double *coords, sm_quality_stats *st)
{
    st->min = m->nelems ? INFINITY : 0.0;
    st->mean = 0.0;
    st->worst_elem = -1;
    st->ninverted = 0;
    for (int32_t e = 0; e < m->nelems; e++) {
        double q = sm_elem_quality(m, coords, e);
        if (sm_elem_volume(m, coords, e) <= 0.0)
            st->ninverted++;
        if (q < st->min) {
            st->min = q;
            st->worst_elem = e;
        }
        st->mean += q;
    }
    if (m->nelems)
        st->mean /= m->nelems;
}

void sm_mesh_bbox(const sm_mesh *m, const double *coords, double *lo, double *hi)
{
    for (int c = 0; c < m->dim; c++) {
        lo[c] = m->nverts ? INFINITY : 0.0;
        hi[c] = m->nverts ? -INFINITY : 0.0;
    }
    for (int32_t v = 0; v < m->nverts; v++)
        for (int c = 0; c < m->dim; c++) {
            double x = coords[(size_t)v * (size_t)m->dim + (size_t)c];
            if (x < lo[c])
                lo[c] = x;
            if (x > hi[c])
                hi[c] = x;
        }
}

double sm_mesh_diameter(const sm_mesh *m, const double *coords)
{
    double lo[3], hi[3], s = 0.0;
    sm_mesh_bbox(m, coords, lo, hi);
    for (int c = 0; c < m->dim; c++)
        s += (hi[c] - lo[c]) * (hi[c] - lo[c]);
    return sqrt(s);
}

/* Area-weighted normal of a facet given by its vertices (not normalized):
 * 2D: the edge (p,q) rotated clockwise; 3D: (q-p) x (r-p) / 2. */
static void facet_area_normal(int dim, const double *coords, const int32_t *fv, double *n)
{
    const double *p = vertex(coords, dim, fv[0]), *q = vertex(coords, dim, fv[1]);
    if (dim == 2) {
        n[0] = q[1] - p[1];
        n[1] = -(q[0] - p[0]);
        return;
    }
    const double *r = vertex(coords, 3, fv[2]);
    double u[3] = {q[0] - p[0], q[1] - p[1], q[2] - p[2]};
    double v[3] = {r[0] - p[0], r[1] - p[1], r[2] - p[2]};
    n[0] = 0.5 * (u[1] * v[2] - u[2] * v[1]);
    n[1] = 0.5 * (u[2] * v[0] - u[0] * v[2]);
    n[2] = 0.5 * (u[0] * v[1] - u[1] * v[0]);
}

double sm_bfacet_normal(const sm_mesh *m, const double *coords, int32_t f, double *normal)
{
    double n[3] = {0, 0, 0};
    facet_area_normal(m->dim, coords, m->bfacets + (size_t)f * (size_t)m->dim, n);
    double len = 0.0;
    for (int c = 0; c < m->dim; c++)
        len += n[c] * n[c];
    len = sqrt(len);
    for (int c = 0; c < m->dim; c++)
        normal[c] = len > 0 ? n[c] / len : 0.0;
    return len;
}

/* ---- topology ------------------------------------------------------------ */

/* A facet seen from one element: its sorted vertex key, the element and
 * the local index of the vertex opposite to it. */
typedef struct facet_entry {
    int32_t key[3];
    int32_t elem;
    int32_t opposite;
} facet_entry;

static int compare_keys(const int32_t *a, const int32_t *b)
{
    for (int i = 0; i < 3; i++)
        if (a[i] != b[i])
            return a[i] < b[i] ? -1 : 1;
    return 0;
}

static int compare_facet_entries(const void *pa, const void *pb)
{
    const facet_entry *a = pa, *b = pb;
    int c = compare_keys(a->key, b->key);
    if (c)
        return c;
    if (a->elem != b->elem)
        return a->elem < b->elem ? -1 : 1;
    return 0;
}

static void sort_key(int32_t *k, int n)
{
    for (int i = 1; i < n; i++)
        for (int j = i; j > 0 && k[j - 1] > k[j]; j--) {
            int32_t t = k[j];
            k[j] = k[j - 1];
            k[j - 1] = t;
        }
}

static sm_status check_mesh(const sm_mesh *m, sm_error *err)
{
    int nv = m->dim + 1;
    if (m->nelems == 0)
        return sm_error_set(err, SM_ERR_INVALID, "the mesh has no %s",
                            m->dim == 2 ? "triangles" : "tetrahedra");
    for (size_t i = 0; i < (size_t)m->nverts * (size_t)m->dim; i++)
        if (!isfinite(m->coords[i]))
            return sm_error_set(err, SM_ERR_INVALID, "vertex %zu has a non-finite coordinate",
                                i / (size_t)m->dim + 1);
    for (int32_t e = 0; e < m->nelems; e++)
        for (int i = 0; i < nv; i++) {
            int32_t v = m->elems[(size_t)e * (size_t)nv + (size_t)i];
            if (v < 0 || v >= m->nverts)
                return sm_error_set(err, SM_ERR_INVALID,
                                    "element %ld refers to vertex %ld, outside 1..%ld",
                                    (long)e + 1, (long)v + 1, (long)m->nverts);
        }
    for (int32_t f = 0; f < m->nfacets; f++)
        for (int i = 0; i < m->dim; i++) {
            int32_t v = m->facets[(size_t)f * (size_t)m->dim + (size_t)i];
            if (v < 0 || v >= m->nverts)
                return sm_error_set(err, SM_ERR_INVALID,
                                    "facet %ld refers to vertex %ld, outside 1..%ld",
                                    (long)f + 1, (long)v + 1, (long)m->nverts);
        }
    return SM_OK;
}

/* Flips elements of negative orientation; rejects degenerate ones. */
static sm_status orient_elements(sm_mesh *m, sm_error *err)
{
    int nv = m->dim + 1;
    for (int32_t e = 0; e < m->nelems; e++) {
        double vol = sm_elem_volume(m, m->coords, e);
        double l2 = squared_edge_sum(m, m->coords, e);
        /* relative test: |vol| compared with the volume scale of its edges */
        double scale = m->dim == 2 ? l2 : pow(l2, 1.5);
        if (!(fabs(vol) > 1e-14 * scale))
            return sm_error_set(err, SM_ERR_INVALID,
                                "element %ld is degenerate (volume %.3g)", (long)e + 1, vol);
        if (vol < 0) {
            int32_t *ev = m->elems + (size_t)e * (size_t)nv;
            int32_t t = ev[1];
            ev[1] = ev[2];
            ev[2] = t;
        }
    }
    return SM_OK;
}

/* The facets of the file (m->facets), sorted by key to carry their
 * references over; elem holds the index of the file facet. */
static void sort_file_facets(const sm_mesh *m, facet_entry *file)
{
    const int dim = m->dim;
    for (int32_t f = 0; f < m->nfacets; f++) {
        for (int i = 0; i < dim; i++)
            file[f].key[i] = m->facets[(size_t)f * (size_t)dim + (size_t)i];
        if (dim == 2)
            file[f].key[2] = -1;
        sort_key(file[f].key, dim);
        file[f].elem = f; /* here: index of the file facet */
        file[f].opposite = 0;
    }
    qsort(file, (size_t)m->nfacets, sizeof *file, compare_facet_entries);
}

/* Boundary facet b from its element entry fe: vertices oriented outward,
 * owning element, boundary vertex flags, and the reference of the
 * matching file facet if any. */
static void add_boundary_facet(sm_mesh *m, const facet_entry *fe, const facet_entry *file,
                               size_t b)
{
    const int dim = m->dim, nv = dim + 1;
    const int32_t *ev = m->elems + (size_t)fe->elem * (size_t)nv;
    int32_t *fv = m->bfacets + b * (size_t)dim;
    int k = 0;
    for (int q = 0; q < nv; q++)
        if (q != fe->opposite)
            fv[k++] = ev[q];
    /* orient outward: the normal must point away from the opposite vertex */
    double n[3] = {0, 0, 0}, dot = 0.0;
    facet_area_normal(dim, m->coords, fv, n);
    const double *opp = vertex(m->coords, dim, ev[fe->opposite]);
    const double *p0 = vertex(m->coords, dim, fv[0]);
    for (int c = 0; c < dim; c++)
        dot += n[c] * (p0[c] - opp[c]);
    if (dot < 0) {
        int32_t t = fv[0];
        fv[0] = fv[1];
        fv[1] = t;
    }
    m->bfacet_elem[b] = fe->elem;
    for (int c = 0; c < dim; c++)
        m->on_boundary[fv[c]] = 1;
    /* reference of the matching file facet, if any */
    size_t lo = 0, hi = (size_t)m->nfacets;
    while (lo < hi) {
        size_t mid = (lo + hi) / 2;
        if (compare_keys(file[mid].key, fe->key) < 0)
            lo = mid + 1;
        else
            hi = mid;
    }
    if (lo < (size_t)m->nfacets && compare_keys(file[lo].key, fe->key) == 0)
        m->bfacet_refs[b] = m->facet_refs[file[lo].elem];
}

sm_status sm_mesh_build_boundary(sm_mesh *m, sm_error *err)
{
    sm_status st = check_mesh(m, err);
    if (st != SM_OK)
        return st;
    if ((st = orient_elements(m, err)) != SM_OK)
        return st;
    free_boundary(m);

    const int dim = m->dim, nv = dim + 1;
    const size_t nf = (size_t)m->nelems * (size_t)nv;
    int32_t *nbr = sm__alloc_huge(nf * sizeof *nbr);
    int32_t *order = sm__alloc_huge(nf * sizeof *order);
    sm_facet_match fm;
    if (!nbr || !order) {
        free(nbr);
        free(order);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory building the boundary");
    }
    st = sm__facet_match(dim, m->nverts, m->nelems, m->elems, nbr, order, &fm, err);
    free(nbr);
    if (st == SM_OK && fm.crowded >= 0) {
        int32_t key[3];
        sm__facet_sorted_vertices(dim, m->elems + (size_t)(fm.crowded / nv) * (size_t)nv,
                                  (int)(fm.crowded % nv), key);
        st = sm_error_set(err, SM_ERR_INVALID,
                          "facet (%ld %ld%s) is shared by %ld elements: the mesh is not manifold",
                          (long)key[0] + 1, (long)key[1] + 1, dim == 3 ? " ..." : "",
                          (long)fm.crowded_holders);
    }
    if (st != SM_OK) {
        free(order);
        return st;
    }

    const size_t nb = (size_t)fm.nboundary;
    m->nbfacets = (int32_t)nb;
    m->bfacets = malloc((nb ? nb : 1) * (size_t)dim * sizeof(int32_t));
    m->bfacet_refs = calloc(nb ? nb : 1, sizeof(int32_t));
    m->bfacet_elem = malloc((nb ? nb : 1) * sizeof(int32_t));
    m->on_boundary = calloc(m->nverts ? (size_t)m->nverts : 1, 1);
    facet_entry *file = malloc((m->nfacets ? (size_t)m->nfacets : 1) * sizeof *file);
    if (!m->bfacets || !m->bfacet_refs || !m->bfacet_elem || !m->on_boundary || !file) {
        free(order);
        free(file);
        free_boundary(m);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory building the boundary");
    }
    sort_file_facets(m, file);
    /* in the order of their sorted vertex lists, as the facets always were */
    for (size_t b = 0; b < nb; b++) {
        facet_entry fe = {.elem = order[b] / nv, .opposite = order[b] % nv};
        fe.key[2] = -1;
        sm__facet_sorted_vertices(dim, m->elems + (size_t)fe.elem * (size_t)nv, fe.opposite,
                                  fe.key);
        add_boundary_facet(m, &fe, file, b);
    }
    free(order);
    free(file);
    return SM_OK;
}
