/* Target surfaces read from a file: the dispatch by content (Gmsh, Medit,
 * PLY, OFF/PLY2, VTK legacy and XML, STL, OBJ; never by the file name), vertex welding for the formats that
 * repeat vertices per facet, and the surface of a Gmsh .msh file.  The
 * surface model itself (allocation, measures) is core/sm_surface.c. */
#include "io/sm_io_formats.h"

#include <ctype.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "io/sm_io_msh.h"
#include "io/sm_medit_common.h"
#include "io/sm_read_input.h"
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

/* ---- dispatch ---- */

static int medit_ascii_start(sm_reader *r)
{
    char head[256];
    size_t got = 0;
    if (sm__reader_peek(r, head, sizeof head - 1, &got) != SM_OK)
        return 0;
    head[got] = '\0';
    const char *p = head;
    for (;;) {
        while (*p && isspace((unsigned char)*p))
            p++;
        if (*p != '#')
            break;
        while (*p && *p != '\n')
            p++;
    }
    return strncasecmp(p, "MeshVersionFormatted", 20) == 0 || strncasecmp(p, "Dimension", 9) == 0;
}

/* Text (a format we do not read) rather than binary data (perhaps a
 * binary STL whose size does not match its count). */
static int looks_text(const unsigned char *p, size_t n)
{
    for (size_t k = 0; k < n; k++)
        if (p[k] >= 127 || (p[k] < 32 && p[k] != '\n' && p[k] != '\r' && p[k] != '\t'))
            return 0;
    return 1;
}

sm_status sm_surface_read(const char *path, sm_surface **out, sm_error *err)
{
    return sm_surface_read_limited(path, NULL, out, err);
}

sm_status sm_surface_read_limited(const char *path, sm_read_limits *limits, sm_surface **out,
                                  sm_error *err)
{
    *out = NULL;
    if (!path)
        return sm_error_set(err, SM_ERR_INVALID, "no surface file name");
    return sm__surface_read_input(&(sm_reader_input){.path = path}, limits, out, err);
}

sm_status sm__surface_read_input(const sm_reader_input *in, sm_read_limits *limits,
                                 sm_surface **out, sm_error *err)
{
    const char *path = in->path;
    *out = NULL;
    sm_reader r;
    sm_status st = sm__reader_open_input(&r, in, err);
    if (st != SM_OK)
        return st;
    r.limits = limits;
    int binary = 0;
    unsigned char head[512];
    size_t got = 0;
    if ((st = sm__reader_peek(&r, head, sizeof head, &got)) != SM_OK)
        st = sm__reader_fail_byte(&r, err, st, 0, "%s", r.why);
    if (st != SM_OK || (st = sm__medit_detect(&r, &binary, err)) != SM_OK) {
        sm__reader_close(&r);
        return st;
    }
    int ply2 = 0;
    sm_msh_data d;
    sm_status (*cells)(sm_reader *, sm_msh_data *, sm_error *) =
        sm__msh_detect(&r) ? sm__msh_parse : sm__vtk_detect(&r) ? sm__vtk_parse
                                           : sm__vtkxml_detect(&r) ? sm__vtkxml_parse : NULL;
    if (cells) {
        st = cells(&r, &d, err);
        if (st == SM_OK)
            st = sm__msh_surface(path, &d, out, err);
        sm__msh_data_free(&d);
    } else if (medit_ascii_start(&r) || (binary && !sm__stl_detect(&r))) {
        st = sm__medit_surface_read(&r, out, err);
    } else if (sm__ply_detect(&r)) {
        st = sm__ply_read(&r, out, err);
    } else if (sm__stl_detect(&r)) {
        st = sm__stl_read(&r, out, err);
    } else if (sm__obj_detect(&r)) {
        st = sm__obj_read(&r, out, err);
    } else if (sm__off_detect(&r, &ply2)) {
        st = sm__off_read(&r, out, err);
    } else if (got >= 84 && !looks_text(head, got)) {
        /* binary content of no other format is taken for a binary STL,
         * whose reader says precisely what does not fit */
        st = sm__stl_read(&r, out, err);
    } else {
        st = sm_error_set(err, SM_ERR_FORMAT, "%s: unknown surface format; surfaces are read "
                          "as " SM_SURFACE_FORMATS, path);
    }
    sm__reader_close(&r);
    return st;
}
