/* Label-map images out (sm_image.h: sm_image_write): float32 voxels on the
 * image's own grid, with its geometry, in the three formats the readers
 * take.  Each file carries its frame the way its format defines it:
 * NIfTI's world is RAS (x and y of the LPS map negated), NRRD names
 * its `space`, MetaImage's world is ITK's, LPS.  The sm_writer under
 * them writes to a temporary name and renames, and gzips a ".gz" name. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "shapematch/sm_image.h"
#include "io/sm_writer.h"

static int ends_with(const char *s, const char *tail)
{
    size_t n = strlen(s), m = strlen(tail);
    return n >= m && strcmp(s + n - m, tail) == 0;
}

static double column_length(const double *m, int col)
{
    return sqrt(m[col] * m[col] + m[4 + col] * m[4 + col] + m[8 + col] * m[8 + col]);
}

static void put16(uint8_t *h, int at, int16_t v) { memcpy(h + at, &v, 2); }
static void put32(uint8_t *h, int at, int32_t v) { memcpy(h + at, &v, 4); }
static void putf(uint8_t *h, int at, double v)
{
    float f = (float)v;
    memcpy(h + at, &f, 4);
}

/* The qform quaternion of the RAS map r (3x4) when its axes are
 * orthogonal (a rotation, maybe with a flip: qfac -1); 0 when they are
 * not, and the file then holds the sform alone. */
static int qform_of(const double *r, const double h[3], double q[3], double *qfac)
{
    double a[3][3];
    for (int row = 0; row < 3; row++)
        for (int col = 0; col < 3; col++)
            a[row][col] = r[4 * row + col] / h[col];
    for (int i = 0; i < 3; i++)
        for (int j = i + 1; j < 3; j++) {
            double dot = a[0][i] * a[0][j] + a[1][i] * a[1][j] + a[2][i] * a[2][j];
            if (fabs(dot) > 1e-6)
                return 0;
        }
    double det = a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) -
                 a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0]) +
                 a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
    *qfac = det < 0 ? -1.0 : 1.0;
    if (det < 0) /* NIfTI flips the third axis with qfac */
        for (int row = 0; row < 3; row++)
            a[row][2] = -a[row][2];
    /* the rotation's quaternion (a, b, c, d), a >= 0 as NIfTI stores it */
    double tr = a[0][0] + a[1][1] + a[2][2], qa, qb, qc, qd;
    if (tr > 0) {
        double s = 2 * sqrt(1 + tr);
        qa = s / 4;
        qb = (a[2][1] - a[1][2]) / s;
        qc = (a[0][2] - a[2][0]) / s;
        qd = (a[1][0] - a[0][1]) / s;
    } else if (a[0][0] > a[1][1] && a[0][0] > a[2][2]) {
        double s = 2 * sqrt(1 + a[0][0] - a[1][1] - a[2][2]);
        qa = (a[2][1] - a[1][2]) / s;
        qb = s / 4;
        qc = (a[0][1] + a[1][0]) / s;
        qd = (a[0][2] + a[2][0]) / s;
    } else if (a[1][1] > a[2][2]) {
        double s = 2 * sqrt(1 + a[1][1] - a[0][0] - a[2][2]);
        qa = (a[0][2] - a[2][0]) / s;
        qb = (a[0][1] + a[1][0]) / s;
        qc = s / 4;
        qd = (a[1][2] + a[2][1]) / s;
    } else {
        double s = 2 * sqrt(1 + a[2][2] - a[0][0] - a[1][1]);
        qa = (a[1][0] - a[0][1]) / s;
        qb = (a[0][2] + a[2][0]) / s;
        qc = (a[1][2] + a[2][1]) / s;
        qd = s / 4;
    }
    if (qa < 0) {
        qb = -qb;
        qc = -qc;
        qd = -qd;
    }
    q[0] = qb;
    q[1] = qc;
    q[2] = qd;
    return 1;
}

/* NIfTI-1, single file: a 348-byte header, 4 bytes of no extension, the
 * voxels at offset 352.  sform (code 2, "aligned") holds the map; the
 * qform (code 2) too where the axes are orthogonal. */
