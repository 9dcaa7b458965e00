/* Topology checks of a template that the solver needs but the readers
 * cannot see: vertex stars connected through facets (no bowtie), and
 * every connected part held by the clamp (sm_mesh.h, sm_clamp.h).  Both
 * are O(elements + vertices) in time and memory. */
#include "shapematch/sm_clamp.h"
#include "shapematch/sm_mesh.h"

#include <stdlib.h>
#include <string.h>

#include "sm_alloc.h"
#include "sm_facets.h"

/* nbr[e * nv + i]: the element across the facet opposite local vertex i
 * of e, or -1 (boundary, or a facet shared by more than two elements:
 * sm_mesh_build_boundary refuses those). */
static int32_t *facet_neighbours(const sm_mesh *m)
{
    size_t n = (size_t)m->nelems * (size_t)(m->dim + 1);
    int32_t *nbr = sm__alloc_huge((n ? n : 1) * sizeof *nbr);
    sm_facet_match fm;
    sm_error err;
    if (!nbr || sm__facet_match(m->dim, m->nverts, m->nelems, m->elems, nbr, NULL, &fm, &err) !=
                    SM_OK) {
        free(nbr);
        return NULL;
    }
    for (size_t k = 0; k < n; k++)
        if (nbr[k] < 0)
            nbr[k] = -1;
    return nbr;
}

/* Elements around each vertex (CSR): star[first[v] .. first[v+1]). */
static int vertex_stars(const sm_mesh *m, int32_t **first_out, int32_t **star_out)
{
    const int nv = m->dim + 1;
    size_t n = (size_t)m->nelems * (size_t)nv;
    int32_t *first = calloc((size_t)m->nverts + 1, sizeof *first);
    int32_t *star = sm__alloc_huge((n ? n : 1) * sizeof *star);
    if (!first || !star) {
        free(first);
        free(star);
        return -1;
    }
    for (size_t k = 0; k < n; k++)
        first[m->elems[k] + 1]++;
    for (int32_t v = 0; v < m->nverts; v++)
        first[v + 1] += first[v];
    int32_t *fill = malloc(((size_t)m->nverts + 1) * sizeof *fill);
    if (!fill) {
        free(first);
        free(star);
        return -1;
    }
    memcpy(fill, first, ((size_t)m->nverts + 1) * sizeof *fill);
    for (size_t k = 0; k < n; k++)
        star[fill[m->elems[k]]++] = (int32_t)(k / (size_t)nv);
    free(fill);
    *first_out = first;
    *star_out = star;
    return 0;
}

/* Walks the star of v from its first element across facets holding v;
 * returns how many star elements were reached.  mark[e] == v + 1 flags a
 * reached element; queue has room for the star. */
static int32_t walk_star(const sm_mesh *m, const int32_t *nbr, const int32_t *star, int32_t size,
                         int32_t v, int32_t *mark, int32_t *queue)
{
    const int nv = m->dim + 1;
    int32_t head = 0, tail = 0;
    queue[tail++] = star[0];
    mark[star[0]] = v + 1;
    while (head < tail && tail <= size) {
        int32_t e = queue[head++];
        for (int i = 0; i < nv; i++) {
            if (m->elems[(size_t)e * (size_t)nv + (size_t)i] == v)
                continue; /* the facet opposite v does not hold v */
            int32_t o = nbr[(size_t)e * (size_t)nv + (size_t)i];
            if (o >= 0 && mark[o] != v + 1 && tail < size) {
                mark[o] = v + 1;
                queue[tail++] = o;
            }
        }
    }
    return tail;
}

