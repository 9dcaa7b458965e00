/* shapematch_job.h's warp: the job layer's warp use case (sm_job_warp.h)
 * behind plain C types, for bindings (python/shapematch/_warp.py). */
#include <stdlib.h>
#include <string.h>

#include "job/shapematch_job.h"
#include "job/sm_job_warp.h"

struct sm_run_map {
    sm_job_map *map;
};

static sm_status wrap(sm_job_map *map, sm_run_map **out, sm_error *err)
{
    if (!(*out = malloc(sizeof **out))) {
        sm_job_map_free(map);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    }
    (*out)->map = map;
    return SM_OK;
}

sm_status sm_run_map_open(const char *result_dir, sm_run_map **out, sm_error *err)
{
    *out = NULL;
    sm_job_map *map;
    sm_status st = sm_job_map_open(result_dir, 0, &map, err);
    return st == SM_OK ? wrap(map, out, err) : st;
}

sm_status sm_run_map_new(int dim, int32_t nverts, const double *template_coords,
                         const double *deformed_coords, int32_t nelems, const int32_t *elems,
                         sm_run_map **out, sm_error *err)
{
    *out = NULL;
    if ((dim != 2 && dim != 3) || nverts < 0 || nelems < 0)
        return sm_error_set(err, SM_ERR_INVALID, "a map of dimension %d with %ld vertices and "
                            "%ld elements", dim, (long)nverts, (long)nelems);
    sm_mesh *m = NULL;
    sm_status st = sm_mesh_alloc(&m, dim, nverts, nelems, 0, err);
    if (st != SM_OK)
        return st;
    size_t nc = (size_t)nverts * (size_t)dim, ne = (size_t)nelems * (size_t)(dim + 1);
    for (size_t i = 0; i < ne; i++)
        if (elems[i] < 0 || elems[i] >= nverts) {
            sm_mesh_free(m);
            return sm_error_set(err, SM_ERR_INVALID, "element %zu: vertex %ld of %ld",
                                i / (size_t)(dim + 1) + 1, (long)elems[i], (long)nverts);
        }
    double *deformed = malloc((nc ? nc : 1) * sizeof *deformed);
    if (!deformed) {
        sm_mesh_free(m);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    }
    memcpy(m->coords, template_coords, nc * sizeof *m->coords);
    memcpy(m->elems, elems, ne * sizeof *m->elems);
    memcpy(deformed, deformed_coords, nc * sizeof *deformed);
    sm_job_map *map;
    st = sm_job_map_new(m, deformed, 0, &map, err);
    return st == SM_OK ? wrap(map, out, err) : st;
}

void sm_run_map_free(sm_run_map *m)
{
    if (m)
        sm_job_map_free(m->map);
    free(m);
}

int sm_run_map_dim(const sm_run_map *m)
{
    return sm_job_map_dim(m->map);
}

int32_t sm_run_map_nverts(const sm_run_map *m)
{
    return sm_job_map_template(m->map)->nverts;
}

sm_status sm_run_warp_points(sm_run_map *m, int inverse, int strict, int outside, int dim,
                             int64_t n, const double *xyz, double *out, uint8_t *inside,
                             int64_t *noutside, int64_t *kept, sm_error *err)
{
    if (outside < SM_JOB_OUTSIDE_EXTRAPOLATE || outside > SM_JOB_OUTSIDE_SKIP)
        return sm_error_set(err, SM_ERR_INVALID, "outside: expected 0 (extrapolate), 1 (flag) "
                            "or 2 (skip), got %d", outside);
    uint8_t *flags = inside ? inside : malloc((size_t)n + 1);
    if (!flags)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for %lld points", (long long)n);
    sm_job_warp_request rq = {.direction = inverse ? SM_WARP_INVERSE : SM_WARP_FORWARD,
                              .strict = strict, .outside = (sm_job_warp_outside)outside};
    sm_job_warp_report rep;
    int64_t rows;
    sm_status st = sm_job_warp_points(m->map, dim, n, xyz, &rq, out, flags, &rows, &rep, err);
    if (flags != inside)
        free(flags);
    if (noutside)
        *noutside = st == SM_OK ? rep.noutside : 0;
    if (kept)
        *kept = st == SM_OK ? rows : 0;
    return st;
}

sm_status sm_run_warp_field(sm_run_map *m, int inverse, int normalize, int dim, int32_t nverts,
                            int ncomp, double *values, sm_error *err)
{
    sm_job_warp_request rq = {.direction = inverse ? SM_WARP_INVERSE : SM_WARP_FORWARD,
                              .normalize = normalize};
    sm_job_warp_report rep;
    return sm_job_warp_field(m->map, dim, nverts, ncomp, values, &rq, &rep, err);
}

sm_status sm_run_warp_file(sm_run_map *m, int field, const char *in, const char *out,
                           int inverse, int strict, int normalize, double **values,
                           int64_t *rows, int *cols, sm_error *err)
{
    sm_job_warp_request rq = {.direction = inverse ? SM_WARP_INVERSE : SM_WARP_FORWARD,
                              .strict = strict, .normalize = normalize};
    sm_job_warp_report rep;
    *values = NULL;
    *rows = 0;
    *cols = 0;
    if (!field) {
        sm_status st = sm_job_warp_mesh_file(m->map, in, out, &rq, values, &rep, err);
        if (st == SM_OK) {
            *rows = rep.n;
            *cols = sm_job_map_dim(m->map);
        }
        return st;
    }
    sm_sol *s = NULL;
    sm_status st = sm_job_warp_field_file(m->map, in, out, &rq, &s, &rep, err);
    if (st != SM_OK)
        return st;
    size_t n = (size_t)s->nverts * (size_t)s->ncomp;
    if (!(*values = malloc((n ? n : 1) * sizeof **values))) {
        sm_sol_free(s);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    }
    memcpy(*values, s->values, n * sizeof **values);
    *rows = s->nverts;
    *cols = s->ncomp;
    sm_sol_free(s);
    return SM_OK;
}

void sm_run_warp_values_free(double *values)
{
    free(values);
}