static void write_nifti(sm_writer *w, const sm_image *im, const float *v)
{
    uint8_t h[352];
    memset(h, 0, sizeof h);
    double r[12], sp[3];
    memcpy(r, im->ijk_to_lps, sizeof r);
    for (int col = 0; col < 4; col++) { /* LPS -> RAS */
        r[col] = -r[col];
        r[4 + col] = -r[4 + col];
    }
    for (int c = 0; c < 3; c++)
        sp[c] = column_length(r, c);
    put32(h, 0, 348);
    put16(h, 40, 3);
    for (int c = 0; c < 3; c++)
        put16(h, 42 + 2 * c, (int16_t)im->dims[c]);
    put16(h, 48, 1);
    put16(h, 70, 16); /* DT_FLOAT32 */
    put16(h, 72, 32);
    double q[3] = {0, 0, 0}, qfac = 1;
    int has_q = qform_of(r, sp, q, &qfac);
    putf(h, 76, qfac);
    for (int c = 0; c < 3; c++)
        putf(h, 80 + 4 * c, sp[c]);
    putf(h, 108, 352);
    putf(h, 112, 1); /* scl_slope: the values as stored */
    h[123] = 2;      /* NIFTI_UNITS_MM */
    put16(h, 252, has_q ? 2 : 0);
    put16(h, 254, 2);
    for (int k = 0; k < 3; k++) {
        putf(h, 256 + 4 * k, q[k]);
        putf(h, 268 + 4 * k, r[4 * k + 3]);
    }
    for (int k = 0; k < 12; k++)
        putf(h, 280 + 4 * k, r[k]);
    memcpy(h + 344, "n+1", 4);
    sm__writer_bytes(w, h, sizeof h);
    sm__writer_bytes(w, v, (size_t)(im->dims[0] * im->dims[1] * im->dims[2]) * sizeof *v);
}

/* NRRD, attached, raw. */
static void write_nrrd(sm_writer *w, const sm_image *im, const float *v)
{
    const double *m = im->ijk_to_lps;
    sm__writer_printf(w, "NRRD0004\n# the signed distance (negative inside), written by "
                         "shapematch\ntype: float\ndimension: 3\n"
                         "space: left-posterior-superior\nsizes: %lld %lld %lld\n"
                         "space directions:",
                      (long long)im->dims[0], (long long)im->dims[1], (long long)im->dims[2]);
    for (int col = 0; col < 3; col++)
        sm__writer_printf(w, " (%.17g,%.17g,%.17g)", m[col], m[4 + col], m[8 + col]);
    sm__writer_printf(w, "\nspace origin: (%.17g,%.17g,%.17g)\nendian: little\nencoding: raw\n\n",
                      m[3], m[7], m[11]);
    sm__writer_bytes(w, v, (size_t)(im->dims[0] * im->dims[1] * im->dims[2]) * sizeof *v);
}

/* MetaImage, one file (ElementDataFile = LOCAL): TransformMatrix holds
 * axis a's direction at [3a..3a+2], as ITK writes it. */
static void write_mha(sm_writer *w, const sm_image *im, const float *v)
{
    const double *m = im->ijk_to_lps;
    double sp[3];
    for (int c = 0; c < 3; c++)
        sp[c] = column_length(m, c);
    sm__writer_printf(w, "ObjectType = Image\nNDims = 3\nBinaryData = True\n"
                         "BinaryDataByteOrderMSB = False\nCompressedData = False\n"
                         "TransformMatrix =");
    for (int col = 0; col < 3; col++)
        for (int row = 0; row < 3; row++)
            sm__writer_printf(w, " %.17g", m[4 * row + col] / sp[col]);
    sm__writer_printf(w, "\nOffset = %.17g %.17g %.17g\nAnatomicalOrientation = RAI\n"
                         "ElementSpacing = %.17g %.17g %.17g\nDimSize = %lld %lld %lld\n"
                         "ElementType = MET_FLOAT\nElementDataFile = LOCAL\n",
                      m[3], m[7], m[11], sp[0], sp[1], sp[2], (long long)im->dims[0],
                      (long long)im->dims[1], (long long)im->dims[2]);
    sm__writer_bytes(w, v, (size_t)(im->dims[0] * im->dims[1] * im->dims[2]) * sizeof *v);
}

int sm_image_write_format(const char *path)
{
    return ends_with(path, ".nii") || ends_with(path, ".nii.gz") ? 1
           : ends_with(path, ".nrrd")                            ? 2
           : ends_with(path, ".mha")                             ? 3
                                                                 : 0;
}

sm_status sm_image_write(const char *path, const sm_image *im, sm_error *err)
{
    int format = sm_image_write_format(path);
    if (!format)
        return sm_error_set(err, SM_ERR_INVALID,
                            "%s: an image is written as .nii, .nii.gz, .nrrd or .mha", path);
    if (im->type != SM_VOXEL_F32 || !im->voxels)
        return sm_error_set(err, SM_ERR_INVALID, "%s: only float32 images are written", path);
    for (int c = 0; c < 3; c++)
        if (im->dims[c] < 1 || im->dims[c] > (format == 1 ? INT16_MAX : SM_IMAGE_MAX_DIM))
            return sm_error_set(err, SM_ERR_INVALID,
                                "%s: %lld voxels along axis %d do not fit the format", path,
                                (long long)im->dims[c], c);
    sm_writer *w;
    sm_status st = sm__writer_open(&w, path, err);
    if (st != SM_OK)
        return st;
    if (format == 1)
        write_nifti(w, im, im->voxels);
    else if (format == 2)
        write_nrrd(w, im, im->voxels);
    else
        write_mha(w, im, im->voxels);
    return sm__writer_close(w, err);
}