sm_status sm_mesh_check_manifold(const sm_mesh *m, sm_error *err)
{
    int32_t *first = NULL, *star = NULL;
    int32_t *nbr = facet_neighbours(m);
    int32_t *mark = sm__alloc_huge(((size_t)m->nelems + 1) * sizeof *mark);
    int32_t *queue = sm__alloc_huge(((size_t)m->nelems + 1) * sizeof *queue);
    sm_status st = SM_OK;
    if (!nbr || !mark || !queue || vertex_stars(m, &first, &star) != 0) {
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory checking the topology");
        goto done;
    }
    memset(mark, 0, ((size_t)m->nelems + 1) * sizeof *mark);
    for (int32_t v = 0; v < m->nverts; v++) {
        int32_t size = first[v + 1] - first[v];
        if (size == 0)
            continue;
        int32_t reached = walk_star(m, nbr, star + first[v], size, v, mark, queue);
        if (reached < size) {
            /* name an element of the star that was not reached */
            int32_t other = star[first[v]];
            for (int32_t k = first[v]; k < first[v + 1]; k++)
                if (mark[star[k]] != v + 1) {
                    other = star[k];
                    break;
                }
            st = sm_error_set(err, SM_ERR_INVALID,
                              "vertex %ld is non-manifold (a bowtie: elements %ld and %ld share "
                              "it but are not joined through %s around it); split or remove the "
                              "pinch",
                              (long)v + 1, (long)star[first[v]] + 1, (long)other + 1,
                              m->dim == 2 ? "edges" : "faces");
            goto done;
        }
    }
done:
    free(nbr);
    free(mark);
    free(queue);
    free(first);
    free(star);
    return st;
}

static int32_t find_root(int32_t *parent, int32_t v)
{
    while (parent[v] != v) {
        parent[v] = parent[parent[v]];
        v = parent[v];
    }
    return v;
}

/* parent[v]: union-find of the vertices joined by elements. */
static void join_parts(const sm_mesh *m, int32_t *parent)
{
    const int nv = m->dim + 1;
    for (int32_t v = 0; v < m->nverts; v++)
        parent[v] = v;
    for (int32_t e = 0; e < m->nelems; e++) {
        const int32_t *ev = m->elems + (size_t)e * (size_t)nv;
        int32_t r0 = find_root(parent, ev[0]);
        for (int i = 1; i < nv; i++) {
            int32_t r = find_root(parent, ev[i]);
            if (r != r0)
                parent[r] = r0;
        }
    }
    for (int32_t v = 0; v < m->nverts; v++)
        parent[v] = find_root(parent, v);
}

static double dist2(const double *x, int dim, int32_t a, int32_t b)
{
    double s = 0.0;
    for (int k = 0; k < dim; k++) {
        double d = x[(size_t)a * (size_t)dim + (size_t)k] - x[(size_t)b * (size_t)dim + (size_t)k];
        s += d * d;
    }
    return s;
}

/* The first part (by root) whose clamped vertices leave it free to move
 * rigidly (rank 0: none, or one distinct point, clamped), or -1; fills
 * a (first clamped vertex), far (the farthest from it) and best (that
 * squared distance) per part root.  O(vertices). */
static int32_t loose_part(const sm_mesh *m, const uint8_t *clamped, const int32_t *root,
                          int32_t *a, int32_t *far, double *best)
{
    const int dim = m->dim;
    const double *x = m->coords;
    double diam = sm_mesh_diameter(m, x);
    for (int32_t v = 0; v < m->nverts; v++) {
        a[v] = -1;
        far[v] = -1;
        best[v] = 0.0;
    }
    for (int32_t v = 0; v < m->nverts; v++)
        if (root[v] >= 0 && clamped[v] && a[root[v]] < 0)
            a[root[v]] = v;
    for (int32_t v = 0; v < m->nverts; v++) {
        int32_t r = root[v];
        if (r < 0 || !clamped[v] || v == a[r])
            continue;
        double d2 = dist2(x, dim, v, a[r]);
        if (d2 > best[r]) {
            best[r] = d2;
            far[r] = v;
        }
    }
    for (int32_t v = 0; v < m->nverts; v++) {
        int32_t r = root[v];
        if (r != v)
            continue;
        if (a[r] < 0 || far[r] < 0 || !(best[r] > 1e-20 * diam * diam))
            return r;
    }
    return -1;
}

