/* MetaImage (ITK's MetaIO): "Key = Value" lines, ElementDataFile last;
 * its value LOCAL means the data follows in the same file (.mha), a name
 * a data file beside the header (.mhd + .raw/.zraw).  Read: NDims 3, or
 * 2 (a 2D image: one slice along a unit z axis; its DimSize,
 * ElementSpacing, Offset have two values, TransformMatrix four), DimSize, ElementType MET_(U)CHAR/(U)SHORT/(U)INT/(U)LONG (32-bit)/
 * FLOAT/DOUBLE, ElementNumberOfChannels 1, BinaryData True,
 * BinaryDataByteOrderMSB (ElementByteOrderMSB), CompressedData (zlib),
 * HeaderSize (-1: data at the end), ElementSpacing, Offset (Position,
 * Origin), TransformMatrix (Rotation, Orientation); other keys are
 * ignored.  Keys are matched without regard to case.
 *
 * The world is ITK's physical space, LPS.  TransformMatrix holds the
 * direction of image axis a in its values 3a..3a+2 (ITK's MetaImageIO
 * sets axis a's direction from row a), so a voxel (i, j, k) is at
 * Offset + sum_a idx_a * ElementSpacing_a * TM[3a..3a+2]. */
#include "io/sm_image_formats.h"

#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

static const char *const mha_first_keys[] = {"ObjectType", "NDims", "Comment", "ObjectSubType",
                                             "TransformType", "Name"};

int sm__mha_detect(sm_reader *r)
{
    char h[32];
    size_t got = 0;
    if (sm__reader_peek(r, h, sizeof h - 1, &got) != SM_OK)
        return 0;
    h[got] = '\0';
    for (size_t k = 0; k < sizeof mha_first_keys / sizeof *mha_first_keys; k++) {
        size_t n = strlen(mha_first_keys[k]);
        if (strncasecmp(h, mha_first_keys[k], n) == 0) {
            const char *p = h + n;
            while (*p == ' ' || *p == '\t')
                p++;
            if (*p == '=')
                return 1;
        }
    }
    return 0;
}

typedef struct mha_hdr {
    int64_t ndims, dims[3], header_size, channels;
    sm_voxel_type type;
    int compressed, msb, have_dims, binary;
    double spacing[3], offset[3], tm[9];
    char data_file[SM_IMAGE_LINE_LEN];
    long data_file_line;
} mha_hdr;

static const struct {
    const char *name;
    sm_voxel_type type;
} mha_types[] = {
    {"MET_UCHAR", SM_VOXEL_U8},  {"MET_CHAR", SM_VOXEL_S8},   {"MET_USHORT", SM_VOXEL_U16},
    {"MET_SHORT", SM_VOXEL_S16}, {"MET_UINT", SM_VOXEL_U32},  {"MET_INT", SM_VOXEL_S32},
    {"MET_ULONG", SM_VOXEL_U32}, {"MET_LONG", SM_VOXEL_S32},  {"MET_FLOAT", SM_VOXEL_F32},
    {"MET_DOUBLE", SM_VOXEL_F64},
};

static sm_status bad(sm_reader *r, const char *path, sm_error *err, const char *what,
                     const char *value)
{
    char q[96];
    sm__quote_token(value, q, sizeof q);
    return sm_error_set(err, SM_ERR_FORMAT, "%s:%ld: %s, found %s", path, r->token_line, what, q);
}

static int is_true(const char *v, int *out)
{
    if (strcasecmp(v, "True") == 0 || strcmp(v, "1") == 0)
        return *out = 1, 1;
    if (strcasecmp(v, "False") == 0 || strcmp(v, "0") == 0)
        return *out = 0, 1;
    return 0;
}

static int key_is(const char *key, const char *a, const char *b, const char *c)
{
    return strcasecmp(key, a) == 0 || (b && strcasecmp(key, b) == 0) || (c && strcasecmp(key, c) == 0);
}

static sm_status reals3(sm_reader *r, const char *path, const char *v, double *out, int count,
                        const char *what, sm_error *err)
{
    int n;
    if (!sm__image_reals(v, out, count, &n) || n != count)
        return bad(r, path, err, what, v);
    return SM_OK;
}

