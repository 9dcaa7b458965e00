/* NIfTI-1 (348-byte header, magic "n+1") and NIfTI-2 (540 bytes, "n+2")
 * single files, .nii or .nii.gz (the reader inflates gzip files).
 * Our own reader rather than Debian's libnifti2: nifti_image_read trusts
 * the header (it allocates what dim[] says and reads through znzlib with
 * its own error printing to stderr), while this one keeps the readers'
 * one hostile-input discipline — sizes checked before allocation, the
 * daemon's limits, messages with the byte, in-memory fuzzing — in ~250
 * lines for the part of the standard a label map uses.
 *
 * Geometry, as the standard orders it: sform (srow_x/y/z) when sform_code
 * > 0, else the qform quaternion (quatern_b/c/d, qoffset, pixdim, qfac =
 * pixdim[0]) when qform_code > 0, else pixdim scaling alone ("method 1",
 * for old ANALYZE files).  NIfTI's world is RAS; we store LPS. */
#include "io/sm_image_formats.h"

#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#define NIFTI1_HDR 348
#define NIFTI2_HDR 540

static uint16_t rd16(const unsigned char *p, int swap)
{
    uint16_t v;
    memcpy(&v, p, 2);
    return swap ? (uint16_t)((v >> 8) | (v << 8)) : v;
}

static uint32_t rd32(const unsigned char *p, int swap)
{
    uint32_t v;
    memcpy(&v, p, 4);
    return swap ? sm__bswap32(v) : v;
}

static uint64_t rd64(const unsigned char *p, int swap)
{
    uint64_t v;
    memcpy(&v, p, 8);
    return swap ? sm__bswap64(v) : v;
}

static double rdf32(const unsigned char *p, int swap)
{
    uint32_t u = rd32(p, swap);
    float f;
    memcpy(&f, &u, 4);
    return f;
}

static double rdf64(const unsigned char *p, int swap)
{
    uint64_t u = rd64(p, swap);
    double d;
    memcpy(&d, &u, 8);
    return d;
}

/* 0: not NIfTI; else the header size, and *swap. */
static int header_kind(const unsigned char *h, size_t got, int *swap)
{
    if (got < 4)
        return 0;
    for (int s = 0; s < 2; s++) {
        uint32_t size = rd32(h, s);
        if (size == NIFTI1_HDR && got >= NIFTI1_HDR && memcmp(h + 344, "n+1", 4) == 0) {
            *swap = s;
            return NIFTI1_HDR;
        }
        if (size == NIFTI2_HDR && got >= 12 && memcmp(h + 4, "n+2\0\r\n\032\n", 8) == 0) {
            *swap = s;
            return NIFTI2_HDR;
        }
    }
    return 0;
}

int sm__nifti_detect(sm_reader *r)
{
    unsigned char h[NIFTI1_HDR];
    size_t got = 0;
    int swap;
    if (sm__reader_peek(r, h, sizeof h, &got) != SM_OK)
        return 0;
    if (got >= 4 && (rd32(h, 0) == NIFTI1_HDR || rd32(h, 1) == NIFTI1_HDR ||
                     rd32(h, 0) == NIFTI2_HDR || rd32(h, 1) == NIFTI2_HDR))
        return 1; /* the header size says NIfTI; the reader names what is wrong */
    return header_kind(h, got, &swap) != 0;
}

/* The header's fields, whichever version. */
typedef struct nifti_hdr {
    int version;
    int64_t dim[8];
    int datatype;
    double pixdim[8], vox_offset, slope, inter;
    int qform_code, sform_code;
    double quatern[3], qoffset[3], srow[12];
} nifti_hdr;

static void parse1(const unsigned char *h, int s, nifti_hdr *n)
{
    n->version = 1;
    for (int k = 0; k < 8; k++) {
        n->dim[k] = (int16_t)rd16(h + 40 + 2 * k, s);
        n->pixdim[k] = rdf32(h + 76 + 4 * k, s);
    }
    n->datatype = (int16_t)rd16(h + 70, s);
    n->vox_offset = rdf32(h + 108, s);
    n->slope = rdf32(h + 112, s);
    n->inter = rdf32(h + 116, s);
    n->qform_code = (int16_t)rd16(h + 252, s);
    n->sform_code = (int16_t)rd16(h + 254, s);
    for (int k = 0; k < 3; k++) {
        n->quatern[k] = rdf32(h + 256 + 4 * k, s);
        n->qoffset[k] = rdf32(h + 268 + 4 * k, s);
    }
    for (int k = 0; k < 12; k++)
        n->srow[k] = rdf32(h + 280 + 4 * k, s);
}

