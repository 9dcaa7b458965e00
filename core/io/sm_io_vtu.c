/* VTK XML UnstructuredGrid writer (.vtu), which ParaView and VTK read
 * directly: by default binary, compressed as VTK itself compresses
 * (compressor="vtkZLibDataCompressor": per array a header of UInt64
 * [blocks, block size, last block size, compressed sizes...], then the
 * zlib blocks), inline in base64 as VTK writes it (format="binary": the
 * header encoded, then the blocks encoded, each padded), so that the file
 * stays well-formed XML for any XML tool (appended raw bytes would not);
 * or inline ASCII (SM_VTU_ASCII).  Points are padded to 3D.  Cells: the elements
 * (VTK_TRIANGLE 5 in 2D, VTK_TETRA 10 in 3D), then the mesh's facets with
 * their references (VTK_LINE 3 in 2D, VTK_TRIANGLE in 3D), so boundary
 * parts can be coloured and selected by reference: cell field "ref"
 * (element or facet reference) and "cell_dim" (dim for elements, dim - 1
 * for facets; ParaView: Threshold on cell_dim, then on ref).  Both
 * encodings hold the same values (non-finite ones as 0, see below). */
#include "shapematch/sm_io.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

#include "io/sm_writer.h"

enum { VTK_LINE = 3, VTK_TRIANGLE = 5, VTK_TETRA = 10 };

/* VTK's ASCII parser does not read "nan"/"inf"; such values (a diverged
 * computation being inspected) are written as 0 so the file still opens. */
static double finite_or_zero(double x)
{
    return isfinite(x) ? x : 0.0;
}

/* The cell fields: ref and cell_dim of the elements, then of the facets. */
static void write_cell_data(sm_writer *w, const sm_mesh *m, int32_t nf)
{
    const int d = m->dim;
    sm__writer_printf(w, "      <CellData Scalars=\"ref\">\n"
                        "        <DataArray type=\"Int32\" Name=\"ref\" format=\"ascii\">\n");
    for (int32_t e = 0; e < m->nelems; e++)
        sm__writer_int(w, m->elem_refs[e], '\n');
    for (int32_t f = 0; f < nf; f++)
        sm__writer_int(w, m->facet_refs ? m->facet_refs[f] : 0, '\n');
    sm__writer_printf(w, "        </DataArray>\n"
                        "        <DataArray type=\"UInt8\" Name=\"cell_dim\" format=\"ascii\">\n");
    for (int32_t e = 0; e < m->nelems; e++)
        sm__writer_int(w, d, '\n');
    for (int32_t f = 0; f < nf; f++)
        sm__writer_int(w, d - 1, '\n');
    sm__writer_printf(w, "        </DataArray>\n      </CellData>\n");

}

/* One line of k indices. */
static void write_indices(sm_writer *w, const int32_t *v, int k)
{
    for (int j = 0; j < k; j++)
        sm__writer_int(w, v[j], j + 1 < k ? ' ' : '\n');
}

/* Connectivity, offsets and types of the elements, then of the facets. */
static void write_cells(sm_writer *w, const sm_mesh *m, int32_t nf)
{
    const int d = m->dim, k = m->dim + 1;
    sm__writer_printf(w, "      <Cells>\n        <DataArray type=\"Int32\" Name=\"connectivity\" "
                        "format=\"ascii\">\n");
    for (int32_t e = 0; e < m->nelems; e++)
        write_indices(w, m->elems + (size_t)e * (size_t)k, k);
    for (int32_t f = 0; f < nf; f++)
        write_indices(w, m->facets + (size_t)f * (size_t)d, d);
    /* Offsets are 64-bit: nelems * 4 can exceed the Int32 range. */
    sm__writer_printf(w, "        </DataArray>\n        <DataArray type=\"Int64\" "
                        "Name=\"offsets\" format=\"ascii\">\n");
    for (int32_t e = 0; e < m->nelems; e++)
        sm__writer_int(w, (int64_t)(e + 1) * k, '\n');
    for (int32_t f = 0; f < nf; f++)
        sm__writer_int(w, (int64_t)m->nelems * k + (int64_t)(f + 1) * d, '\n');
    sm__writer_printf(w, "        </DataArray>\n        <DataArray type=\"UInt8\" Name=\"types\" "
                        "format=\"ascii\">\n");
    int type = d == 2 ? VTK_TRIANGLE : VTK_TETRA;
    for (int32_t e = 0; e < m->nelems; e++)
        sm__writer_int(w, type, '\n');
    for (int32_t f = 0; f < nf; f++)
        sm__writer_int(w, d == 2 ? VTK_LINE : VTK_TRIANGLE, '\n');
}

