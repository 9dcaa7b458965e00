/* Medit meshes, writing: .mesh (ASCII) or .meshb (libMeshb binary,
 * version 2 or 3 as the offsets need), plain or gzip, chosen by the file
 * name (sm_io_medit.c has the reader). */
#include "shapematch/sm_io.h"

#include <math.h>
#include <string.h>
#include <strings.h>

#include "io/sm_medit_common.h"
#include "io/sm_stream.h"
#include "io/sm_writer.h"

/* Decides ASCII/binary from the name, ignoring a trailing ".gz". */
static int is_binary_name(const char *path, const char *ascii_ext, const char *binary_ext,
                          int *binary)
{
    size_t n = strlen(path);
    if (sm__path_has_suffix(path, ".gz"))
        n -= 3;
    size_t kb = strlen(binary_ext), ka = strlen(ascii_ext);
    if (n >= kb && strncasecmp(path + n - kb, binary_ext, kb) == 0) {
        *binary = 1;
        return 1;
    }
    if (n >= ka && strncasecmp(path + n - ka, ascii_ext, ka) == 0) {
        *binary = 0;
        return 1;
    }
    return 0;
}

static sm_status check_mesh(const sm_mesh *m, const double *coords, sm_error *err)
{
    if (!m || (m->dim != 2 && m->dim != 3) || m->nverts < 0 || m->nelems < 0 ||
        m->nfacets < 0 || (m->nverts > 0 && !coords))
        return sm_error_set(err, SM_ERR_INVALID, "sm_mesh_write: invalid mesh");
    size_t nc = (size_t)m->nverts * (size_t)m->dim;
    for (size_t i = 0; i < nc; i++)
        if (!isfinite(coords[i]))
            return sm_error_set(err, SM_ERR_INVALID,
                                "sm_mesh_write: vertex %zu has a non-finite coordinate",
                                i / (size_t)m->dim + 1);
    const struct { int32_t n; int k; const int32_t *idx; } blocks[2] = {
        {m->nelems, m->dim + 1, m->elems}, {m->nfacets, m->dim, m->facets}};
    for (int b = 0; b < 2; b++)
        for (size_t i = 0; i < (size_t)blocks[b].n * (size_t)blocks[b].k; i++)
            if (blocks[b].idx[i] < 0 || blocks[b].idx[i] >= m->nverts)
                return sm_error_set(err, SM_ERR_INVALID,
                                    "sm_mesh_write: %s %zu has vertex index %ld out of range",
                                    b == 0 ? "element" : "facet", i / (size_t)blocks[b].k + 1,
                                    (long)blocks[b].idx[i]);
    return SM_OK;
}

static void write_ascii_block(sm_writer *w, const char *name, int32_t n, int k,
                              const int32_t *idx, const int32_t *refs)
{
    if (n == 0)
        return;
    sm__writer_printf(w, "\n%s\n%ld\n", name, (long)n);
    for (int32_t i = 0; i < n; i++) {
        const int32_t *v = idx + (size_t)i * (size_t)k;
        for (int j = 0; j < k; j++)
            sm__writer_int(w, (int64_t)v[j] + 1, ' ');
        sm__writer_int(w, refs[i], '\n');
    }
}

static void write_ascii(sm_writer *w, const sm_mesh *m, const double *coords)
{
    int d = m->dim;
    sm__writer_printf(w, "MeshVersionFormatted 2\n\nDimension %d\n\nVertices\n%ld\n", d,
                     (long)m->nverts);
    for (int32_t i = 0; i < m->nverts; i++) {
        const double *x = coords + (size_t)i * (size_t)d;
        for (int c = 0; c < d; c++)
            sm__writer_real(w, x[c], ' ');
        sm__writer_int(w, m->vert_refs[i], '\n');
    }
    if (d == 2) {
        write_ascii_block(w, "Edges", m->nfacets, 2, m->facets, m->facet_refs);
        write_ascii_block(w, "Triangles", m->nelems, 3, m->elems, m->elem_refs);
    } else {
        write_ascii_block(w, "Triangles", m->nfacets, 3, m->facets, m->facet_refs);
        write_ascii_block(w, "Tetrahedra", m->nelems, 4, m->elems, m->elem_refs);
    }
    sm__writer_printf(w, "\nEnd\n");
}

