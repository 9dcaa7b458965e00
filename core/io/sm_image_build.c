/* What the three image formats share (sm_image_formats.h) — the checked
 * allocation, the voxel data raw or inflated, the detached data file, the
 * geometry check — and the image model's small functions (free, flip,
 * value).  The readers call these; the dispatch by content is sm_io.c's
 * table. */
#include "io/sm_image_formats.h"

#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include "io/sm_inflate.h"
#include "shapematch/sm_path.h"

int sm_voxel_size(sm_voxel_type t)
{
    switch (t) {
    case SM_VOXEL_U8:
    case SM_VOXEL_S8:
        return 1;
    case SM_VOXEL_U16:
    case SM_VOXEL_S16:
        return 2;
    case SM_VOXEL_U32:
    case SM_VOXEL_S32:
    case SM_VOXEL_F32:
        return 4;
    case SM_VOXEL_F64:
        return 8;
    }
    return 0;
}

const char *sm_voxel_type_name(sm_voxel_type t)
{
    static const char *names[] = {"?",     "uint8", "int8",    "uint16", "int16",
                                  "uint32", "int32", "float32", "float64"};
    return (unsigned)t <= SM_VOXEL_F64 ? names[t] : "?";
}

void sm_image_free(sm_image *im)
{
    if (!im)
        return;
    free(im->voxels);
    free(im);
}

void sm_image_flip_ras(sm_image *im)
{
    for (int c = 0; c < 8; c++)
        im->ijk_to_lps[c] = -im->ijk_to_lps[c];
}

double sm_image_value(const sm_image *im, int64_t n)
{
    double v = 0;
    switch (im->type) {
    case SM_VOXEL_U8: v = ((const uint8_t *)im->voxels)[n]; break;
    case SM_VOXEL_S8: v = ((const int8_t *)im->voxels)[n]; break;
    case SM_VOXEL_U16: v = ((const uint16_t *)im->voxels)[n]; break;
    case SM_VOXEL_S16: v = ((const int16_t *)im->voxels)[n]; break;
    case SM_VOXEL_U32: v = ((const uint32_t *)im->voxels)[n]; break;
    case SM_VOXEL_S32: v = ((const int32_t *)im->voxels)[n]; break;
    case SM_VOXEL_F32: v = ((const float *)im->voxels)[n]; break;
    case SM_VOXEL_F64: v = ((const double *)im->voxels)[n]; break;
    }
    return im->slope * v + im->inter;
}

sm_status sm__image_new(const sm_image_src *src, const char *where, const int64_t dims[3],
                        sm_voxel_type type, sm_image **out, sm_error *err)
{
    *out = NULL;
    int64_t count = 1;
    for (int k = 0; k < 3; k++) {
        if (dims[k] < 1 || dims[k] > SM_IMAGE_MAX_DIM)
            return sm_error_set(err, SM_ERR_FORMAT, "%s: %s: size %" PRId64
                                " along axis %d is not in [1, %" PRId64 "]",
                                src->path, where, dims[k], k + 1, SM_IMAGE_MAX_DIM);
        count *= dims[k]; /* < 2^60: no overflow */
    }
    if (count > SM_IMAGE_MAX_VOXELS)
        return sm_error_set(err, SM_ERR_FORMAT, "%s: %s: %" PRId64 " voxels, more than the %"
                            PRId64 " read", src->path, where, count, SM_IMAGE_MAX_VOXELS);
    sm_image_limits *lim = src->limits;
    uint64_t bytes = (uint64_t)count * (uint64_t)sm_voxel_size(type);
    if (lim && lim->max_voxels > 0 && count > lim->max_voxels) {
        lim->hit = SM_IMAGE_LIMIT_VOXELS;
        return sm_error_set(err, SM_ERR_NOMEM, "%s: %" PRId64 " voxels, more than the limit of %"
                            PRId64 " voxels", src->path, count, lim->max_voxels);
    }
    if (lim && lim->max_inflated > 0 && bytes > lim->max_inflated) {
        lim->hit = SM_IMAGE_LIMIT_INFLATED;
        return sm_error_set(err, SM_ERR_NOMEM, "%s: %" PRIu64 " bytes of voxels, more than the "
                            "limit of %" PRIu64 " bytes", src->path, bytes, lim->max_inflated);
    }
    sm_image *im = calloc(1, sizeof *im);
    if (!im)
        return sm_error_set(err, SM_ERR_NOMEM, "%s: out of memory", src->path);
    memcpy(im->dims, dims, sizeof im->dims);
    im->type = type;
    im->slope = 1;
    im->inter = 0;
    *out = im;
    return SM_OK;
}

