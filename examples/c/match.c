/* A program of your own on libshapematch: reads a template, a background
 * mesh and the target's signed distance on it, matches with a clamp ball
 * and writes the deformed template.  Built against an installed tree:
 *
 *   cc match.c $(pkg-config --cflags --libs shapematch) -o match
 *   ./match template.mesh background.mesh.gz background.sol.gz X,Y[,Z],R out.mesh
 *
 * (docs/c-api.md walks through it; tests/build/install.sh builds and runs
 * it on examples/2d.) */
#include <shapematch.h>

#include <stdio.h>
#include <stdlib.h>

static int on_progress(const sm_progress *p, const double *coords, void *user)
{
    (void)coords;
    (void)user;
    if (p->iteration % 50 == 0)
        fprintf(stderr, "iteration %d: boundary RMS %.3e\n", p->iteration, p->boundary_rms);
    return 0; /* nonzero would stop the run */
}

static int fail(const char *what, const sm_error *err)
{
    fprintf(stderr, "match: %s: %s\n", what, err->msg);
    return 1;
}

int main(int argc, char **argv)
{
    if (argc != 6) {
        fprintf(stderr, "usage: %s TEMPLATE BACKGROUND SOL X,Y[,Z],R OUT.mesh\n", argv[0]);
        return 2;
    }
    sm_error err;
    sm_error_clear(&err);
    sm_mesh *tmpl = NULL, *bg = NULL;
    sm_sol *sol = NULL;
    sm_field *field = NULL;
    double *coords = NULL;
    int rc = 1;

    if (sm_mesh_read(argv[1], &tmpl, &err) != SM_OK) {
        rc = fail(argv[1], &err);
        goto done;
    }
    if (sm_mesh_read(argv[2], &bg, &err) != SM_OK || sm_sol_read(argv[3], &sol, &err) != SM_OK ||
        sm_field_new(bg, sol->values, &field, &err) != SM_OK) {
        rc = fail("target", &err);
        goto done;
    }

    sm_params params;
    sm_params_default(&params);
    double b[4];
    int n = sscanf(argv[4], "%lf,%lf,%lf,%lf", &b[0], &b[1], &b[2], &b[3]);
    if (n != tmpl->dim + 1) {
        fprintf(stderr, "match: the clamp ball of a %dD template is %d numbers\n", tmpl->dim,
                tmpl->dim + 1);
        rc = 2;
        goto done;
    }
    params.clamp = SM_CLAMP_BALL;
    for (int i = 0; i < tmpl->dim; i++)
        params.clamp_center[i] = b[i];
    params.clamp_radius = b[tmpl->dim];
    if (sm_params_validate(&params, tmpl->dim, &err) != SM_OK) {
        rc = fail("parameters", &err);
        goto done;
    }

    coords = malloc((size_t)tmpl->nverts * (size_t)tmpl->dim * sizeof *coords);
    if (!coords)
        goto done;
    sm_match_opts opts = {.template_mesh = tmpl, .target = field, .params = &params};
    sm_match_callbacks cb = {.progress = on_progress};
    sm_result res;
    if (sm_match_run(&opts, &cb, coords, &res, &err) != SM_OK) {
        rc = fail("run", &err);
        goto done;
    }
    printf("%s after %d iterations: boundary RMS %.3e, min quality %.3f\n",
           sm_stop_reason_name(res.stop), res.iterations, res.boundary_rms, res.min_quality);
    if (sm_mesh_write_coords(argv[5], tmpl, coords, &err) != SM_OK) {
        rc = fail(argv[5], &err);
        goto done;
    }
    rc = 0;
done:
    free(coords);
    sm_field_free(field);
    sm_sol_free(sol);
    sm_mesh_free(bg);
    sm_mesh_free(tmpl);
    return rc;
}