static void write_pos(sm_writer *w, int pos_size, uint64_t pos)
{
    if (pos_size == 8)
        sm__writer_i64(w, (int64_t)pos);
    else
        sm__writer_i32(w, (int32_t)pos);
}

/* Keyword code and the position right after its block. */
static void write_kw(sm_writer *w, int pos_size, int32_t code, uint64_t block_bytes)
{
    uint64_t next = sm__writer_offset(w) + 4 + (uint64_t)pos_size + block_bytes;
    sm__writer_i32(w, code);
    write_pos(w, pos_size, next);
}

static void write_binary_block(sm_writer *w, int pos_size, int32_t code, int32_t n, int k,
                               const int32_t *idx, const int32_t *refs)
{
    if (n == 0)
        return;
    write_kw(w, pos_size, code, 4 + (uint64_t)n * (uint64_t)(k + 1) * 4);
    sm__writer_i32(w, n);
    int32_t rec[5];
    for (int32_t i = 0; i < n; i++) {
        for (int j = 0; j < k; j++)
            rec[j] = idx[(size_t)i * (size_t)k + (size_t)j] + 1;
        rec[k] = refs[i];
        sm__writer_bytes(w, rec, (size_t)(k + 1) * 4);
    }
}

static void write_binary(sm_writer *w, const sm_mesh *m, const double *coords)
{
    int d = m->dim;
    uint64_t vrec = (uint64_t)d * 8 + 4;
    uint64_t total = 64 + (uint64_t)m->nverts * vrec +
                     (uint64_t)m->nelems * (uint64_t)(d + 2) * 4 +
                     (uint64_t)m->nfacets * (uint64_t)(d + 1) * 4;
    /* Version 2 has 32-bit positions; larger files need version 3. */
    int version = total < INT32_MAX ? 2 : 3;
    int pos_size = version >= 3 ? 8 : 4;
    sm__writer_i32(w, 1);
    sm__writer_i32(w, version);
    write_kw(w, pos_size, SM_KW_DIMENSION, 4);
    sm__writer_i32(w, d);
    write_kw(w, pos_size, SM_KW_VERTICES, 4 + (uint64_t)m->nverts * vrec);
    sm__writer_i32(w, m->nverts);
    unsigned char rec[3 * 8 + 4];
    for (int32_t i = 0; i < m->nverts; i++) {
        memcpy(rec, coords + (size_t)i * (size_t)d, (size_t)d * 8);
        memcpy(rec + (size_t)d * 8, &m->vert_refs[i], 4);
        sm__writer_bytes(w, rec, (size_t)vrec);
    }
    if (d == 2) {
        write_binary_block(w, pos_size, SM_KW_EDGES, m->nfacets, 2, m->facets, m->facet_refs);
        write_binary_block(w, pos_size, SM_KW_TRIANGLES, m->nelems, 3, m->elems, m->elem_refs);
    } else {
        write_binary_block(w, pos_size, SM_KW_TRIANGLES, m->nfacets, 3, m->facets,
                           m->facet_refs);
        write_binary_block(w, pos_size, SM_KW_TETRAHEDRA, m->nelems, 4, m->elems, m->elem_refs);
    }
    sm__writer_i32(w, SM_KW_END);
    write_pos(w, pos_size, 0);
}

sm_status sm_mesh_write_coords(const char *path, const sm_mesh *m, const double *coords,
                               sm_error *err)
{
    if (!path)
        return sm_error_set(err, SM_ERR_INVALID, "no mesh file name");
    if (!coords && m)
        coords = m->coords;
    int binary;
    if (!is_binary_name(path, ".mesh", ".meshb", &binary))
        return sm_error_set(err, SM_ERR_INVALID,
                            "%s: cannot tell the mesh format from the name (expected .mesh or "
                            ".meshb, optionally followed by .gz)",
                            path);
    sm_status st = check_mesh(m, coords, err);
    if (st != SM_OK)
        return st;
    sm_writer *w;
    if ((st = sm__writer_open(&w, path, err)) != SM_OK)
        return st;
    if (binary)
        write_binary(w, m, coords);
    else
        write_ascii(w, m, coords);
    return sm__writer_close(w, err);
}

sm_status sm_mesh_write(const char *path, const sm_mesh *m, sm_error *err)
{
    return sm_mesh_write_coords(path, m, m ? m->coords : NULL, err);
}
