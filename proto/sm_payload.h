/* The binary mesh payload, media type application/vnd.shapematch.mesh
 * (specification: proto/PAYLOAD.md).
 *
 * Little-endian, 8-byte aligned arrays:
 *   header (40 bytes): magic "SMMESH\0\0", version u32 (1), dim u32 (2|3),
 *     nverts u32, nelems u32, nfacets u32, flags u32, header_crc32 u32
 *     (zlib crc32 of bytes 0..31), reserved u32 (0)
 *   coords f64[nverts*dim], vert_refs i32[nverts],
 *   elems u32[nelems*(dim+1)], elem_refs i32[nelems],
 *   facets u32[nfacets*dim], facet_refs i32[nfacets],
 *   displacement f64[nverts*dim]   (flags bit 0)
 *   distance f64[nverts]           (flags bit 1)
 *   each array starts at a multiple of 8 (zero padding before it),
 *   trailer: crc32 u32 of every byte before it.
 * Indices are 0-based.
 *
 * The reader treats its input as hostile: the length must match the
 * counts exactly, every index must be < nverts, every double finite,
 * padding and reserved bytes zero, both CRCs right; errors
 * (SM_ERR_FORMAT) give the byte offset and what was expected.
 *
 * Link with libsmproto.a, libshapematch.a and -lz. */
#ifndef SM_PAYLOAD_H
#define SM_PAYLOAD_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "shapematch/sm_error.h"
#include "shapematch/sm_mesh.h"

#define SM_PAYLOAD_MEDIA_TYPE "application/vnd.shapematch.mesh"
#define SM_PAYLOAD_MAGIC "SMMESH\0\0" /* 8 bytes, the last two are NUL */
#define SM_PAYLOAD_MAGIC_LEN 8
#define SM_PAYLOAD_VERSION 1u
#define SM_PAYLOAD_HEADER_SIZE 40
#define SM_PAYLOAD_TRAILER_SIZE 4

#define SM_PAYLOAD_HAS_DISPLACEMENT 0x1u
#define SM_PAYLOAD_HAS_DISTANCE 0x2u
#define SM_PAYLOAD_KNOWN_FLAGS 0x3u

/* Default bound used by the readers when max_bytes is 0. */
#define SM_PAYLOAD_DEFAULT_MAX_BYTES ((uint64_t)4 << 30)

typedef struct sm_payload_header {
    uint32_t version;
    uint32_t dim;
    uint32_t nverts, nelems, nfacets;
    uint32_t flags;
    uint64_t total_size; /* bytes the whole payload must have, trailer included */
} sm_payload_header;

/* A decoded payload.  Everything is owned by it. */
typedef struct sm_payload {
    sm_mesh *mesh;        /* coords, refs, elements, file facets; boundary
                             not built (see sm_mesh_build_boundary) */
    double *displacement; /* nverts*dim, or NULL when absent */
    double *distance;     /* nverts, or NULL when absent */
} sm_payload;

void sm_payload_free(sm_payload *p);

/* Exact byte size of a payload with these counts and flags, or 0 when the
 * counts are out of range (dim not 2/3, a count > SM_MAX_ENTITIES, unknown
 * flags).  For Content-Length. */
uint64_t sm_payload_size(int dim, int32_t nverts, int32_t nelems,
                         int32_t nfacets, uint32_t flags);

/* Writers.  coords (nverts*dim) replaces m->coords when non-NULL (e.g. the
 * deformed positions of a result); displacement (nverts*dim) and distance
 * (nverts) are optional (NULL = absent, flags set accordingly).  The mesh
 * is checked first (dim, counts, indices < nverts, finite doubles):
 * SM_ERR_INVALID and nothing written when it is wrong.  m's derived
 * boundary data is not written. */
/* Into a new malloc'd buffer (*out, *out_len; caller frees with free()). */
sm_status sm_payload_encode(const sm_mesh *m, const double *coords,
                            const double *displacement, const double *distance,
                            unsigned char **out, size_t *out_len,
                            sm_error *err);
/* Streamed to f (no buffer of the whole payload), then fflush(f) so that
 * write errors show; SM_ERR_IO on a failed write.  Does not close f. */
sm_status sm_payload_write(FILE *f, const sm_mesh *m, const double *coords,
                           const double *displacement, const double *distance,
                           sm_error *err);
/* Creates/truncates path and writes to it (callers wanting atomicity
 * write to a temporary name and rename). */
sm_status sm_payload_write_file(const char *path, const sm_mesh *m,
                                const double *coords,
                                const double *displacement,
                                const double *distance, sm_error *err);

/* Reads and checks the 40-byte header only (magic, version, dim, counts,
 * flags, header CRC, reserved) from the first len bytes of buf; fills h
 * (total_size computed from the counts).  Does not look at the body. */
sm_status sm_payload_parse_header(const void *buf, size_t len,
                                  sm_payload_header *h, sm_error *err);

/* Decodes a whole payload of exactly len bytes.  *out is NULL on error. */
sm_status sm_payload_decode(const void *buf, size_t len, sm_payload **out,
                            sm_error *err);
/* Reads one payload from f: the header, then exactly the size its counts
 * announce (bytes after the trailer are left unread in f).  Payloads
 * larger than max_bytes (0 = SM_PAYLOAD_DEFAULT_MAX_BYTES) are refused
 * before anything is allocated.  SM_ERR_IO on a read error,
 * SM_ERR_FORMAT on a short or bad payload, SM_ERR_NOMEM past max_bytes. */
sm_status sm_payload_read(FILE *f, uint64_t max_bytes, sm_payload **out,
                          sm_error *err);
/* Reads a file that must hold exactly one payload (trailing bytes are an
 * error).  Messages are prefixed with path. */
sm_status sm_payload_read_file(const char *path, uint64_t max_bytes,
                               sm_payload **out, sm_error *err);

#endif
