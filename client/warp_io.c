/* Files of `shapematch warp` (see warp_io.h). */
#include "warp_io.h"

#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "shapematch/sm_atomic.h"
#include "shapematch/sm_io.h"
#include "shapematch/sm_surface.h"

sm_status warp_read_file(const char *path, size_t max, char **out, size_t *len, sm_error *err)
{
    *out = NULL;
    *len = 0;
    FILE *f = fopen(path, "rb");
    if (!f)
        return sm_error_set(err, SM_ERR_IO, "cannot open '%s': %s", path, strerror(errno));
    size_t cap = 1 << 16, n = 0;
    char *buf = malloc(cap + 1);
    sm_status st = SM_OK;
    while (buf) {
        if (n == cap) {
            if (cap >= max) {
                st = sm_error_set(err, SM_ERR_NOMEM, "'%s' is larger than %zu bytes", path, max);
                break;
            }
            cap = cap * 2 > max ? max : cap * 2;
            char *grown = realloc(buf, cap + 1);
            if (!grown)
                break;
            buf = grown;
        }
        size_t got = fread(buf + n, 1, cap - n, f);
        n += got;
        if (got == 0) {
            if (ferror(f))
                st = sm_error_set(err, SM_ERR_IO, "cannot read '%s': %s", path, strerror(errno));
            break;
        }
    }
    fclose(f);
    if (!buf)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory reading '%s'", path);
    if (st != SM_OK) {
        free(buf);
        return st;
    }
    buf[n] = '\0';
    *out = buf;
    *len = n;
    return SM_OK;
}

/* ------------------------------------------------------------ formats */

typedef enum out_format { OUT_UNKNOWN, OUT_MEDIT, OUT_VTU, OUT_SURFACE } out_format;

static int ends_with(const char *s, const char *suffix)
{
    size_t n = strlen(s), k = strlen(suffix);
    return n >= k && strcmp(s + n - k, suffix) == 0;
}

/* Medit and .vtu for both kinds; the surface formats (sm_surface_write:
 * STL, OBJ, PLY, OFF, VTK legacy) for surfaces. */
static out_format format_of(const char *path)
{
    static const char *const medit[] = {".mesh", ".meshb", ".mesh.gz", ".meshb.gz"};
    static const char *const surface[] = {".stl", ".obj", ".ply", ".off", ".vtk"};
    for (size_t i = 0; i < 4; i++)
        if (ends_with(path, medit[i]))
            return OUT_MEDIT;
    for (size_t i = 0; i < 5; i++)
        if (ends_with(path, surface[i]))
            return OUT_SURFACE;
    return ends_with(path, ".vtu") ? OUT_VTU : OUT_UNKNOWN;
}

/* ------------------------------------------------------------- warp */

/* Maps n vertices; prints the error and returns an exit code, or 0. */
static int warp_vertices(const char *in_path, const sm_warp *w, sm_warp_direction dir, int strict,
                         int dim, int32_t n, const double *xyz, double **out, int64_t *nout)
{
    *out = NULL;
    if (dim != sm_warp_dim(w)) {
        fprintf(stderr, "shapematch warp: %s is %dD and the map is %dD\n", in_path, dim,
                sm_warp_dim(w));
        return CLI_EXIT_INPUT;
    }
    *out = malloc(((size_t)n * (size_t)dim + 1) * sizeof **out);
    if (!*out) {
        fprintf(stderr, "shapematch warp: out of memory\n");
        return CLI_EXIT_NUMERIC;
    }
    sm_error err;
    sm_error_clear(&err);
    if (sm_warp_points(w, dir, strict, n, xyz, *out, NULL, nout, &err) != SM_OK) {
        fprintf(stderr, "shapematch warp: %s: vertices: %s\n", in_path, err.msg);
        free(*out);
        *out = NULL;
        return CLI_EXIT_INPUT;
    }
    return 0;
}

