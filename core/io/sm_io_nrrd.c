/* NRRD (teem's "nearly raw raster data"): "NRRD000N" then "field: value"
 * lines ('#' comments, "key:=value" pairs skipped) up to a blank line;
 * the data follows (.nrrd) or is in the file "data file" names (.nhdr).
 * Read: dimension 3, or 2 (a 2D image: one slice along a unit z axis;
 * its sizes, spacings and space directions have two entries, and its
 * vectors two components when `space dimension` is 2, as ITK writes
 * them), the scalar types, encodings raw and gzip (gz),
 * endian, byte skip (-1: data at the end), space, space directions,
 * space origin, spacings; other fields are ignored (they describe, not
 * place, the samples).  The world is the frame `space` names (LPS, RAS,
 * LAS in short or long form; scanner-xyz and 3D-right-handed are taken as
 * LPS, what ITK does); without `space directions` the axes are the
 * `spacings` (1 when absent) along x, y, z.  Samples are at the index
 * points (the origin is the first sample's centre). */
#include "io/sm_image_formats.h"

#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

int sm__nrrd_detect(sm_reader *r)
{
    char h[7];
    size_t got = 0;
    return sm__reader_peek(r, h, sizeof h, &got) == SM_OK && got == 7 &&
           memcmp(h, "NRRD000", 7) == 0;
}

typedef struct nrrd_hdr {
    int dimension;
    int sdim;         /* space dimension: 3, or 2 given (2D images) */
    int64_t sizes[3];
    sm_voxel_type type;
    int gzip, big, have_sizes, have_dirs, have_origin, have_spacings;
    double flip[3];
    double dirs[9], origin[3], spacings[3];
    int64_t byte_skip;
    char data_file[SM_IMAGE_LINE_LEN];
    long data_file_line;
} nrrd_hdr;

static const struct {
    const char *name;
    sm_voxel_type type;
} nrrd_types[] = {
    {"uchar", SM_VOXEL_U8},         {"unsigned char", SM_VOXEL_U8},   {"uint8", SM_VOXEL_U8},
    {"uint8_t", SM_VOXEL_U8},       {"signed char", SM_VOXEL_S8},     {"int8", SM_VOXEL_S8},
    {"int8_t", SM_VOXEL_S8},        {"short", SM_VOXEL_S16},          {"short int", SM_VOXEL_S16},
    {"signed short", SM_VOXEL_S16}, {"signed short int", SM_VOXEL_S16}, {"int16", SM_VOXEL_S16},
    {"int16_t", SM_VOXEL_S16},      {"ushort", SM_VOXEL_U16},         {"unsigned short", SM_VOXEL_U16},
    {"unsigned short int", SM_VOXEL_U16}, {"uint16", SM_VOXEL_U16},   {"uint16_t", SM_VOXEL_U16},
    {"int", SM_VOXEL_S32},          {"signed int", SM_VOXEL_S32},     {"int32", SM_VOXEL_S32},
    {"int32_t", SM_VOXEL_S32},      {"uint", SM_VOXEL_U32},           {"unsigned int", SM_VOXEL_U32},
    {"uint32", SM_VOXEL_U32},       {"uint32_t", SM_VOXEL_U32},       {"float", SM_VOXEL_F32},
    {"double", SM_VOXEL_F64},
};

static const struct {
    const char *name;
    double flip[3]; /* the frame's axes in LPS */
} nrrd_spaces[] = {
    {"left-posterior-superior", {1, 1, 1}}, {"LPS", {1, 1, 1}},
    {"right-anterior-superior", {-1, -1, 1}}, {"RAS", {-1, -1, 1}},
    {"left-anterior-superior", {1, -1, 1}}, {"LAS", {1, -1, 1}},
    {"scanner-xyz", {1, 1, 1}}, {"3D-right-handed", {1, 1, 1}},
};

static sm_status bad(sm_reader *r, const char *path, sm_error *err, const char *what,
                     const char *value)
{
    char q[96];
    sm__quote_token(value, q, sizeof q);
    return sm_error_set(err, SM_ERR_FORMAT, "%s:%ld: %s, found %s", path, r->token_line, what, q);
}

/* Space directions: naxes vectors "(x,y[,z])" of ncomp components into
 * the rows of dirs (3 per axis, missing components 0). */
static int parse_dirs(const char *v, double dirs[9], int naxes, int ncomp)
{
    for (int a = 0; a < naxes; a++) {
        while (*v == ' ' || *v == '\t')
            v++;
        if (*v != '(')
            return 0;
        const char *close = strchr(v, ')');
        if (!close)
            return 0;
        char vec[256];
        size_t len = (size_t)(close - v) + 1;
        if (len >= sizeof vec)
            return 0;
        memcpy(vec, v, len);
        vec[len] = '\0';
        int n;
        if (!sm__image_reals(vec, dirs + 3 * a, ncomp, &n) || n != ncomp)
            return 0;
        v = close + 1;
    }
    while (*v == ' ' || *v == '\t')
        v++;
    return *v == '\0';
}

