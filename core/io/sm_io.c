/* Meshes read from a file: the dispatch by content.  A Gmsh .msh file
 * (sm_io_msh.c) is recognised by its first line, a VTK legacy or XML file
 * (sm_io_vtk.c, sm_io_vtkxml.c) by its first bytes, anything else is read as
 * Medit (sm_io_medit.c: ASCII or binary by the first bytes); the file name
 * is never consulted.  Surfaces have their own dispatcher
 * (sm_io_surface.c), solutions a single format (sm_io_sol.c). */
#include "shapematch/sm_io.h"

#include <string.h>

#include "io/sm_io_formats.h"
#include "io/sm_io_msh.h"
#include "io/sm_read_input.h"

sm_status sm_mesh_read(const char *path, sm_mesh **out, sm_error *err)
{
    return sm_mesh_read_limited(path, NULL, out, err);
}

sm_status sm_mesh_read_limited(const char *path, sm_read_limits *limits, sm_mesh **out,
                               sm_error *err)
{
    *out = NULL;
    if (!path)
        return sm_error_set(err, SM_ERR_INVALID, "no mesh file name");
    return sm__mesh_read_input(&(sm_reader_input){.path = path}, limits, out, err);
}

sm_status sm__mesh_read_input(const sm_reader_input *in, sm_read_limits *limits, sm_mesh **out,
                              sm_error *err)
{
    *out = NULL;
    sm_reader r;
    sm_status st = sm__reader_open_input(&r, in, err);
    if (st != SM_OK)
        return st;
    r.limits = limits;
    /* the formats read as simplices into an sm_msh_data */
    sm_status (*cells)(sm_reader *, sm_msh_data *, sm_error *) =
        sm__msh_detect(&r) ? sm__msh_parse : sm__vtk_detect(&r) ? sm__vtk_parse
                                           : sm__vtkxml_detect(&r) ? sm__vtkxml_parse : NULL;
    if (cells) {
        sm_msh_data d;
        st = cells(&r, &d, err);
        if (st == SM_OK)
            st = sm__msh_to_mesh(in->path, &d, out, err);
        sm__msh_data_free(&d);
    } else {
        st = sm__medit_mesh_read(&r, out, err);
    }
    sm__reader_close(&r);
    return st;
}