/* 3D: a part whose clamped vertices are collinear (rank 1), or -1. */
static int32_t collinear_part(const sm_mesh *m, const uint8_t *clamped, const int32_t *root,
                              const int32_t *a, const int32_t *far, const double *far_d2,
                              double *cross)
{
    const double *x = m->coords;
    for (int32_t v = 0; v < m->nverts; v++)
        cross[v] = 0.0;
    for (int32_t v = 0; v < m->nverts; v++) {
        int32_t r = root[v];
        if (r < 0 || !clamped[v])
            continue;
        double p[3], q[3];
        for (int k = 0; k < 3; k++) {
            p[k] = x[(size_t)far[r] * 3 + (size_t)k] - x[(size_t)a[r] * 3 + (size_t)k];
            q[k] = x[(size_t)v * 3 + (size_t)k] - x[(size_t)a[r] * 3 + (size_t)k];
        }
        double c0 = p[1] * q[2] - p[2] * q[1], c1 = p[2] * q[0] - p[0] * q[2],
               c2 = p[0] * q[1] - p[1] * q[0];
        double n2 = c0 * c0 + c1 * c1 + c2 * c2;
        if (n2 > cross[r])
            cross[r] = n2;
    }
    for (int32_t v = 0; v < m->nverts; v++)
        if (root[v] == v && a[v] >= 0 && far[v] >= 0 && !(cross[v] > 1e-20 * far_d2[v] * far_d2[v]))
            return v;
    return -1;
}

sm_status sm_clamp_check_parts(const sm_mesh *m, const sm_params *p, sm_error *err)
{
    if (p->clamp == SM_CLAMP_NONE || m->nverts == 0)
        return SM_OK;
    size_t n = (size_t)m->nverts;
    uint8_t *clamped = malloc(n);
    int32_t *root = malloc(n * sizeof *root), *a = malloc(n * sizeof *a),
            *far = malloc(n * sizeof *far);
    double *best = malloc(n * sizeof *best), *cross = malloc(n * sizeof *cross);
    sm_status st = SM_OK;
    if (!clamped || !root || !a || !far || !best || !cross) {
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory checking the clamp");
        goto done;
    }
    sm_clamp_mark(m, p, clamped);
    join_parts(m, root);
    /* vertices of no element belong to no part (root -1) */
    uint8_t *used = (uint8_t *)cross; /* scratch until collinear_part */
    memset(used, 0, n);
    for (size_t k = 0; k < (size_t)m->nelems * (size_t)(m->dim + 1); k++)
        used[m->elems[k]] = 1;
    for (int32_t v = 0; v < m->nverts; v++)
        if (!used[v]) {
            clamped[v] = 0;
            root[v] = -1;
        }
    int32_t parts = 0;
    for (int32_t v = 0; v < m->nverts; v++)
        parts += root[v] == v;
    if (parts < 2)
        goto done; /* sm_clamp_check covers a single part */
    int32_t r = loose_part(m, clamped, root, a, far, best);
    if (r < 0 && m->dim == 3)
        r = collinear_part(m, clamped, root, a, far, best, cross);
    if (r >= 0)
        st = sm_error_set(err, SM_ERR_INVALID,
                          "the template has %ld separate parts and the one holding vertex %ld "
                          "is %s: it could move freely (the elasticity system is singular); "
                          "clamp every part, or use clamp none with alpha > 0",
                          (long)parts, (long)r + 1,
                          r >= 0 && a[r] < 0 ? "not clamped at all"
                                             : "clamped at too few points (rigid rotations stay free)");
done:
    free(clamped);
    free(root);
    free(a);
    free(far);
    free(best);
    free(cross);
    return st;
}