/* The keys whose counts NDims gives (2 or 3 values, 4 or 9 for the
 * matrix), after NDims (MetaIO writes it first).  *done 0: not one of
 * them. */
static sm_status sized_field(sm_reader *r, const char *path, const char *key, const char *v,
                             mha_hdr *h, int *done, sm_error *err)
{
    int n, nd = (int)h->ndims;
    *done = 1;
    if (key_is(key, "DimSize", NULL, NULL)) {
        if (nd && (!sm__image_ints(v, 1, SM_IMAGE_MAX_DIM, h->dims, nd, &n) || n != nd))
            return bad(r, path, err, nd == 3 ? "DimSize: three sizes in [1, 2^20] expected"
                                             : "DimSize: two sizes in [1, 2^20] expected (NDims 2)", v);
        h->have_dims = 1;
    } else if (key_is(key, "ElementSpacing", NULL, NULL)) {
        if (nd)
            return reals3(r, path, v, h->spacing, nd, nd == 3 ? "ElementSpacing: three finite "
                          "numbers expected" : "ElementSpacing: two finite numbers expected "
                          "(NDims 2)", err);
    } else if (key_is(key, "Offset", "Position", "Origin")) {
        if (nd)
            return reals3(r, path, v, h->offset, nd, nd == 3 ? "Offset: three finite numbers "
                          "expected" : "Offset: two finite numbers expected (NDims 2)", err);
    } else if (key_is(key, "TransformMatrix", "Rotation", "Orientation")) {
        if (nd == 3)
            return reals3(r, path, v, h->tm, 9, "TransformMatrix: nine finite numbers expected",
                          err);
        if (nd == 2) { /* the 2 x 2 matrix into the upper left of the 3 x 3 */
            double t[4];
            sm_status st = reals3(r, path, v, t, 4, "TransformMatrix: four finite numbers "
                                  "expected (NDims 2)", err);
            h->tm[0] = t[0], h->tm[1] = t[1], h->tm[3] = t[2], h->tm[4] = t[3];
            return st;
        }
    } else {
        *done = 0;
        return SM_OK;
    }
    if (!nd)
        return bad(r, path, err, "NDims must come before the keys sized by it (DimSize, "
                   "ElementSpacing, Offset, TransformMatrix)", key);
    return SM_OK;
}

static sm_status field(sm_reader *r, const char *path, const char *key, const char *v, mha_hdr *h,
                       sm_error *err)
{
    int n, b, done;
    sm_status st = sized_field(r, path, key, v, h, &done, err);
    if (done)
        return st;
    if (key_is(key, "NDims", NULL, NULL)) {
        if (!sm__image_ints(v, 1, 16, &h->ndims, 1, &n) || n != 1 ||
            (h->ndims != 2 && h->ndims != 3))
            return bad(r, path, err, "NDims 2 or 3 is read", v);
    } else if (key_is(key, "ElementType", NULL, NULL)) {
        for (size_t k = 0; k < sizeof mha_types / sizeof *mha_types; k++)
            if (strcmp(v, mha_types[k].name) == 0)
                h->type = mha_types[k].type;
        if (!h->type)
            return bad(r, path, err, "ElementType MET_(U)CHAR/(U)SHORT/(U)INT/FLOAT/DOUBLE "
                       "expected", v);
    } else if (key_is(key, "ElementNumberOfChannels", NULL, NULL)) {
        if (!sm__image_ints(v, 1, 1, &h->channels, 1, &n) || n != 1)
            return bad(r, path, err, "one channel (ElementNumberOfChannels = 1) is read", v);
    } else if (key_is(key, "BinaryData", NULL, NULL)) {
        if (!is_true(v, &h->binary) || !h->binary)
            return bad(r, path, err, "BinaryData True is read", v);
    } else if (key_is(key, "BinaryDataByteOrderMSB", "ElementByteOrderMSB", NULL)) {
        if (!is_true(v, &h->msb))
            return bad(r, path, err, "True or False expected", v);
    } else if (key_is(key, "CompressedData", NULL, NULL)) {
        if (!is_true(v, &b))
            return bad(r, path, err, "True or False expected", v);
        h->compressed = b;
    } else if (key_is(key, "HeaderSize", NULL, NULL)) {
        if (!sm__image_ints(v, -1, INT64_MAX / 2, &h->header_size, 1, &n) || n != 1)
            return bad(r, path, err, "HeaderSize: an integer >= -1 expected", v);
    } else if (key_is(key, "ObjectType", NULL, NULL)) {
        if (strcasecmp(v, "Image") != 0)
            return bad(r, path, err, "ObjectType Image expected", v);
    }
    return SM_OK;
}