static void parse2(const unsigned char *h, int s, nifti_hdr *n)
{
    n->version = 2;
    for (int k = 0; k < 8; k++) {
        n->dim[k] = (int64_t)rd64(h + 16 + 8 * k, s);
        n->pixdim[k] = rdf64(h + 104 + 8 * k, s);
    }
    n->datatype = (int16_t)rd16(h + 12, s);
    n->vox_offset = (double)(int64_t)rd64(h + 168, s);
    n->slope = rdf64(h + 176, s);
    n->inter = rdf64(h + 184, s);
    n->qform_code = (int32_t)rd32(h + 344, s);
    n->sform_code = (int32_t)rd32(h + 348, s);
    for (int k = 0; k < 3; k++) {
        n->quatern[k] = rdf64(h + 352 + 8 * k, s);
        n->qoffset[k] = rdf64(h + 376 + 8 * k, s);
    }
    for (int k = 0; k < 12; k++)
        n->srow[k] = rdf64(h + 400 + 8 * k, s);
}

static sm_voxel_type voxel_type(int datatype)
{
    switch (datatype) {
    case 2: return SM_VOXEL_U8;
    case 4: return SM_VOXEL_S16;
    case 8: return SM_VOXEL_S32;
    case 16: return SM_VOXEL_F32;
    case 64: return SM_VOXEL_F64;
    case 256: return SM_VOXEL_S8;
    case 512: return SM_VOXEL_U16;
    case 768: return SM_VOXEL_U32;
    }
    return 0;
}

/* The RAS map of the header (the standard's three methods). */
static void ras_map(const nifti_hdr *n, double m[12])
{
    if (n->sform_code > 0) {
        memcpy(m, n->srow, 12 * sizeof *m);
        return;
    }
    memset(m, 0, 12 * sizeof *m);
    if (n->qform_code <= 0) {
        for (int k = 0; k < 3; k++)
            m[5 * k] = n->pixdim[k + 1];
        return;
    }
    double b = n->quatern[0], c = n->quatern[1], d = n->quatern[2];
    double a = 1 - (b * b + c * c + d * d);
    if (a < 1e-7) { /* as nifti1_io: a 180-degree turn, renormalised */
        double s = 1 / sqrt(b * b + c * c + d * d);
        b *= s;
        c *= s;
        d *= s;
        a = 0;
    } else {
        a = sqrt(a);
    }
    double R[9] = {a * a + b * b - c * c - d * d, 2 * (b * c - a * d), 2 * (b * d + a * c),
                   2 * (b * c + a * d), a * a + c * c - b * b - d * d, 2 * (c * d - a * b),
                   2 * (b * d - a * c), 2 * (c * d + a * b), a * a + d * d - c * c - b * b};
    double qfac = n->pixdim[0] < 0 ? -1 : 1;
    double sc[3] = {n->pixdim[1], n->pixdim[2], n->pixdim[3] * qfac};
    for (int row = 0; row < 3; row++) {
        for (int col = 0; col < 3; col++)
            m[4 * row + col] = R[3 * row + col] * sc[col];
        m[4 * row + 3] = n->qoffset[row];
    }
}