/* The fields that place the samples in space. */
static sm_status space_field(sm_reader *r, const char *path, const char *key, const char *v,
                             nrrd_hdr *h, sm_error *err)
{
    int n;
    if (strcmp(key, "space") == 0) {
        size_t k, ns = sizeof nrrd_spaces / sizeof *nrrd_spaces;
        for (k = 0; k < ns && strcasecmp(v, nrrd_spaces[k].name) != 0; k++)
            ;
        if (k == ns)
            return bad(r, path, err, "space: a 3D frame (left-posterior-superior, "
                       "right-anterior-superior, left-anterior-superior, scanner-xyz) expected", v);
        memcpy(h->flip, nrrd_spaces[k].flip, sizeof h->flip);
    } else if (strcmp(key, "space dimension") == 0) {
        int64_t d;
        if (!sm__image_ints(v, 1, 16, &d, 1, &n) || n != 1 || (d != 3 && d != 2) ||
            (d == 2 && h->dimension == 3))
            return bad(r, path, err, "space dimension 3 (or 2 for a 2D image) is read", v);
        h->sdim = (int)d;
    } else if (strcmp(key, "space directions") == 0) {
        int sd = h->sdim ? h->sdim : 3;
        if (!parse_dirs(v, h->dirs, h->dimension, sd))
            return bad(r, path, err, h->dimension == 3 ? "space directions: three finite vectors "
                       "(x,y,z) expected" : sd == 3 ? "space directions: two finite vectors "
                       "(x,y,z) expected (dimension 2)" : "space directions: two finite vectors "
                       "(x,y) expected (dimension 2)", v);
        h->have_dirs = 1;
    } else if (strcmp(key, "space origin") == 0) {
        int sd = h->sdim ? h->sdim : 3;
        if (!sm__image_reals(v, h->origin, sd, &n) || n != sd || !strchr(v, '('))
            return bad(r, path, err, sd == 3 ? "space origin: a finite vector (x,y,z) expected"
                       : "space origin: a finite vector (x,y) expected (space dimension 2)", v);
        h->have_origin = 1;
    } else if (strcmp(key, "spacings") == 0) {
        if (!sm__image_reals(v, h->spacings, h->dimension, &n) || n != h->dimension)
            return bad(r, path, err, h->dimension == 3 ? "spacings: three finite numbers expected"
                       : "spacings: two finite numbers expected (dimension 2)", v);
        h->have_spacings = 1;
    }
    return SM_OK;
}

static sm_status field(sm_reader *r, const char *path, const char *key, const char *v, nrrd_hdr *h,
                       sm_error *err)
{
    int n;
    if (strcmp(key, "dimension") == 0) {
        int64_t d;
        if (!sm__image_ints(v, 1, 16, &d, 1, &n) || n != 1 || (d != 3 && d != 2))
            return bad(r, path, err, "dimension 2 or 3 is read", v);
        h->dimension = (int)d;
    } else if (strcmp(key, "type") == 0) {
        for (size_t k = 0; k < sizeof nrrd_types / sizeof *nrrd_types; k++)
            if (strcmp(v, nrrd_types[k].name) == 0)
                h->type = nrrd_types[k].type;
        if (!h->type)
            return bad(r, path, err, "unknown or unsupported type (8/16/32-bit integers, float, "
                       "double)", v);
    } else if (strcmp(key, "sizes") == 0) {
        if (!sm__image_ints(v, 1, SM_IMAGE_MAX_DIM, h->sizes, h->dimension, &n) ||
            n != h->dimension)
            return bad(r, path, err, h->dimension == 3 ? "sizes: three sizes in [1, 2^20] expected"
                       : "sizes: two sizes in [1, 2^20] expected (dimension 2)", v);
        h->have_sizes = 1;
    } else if (strcmp(key, "encoding") == 0) {
        if (strcmp(v, "raw") == 0)
            h->gzip = 0;
        else if (strcmp(v, "gzip") == 0 || strcmp(v, "gz") == 0)
            h->gzip = 1;
        else
            return bad(r, path, err, "encoding raw or gzip is read", v);
    } else if (strcmp(key, "endian") == 0) {
        if (strcmp(v, "little") != 0 && strcmp(v, "big") != 0)
            return bad(r, path, err, "endian little or big expected", v);
        h->big = strcmp(v, "big") == 0;
    } else if (strcmp(key, "byte skip") == 0) {
        if (!sm__image_ints(v, -1, INT64_MAX / 2, &h->byte_skip, 1, &n) || n != 1)
            return bad(r, path, err, "byte skip: an integer >= -1 expected", v);
    } else if (strcmp(key, "line skip") == 0) {
        int64_t s;
        if (!sm__image_ints(v, 0, 0, &s, 1, &n) || n != 1)
            return bad(r, path, err, "line skip other than 0 is not read", v);
    } else if (strcmp(key, "data file") == 0 || strcmp(key, "datafile") == 0) {
        if (strncmp(v, "LIST", 4) == 0 || strchr(v, '%'))
            return bad(r, path, err, "a single data file is read (not a list or pattern)", v);
        snprintf(h->data_file, sizeof h->data_file, "%s", v);
        h->data_file_line = r->token_line;
    } else {
        return space_field(r, path, key, v, h, err);
    }
    return SM_OK;
}

