/* Cells of PLY, OFF and VTK files into an sm_msh_data (sm_io_cells.h). */
#include "io/sm_io_cells.h"

#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void sm__cells_init(sm_msh_data *d)
{
    memset(d, 0, sizeof *d);
    d->lines.nidx = 2;
    d->triangles.nidx = 3;
    d->tetrahedra.nidx = 4;
}

static sm_status why_nomem(sm_reader *r)
{
    snprintf(r->why, sizeof r->why, "out of memory");
    return SM_ERR_NOMEM;
}

sm_status sm__cells_points(sm_reader *r, sm_msh_data *d, int64_t n, sm_error *err)
{
    if (n < 0 || n > SM_MAX_ENTITIES) {
        snprintf(r->why, sizeof r->why, "point count %" PRId64 " out of range [0, %d]", n,
                 SM_MAX_ENTITIES);
        return SM_ERR_FORMAT;
    }
    sm_status st = sm__reader_limit_count(r, err, n, 1, "vertices");
    if (st != SM_OK) {
        snprintf(r->why, sizeof r->why, "%.150s", err->msg);
        return st;
    }
    free(d->coords);
    d->coords = calloc((size_t)n * 3 + 1, sizeof *d->coords);
    d->nnodes = d->coords ? n : 0;
    return d->coords ? SM_OK : why_nomem(r);
}

/* One simplex of b on the nodes v (already checked), from cell cell. */
static sm_status push(sm_reader *r, sm_msh_block *b, const int64_t *v, int64_t cell)
{
    if (b->count == b->cap) {
        int64_t cap = b->cap ? 2 * b->cap : 64; /* small inputs, small buffers */
        if (b->count >= SM_MAX_ENTITIES) {
            snprintf(r->why, sizeof r->why, "more than %d simplices of one kind",
                     SM_MAX_ENTITIES);
            return SM_ERR_FORMAT;
        }
        if (cap > SM_MAX_ENTITIES)
            cap = SM_MAX_ENTITIES;
        int32_t *idx = realloc(b->idx, (size_t)cap * (size_t)b->nidx * sizeof *idx);
        if (idx)
            b->idx = idx;
        int32_t *refs = realloc(b->refs, (size_t)cap * sizeof *refs);
        if (refs)
            b->refs = refs;
        if (!idx || !refs)
            return why_nomem(r);
        b->cap = cap;
    }
    for (int k = 0; k < b->nidx; k++)
        b->idx[b->count * b->nidx + k] = (int32_t)v[k];
    b->refs[b->count++] = (int32_t)cell;
    return SM_OK;
}

static sm_status check_nodes(sm_reader *r, const sm_msh_data *d, int64_t nv, const int64_t *v,
                             int64_t cell)
{
    if (cell < 0 || cell >= SM_MAX_ENTITIES) {
        snprintf(r->why, sizeof r->why, "more than %d cells", SM_MAX_ENTITIES);
        return SM_ERR_FORMAT;
    }
    for (int64_t k = 0; k < nv; k++)
        if (v[k] < 0 || v[k] >= d->nnodes) {
            snprintf(r->why, sizeof r->why, "cell %" PRId64 ": point index %" PRId64
                     " out of range [0, %" PRId64 ")", cell + 1, v[k], d->nnodes);
            return SM_ERR_FORMAT;
        }
    if (r->limits) {
        int64_t n = d->lines.count + d->triangles.count + d->tetrahedra.count + nv;
        sm_error e;
        if (sm__reader_limit_count(r, &e, n, 0, "cells") != SM_OK) {
            snprintf(r->why, sizeof r->why, "%.150s", e.msg);
            return SM_ERR_NOMEM;
        }
    }
    return SM_OK;
}

sm_status sm__cells_add_polygon(sm_reader *r, sm_msh_data *d, int64_t nv, const int64_t *v,
                                int64_t cell)
{
    if (nv < 3) {
        snprintf(r->why, sizeof r->why, "face %" PRId64 " has %" PRId64 " vertices (at least "
                 "3 are needed)", cell + 1, nv);
        return SM_ERR_FORMAT;
    }
    sm_status st = check_nodes(r, d, nv, v, cell);
    for (int64_t k = 1; st == SM_OK && k + 1 < nv; k++)
        st = push(r, &d->triangles, (int64_t[3]){v[0], v[k], v[k + 1]}, cell);
    return st;
}

static const char *vtk_type_name(int type)
{
    static const struct {
        int type;
        const char *name;
    } names[] = {{11, "voxel"}, {12, "hexahedron"}, {13, "wedge"}, {14, "pyramid"},
                 {15, "pentagonal prism"}, {16, "hexagonal prism"}, {21, "quadratic edge"},
                 {22, "quadratic triangle"}, {23, "quadratic quad"}, {24, "quadratic tetra"},
                 {25, "quadratic hexahedron"}, {42, "polyhedron"}};
    for (size_t k = 0; k < sizeof names / sizeof names[0]; k++)
        if (names[k].type == type)
            return names[k].name;
    return "unknown";
}

