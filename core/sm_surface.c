/* Target surfaces, the model: allocation and measures.  Reading them is
 * core/io/sm_io.c (the dispatch by content) and the format
 * readers beside it. */
#include "shapematch/sm_surface.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "shapematch/sm_mesh.h"

sm_status sm_surface_alloc(sm_surface **out, int dim, int32_t nverts, int32_t nfacets,
                           sm_error *err)
{
    *out = NULL;
    if (dim != 2 && dim != 3)
        return sm_error_set(err, SM_ERR_INVALID, "dimension %d is not 2 or 3", dim);
    if (nverts < 0 || nfacets < 0 || nverts > SM_MAX_ENTITIES || nfacets > SM_MAX_ENTITIES)
        return sm_error_set(err, SM_ERR_NOMEM, "surface sizes out of range (vertices %ld, "
                            "facets %ld; limit %d)", (long)nverts, (long)nfacets,
                            SM_MAX_ENTITIES);
    sm_surface *s = calloc(1, sizeof *s);
    if (!s)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    s->dim = dim;
    s->nverts = nverts;
    s->nfacets = nfacets;
    s->coords = calloc((size_t)nverts * (size_t)dim + 1, sizeof(double));
    s->facets = calloc((size_t)nfacets * (size_t)dim + 1, sizeof(int32_t));
    s->facet_refs = calloc((size_t)nfacets + 1, sizeof(int32_t));
    if (!s->coords || !s->facets || !s->facet_refs) {
        sm_surface_free(s);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for a surface of %ld facets",
                            (long)nfacets);
    }
    *out = s;
    return SM_OK;
}

void sm_surface_free(sm_surface *s)
{
    if (!s)
        return;
    free(s->coords);
    free(s->facets);
    free(s->facet_refs);
    free(s);
}

double sm_surface_mean_edge(const sm_surface *s)
{
    int dim = s->dim;
    double sum = 0;
    int64_t count = 0;
    for (int32_t f = 0; f < s->nfacets; f++)
        for (int a = 0; a < dim; a++)
            for (int b = a + 1; b < dim; b++) {
                const double *p = s->coords + (size_t)s->facets[(size_t)f * dim + a] * dim;
                const double *q = s->coords + (size_t)s->facets[(size_t)f * dim + b] * dim;
                double d2 = 0;
                for (int k = 0; k < dim; k++)
                    d2 += (p[k] - q[k]) * (p[k] - q[k]);
                sum += sqrt(d2);
                count++;
            }
    return count ? sum / (double)count : 0;
}
