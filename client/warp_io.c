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

typedef enum out_format { OUT_UNKNOWN, OUT_MEDIT, OUT_VTU, OUT_STL, OUT_OBJ } out_format;

static int ends_with(const char *s, const char *suffix)
{
    size_t n = strlen(s), k = strlen(suffix);
    return n >= k && strcmp(s + n - k, suffix) == 0;
}

static out_format format_of(const char *path)
{
    static const char *const medit[] = {".mesh", ".meshb", ".mesh.gz", ".meshb.gz"};
    for (size_t i = 0; i < 4; i++)
        if (ends_with(path, medit[i]))
            return OUT_MEDIT;
    return ends_with(path, ".vtu")   ? OUT_VTU
           : ends_with(path, ".stl") ? OUT_STL
           : ends_with(path, ".obj") ? OUT_OBJ
                                     : OUT_UNKNOWN;
}

static void put_f32(unsigned char *p, double v)
{
    float f = (float)v;
    uint32_t u;
    memcpy(&u, &f, 4);
    for (int i = 0; i < 4; i++)
        p[i] = (unsigned char)(u >> (8 * i));
}

/* Binary STL (little endian), normals from the warped triangles. */
static sm_status write_stl(const char *path, const sm_surface *s, const double *xyz, sm_error *err)
{
    sm_atomic a;
    sm_status st = sm_atomic_open(&a, path, err);
    if (st != SM_OK)
        return st;
    unsigned char head[84] = "binary STL written by shapematch warp";
    uint32_t n = (uint32_t)s->nfacets;
    for (int i = 0; i < 4; i++)
        head[80 + i] = (unsigned char)(n >> (8 * i));
    fwrite(head, 1, sizeof head, a.f);
    for (int32_t t = 0; t < s->nfacets; t++) {
        const double *p[3];
        for (int k = 0; k < 3; k++)
            p[k] = xyz + (size_t)s->facets[(size_t)t * 3 + k] * 3;
        double u[3], v[3], nrm[3], len = 0;
        for (int i = 0; i < 3; i++) {
            u[i] = p[1][i] - p[0][i];
            v[i] = p[2][i] - p[0][i];
        }
        for (int i = 0; i < 3; i++) {
            nrm[i] = u[(i + 1) % 3] * v[(i + 2) % 3] - u[(i + 2) % 3] * v[(i + 1) % 3];
            len += nrm[i] * nrm[i];
        }
        len = sqrt(len);
        unsigned char rec[50] = {0};
        for (int i = 0; i < 3; i++)
            put_f32(rec + 4 * i, len > 0 ? nrm[i] / len : 0.0);
        for (int k = 0; k < 3; k++)
            for (int i = 0; i < 3; i++)
                put_f32(rec + 12 + 12 * k + 4 * i, p[k][i]);
        fwrite(rec, 1, sizeof rec, a.f);
    }
    return sm_atomic_commit(&a, 0, err);
}

/* OBJ: v lines (z = 0 in 2D), then f (triangles) or l (segments). */
static sm_status write_obj(const char *path, const sm_surface *s, const double *xyz, sm_error *err)
{
    sm_atomic a;
    sm_status st = sm_atomic_open(&a, path, err);
    if (st != SM_OK)
        return st;
    const int D = s->dim;
    fprintf(a.f, "# written by shapematch warp\n");
    for (int32_t v = 0; v < s->nverts; v++) {
        const double *x = xyz + (size_t)v * D;
        fprintf(a.f, "v %.17g %.17g %.17g\n", x[0], x[1], D == 3 ? x[2] : 0.0);
    }
    for (int32_t t = 0; t < s->nfacets; t++) {
        const int32_t *f = s->facets + (size_t)t * D;
        if (D == 3)
            fprintf(a.f, "f %ld %ld %ld\n", (long)f[0] + 1, (long)f[1] + 1, (long)f[2] + 1);
        else
            fprintf(a.f, "l %ld %ld\n", (long)f[0] + 1, (long)f[1] + 1);
    }
    return sm_atomic_commit(&a, 0, err);
}

/* A surface as a Medit mesh of facets only. */
static sm_status write_surface_medit(const char *path, const sm_surface *s, const double *xyz,
                                     sm_error *err)
{
    sm_mesh m;
    memset(&m, 0, sizeof m);
    m.dim = s->dim;
    m.nverts = s->nverts;
    m.coords = (double *)xyz;
    int32_t *refs = calloc((size_t)s->nverts + 1, sizeof *refs);
    int32_t *frefs = s->facet_refs ? NULL : calloc((size_t)s->nfacets + 1, sizeof *frefs);
    if (!refs || (!s->facet_refs && !frefs)) {
        free(refs);
        free(frefs);
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    }
    m.vert_refs = refs;
    m.nfacets = s->nfacets;
    m.facets = s->facets;
    m.facet_refs = s->facet_refs ? s->facet_refs : frefs;
    sm_status st = sm_mesh_write_coords(path, &m, xyz, err);
    free(refs);
    free(frefs);
    return st;
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
                ".vtu\n", in_path);
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
    if (fmt == OUT_VTU || (fmt == OUT_STL && s->dim != 3)) {
        fprintf(stderr, "shapematch warp: %s is a %s: write it as .mesh, .meshb, .obj%s\n",
                in_path, s->dim == 3 ? "surface" : "polyline", s->dim == 3 ? " or .stl" : "");
        return CLI_EXIT_USAGE;
    }
    double *xyz;
    int64_t nout = 0;
    int rc = warp_vertices(in_path, w, dir, strict, s->dim, s->nverts, s->coords, &xyz, &nout);
    if (rc != 0)
        return rc;
    sm_error err;
    sm_error_clear(&err);
    sm_status st = fmt == OUT_MEDIT ? write_surface_medit(out_path, s, xyz, &err)
                   : fmt == OUT_STL ? write_stl(out_path, s, xyz, &err)
                                    : write_obj(out_path, s, xyz, &err);
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
                ".mesh, .meshb (optionally .gz), .vtu, .stl or .obj\n", out_path);
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
