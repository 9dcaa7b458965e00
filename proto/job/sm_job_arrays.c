/* Inputs in memory made into core objects (see sm_job_arrays.h). */
#include "job/sm_job_arrays.h"

#include <math.h>
#include <string.h>

static sm_status check_count(const char *name, const char *what, int32_t n, int32_t least,
                             const void *array, sm_error *err)
{
    if (n < least || n > SM_MAX_ENTITIES)
        return sm_error_set(err, SM_ERR_FORMAT, "%s: %ld %s: between %ld and %d are read", name,
                            (long)n, what, (long)least, SM_MAX_ENTITIES);
    if (n > 0 && !array)
        return sm_error_set(err, SM_ERR_INVALID, "%s: %ld %s but no array", name, (long)n, what);
    return SM_OK;
}

static sm_status check_coords(const char *name, const double *x, int32_t n, int dim,
                              sm_error *err)
{
    for (int64_t i = 0; i < (int64_t)n * dim; i++)
        if (!isfinite(x[i]))
            return sm_error_set(err, SM_ERR_FORMAT, "%s: vertex %ld: coordinate %d is not a "
                                "finite number (%g)", name, (long)(i / dim), (int)(i % dim) + 1,
                                x[i]);
    return SM_OK;
}

/* rows of k indices, each in [0, nverts) */
static sm_status check_indices(const char *name, const char *what, const int32_t *idx,
                               int32_t rows, int k, int32_t nverts, sm_error *err)
{
    for (int64_t i = 0; i < (int64_t)rows * k; i++)
        if (idx[i] < 0 || idx[i] >= nverts)
            return sm_error_set(err, SM_ERR_FORMAT, "%s: %s %ld: vertex index %ld out of range "
                                "[0, %ld) (indices are 0-based)", name, what, (long)(i / k),
                                (long)idx[i], (long)nverts);
    return SM_OK;
}

static sm_status check_dim(const char *name, int dim, sm_error *err)
{
    if (dim != 2 && dim != 3)
        return sm_error_set(err, SM_ERR_FORMAT, "%s: dimension %d (2 or 3 are read)", name, dim);
    return SM_OK;
}

sm_status sm_job_mesh_from_arrays(const sm_run_mesh *a, const char *name, sm_mesh **out,
                                  sm_error *err)
{
    *out = NULL;
    sm_status st;
    if ((st = check_dim(name, a->dim, err)) != SM_OK ||
        (st = check_count(name, "vertices", a->nverts, 1, a->coords, err)) != SM_OK ||
        (st = check_count(name, "elements", a->nelems, 1, a->elems, err)) != SM_OK ||
        (st = check_count(name, "facets", a->nfacets, 0, a->facets, err)) != SM_OK ||
        (st = check_coords(name, a->coords, a->nverts, a->dim, err)) != SM_OK ||
        (st = check_indices(name, "element", a->elems, a->nelems, a->dim + 1, a->nverts, err)) !=
            SM_OK ||
        (a->nfacets && (st = check_indices(name, "facet", a->facets, a->nfacets, a->dim,
                                           a->nverts, err)) != SM_OK))
        return st;
    sm_mesh *m;
    if ((st = sm_mesh_alloc(&m, a->dim, a->nverts, a->nelems, a->nfacets, err)) != SM_OK)
        return st;
    size_t nv = (size_t)a->nverts, ne = (size_t)a->nelems, nf = (size_t)a->nfacets;
    memcpy(m->coords, a->coords, nv * (size_t)a->dim * sizeof(double));
    memcpy(m->elems, a->elems, ne * (size_t)(a->dim + 1) * sizeof(int32_t));
    if (a->elem_refs)
        memcpy(m->elem_refs, a->elem_refs, ne * sizeof(int32_t));
    if (a->vert_refs)
        memcpy(m->vert_refs, a->vert_refs, nv * sizeof(int32_t));
    if (nf) {
        memcpy(m->facets, a->facets, nf * (size_t)a->dim * sizeof(int32_t));
        if (a->facet_refs)
            memcpy(m->facet_refs, a->facet_refs, nf * sizeof(int32_t));
    }
    *out = m;
    return SM_OK;
}

sm_status sm_job_surface_from_arrays(const sm_run_surface *a, const char *name,
                                     sm_surface **out, sm_error *err)
{
    *out = NULL;
    sm_status st;
    if ((st = check_dim(name, a->dim, err)) != SM_OK ||
        (st = check_count(name, "vertices", a->nverts, 1, a->coords, err)) != SM_OK ||
        (st = check_count(name, a->dim == 3 ? "triangles" : "segments", a->nfacets, 1,
                          a->facets, err)) != SM_OK ||
        (st = check_coords(name, a->coords, a->nverts, a->dim, err)) != SM_OK ||
        (st = check_indices(name, a->dim == 3 ? "triangle" : "segment", a->facets, a->nfacets,
                            a->dim, a->nverts, err)) != SM_OK)
        return st;
    sm_surface *s;
    if ((st = sm_surface_alloc(&s, a->dim, a->nverts, a->nfacets, err)) != SM_OK)
        return st;
    memcpy(s->coords, a->coords, (size_t)a->nverts * (size_t)a->dim * sizeof(double));
    memcpy(s->facets, a->facets, (size_t)a->nfacets * (size_t)a->dim * sizeof(int32_t));
    *out = s;
    return SM_OK;
}

sm_status sm_job_sol_from_values(const double *values, int32_t n, int dim, const char *name,
                                 sm_sol **out, sm_error *err)
{
    *out = NULL;
    sm_status st = check_count(name, "values", n, 1, values, err);
    if (st != SM_OK || (st = sm_sol_alloc(out, dim, n, 1, err)) != SM_OK)
        return st;
    memcpy((*out)->values, values, (size_t)n * sizeof(double));
    return SM_OK;
}