/* One point's vector, padded to 3D, non-finite components as 0. */
static void write_vector(sm_writer *w, const double *x, int d)
{
    sm__writer_real(w, finite_or_zero(x[0]), ' ');
    sm__writer_real(w, finite_or_zero(x[1]), ' ');
    sm__writer_real(w, d == 3 ? finite_or_zero(x[2]) : 0.0, '\n');
}

static sm_status write_binary(sm_writer *w, const sm_mesh *m, const double *coords,
                              const sm_vtu_field *vec, int nvec, const double *distance,
                              int32_t nf, sm_error *err);

sm_status sm_vtu_write(const char *path, const sm_mesh *m, const double *coords,
                       const double *displacement, const double *distance, sm_error *err)
{
    return sm_vtu_write_as(path, m, coords, displacement, distance, SM_VTU_ZLIB, err);
}

/* The checks every writer makes before it opens the file; the number of
 * facets written (those of the file, when it lists them). */
static sm_status check_mesh(const char *path, const sm_mesh *m, int32_t *nf_out, sm_error *err)
{
    if (!path)
        return sm_error_set(err, SM_ERR_INVALID, "no .vtu file name");
    if (!m || (m->dim != 2 && m->dim != 3) || m->nverts < 0 || m->nelems < 0)
        return sm_error_set(err, SM_ERR_INVALID, "sm_vtu_write: invalid mesh");
    int d = m->dim, k = m->dim + 1;
    for (size_t i = 0; i < (size_t)m->nelems * (size_t)k; i++)
        if (m->elems[i] < 0 || m->elems[i] >= m->nverts)
            return sm_error_set(err, SM_ERR_INVALID,
                                "sm_vtu_write: element %zu has vertex index %ld out of range",
                                i / (size_t)k + 1, (long)m->elems[i]);
    const int32_t nf = m->facets && m->nfacets > 0 ? m->nfacets : 0;
    for (size_t i = 0; i < (size_t)nf * (size_t)d; i++)
        if (m->facets[i] < 0 || m->facets[i] >= m->nverts)
            return sm_error_set(err, SM_ERR_INVALID,
                                "sm_vtu_write: facet %zu has vertex index %ld out of range",
                                i / (size_t)d + 1, (long)m->facets[i]);
    *nf_out = nf;
    return SM_OK;
}

/* Opens, writes the binary file, closes (removing it on failure). */
static sm_status binary_file(const char *path, const sm_mesh *m, const double *coords,
                             const sm_vtu_field *vec, int nvec, const double *distance,
                             sm_error *err)
{
    int32_t nf;
    sm_status st = check_mesh(path, m, &nf, err);
    sm_writer *w;
    if (st == SM_OK)
        st = sm__writer_open(&w, path, err);
    if (st != SM_OK)
        return st;
    st = write_binary(w, m, coords ? coords : m->coords, vec, nvec, distance, nf, err);
    if (st != SM_OK) {
        sm_error e; /* the file is removed; the first error is kept */
        sm__writer_close(w, &e);
        return st;
    }
    return sm__writer_close(w, err);
}

sm_status sm_vtu_write_fields(const char *path, const sm_mesh *m, const double *coords,
                              const sm_vtu_field *fields, int nfields, sm_error *err)
{
    for (int i = 0; i < nfields; i++)
        if (!fields[i].name || !fields[i].values)
            return sm_error_set(err, SM_ERR_INVALID, "sm_vtu_write_fields: field %d unnamed or "
                                "empty", i + 1);
    return binary_file(path, m, coords, fields, nfields > 0 ? nfields : 0, NULL, err);
}

