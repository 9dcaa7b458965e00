/* The generated background mesh (sm_sdf.h): a Kuhn subdivision of a
 * uniform grid.  The vertex of grid node (i, j, k) is i + nx' (j + ny' k)
 * with nx' = nx + 1 points per row. */
#include <math.h>
#include <stdlib.h>

#include "shapematch/sm_mesh.h"
#include "shapematch/sm_sdf.h"

/* the 6 axis orders of the Kuhn tetrahedra */
static const int kuhn3[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};

static int32_t node_id(const int64_t *np, const int64_t *ijk, int dim)
{
    return (int32_t)(ijk[0] + np[0] * (ijk[1] + (dim == 3 ? np[1] * ijk[2] : 0)));
}

static void cell_elements(sm_mesh *m, const int64_t *np, const int64_t *c, int32_t *e)
{
    int dim = m->dim;
    int nperm = dim == 3 ? 6 : 2;
    for (int t = 0; t < nperm; t++) {
        int64_t ijk[3] = {c[0], c[1], dim == 3 ? c[2] : 0};
        int32_t *v = m->elems + (size_t)(*e) * (dim + 1);
        v[0] = node_id(np, ijk, dim);
        for (int s = 0; s < dim; s++) {
            ijk[dim == 3 ? kuhn3[t][s] : (t + s) % 2]++;
            v[s + 1] = node_id(np, ijk, dim);
        }
        (*e)++;
    }
}

sm_status sm_background_new(int dim, const double *lo, const double *hi, double h,
                            sm_mesh **out, sm_error *err)
{
    *out = NULL;
    if ((dim != 2 && dim != 3) || !(h > 0) || !isfinite(h))
        return sm_error_set(err, SM_ERR_INVALID, "background: bad dimension or size %g", h);
    int64_t n[3] = {1, 1, 1}, np[3] = {2, 2, 2};
    double total = 1;
    for (int k = 0; k < dim; k++) {
        double len = hi[k] - lo[k];
        if (!(len > 0) || !isfinite(len))
            return sm_error_set(err, SM_ERR_INVALID, "background: empty box along axis %d", k);
        double cells = ceil(len / h);
        if (cells > 1e6)
            cells = 1e6;
        n[k] = (int64_t)(cells < 1 ? 1 : cells);
        np[k] = n[k] + 1;
        total *= (double)np[k];
    }
    if (total > SM_BACKGROUND_MAX_VERTS)
        return sm_error_set(err, SM_ERR_INVALID,
                            "background of size %g would have %.3g vertices (limit %d): give "
                            "a larger --background-size", h, total, SM_BACKGROUND_MAX_VERTS);
    int64_t ncells = n[0] * n[1] * (dim == 3 ? n[2] : 1);
    sm_mesh *m;
    sm_status st = sm_mesh_alloc(&m, dim, (int32_t)total, (int32_t)(ncells * (dim == 3 ? 6 : 2)),
                                 0, err);
    if (st != SM_OK)
        return st;
    int64_t kmax = dim == 3 ? np[2] : 1;
    for (int64_t k = 0; k < kmax; k++)
        for (int64_t j = 0; j < np[1]; j++)
            for (int64_t i = 0; i < np[0]; i++) {
                int64_t ijk[3] = {i, j, k};
                double *x = m->coords + (size_t)node_id(np, ijk, dim) * dim;
                for (int a = 0; a < dim; a++)
                    x[a] = ijk[a] == n[a] ? hi[a] : lo[a] + (hi[a] - lo[a]) * (double)ijk[a] / (double)n[a];
            }
    int32_t e = 0;
    for (int64_t k = 0; k < (dim == 3 ? n[2] : 1); k++)
        for (int64_t j = 0; j < n[1]; j++)
            for (int64_t i = 0; i < n[0]; i++) {
                int64_t c[3] = {i, j, k};
                cell_elements(m, np, c, &e);
            }
    *out = m;
    return SM_OK;
}