static sm_status check_header(sm_reader *r, const nifti_hdr *n, sm_error *err)
{
    int v2 = n->version == 2;
    uint64_t dim_at = v2 ? 16 : 40, dt_at = v2 ? 12 : 70, off_at = v2 ? 168 : 108;
    if (n->dim[0] < 1 || n->dim[0] > 7)
        return sm__reader_fail_byte(r, err, SM_ERR_FORMAT, dim_at, "dim[0] = %" PRId64
                                    " is not a number of dimensions in [1, 7]", n->dim[0]);
    for (int k = 1; k <= n->dim[0]; k++)
        if (n->dim[k] < 1)
            return sm__reader_fail_byte(r, err, SM_ERR_FORMAT, dim_at + (uint64_t)k * (v2 ? 8 : 2),
                                        "dim[%d] = %" PRId64 " is not a positive size", k,
                                        n->dim[k]);
    for (int k = 4; k <= n->dim[0]; k++)
        if (n->dim[k] != 1)
            return sm__reader_fail_byte(r, err, SM_ERR_FORMAT, dim_at + (uint64_t)k * (v2 ? 8 : 2),
                                        "dim[%d] = %" PRId64 ": a 3D label map with one volume "
                                        "and one channel is read", k, n->dim[k]);
    if (!voxel_type(n->datatype))
        return sm__reader_fail_byte(r, err, SM_ERR_FORMAT, dt_at, "datatype %d is not a voxel "
                                    "type read (uint8/16/32, int8/16/32, float32/64: 2, 512, "
                                    "768, 256, 4, 8, 16, 64)", n->datatype);
    uint64_t hdr = v2 ? NIFTI2_HDR : NIFTI1_HDR;
    if (!isfinite(n->vox_offset) || n->vox_offset < (double)hdr || n->vox_offset > 1e15 ||
        n->vox_offset != floor(n->vox_offset))
        return sm__reader_fail_byte(r, err, SM_ERR_FORMAT, off_at, "vox_offset %g is not a "
                                    "whole byte offset at or after the %" PRIu64 "-byte header",
                                    n->vox_offset, hdr);
    if (n->sform_code <= 0)
        for (int k = 1; k <= 3; k++)
            if (!isfinite(n->pixdim[k]) || n->pixdim[k] == 0)
                return sm__reader_fail_byte(r, err, SM_ERR_FORMAT, (v2 ? 104 : 76) +
                                            (uint64_t)k * (v2 ? 8 : 4), "pixdim[%d] = %g is not "
                                            "a nonzero spacing", k, n->pixdim[k]);
    return SM_OK;
}

sm_status sm__nifti_read(sm_reader *r, const sm_image_src *src, sm_image **out, sm_error *err)
{
    *out = NULL;
    unsigned char h[NIFTI2_HDR];
    size_t got = 0;
    int swap = 0;
    sm_status st = sm__reader_peek(r, h, sizeof h, &got);
    if (st != SM_OK)
        return sm__reader_fail_byte(r, err, st, 0, "%s", r->why);
    int size = header_kind(h, got, &swap);
    if (!size && got < NIFTI1_HDR)
        return sm__reader_fail_byte(r, err, SM_ERR_FORMAT, got, "truncated NIfTI header (%zu "
                                    "bytes)", got);
    if (!size)
        return sm__reader_fail_byte(r, err, SM_ERR_FORMAT, 344, "no NIfTI magic 'n+1' or 'n+2' "
                                    "(a .hdr/.img pair is not read: convert it to .nii)");
    if (got < (size_t)size)
        return sm__reader_fail_byte(r, err, SM_ERR_FORMAT, got, "truncated NIfTI-2 header "
                                    "(%zu of 540 bytes)", got);
    nifti_hdr n;
    memset(&n, 0, sizeof n);
    if (size == NIFTI1_HDR)
        parse1(h, swap, &n);
    else
        parse2(h, swap, &n);
    if ((st = check_header(r, &n, err)) != SM_OK)
        return st;
    int64_t dims[3] = {n.dim[1], n.dim[0] >= 2 ? n.dim[2] : 1, n.dim[0] >= 3 ? n.dim[3] : 1};
    sm_image *im;
    char where[32];
    snprintf(where, sizeof where, "byte %d", n.version == 2 ? 16 : 40);
    if ((st = sm__image_new(src, where, dims, voxel_type(n.datatype), &im, err)) != SM_OK)
        return st;
    im->format = n.version == 2 ? "NIfTI-2" : "NIfTI-1";
    if (isfinite(n.slope) && n.slope != 0 && isfinite(n.inter)) {
        im->slope = n.slope;
        im->inter = n.inter;
    }
    ras_map(&n, im->ijk_to_lps);
    sm_image_flip_ras(im); /* RAS -> LPS: the same flip both ways */
    sm_image_data d = {0, swap, (int64_t)n.vox_offset};
    if ((st = sm__image_read_voxels(r, src, &d, im, err)) != SM_OK) {
        sm_image_free(im);
        return st;
    }
    *out = im;
    return SM_OK;
}