sm_status sm_vtu_write_as(const char *path, const sm_mesh *m, const double *coords,
                          const double *displacement, const double *distance,
                          sm_vtu_encoding encoding, sm_error *err)
{
    sm_vtu_field disp = {"displacement", displacement};
    if (encoding != SM_VTU_ASCII)
        return binary_file(path, m, coords, &disp, displacement ? 1 : 0, distance, err);
    int32_t nf;
    sm_status st = check_mesh(path, m, &nf, err);
    if (st != SM_OK)
        return st;
    if (!coords)
        coords = m->coords;
    const int d = m->dim;
    sm_writer *w;
    st = sm__writer_open(&w, path, err);
    if (st != SM_OK)
        return st;
    sm__writer_printf(w,
                     "<?xml version=\"1.0\"?>\n"
                     "<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" "
                     "byte_order=\"LittleEndian\">\n"
                     "  <UnstructuredGrid>\n"
                     "    <Piece NumberOfPoints=\"%ld\" NumberOfCells=\"%ld\">\n",
                     (long)m->nverts, (long)m->nelems + (long)nf);

    if (displacement || distance) {
        sm__writer_printf(w, "      <PointData%s%s>\n", distance ? " Scalars=\"distance\"" : "",
                         displacement ? " Vectors=\"displacement\"" : "");
        if (displacement) {
            sm__writer_printf(w, "        <DataArray type=\"Float64\" Name=\"displacement\" "
                                "NumberOfComponents=\"3\" format=\"ascii\">\n");
            for (int32_t i = 0; i < m->nverts; i++)
                write_vector(w, displacement + (size_t)i * (size_t)d, d);
            sm__writer_printf(w, "        </DataArray>\n");
        }
        if (distance) {
            sm__writer_printf(w, "        <DataArray type=\"Float64\" Name=\"distance\" "
                                "format=\"ascii\">\n");
            for (int32_t i = 0; i < m->nverts; i++)
                sm__writer_real(w, finite_or_zero(distance[i]), '\n');
            sm__writer_printf(w, "        </DataArray>\n");
        }
        sm__writer_printf(w, "      </PointData>\n");
    }

    write_cell_data(w, m, nf);

    sm__writer_printf(w, "      <Points>\n        <DataArray type=\"Float64\" "
                        "NumberOfComponents=\"3\" format=\"ascii\">\n");
    for (int32_t i = 0; i < m->nverts; i++)
        write_vector(w, coords + (size_t)i * (size_t)d, d);
    sm__writer_printf(w, "        </DataArray>\n      </Points>\n");

    write_cells(w, m, nf);
    sm__writer_printf(w, "        </DataArray>\n      </Cells>\n"
                        "    </Piece>\n  </UnstructuredGrid>\n</VTKFile>\n");
    return sm__writer_close(w, err);
}

/* ---- binary, zlib-compressed, appended ---- */

#define VTU_BLOCK 32768u /* VTK's own block size */

/* One array: its raw values, then (after compression) the bytes of the
 * appended section that hold it. */
typedef struct vtu_array {
    const char *type, *name; /* name NULL: no Name attribute */
    int ncomp;
    size_t size, n;          /* bytes per value, values */
    void *raw;
    unsigned char *z;        /* header + blocks */
    size_t zlen;
} vtu_array;

static void put_u64(unsigned char *p, uint64_t v)
{
    for (int k = 0; k < 8; k++)
        p[k] = (unsigned char)(v >> (8 * k)); /* byte_order="LittleEndian" */
}

static int compress_array(vtu_array *a)
{
    size_t bytes = a->n * a->size, nb = (bytes + VTU_BLOCK - 1) / VTU_BLOCK;
    size_t head = (3 + nb) * 8, cap = head;
    for (size_t b = 0; b < nb; b++)
        cap += compressBound(VTU_BLOCK);
    if (!(a->z = malloc(cap + 1)))
        return -1;
    put_u64(a->z, nb);
    put_u64(a->z + 8, VTU_BLOCK);
    put_u64(a->z + 16, bytes % VTU_BLOCK);
    size_t at = head;
    for (size_t b = 0; b < nb; b++) {
        size_t len = b + 1 < nb || bytes % VTU_BLOCK == 0 ? VTU_BLOCK : bytes % VTU_BLOCK;
        uLongf out = (uLongf)(cap - at);
        /* level 1: several times faster than the default, a few per cent larger */
        if (compress2(a->z + at, &out, (const Bytef *)a->raw + b * VTU_BLOCK, (uLong)len, 1) !=
            Z_OK)
            return -1;
        put_u64(a->z + (3 + b) * 8, out);
        at += out;
    }
    a->zlen = at;
    return 0;
}