static sm_status parse_header(sm_reader *r, const char *path, mha_hdr *h, sm_error *err)
{
    char line[SM_IMAGE_LINE_LEN];
    int found;
    for (;;) {
        sm_status st = sm__image_line(r, path, line, &found, err);
        if (st != SM_OK)
            return st;
        if (!found)
            return sm_error_set(err, SM_ERR_FORMAT, "%s:%ld: the header ends without "
                                "ElementDataFile", path, r->line);
        char *eq = strchr(line, '=');
        if (!eq) {
            if (strspn(line, " \t") == strlen(line))
                continue;
            return bad(r, path, err, "a 'Key = Value' line expected", line);
        }
        char *kend = eq;
        while (kend > line && (kend[-1] == ' ' || kend[-1] == '\t'))
            kend--;
        *kend = '\0';
        char *v = eq + 1;
        while (*v == ' ' || *v == '\t')
            v++;
        size_t vl = strlen(v);
        while (vl > 0 && (v[vl - 1] == ' ' || v[vl - 1] == '\t'))
            v[--vl] = '\0';
        const char *key = line + strspn(line, " \t");
        if (key_is(key, "ElementDataFile", NULL, NULL)) {
            if (strncmp(v, "LIST", 4) == 0 || strchr(v, '%') || vl == 0)
                return bad(r, path, err, "ElementDataFile: LOCAL or one file name expected", v);
            if (strcmp(v, "LOCAL") != 0)
                snprintf(h->data_file, sizeof h->data_file, "%s", v);
            h->data_file_line = r->token_line;
            break;
        }
        if ((st = field(r, path, key, v, h, err)) != SM_OK)
            return st;
    }
    const char *missing = !h->ndims ? "NDims" : !h->have_dims ? "DimSize" : !h->type ? "ElementType" : NULL;
    if (missing)
        return sm_error_set(err, SM_ERR_FORMAT, "%s:%ld: the header has no %s", path,
                            h->data_file_line, missing);
    return SM_OK;
}

sm_status sm__mha_read(sm_reader *r, const sm_image_src *src, sm_image **out, sm_error *err)
{
    *out = NULL;
    mha_hdr *h = calloc(1, sizeof *h);
    if (!h)
        return sm_error_set(err, SM_ERR_NOMEM, "%s: out of memory", src->path);
    h->binary = 1;
    for (int k = 0; k < 3; k++) {
        h->spacing[k] = 1;
        h->tm[4 * k] = 1;
    }
    sm_image *im = NULL;
    sm_status st = parse_header(r, src->path, h, err);
    if (st == SM_OK && h->ndims == 2)
        h->dims[2] = 1; /* a 2D image: one slice, its axis the unit z */
    if (st == SM_OK)
        st = sm__image_new(src, "DimSize", h->dims, h->type, &im, err);
    if (st == SM_OK) {
        im->format = "MetaImage";
        for (int row = 0; row < 3; row++) {
            for (int col = 0; col < 3; col++)
                im->ijk_to_lps[4 * row + col] = h->tm[3 * col + row] * h->spacing[col];
            im->ijk_to_lps[4 * row + 3] = h->offset[row];
        }
        sm_image_data d = {h->compressed, h->msb && sm_voxel_size(h->type) > 1,
                           h->header_size};
        if (h->data_file[0]) {
            st = sm__image_read_detached(src, h->data_file_line, h->data_file, d, im, err);
        } else {
            if (h->header_size != 0)
                st = sm_error_set(err, SM_ERR_FORMAT, "%s:%ld: HeaderSize with LOCAL data is "
                                  "not read", src->path, h->data_file_line);
            else
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