static void swap_voxels(sm_image *im)
{
    int size = sm_voxel_size(im->type);
    size_t n = (size_t)(im->dims[0] * im->dims[1] * im->dims[2]);
    unsigned char *p = im->voxels;
    for (size_t i = 0; i < n; i++, p += size)
        for (int a = 0, b = size - 1; a < b; a++, b--) {
            unsigned char t = p[a];
            p[a] = p[b];
            p[b] = t;
        }
}

/* The zlib or gzip stream at r's position inflated into exactly bytes
 * bytes of dst: the stream must hold that many (not fewer; more is
 * trailing data, ignored as zlib ignores it). */
static sm_status inflate_voxels(sm_reader *r, const sm_image_src *src, unsigned char *dst,
                                size_t bytes, sm_error *err)
{
    z_stream z;
    memset(&z, 0, sizeof z);
    uint64_t start = sm__reader_offset(r);
    if (inflateInit2(&z, 15 + 32) != Z_OK) /* 32: zlib or gzip header */
        return sm_error_set(err, SM_ERR_NOMEM, "%s: out of memory", src->path);
    size_t done = 0;
    sm_status st = SM_OK;
    int zr = Z_OK;
    while (done < bytes && zr != Z_STREAM_END) {
        const unsigned char *p;
        size_t avail;
        st = sm__reader_window(r, &p, &avail);
        if (st != SM_OK) {
            sm__reader_fail_byte(r, err, st, sm__reader_offset(r), "%s", r->why);
            break;
        }
        if (avail == 0) {
            st = sm__reader_fail_byte(r, err, SM_ERR_FORMAT, sm__reader_offset(r),
                                      "compressed voxel data (from byte %" PRIu64 ") ends after "
                                      "%zu of %zu bytes", start, done, bytes);
            break;
        }
        size_t in = avail > (1u << 30) ? (1u << 30) : avail;
        size_t room = bytes - done > (1u << 30) ? (1u << 30) : bytes - done;
        z.next_in = (unsigned char *)(uintptr_t)p;
        z.avail_in = (uInt)in;
        z.next_out = dst + done;
        z.avail_out = (uInt)room;
        zr = inflate(&z, Z_NO_FLUSH);
        sm__reader_consume(r, in - z.avail_in);
        done += room - z.avail_out;
        if (zr != Z_OK && zr != Z_STREAM_END && !(zr == Z_BUF_ERROR && done == bytes)) {
            st = sm__reader_fail_byte(r, err, SM_ERR_FORMAT, sm__reader_offset(r),
                                      "corrupt compressed voxel data (%s)",
                                      z.msg ? z.msg : "zlib error");
            break;
        }
    }
    if (st == SM_OK && done < bytes)
        st = sm__reader_fail_byte(r, err, SM_ERR_FORMAT, sm__reader_offset(r),
                                  "compressed voxel data (from byte %" PRIu64 ") inflates to %zu "
                                  "bytes, the header says %zu", start, done, bytes);
    inflateEnd(&z);
    return st;
}

/* The voxel array, once the data is known to be able to fill it. */
static sm_status alloc_voxels(const sm_image_src *src, sm_image *im, size_t bytes, sm_error *err)
{
    free(im->voxels);
    im->voxels = malloc(bytes);
    if (!im->voxels)
        return sm_error_set(err, SM_ERR_NOMEM, "%s: out of memory for %zu bytes of voxels",
                            src->path, bytes);
    return SM_OK;
}

