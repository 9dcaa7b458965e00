/* Every format read, by content: one table, one row per format in the
 * order of detection (curl's available_backends[]), the first row whose
 * detect says yes reads the file; the file name is never consulted.  A
 * row reads what its format holds: simplices (Gmsh, VTK legacy and XML:
 * made into a volume mesh or a surface), a volume mesh, a surface, or a
 * label-map image.  A file of one kind given as another is named for what
 * it is ("t.stl: a surface (STL), not a volume mesh: ...").  Fallbacks,
 * for what no row recognises: a mesh is read as Medit (whose reader says
 * what does not fit), a surface of binary content as a binary STL (the
 * same), anything else is an unknown format listing those read.
 * Solutions have a single format (sm_io_sol.c).  A new format is a row
 * here and a reader in its own file (declared in sm_io_formats.h or
 * sm_image_formats.h). */
#include "shapematch/sm_io.h"

#include <ctype.h>
#include <stdio.h>
#include <string.h>
#include <strings.h>

#include "io/sm_image_formats.h"
#include "io/sm_io_formats.h"
#include "io/sm_io_msh.h"
#include "io/sm_read_input.h"

typedef struct sm_format {
    const char *name;
    int (*detect)(sm_reader *r);
    /* simplices into an sm_msh_data, a mesh or a surface alike */
    sm_status (*read_cells)(sm_reader *r, sm_msh_data *d, sm_error *err);
    sm_status (*read_mesh)(sm_reader *r, sm_mesh **out, sm_error *err);
    sm_status (*read_surface)(sm_reader *r, sm_surface **out, sm_error *err);
    sm_status (*read_image)(sm_reader *r, const sm_image_src *src, sm_image **out,
                            sm_error *err);
} sm_format;

/* Medit: ASCII by its first keyword (after '#' comments), binary by the
 * code 1 in its first 4 bytes unless the file is an STL whose size fits
 * its count (an STL header may start with any bytes). */