/* The node count a fixed-size type needs (0: any). */
static int64_t vtk_type_nodes(int type)
{
    switch (type) {
    case SM_VTK_VERTEX: return 1;
    case SM_VTK_LINE: return 2;
    case SM_VTK_TRIANGLE: return 3;
    case SM_VTK_PIXEL:
    case SM_VTK_QUAD:
    case SM_VTK_TETRA: return 4;
    default: return 0;
    }
}

sm_status sm__cells_add_vtk(sm_reader *r, sm_msh_data *d, int type, int64_t nv,
                            const int64_t *v, int64_t cell)
{
    if (type < SM_VTK_VERTEX || type > SM_VTK_TETRA) {
        snprintf(r->why, sizeof r->why, "cell %" PRId64 ": VTK cell type %d (%s) is not "
                 "supported: shapematch reads lines, triangles, polygons, quads and "
                 "tetrahedra", cell + 1, type, vtk_type_name(type));
        return SM_ERR_FORMAT;
    }
    int64_t want = vtk_type_nodes(type);
    if ((want && nv != want) || nv < 1 || (type == SM_VTK_POLY_LINE && nv < 2) ||
        ((type == SM_VTK_TRIANGLE_STRIP || type == SM_VTK_POLYGON) && nv < 3)) {
        snprintf(r->why, sizeof r->why, "cell %" PRId64 " of type %d has %" PRId64
                 " points", cell + 1, type, nv);
        return SM_ERR_FORMAT;
    }
    sm_status st = check_nodes(r, d, nv, v, cell);
    if (st != SM_OK)
        return st;
    switch (type) {
    case SM_VTK_LINE:
    case SM_VTK_POLY_LINE:
        for (int64_t k = 0; st == SM_OK && k + 1 < nv; k++)
            st = push(r, &d->lines, v + k, cell);
        return st;
    case SM_VTK_TRIANGLE_STRIP:
        /* every other triangle is turned so that all face the same way */
        for (int64_t k = 0; st == SM_OK && k + 2 < nv; k++)
            st = push(r, &d->triangles, k % 2 ? (int64_t[3]){v[k + 1], v[k], v[k + 2]}
                                              : (int64_t[3]){v[k], v[k + 1], v[k + 2]},
                      cell);
        return st;
    case SM_VTK_PIXEL: /* corners in x-then-y order, not around */
        return sm__cells_add_polygon(r, d, 4, (int64_t[4]){v[0], v[1], v[3], v[2]}, cell);
    case SM_VTK_TRIANGLE:
    case SM_VTK_POLYGON:
    case SM_VTK_QUAD:
        return sm__cells_add_polygon(r, d, nv, v, cell);
    case SM_VTK_TETRA:
        return push(r, &d->tetrahedra, v, cell);
    default: /* vertices and poly-vertices carry no simplex we use */
        return SM_OK;
    }
}

void sm__cells_finish(sm_msh_data *d, const int32_t *refs, int64_t ncells)
{
    sm_msh_block *b[] = {&d->lines, &d->triangles, &d->tetrahedra};
    for (int k = 0; k < 3; k++)
        for (int64_t i = 0; i < b[k]->count; i++)
            b[k]->refs[i] = refs && b[k]->refs[i] < ncells ? refs[b[k]->refs[i]] : 0;
}

sm_status sm__reader_line(sm_reader *r, char *buf, size_t cap)
{
    size_t n = 0;
    for (;;) {
        const unsigned char *b;
        size_t avail;
        sm_status st = sm__reader_window(r, &b, &avail);
        if (st != SM_OK)
            return st;
        if (!avail)
            break;
        const unsigned char *nl = memchr(b, '\n', avail);
        size_t span = nl ? (size_t)(nl - b) : avail;
        size_t keep = span < cap - 1 - n ? span : cap - 1 - n;
        memcpy(buf + n, b, keep);
        n += keep;
        sm__reader_consume(r, span + (nl != NULL));
        if (nl) {
            r->line++;
            break;
        }
    }
    while (n > 0 && buf[n - 1] == '\r')
        n--;
    buf[n] = '\0';
    return SM_OK;
}

int sm__cells_ref_name(const char *name)
{
    static const char *const names[] = {"ref", "CellEntityIds", "gmsh:physical", "medit:ref"};
    for (size_t k = 0; k < sizeof names / sizeof names[0]; k++)
        if (strcmp(name, names[k]) == 0)
            return 1;
    return 0;
}