static int sized_by_dimension(const char *key)
{
    return strcmp(key, "sizes") == 0 || strcmp(key, "spacings") == 0 ||
           (strncmp(key, "space ", 6) == 0 && strcmp(key, "space dimension") != 0);
}

static sm_status parse_header(sm_reader *r, const char *path, nrrd_hdr *h, sm_error *err)
{
    char line[SM_IMAGE_LINE_LEN];
    int found;
    sm_status st = sm__image_line(r, path, line, &found, err);
    if (st != SM_OK)
        return st;
    if (strncmp(line, "NRRD000", 7) != 0 || line[7] < '1' || line[7] > '5' || line[8])
        return bad(r, path, err, "magic NRRD0001 to NRRD0005 expected", line);
    for (;;) {
        if ((st = sm__image_line(r, path, line, &found, err)) != SM_OK)
            return st;
        if (!found || line[0] == '\0')
            break;
        if (line[0] == '#' || strstr(line, ":="))
            continue;
        char *colon = strstr(line, ": ");
        if (!colon)
            return bad(r, path, err, "a 'field: value' line expected", line);
        *colon = '\0';
        const char *v = colon + 2;
        while (*v == ' ')
            v++;
        /* the fields sized by the dimension come after it, as the format
         * requires */
        if (!h->dimension && sized_by_dimension(line))
            return bad(r, path, err, "the 'dimension' field must come before the fields sized "
                       "by it", line);
        if ((st = field(r, path, line, v, h, err)) != SM_OK)
            return st;
    }
    const char *missing = !h->dimension ? "dimension" : !h->type ? "type" : !h->have_sizes ? "sizes" : NULL;
    if (missing)
        return sm_error_set(err, SM_ERR_FORMAT, "%s:%ld: the header has no '%s' field", path,
                            r->line, missing);
    return SM_OK;
}

static void geometry(const nrrd_hdr *h, sm_image *im)
{
    double *m = im->ijk_to_lps;
    for (int row = 0; row < 3; row++) {
        for (int col = 0; col < 3; col++) {
            double v = h->have_dirs ? h->dirs[3 * col + row]
                       : row == col ? (h->have_spacings && !isnan(h->spacings[col]) ? h->spacings[col] : 1)
                                    : 0;
            m[4 * row + col] = h->flip[row] * v;
        }
        m[4 * row + 3] = h->flip[row] * (h->have_origin ? h->origin[row] : 0);
    }
}

sm_status sm__nrrd_read(sm_reader *r, const sm_image_src *src, sm_image **out, sm_error *err)
{
    *out = NULL;
    nrrd_hdr *h = calloc(1, sizeof *h);
    if (!h)
        return sm_error_set(err, SM_ERR_NOMEM, "%s: out of memory", src->path);
    h->flip[0] = h->flip[1] = h->flip[2] = 1;
    sm_image *im = NULL;
    sm_status st = parse_header(r, src->path, h, err);
    if (st == SM_OK && h->dimension == 2) {
        /* a 2D image: one slice along the unit z axis */
        h->sizes[2] = 1;
        h->dirs[8] = 1;
        h->spacings[2] = 1;
    }
    if (st == SM_OK)
        st = sm__image_new(src, "sizes", h->sizes, h->type, &im, err);
    if (st == SM_OK) {
        im->format = "NRRD";
        geometry(h, im);
        int size = sm_voxel_size(h->type);
        sm_image_data d = {h->gzip, h->big && size > 1, h->byte_skip};
        if (h->data_file[0]) {
            st = sm__image_read_detached(src, h->data_file_line, h->data_file, d, im, err);
        } else {
            st = sm__image_read_voxels(r, src, &d, im, err);
        }
    }
    free(h);
    if (st != SM_OK) {
        sm_image_free(im);
        return st;
    }
    *out = im;
    return SM_OK;
}
