/* What the surface readers share (sm_io_formats.h): vertex welding for the
 * formats that repeat vertices per facet (STL, OBJ, PLY, OFF), and the
 * surface of a set of simplices (Gmsh, VTK, PLY).  The readers call these;
 * the dispatch by content is sm_io.c's table, the surface model itself
 * (allocation, measures) core/sm_surface.c. */
#include "io/sm_io_formats.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "io/sm_io_msh.h"
#include "shapematch/sm_mesh.h"

/* ---- welding ---- */

typedef struct weld_ctx {
    const double *x;
    int dim;
} weld_ctx;

static int cmp_coords(const double *a, const double *b, int dim)
{
    for (int k = 0; k < dim; k++)
        if (a[k] != b[k])
            return a[k] < b[k] ? -1 : 1;
    return 0;
}

/* merge sort of vertex ids by coordinates (qsort has no context) */
static void sort_ids(int32_t *id, int32_t *tmp, int32_t n, const weld_ctx *c)
{
    if (n < 2)
        return;
    int32_t h = n / 2;
    sort_ids(id, tmp, h, c);
    sort_ids(id + h, tmp, n - h, c);
    int32_t i = 0, j = h, k = 0;
    while (i < h && j < n)
        tmp[k++] = cmp_coords(c->x + (size_t)id[j] * c->dim, c->x + (size_t)id[i] * c->dim,
                              c->dim) < 0 ? id[j++] : id[i++];
    while (i < h)
        tmp[k++] = id[i++];
    while (j < n)
        tmp[k++] = id[j++];
    memcpy(id, tmp, (size_t)n * sizeof *id);
}

sm_status sm__surface_weld(sm_surface *s, sm_error *err)
{
    int32_t n = s->nverts;
    int dim = s->dim;
    int32_t *id = malloc(((size_t)n + 1) * sizeof *id);
    int32_t *tmp = malloc(((size_t)n + 1) * sizeof *tmp);
    int32_t *map = malloc(((size_t)n + 1) * sizeof *map);
    double *x = malloc(((size_t)n * (size_t)dim + 1) * sizeof *x);
    sm_status st = SM_OK;
    if (!id || !tmp || !map || !x) {
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory welding %ld vertices", (long)n);
        goto done;
    }
    for (int32_t i = 0; i < n; i++)
        id[i] = i;
    weld_ctx c = {s->coords, dim};
    sort_ids(id, tmp, n, &c);
    /* the sort is stable: each run of equal points starts with its
     * smallest original id, which represents the run (tmp: rep) */
    for (int32_t i = 0; i < n; i++) {
        int same = i > 0 && cmp_coords(s->coords + (size_t)id[i] * dim,
                                       s->coords + (size_t)id[i - 1] * dim, dim) == 0;
        tmp[id[i]] = same ? tmp[id[i - 1]] : id[i];
    }
    /* new numbers in order of first appearance */
    int32_t m = 0;
    for (int32_t i = 0; i < n; i++) {
        if (tmp[i] == i) {
            memcpy(x + (size_t)m * dim, s->coords + (size_t)i * dim, (size_t)dim * sizeof *x);
            map[i] = m++;
        }
    }
    for (int32_t i = 0; i < n; i++)
        map[i] = map[tmp[i]];
    for (int64_t f = 0; f < (int64_t)s->nfacets * dim; f++)
        s->facets[f] = map[s->facets[f]];
    free(s->coords);
    s->coords = x;
    x = NULL;
    s->nverts = m;
done:
    free(id);
    free(tmp);
    free(map);
    free(x);
    return st;
}

/* ---- Gmsh ---- */

sm_status sm__msh_surface(const char *path, const sm_msh_data *d, sm_surface **out,
                          sm_error *err)
{
    int planar = 1;
    for (int64_t i = 0; i < d->nnodes; i++)
        planar = planar && d->coords[3 * i + 2] == 0.0;
    int dim = d->triangles.count > 0 && !planar ? 3 : 2;
    const sm_msh_block *b = dim == 3 ? &d->triangles : &d->lines;
    if (b->count == 0 || d->nnodes > SM_MAX_ENTITIES) {
        long long z = -1; /* the first vertex off the plane z = 0 */
        for (int64_t i = 0; i < d->nnodes && z < 0; i++)
            if (d->coords[3 * i + 2] != 0.0)
                z = i;
        char plane[64] = "all at z = 0";
        if (z >= 0)
            snprintf(plane, sizeof plane, "vertex %lld at z = %g", z + 1, d->coords[3 * z + 2]);
        return sm_error_set(err, SM_ERR_FORMAT,
                            "%s: no surface: found %lld triangles, %lld line segments and %lld "
                            "tetrahedra on %lld vertices (%s); triangles in 3D, or lines with "
                            "all z = 0 in 2D are needed", path, (long long)d->triangles.count,
                            (long long)d->lines.count, (long long)d->tetrahedra.count,
                            (long long)d->nnodes, plane);
    }
    sm_surface *s;
    sm_status st = sm_surface_alloc(&s, dim, (int32_t)d->nnodes, (int32_t)b->count, err);
    if (st != SM_OK)
        return st;
    for (int64_t i = 0; i < d->nnodes; i++)
        for (int k = 0; k < dim; k++)
            s->coords[dim * i + k] = d->coords[3 * i + k];
    memcpy(s->facets, b->idx, (size_t)b->count * (size_t)dim * sizeof(int32_t));
    memcpy(s->facet_refs, b->refs, (size_t)b->count * sizeof(int32_t));
    *out = s;
    return SM_OK;
}