static int medit_detect(sm_reader *r)
{
    char head[256];
    size_t got = 0;
    if (sm__reader_peek(r, head, sizeof head - 1, &got) != SM_OK)
        return 0;
    head[got] = '\0';
    uint32_t code = 0;
    if (got >= 4)
        memcpy(&code, head, 4);
    if (got >= 4 && (code == 1 || code == 0x01000000u))
        return !sm__stl_detect(r);
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

static int off_detect(sm_reader *r)
{
    int ply2;
    return sm__off_detect(r, &ply2);
}

static const sm_format formats[] = {
    /* magic at byte 0 (or a NIfTI header's size and magic) first */
    {"Gmsh", sm__msh_detect, sm__msh_parse, NULL, NULL, NULL},
    {"VTK", sm__vtk_detect, sm__vtk_parse, NULL, NULL, NULL},
    {"NIfTI", sm__nifti_detect, NULL, NULL, NULL, sm__nifti_read},
    {"NRRD", sm__nrrd_detect, NULL, NULL, NULL, sm__nrrd_read},
    {"MetaImage", sm__mha_detect, NULL, NULL, NULL, sm__mha_read},
    /* "<VTKFile" anywhere in the first 512 bytes */
    {"VTK XML", sm__vtkxml_detect, sm__vtkxml_parse, NULL, NULL, NULL},
    /* then the formats told apart by their first words */
    {"Medit", medit_detect, NULL, sm__medit_mesh_read, sm__medit_surface_read, NULL},
    {"PLY", sm__ply_detect, NULL, NULL, sm__ply_read, NULL},
    {"STL", sm__stl_detect, NULL, NULL, sm__stl_read, NULL},
    {"OBJ", sm__obj_detect, NULL, NULL, sm__obj_read, NULL},
    {"OFF", off_detect, NULL, NULL, sm__off_read, NULL},
};

static const sm_format *detect(sm_reader *r)
{
    for (size_t k = 0; k < sizeof formats / sizeof formats[0]; k++)
        if (formats[k].detect(r))
            return &formats[k];
    return NULL;
}

/* A file of another kind than asked for: what it is, and where it goes. */
static sm_status other_kind(const char *path, const sm_format *f, const char *wanted,
                            const char *read_as, sm_error *err)
{
    if (f->read_image)
        return sm_error_set(err, SM_ERR_FORMAT, "%s: an image (%s), not %s (%s): a label map "
                            "is a target image (--target-image, target_image)", path, f->name,
                            wanted, read_as);
    if (f->read_surface && !f->read_mesh && !f->read_cells)
        return sm_error_set(err, SM_ERR_FORMAT, "%s: a surface (%s), not %s (%s): a surface is "
                            "a target (--target-surface, target_surface)", path, f->name, wanted,
                            read_as);
    return sm_error_set(err, SM_ERR_FORMAT, "%s: a mesh (%s), not %s (%s)", path, f->name,
                        wanted, read_as);
}

/* The first bytes, peeked: an empty file or a read error is named. */
static sm_status peek_start(sm_reader *r, unsigned char *head, size_t cap, size_t *got,
                            sm_error *err)
{
    sm_status st = sm__reader_peek(r, head, cap, got);
    if (st != SM_OK)
        return sm__reader_fail_byte(r, err, st, 0, "%s", r->why);
    if (*got == 0)
        return sm_error_set(err, SM_ERR_FORMAT, "%s: empty file", r->path);
    return SM_OK;
}

/* ---- meshes and surfaces: one dispatcher ---- */

/* Text (a format we do not read) rather than binary data (perhaps a
 * binary STL whose size does not match its count). */
static int looks_text(const unsigned char *p, size_t n)
{
    for (size_t k = 0; k < n; k++)
        if (p[k] >= 127 || (p[k] < 32 && p[k] != '\n' && p[k] != '\r' && p[k] != '\t'))
            return 0;
    return 1;
}

/* Reads a volume mesh (mesh set, surface NULL) or a surface (the other
 * way round) from in: the row that detects the content reads it
 * (simplices made into what is asked, or the row's own reader); a row of
 * another kind is named; content no row recognises falls back to Medit
 * for a mesh, to a binary STL for binary content asked as a surface. */
static sm_status read_shape(const sm_reader_input *in, sm_read_limits *limits, sm_mesh **mesh,
                            sm_surface **surface, sm_error *err)
{
    const char *path = in->path;
    if (!path)
        return sm_error_set(err, SM_ERR_INVALID, "no %s file name", mesh ? "mesh" : "surface");
    sm_reader r;
    sm_status st = sm__reader_open_input(&r, in, err);
    if (st != SM_OK)
        return st;
    r.limits = limits;
    unsigned char head[512];
    size_t got = 0;
    if ((st = peek_start(&r, head, sizeof head, &got, err)) != SM_OK) {
        sm__reader_close(&r);
        return st;
    }
    const sm_format *f = detect(&r);
    if (f && f->read_cells) {
        sm_msh_data d;
        st = f->read_cells(&r, &d, err);
        if (st == SM_OK)
            st = mesh ? sm__msh_to_mesh(path, &d, mesh, err) : sm__msh_surface(path, &d, surface, err);
        sm__msh_data_free(&d);
    } else if (f && mesh && f->read_mesh) {
        st = f->read_mesh(&r, mesh, err);
    } else if (f && surface && f->read_surface) {
        st = f->read_surface(&r, surface, err);
    } else if (f) {
        st = mesh ? other_kind(path, f, "a volume mesh", "meshes are read as " SM_MESH_FORMATS, err)
                  : other_kind(path, f, "a surface", "surfaces are read as " SM_SURFACE_FORMATS,
                               err);
    } else if (mesh) {
        /* Medit's reader says precisely what does not fit */
        st = sm__medit_mesh_read(&r, mesh, err);
    } else if (got >= 84 && !looks_text(head, got)) {
        /* binary content of no other format is taken for a binary STL,
         * whose reader says precisely what does not fit */
        st = sm__stl_read(&r, surface, err);
    } else {
        st = sm_error_set(err, SM_ERR_FORMAT, "%s: unknown surface format; surfaces are read "
                          "as " SM_SURFACE_FORMATS, path);
    }
    sm__reader_close(&r);
    return st;
}

sm_status sm_mesh_read(const char *path, sm_mesh **out, sm_error *err)
{
    return sm_mesh_read_limited(path, NULL, out, err);
}

sm_status sm_mesh_read_limited(const char *path, sm_read_limits *limits, sm_mesh **out,
                               sm_error *err)
{
    *out = NULL;
    return read_shape(&(sm_reader_input){.path = path}, limits, out, NULL, err);
}

sm_status sm__mesh_read_input(const sm_reader_input *in, sm_read_limits *limits, sm_mesh **out,
                              sm_error *err)
{
    *out = NULL;
    return read_shape(in, limits, out, NULL, err);
}

sm_status sm_surface_read(const char *path, sm_surface **out, sm_error *err)
{
    return sm_surface_read_limited(path, NULL, out, err);
}

sm_status sm_surface_read_limited(const char *path, sm_read_limits *limits, sm_surface **out,
                                  sm_error *err)
{
    *out = NULL;
    return read_shape(&(sm_reader_input){.path = path}, limits, NULL, out, err);
}

sm_status sm__surface_read_input(const sm_reader_input *in, sm_read_limits *limits,
                                 sm_surface **out, sm_error *err)
{
    *out = NULL;
    return read_shape(in, limits, NULL, out, err);
}

/* ---- images ---- */

static sm_status image_read_input(const sm_reader_input *in, sm_image_limits *limits,
                                  sm_image **out, sm_error *err)
{
    *out = NULL;
    if (limits)
        limits->hit = 0;
    sm_reader r;
    sm_status st = sm__reader_open_input(&r, in, err);
    if (st != SM_OK)
        return st;
    sm_read_limits rl = {0};
    if (limits && limits->max_inflated) {
        /* the header and the voxels: the voxel bytes are checked on
         * their own before allocation (sm__image_new) */
        rl.max_inflated = limits->max_inflated + (1u << 20);
        r.limits = &rl;
    }
    sm_image_src src = {in->path, in->data != NULL, limits};
    const sm_format *f = detect(&r);
    if (f && f->read_image)
        st = f->read_image(&r, &src, out, err);
    else if (r.stream_status != SM_OK) /* a corrupt gzip file, a read error */
        st = sm__reader_fail_byte(&r, err, r.stream_status, sm__reader_offset(&r), "%s", r.why);
    else if (f)
        st = other_kind(in->path, f, "an image", SM_IMAGE_FORMATS, err);
    else
        st = sm_error_set(err, SM_ERR_FORMAT, "%s: not an image this reads (%s)", in->path,
                          SM_IMAGE_FORMATS);
    if (limits && rl.hit == SM_LIMIT_INFLATED)
        limits->hit = SM_IMAGE_LIMIT_INFLATED;
    sm__reader_close(&r);
    if (st == SM_OK)
        st = sm__image_check_geometry(&src, *out, err);
    if (st != SM_OK) {
        sm_image_free(*out);
        *out = NULL;
    }
    return st;
}

sm_status sm_image_read(const char *path, sm_image_limits *limits, sm_image **out, sm_error *err)
{
    *out = NULL;
    if (!path)
        return sm_error_set(err, SM_ERR_INVALID, "no image file name");
    return image_read_input(&(sm_reader_input){.path = path}, limits, out, err);
}

sm_status sm_image_read_memory(const char *name, const void *data, size_t size,
                               sm_image_limits *limits, sm_image **out, sm_error *err)
{
    *out = NULL;
    static const char empty[1] = "";
    return image_read_input(&(sm_reader_input){.path = name, .data = data ? data : empty,
                                               .size = size},
                            limits, out, err);
}
