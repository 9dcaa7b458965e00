/* The map of a result set, read back (see sm_job_map.h). */
#include "job/sm_job_map.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "shapematch/sm_io.h"
#include "shapematch/sm_path.h"

/* The first of dir/names[i] that exists, malloc'd (NULL: none). */
static char *find_file(const char *dir, const char *const *names)
{
    for (; *names; names++) {
        char *p = sm_path_join(dir, *names);
        if (p && access(p, F_OK) == 0)
            return p;
        free(p);
    }
    return NULL;
}

sm_status sm_job_map_read(const char *dir, sm_mesh **tmpl, double **deformed, sm_error *err)
{
    static const char *const meshes[] = {"result.mesh", "result.meshb", "result.mesh.gz",
                                         "result.meshb.gz", NULL};
    static const char *const sols[] = {"displacement.sol", "displacement.solb",
                                       "displacement.sol.gz", "displacement.solb.gz", NULL};
    *tmpl = NULL;
    *deformed = NULL;
    char *pm = find_file(dir, meshes), *ps = find_file(dir, sols);
    sm_sol *d = NULL;
    sm_mesh *m = NULL;
    sm_status st;
    if (!pm || !ps) {
        st = sm_error_set(err, SM_ERR_IO, "%s has no %s (a result folder of 'run' or 'fetch')",
                          dir, !pm ? "result.mesh or result.meshb"
                                   : "displacement.sol or displacement.solb");
        goto done;
    }
    if ((st = sm_mesh_read(pm, &m, err)) != SM_OK || (st = sm_sol_read(ps, &d, err)) != SM_OK)
        goto done;
    if (d->nverts != m->nverts || d->ncomp != m->dim) {
        st = sm_error_set(err, SM_ERR_FORMAT,
                          "%s has %ld values of %d components, %s %ld vertices in %dD", ps,
                          (long)d->nverts, d->ncomp, pm, (long)m->nverts, m->dim);
        goto done;
    }
    size_t n = (size_t)m->nverts * (size_t)m->dim;
    if (!(*deformed = malloc((n ? n : 1) * sizeof **deformed))) {
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory reading %s", pm);
        goto done;
    }
    memcpy(*deformed, m->coords, n * sizeof **deformed);
    for (size_t i = 0; i < n; i++)
        m->coords[i] -= d->values[i];
    *tmpl = m;
    m = NULL;
done:
    sm_mesh_free(m);
    sm_sol_free(d);
    free(pm);
    free(ps);
    return st;
}
