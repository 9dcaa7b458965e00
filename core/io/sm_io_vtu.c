/* VTK XML UnstructuredGrid writer (.vtu) with inline ASCII data, which
 * ParaView and VTK read directly.  Points are padded to 3D.  Cells: the
 * elements (VTK_TRIANGLE 5 in 2D, VTK_TETRA 10 in 3D), then the mesh's
 * facets with their references (VTK_LINE 3 in 2D, VTK_TRIANGLE in 3D),
 * so boundary parts can be coloured and selected by reference: cell field
 * "ref" (element or facet reference) and "cell_dim" (dim for elements,
 * dim - 1 for facets; ParaView: Threshold on cell_dim, then on ref). */
#include "shapematch/sm_io.h"

#include <math.h>

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

sm_status sm_vtu_write(const char *path, const sm_mesh *m, const double *coords,
                       const double *displacement, const double *distance, sm_error *err)
{
    if (!path)
        return sm_error_set(err, SM_ERR_INVALID, "no .vtu file name");
    if (!m || (m->dim != 2 && m->dim != 3) || m->nverts < 0 || m->nelems < 0)
        return sm_error_set(err, SM_ERR_INVALID, "sm_vtu_write: invalid mesh");
    if (!coords)
        coords = m->coords;
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
    sm_writer *w;
    sm_status st = sm__writer_open(&w, path, err);
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