static void *alloc_values(vtu_array *a, const char *type, const char *name, int ncomp,
                          size_t size, size_t n)
{
    *a = (vtu_array){type, name, ncomp, size, n, malloc(n * size + 1), NULL, 0};
    return a->raw;
}

/* The vector fields, then the points (no name), then distance. */
static void point_arrays(vtu_array *a, int *na, const sm_mesh *m, const double *coords,
                         const sm_vtu_field *vec, int nvec, const double *distance, int *ok)
{
    const int d = m->dim;
    for (int k = 0; k <= nvec; k++) {
        const double *v = k < nvec ? vec[k].values : coords;
        double *x = alloc_values(&a[(*na)++], "Float64", k < nvec ? vec[k].name : NULL, 3, 8,
                                 (size_t)m->nverts * 3);
        if (!(*ok = *ok && x))
            return;
        for (int32_t i = 0; i < m->nverts; i++)
            for (int j = 0; j < 3; j++)
                x[3 * i + j] = j < d ? finite_or_zero(v[(size_t)i * d + j]) : 0.0;
    }
    if (distance) {
        double *x = alloc_values(&a[(*na)++], "Float64", "distance", 1, 8, (size_t)m->nverts);
        if (!(*ok = *ok && x))
            return;
        for (int32_t i = 0; i < m->nverts; i++)
            x[i] = finite_or_zero(distance[i]);
    }
}

/* ref, cell_dim; connectivity, offsets, types (elements, then facets). */
static void cell_arrays(vtu_array *a, int *na, const sm_mesh *m, int32_t nf, int *ok)
{
    const int d = m->dim, k = d + 1;
    size_t nc = (size_t)m->nelems + (size_t)nf;
    size_t nconn = (size_t)m->nelems * (size_t)k + (size_t)nf * (size_t)d;
    vtu_array *ref = &a[(*na)++], *dim = &a[(*na)++], *conn = &a[(*na)++];
    vtu_array *off = &a[(*na)++], *type = &a[(*na)++];
    int32_t *r = alloc_values(ref, "Int32", "ref", 1, 4, nc);
    uint8_t *cd = alloc_values(dim, "UInt8", "cell_dim", 1, 1, nc);
    int32_t *c = alloc_values(conn, "Int32", "connectivity", 1, 4, nconn);
    int64_t *o = alloc_values(off, "Int64", "offsets", 1, 8, nc);
    uint8_t *t = alloc_values(type, "UInt8", "types", 1, 1, nc);
    if (!(*ok = *ok && r && cd && c && o && t))
        return;
    for (int32_t e = 0; e < m->nelems; e++) {
        r[e] = m->elem_refs[e];
        cd[e] = (uint8_t)d;
        o[e] = (int64_t)(e + 1) * k;
        t[e] = d == 2 ? VTK_TRIANGLE : VTK_TETRA;
    }
    memcpy(c, m->elems, (size_t)m->nelems * (size_t)k * sizeof *c);
    for (int32_t f = 0; f < nf; f++) {
        size_t i = (size_t)m->nelems + (size_t)f;
        r[i] = m->facet_refs ? m->facet_refs[f] : 0;
        cd[i] = (uint8_t)(d - 1);
        o[i] = (int64_t)m->nelems * k + (int64_t)(f + 1) * d;
        t[i] = d == 2 ? VTK_LINE : VTK_TRIANGLE;
    }
    memcpy(c + (size_t)m->nelems * (size_t)k, m->facets, (size_t)nf * (size_t)d * sizeof *c);
}