static int report(int rc, const char *in_path, const char *out_path, int32_t n, int64_t nout,
                  int quiet, const sm_error *err)
{
    if (rc == CLI_EXIT_OUTPUT)
        fprintf(stderr, "shapematch warp: %s\n", err->msg);
    else if (rc == 0 && !quiet)
        fprintf(stderr, "shapematch warp: %s -> %s: %ld vertices, %lld outside (extrapolated)\n",
                in_path, out_path, (long)n, (long long)nout);
    return rc;
}

static int warp_volume(const char *in_path, const char *out_path, out_format fmt, sm_mesh *m,
                       const sm_warp *w, sm_warp_direction dir, int strict, int quiet)
{
    if (fmt != OUT_MEDIT && fmt != OUT_VTU) {
        fprintf(stderr, "shapematch warp: %s is a volume mesh: write it as .mesh, .meshb or "
                ".vtu (the surface formats are for surfaces)\n", in_path);
        return CLI_EXIT_USAGE;
    }
    double *xyz;
    int64_t nout = 0;
    int rc = warp_vertices(in_path, w, dir, strict, m->dim, m->nverts, m->coords, &xyz, &nout);
    if (rc != 0)
        return rc;
    sm_error err;
    sm_error_clear(&err);
    sm_status st = fmt == OUT_MEDIT ? sm_mesh_write_coords(out_path, m, xyz, &err)
                                    : sm_vtu_write(out_path, m, xyz, NULL, NULL, &err);
    free(xyz);
    return report(st == SM_OK ? 0 : CLI_EXIT_OUTPUT, in_path, out_path, m->nverts, nout, quiet,
                  &err);
}

static int warp_surface(const char *in_path, const char *out_path, out_format fmt,
                        sm_surface *s, const sm_warp *w, sm_warp_direction dir, int strict,
                        int quiet)
{
    if (s->dim != 3 && (ends_with(out_path, ".stl") || ends_with(out_path, ".ply") ||
                        ends_with(out_path, ".off"))) {
        fprintf(stderr, "shapematch warp: %s is a polyline: write it as .mesh, .meshb, .obj, "
                ".vtk or .vtu\n", in_path);
        return CLI_EXIT_USAGE;
    }
    double *xyz;
    int64_t nout = 0;
    int rc = warp_vertices(in_path, w, dir, strict, s->dim, s->nverts, s->coords, &xyz, &nout);
    if (rc != 0)
        return rc;
    sm_error err;
    sm_error_clear(&err);
    (void)fmt; /* every format of format_of, by the name: sm_surface_write */
    sm_status st = sm_surface_write(out_path, s, xyz, &err);
    free(xyz);
    return report(st == SM_OK ? 0 : CLI_EXIT_OUTPUT, in_path, out_path, s->nverts, nout, quiet,
                  &err);
}

int warp_mesh_file(const char *in_path, const char *out_path, const sm_warp *w,
                   sm_warp_direction dir, int strict, int quiet)
{
    out_format fmt = format_of(out_path);
    if (fmt == OUT_UNKNOWN) {
        fprintf(stderr, "shapematch warp: %s: the output format is chosen by its extension: "
                "%s\n", out_path, SM_SURFACE_WRITE_FORMATS);
        return CLI_EXIT_USAGE;
    }
    sm_error merr, serr;
    sm_error_clear(&merr);
    sm_error_clear(&serr);
    sm_mesh *m = NULL;
    if (sm_mesh_read(in_path, &m, &merr) == SM_OK) {
        int rc = warp_volume(in_path, out_path, fmt, m, w, dir, strict, quiet);
        sm_mesh_free(m);
        return rc;
    }
    if (merr.code == SM_ERR_IO) {
        fprintf(stderr, "shapematch warp: %s\n", merr.msg);
        return CLI_EXIT_INPUT;
    }
    sm_surface *s = NULL;
    if (sm_surface_read(in_path, &s, &serr) != SM_OK) {
        fprintf(stderr, "shapematch warp: %s is neither a mesh (%s) nor a surface (%s)\n",
                in_path, merr.msg, serr.msg);
        return CLI_EXIT_INPUT;
    }
    int rc = warp_surface(in_path, out_path, fmt, s, w, dir, strict, quiet);
    sm_surface_free(s);
    return rc;
}