sm_status sm__image_read_voxels(sm_reader *r, const sm_image_src *src, const sm_image_data *d,
                                sm_image *im, sm_error *err)
{
    size_t bytes = (size_t)(im->dims[0] * im->dims[1] * im->dims[2]) * (size_t)sm_voxel_size(im->type);
    uint64_t left = sm__reader_max_remaining(r);
    uint64_t skip = 0;
    if (d->skip == -1) {
        if (d->compressed || r->compressed)
            return sm_error_set(err, SM_ERR_FORMAT, "%s: a byte skip of -1 (data at the end) "
                                "needs raw, uncompressed data", src->path);
        if (left < bytes)
            return sm__reader_fail_byte(r, err, SM_ERR_FORMAT, sm__reader_offset(r),
                                        "the file holds %" PRIu64 " bytes, the voxels need %zu",
                                        left, bytes);
        skip = left - bytes;
    } else if (d->skip > 0) {
        skip = (uint64_t)d->skip;
    }
    if (skip > 0) {
        if (skip > left)
            return sm__reader_fail_byte(r, err, SM_ERR_FORMAT, sm__reader_offset(r),
                                        "byte skip %" PRIu64 " beyond the end of the file", skip);
        sm_status st = sm__reader_skip(r, skip);
        if (st != SM_OK)
            return sm__reader_fail_byte(r, err, st, sm__reader_offset(r), "%s", r->why);
        left -= skip;
    }
    if (d->compressed) {
        /* deflate expands at most SM_DEFLATE_MAX_RATIO:1: a stream too short
         * to hold the voxels fails here, before they are allocated */
        uint64_t most = left > UINT64_MAX / (2 * SM_DEFLATE_MAX_RATIO) ? UINT64_MAX / 2
                                                                    : left * SM_DEFLATE_MAX_RATIO;
        if (most < bytes)
            return sm__reader_fail_byte(r, err, SM_ERR_FORMAT, sm__reader_offset(r),
                                        "%" PRIu64 " bytes of compressed voxel data left inflate "
                                        "to at most %" PRIu64 " bytes, the header's voxels need "
                                        "%zu",
                                        left, most, bytes);
        sm_status st = alloc_voxels(src, im, bytes, err);
        return st != SM_OK ? st : inflate_voxels(r, src, im->voxels, bytes, err);
    }
    if (left < bytes)
        return sm__reader_fail_byte(r, err, SM_ERR_FORMAT, sm__reader_offset(r),
                                    "%" PRIu64 " bytes of voxel data left, the header's %" PRId64
                                    " x %" PRId64 " x %" PRId64 " %s voxels need %zu (truncated?)",
                                    left, im->dims[0], im->dims[1], im->dims[2],
                                    sm_voxel_type_name(im->type), bytes);
    sm_status ast = alloc_voxels(src, im, bytes, err);
    if (ast != SM_OK)
        return ast;
    uint64_t at = sm__reader_offset(r);
    sm_status st = sm__reader_bytes(r, im->voxels, bytes);
    if (st != SM_OK)
        return sm__reader_fail_byte(r, err, st, sm__reader_offset(r),
                                    "voxel data from byte %" PRIu64 ": %s", at, r->why);
    if (d->swap)
        swap_voxels(im);
    return SM_OK;
}

/* Opens name (relative, without "..") in the folder of the header at
 * header_path one component at a time, each with O_NOFOLLOW: a symbolic
 * link anywhere in name (one beside the header pointing elsewhere) is
 * refused, so nothing outside the folder is reached.  The file must be a
 * regular one: it is opened without blocking (a FIFO would wait for a
 * writer forever, a device never end) and checked with fstat.  Returns
 * the descriptor, or -1 with errno set, or with *why saying what was
 * refused. */