/* base64 of n bytes, padded. */
static void write_base64(sm_writer *w, const unsigned char *p, size_t n)
{
    static const char digits[] =
        "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    char out[4096];
    size_t k = 0;
    for (size_t i = 0; i < n; i += 3) {
        uint32_t v = (uint32_t)p[i] << 16 | (i + 1 < n ? (uint32_t)p[i + 1] << 8 : 0) |
                     (i + 2 < n ? p[i + 2] : 0);
        out[k++] = digits[v >> 18 & 63];
        out[k++] = digits[v >> 12 & 63];
        out[k++] = i + 1 < n ? digits[v >> 6 & 63] : '=';
        out[k++] = i + 2 < n ? digits[v & 63] : '=';
        if (k == sizeof out) {
            sm__writer_bytes(w, out, k);
            k = 0;
        }
    }
    sm__writer_bytes(w, out, k);
}

/* One DataArray: the header's base64, then the blocks' base64. */
static void array_inline(sm_writer *w, const vtu_array *a)
{
    sm__writer_printf(w, "        <DataArray type=\"%s\"", a->type);
    if (a->name)
        sm__writer_printf(w, " Name=\"%s\"", a->name);
    if (a->ncomp > 1)
        sm__writer_printf(w, " NumberOfComponents=\"%d\"", a->ncomp);
    sm__writer_printf(w, " format=\"binary\">\n          ");
    size_t head = (3 + (size_t)((a->n * a->size + VTU_BLOCK - 1) / VTU_BLOCK)) * 8;
    write_base64(w, a->z, head);
    write_base64(w, a->z + head, a->zlen - head);
    sm__writer_printf(w, "\n        </DataArray>\n");
}

static sm_status write_binary(sm_writer *w, const sm_mesh *m, const double *coords,
                              const sm_vtu_field *vec, int nvec, const double *distance,
                              int32_t nf, sm_error *err)
{
    vtu_array *a = calloc((size_t)nvec + 7, sizeof *a);
    int na = 0, ok = a != NULL, npoint;
    if (ok)
        point_arrays(a, &na, m, coords, vec, nvec, distance, &ok);
    npoint = na; /* the fields, points, distance? */
    if (ok)
        cell_arrays(a, &na, m, nf, &ok);
    for (int i = 0; ok && i < na; i++) {
        ok = compress_array(&a[i]) == 0;
        free(a[i].raw);
        a[i].raw = NULL;
    }
    if (ok) {
        sm__writer_printf(w, "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" "
                             "version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\" "
                             "compressor=\"vtkZLibDataCompressor\">\n  <UnstructuredGrid>\n"
                             "    <Piece NumberOfPoints=\"%ld\" NumberOfCells=\"%ld\">\n",
                          (long)m->nverts, (long)m->nelems + (long)nf);
        if (nvec > 0 || distance) {
            sm__writer_printf(w, "      <PointData%s", distance ? " Scalars=\"distance\"" : "");
            if (nvec > 0)
                sm__writer_printf(w, " Vectors=\"%s\"", vec[0].name);
            sm__writer_printf(w, ">\n");
            for (int i = 0; i < npoint; i++)
                if (a[i].name)
                    array_inline(w, &a[i]);
            sm__writer_printf(w, "      </PointData>\n");
        }
    sm__writer_printf(w, "      <CellData Scalars=\"ref\">\n");
        array_inline(w, &a[npoint]);
        array_inline(w, &a[npoint + 1]);
        sm__writer_printf(w, "      </CellData>\n      <Points>\n");
        for (int i = 0; i < npoint; i++)
            if (!a[i].name)
                array_inline(w, &a[i]);
        sm__writer_printf(w, "      </Points>\n      <Cells>\n");
        for (int i = npoint + 2; i < na; i++)
            array_inline(w, &a[i]);
        sm__writer_printf(w, "      </Cells>\n    </Piece>\n  </UnstructuredGrid>\n"
                             "</VTKFile>\n");
    }
    for (int i = 0; a && i < na; i++) {
        free(a[i].raw);
        free(a[i].z);
    }
    free(a);
    return ok ? SM_OK : sm_error_set(err, SM_ERR_NOMEM, "out of memory writing a .vtu");
}