static int open_beside(const char *header_path, const char *name, const char **why)
{
    const char *slash = strrchr(header_path, '/');
    char *dir = slash ? strndup(header_path, (size_t)(slash - header_path) + 1) : strdup(".");
    char *rest = strdup(name);
    int dfd = dir && rest ? open(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC) : -1;
    if (!dir || !rest)
        errno = ENOMEM;
    free(dir);
    char *comp = rest, *next;
    while (dfd >= 0 && (next = strchr(comp, '/')) != NULL) {
        *next = '\0';
        if (comp[0] != '\0' && strcmp(comp, ".") != 0) {
            int sub = openat(dfd, comp, O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
            int e = errno;
            struct stat ls;
            if (sub < 0 && (e == ELOOP || e == ENOTDIR) &&
                fstatat(dfd, comp, &ls, AT_SYMLINK_NOFOLLOW) == 0 && S_ISLNK(ls.st_mode))
                *why = "passes through a symbolic link (refused: the data file must lie in the "
                       "header's folder)";
            close(dfd);
            dfd = sub;
            errno = e;
        }
        comp = next + 1;
    }
    int fd = -1;
    if (dfd >= 0) {
        fd = openat(dfd, comp, O_RDONLY | O_NOFOLLOW | O_NONBLOCK | O_NOCTTY | O_CLOEXEC);
        int e = errno;
        close(dfd);
        errno = e;
        if (fd < 0 && e == ELOOP)
            *why = "is a symbolic link (refused: the data file must be a regular file in the "
                   "header's folder)";
    }
    free(rest);
    struct stat st;
    if (fd >= 0 && (fstat(fd, &st) != 0 || !S_ISREG(st.st_mode))) {
        *why = "is not a regular file (a FIFO, a device or a folder is refused)";
        close(fd);
        return -1;
    }
    if (fd >= 0)
        fcntl(fd, F_SETFL, fcntl(fd, F_GETFL) & ~O_NONBLOCK);
    return fd;
}

sm_status sm__image_open_detached(const sm_image_src *src, const char *where, const char *name,
                                  sm_reader *r, char **data_path, sm_error *err)
{
    *data_path = NULL;
    if (src->in_memory)
        return sm_error_set(err, SM_ERR_FORMAT, "%s: %s: a detached data file ('%.200s') is read "
                            "for files only", src->path, where, name);
    if (src->limits && src->limits->no_detached) {
        src->limits->hit = SM_IMAGE_LIMIT_DETACHED;
        return sm_error_set(err, SM_ERR_INVALID, "%s: %s: names a detached data file ('%.200s'); "
                            "send a single-file image (.nii, .nii.gz, .nrrd, .mha)", src->path,
                            where, name);
    }
    /* Beside the header only: no absolute name, no way up. */
    int up = strcmp(name, "..") == 0 || strncmp(name, "../", 3) == 0 || strstr(name, "/../") ||
             (strlen(name) >= 3 && strcmp(name + strlen(name) - 3, "/..") == 0);
    if (name[0] == '/' || up || name[0] == '\0')
        return sm_error_set(err, SM_ERR_FORMAT, "%s: %s: data file '%.200s' must be a relative "
                            "name beside the header, without '..'", src->path, where, name);
    const char *why = NULL;
    int fd = open_beside(src->path, name, &why);
    if (fd < 0 && why)
        return sm_error_set(err, SM_ERR_FORMAT, "%s: %s: data file '%.200s' %s", src->path, where,
                            name, why);
    if (fd < 0)
        return sm_error_set(err, SM_ERR_IO, "%s: %s: data file '%.200s': cannot open: %s",
                            src->path, where, name, strerror(errno));
    const char *slash = strrchr(src->path, '/');
    char *dir = slash ? strndup(src->path, (size_t)(slash - src->path) + 1) : strdup("");
    char *full = dir ? (slash ? sm_path_join(dir, name) : strdup(name)) : NULL;
    free(dir);
    if (!full) {
        close(fd);
        return sm_error_set(err, SM_ERR_NOMEM, "%s: out of memory", src->path);
    }
    sm_status st = sm__reader_open_fd(r, full, fd, err);
    if (st != SM_OK) {
        sm_error_prefix(err, "%s: %s: data file", src->path, where);
        free(full);
        return st;
    }
    *data_path = full;
    return SM_OK;
}

sm_status sm__image_read_detached(const sm_image_src *src, long line, const char *name,
                                  sm_image_data d, sm_image *im, sm_error *err)
{
    sm_reader dr;
    char *data_path, where[32];
    snprintf(where, sizeof where, "line %ld", line);
    sm_status st = sm__image_open_detached(src, where, name, &dr, &data_path, err);
    if (st != SM_OK)
        return st;
    sm_image_src dsrc = {data_path, 0, src->limits};
    d.compressed = d.compressed && !dr.compressed;
    st = sm__image_read_voxels(&dr, &dsrc, &d, im, err);
    sm__reader_close(&dr);
    free(data_path);
    return st;
}

sm_status sm__image_check_geometry(const sm_image_src *src, const sm_image *im, sm_error *err)
{
    const double *m = im->ijk_to_lps;
    for (int k = 0; k < 12; k++)
        if (!isfinite(m[k]))
            return sm_error_set(err, SM_ERR_FORMAT, "%s: the voxel-to-world map is not finite",
                                src->path);
    double det = m[0] * (m[5] * m[10] - m[6] * m[9]) - m[1] * (m[4] * m[10] - m[6] * m[8]) +
                 m[2] * (m[4] * m[9] - m[5] * m[8]);
    double scale = 1;
    for (int c = 0; c < 3; c++)
        scale *= sqrt(m[c] * m[c] + m[4 + c] * m[4 + c] + m[8 + c] * m[8 + c]);
    if (!(scale > 0) || !(fabs(det) > 1e-9 * scale))
        return sm_error_set(err, SM_ERR_FORMAT, "%s: the voxel axes are singular (zero spacing "
                            "or parallel directions)", src->path);
    return SM_OK;
}
