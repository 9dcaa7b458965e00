/* The binary mesh payload (application/vnd.shapematch.mesh); the format is
 * specified in proto/PAYLOAD.md.  Bytes are assembled explicitly in
 * little-endian order, so the code does not depend on the host's. */
#include "sm_payload.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <zlib.h>

/* ---------------------------------------------------------- byte helpers */

static void put_u32(unsigned char *p, uint32_t v)
{
    p[0] = (unsigned char)v;
    p[1] = (unsigned char)(v >> 8);
    p[2] = (unsigned char)(v >> 16);
    p[3] = (unsigned char)(v >> 24);
}

static uint32_t get_u32(const unsigned char *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static void put_f64(unsigned char *p, double x)
{
    uint64_t bits;
    memcpy(&bits, &x, sizeof bits);
    put_u32(p, (uint32_t)bits);
    put_u32(p + 4, (uint32_t)(bits >> 32));
}

static double get_f64(const unsigned char *p)
{
    uint64_t bits = (uint64_t)get_u32(p) | (uint64_t)get_u32(p + 4) << 32;
    double x;
    memcpy(&x, &bits, sizeof x);
    return x;
}

static uint64_t align8(uint64_t n) { return (n + 7) & ~(uint64_t)7; }

static uint32_t crc_update(uint32_t crc, const unsigned char *p, size_t n)
{
    return (uint32_t)crc32_z(crc, p, n);
}

/* ---------------------------------------------------------------- layout */

enum { A_COORDS, A_VREFS, A_ELEMS, A_EREFS, A_FACETS, A_FREFS, A_DISP, A_DIST, A_COUNT };
static const char *const array_names[A_COUNT] = {
    "coords", "vert_refs", "elems", "elem_refs", "facets", "facet_refs", "displacement",
    "distance"};

typedef struct layout {
    uint64_t offset[A_COUNT]; /* start of each array (0 when absent) */
    uint64_t bytes[A_COUNT];  /* payload bytes of each array, padding excluded */
    uint64_t body_end;        /* where the trailer starts */
    uint64_t total;
} layout;

/* Computes offsets; 0 when the header values are out of range. */
static int make_layout(uint32_t dim, uint32_t nverts, uint32_t nelems, uint32_t nfacets,
                       uint32_t flags, layout *L)
{
    if ((dim != 2 && dim != 3) || nverts > SM_MAX_ENTITIES || nelems > SM_MAX_ENTITIES ||
        nfacets > SM_MAX_ENTITIES || (flags & ~SM_PAYLOAD_KNOWN_FLAGS))
        return 0;
    const uint64_t nv = nverts, ne = nelems, nf = nfacets, d = dim;
    L->bytes[A_COORDS] = 8 * nv * d;
    L->bytes[A_VREFS] = 4 * nv;
    L->bytes[A_ELEMS] = 4 * ne * (d + 1);
    L->bytes[A_EREFS] = 4 * ne;
    L->bytes[A_FACETS] = 4 * nf * d;
    L->bytes[A_FREFS] = 4 * nf;
    L->bytes[A_DISP] = (flags & SM_PAYLOAD_HAS_DISPLACEMENT) ? 8 * nv * d : 0;
    L->bytes[A_DIST] = (flags & SM_PAYLOAD_HAS_DISTANCE) ? 8 * nv : 0;
    uint64_t at = SM_PAYLOAD_HEADER_SIZE;
    for (int a = 0; a < A_COUNT; a++) {
        int present = !(a == A_DISP && !(flags & SM_PAYLOAD_HAS_DISPLACEMENT)) &&
                      !(a == A_DIST && !(flags & SM_PAYLOAD_HAS_DISTANCE));
        L->offset[a] = present ? at : 0;
        at = align8(at + L->bytes[a]);
    }
    L->body_end = at;
    L->total = at + SM_PAYLOAD_TRAILER_SIZE;
    return 1;
}

uint64_t sm_payload_size(int dim, int32_t nverts, int32_t nelems, int32_t nfacets,
                         uint32_t flags)
{
    layout L;
    if (dim < 0 || nverts < 0 || nelems < 0 || nfacets < 0 ||
        !make_layout((uint32_t)dim, (uint32_t)nverts, (uint32_t)nelems, (uint32_t)nfacets,
                     flags, &L))
        return 0;
    return L.total;
}

static void encode_header(unsigned char h[SM_PAYLOAD_HEADER_SIZE], uint32_t dim,
                          uint32_t nverts, uint32_t nelems, uint32_t nfacets, uint32_t flags)
{
    memcpy(h, SM_PAYLOAD_MAGIC, SM_PAYLOAD_MAGIC_LEN);
    put_u32(h + 8, SM_PAYLOAD_VERSION);
    put_u32(h + 12, dim);
    put_u32(h + 16, nverts);
    put_u32(h + 20, nelems);
    put_u32(h + 24, nfacets);
    put_u32(h + 28, flags);
    put_u32(h + 32, crc_update(0, h, 32));
    put_u32(h + 36, 0);
}

/* ---------------------------------------------------------------- writer */

/* Output goes through a small staging buffer to either a memory block or
 * a FILE; the running CRC covers every byte passed through. */
typedef struct sink {
    unsigned char *mem; /* memory output (exact size known in advance) */
    FILE *file;         /* or stream output */
    uint64_t at;        /* bytes emitted so far */
    uint32_t crc;
    unsigned char stage[1 << 16];
    size_t staged;
    int failed;
} sink;

static void sink_flush(sink *s)
{
    if (s->staged == 0 || s->failed)
        return;
    if (s->mem)
        memcpy(s->mem + s->at - s->staged, s->stage, s->staged);
    else if (fwrite(s->stage, 1, s->staged, s->file) != s->staged)
        s->failed = 1;
    s->staged = 0;
}

static void sink_bytes(sink *s, const unsigned char *p, size_t n)
{
    s->crc = crc_update(s->crc, p, n);
    while (n > 0) {
        size_t room = sizeof s->stage - s->staged;
        size_t k = n < room ? n : room;
        memcpy(s->stage + s->staged, p, k);
        s->staged += k;
        s->at += k;
        p += k;
        n -= k;
        if (s->staged == sizeof s->stage)
            sink_flush(s);
    }
}

static void sink_u32(sink *s, uint32_t v)
{
    unsigned char b[4];
    put_u32(b, v);
    sink_bytes(s, b, 4);
}

static void sink_f64(sink *s, double x)
{
    unsigned char b[8];
    put_f64(b, x);
    sink_bytes(s, b, 8);
}

static void sink_pad(sink *s)
{
    static const unsigned char zeros[8];
    sink_bytes(s, zeros, (size_t)(align8(s->at) - s->at));
}

static sm_status check_doubles(const double *x, uint64_t n, const char *what, sm_error *err)
{
    for (uint64_t i = 0; i < n; i++)
        if (!isfinite(x[i]))
            return sm_error_set(err, SM_ERR_INVALID,
                                "payload: %s value %llu is not finite (%g)", what,
                                (unsigned long long)i, x[i]);
    return SM_OK;
}

static sm_status check_indices(const int32_t *idx, uint64_t n, int32_t nverts,
                               const char *what, sm_error *err)
{
    for (uint64_t i = 0; i < n; i++)
        if (idx[i] < 0 || idx[i] >= nverts)
            return sm_error_set(err, SM_ERR_INVALID,
                                "payload: %s entry %llu is vertex index %ld, outside [0, %ld)",
                                what, (unsigned long long)i, (long)idx[i], (long)nverts);
    return SM_OK;
}

static sm_status check_mesh(const sm_mesh *m, const double *coords, const double *disp,
                            const double *dist, uint32_t flags, layout *L, sm_error *err)
{
    if (!m)
        return sm_error_set(err, SM_ERR_INVALID, "payload: no mesh");
    if (m->nverts < 0 || m->nelems < 0 || m->nfacets < 0 ||
        !make_layout((uint32_t)m->dim, (uint32_t)m->nverts, (uint32_t)m->nelems,
                     (uint32_t)m->nfacets, flags, L))
        return sm_error_set(err, SM_ERR_INVALID,
                            "payload: mesh of dimension %d with %ld vertices, %ld elements, "
                            "%ld facets cannot be written (dimension 2 or 3, counts 0..%d)",
                            m->dim, (long)m->nverts, (long)m->nelems, (long)m->nfacets,
                            SM_MAX_ENTITIES);
    const uint64_t nv = (uint64_t)m->nverts, d = (uint64_t)m->dim;
    sm_status st;
    if ((st = check_doubles(coords, nv * d, "coordinate", err)) ||
        (st = check_indices(m->elems, (uint64_t)m->nelems * (d + 1), m->nverts, "element",
                            err)) ||
        (st = check_indices(m->facets, (uint64_t)m->nfacets * d, m->nverts, "facet", err)) ||
        (disp && (st = check_doubles(disp, nv * d, "displacement", err))) ||
        (dist && (st = check_doubles(dist, nv, "distance", err))))
        return st;
    return SM_OK;
}

static void emit(sink *s, const sm_mesh *m, const double *coords, const double *disp,
                 const double *dist, uint32_t flags)
{
    const uint64_t nv = (uint64_t)m->nverts, d = (uint64_t)m->dim;
    unsigned char h[SM_PAYLOAD_HEADER_SIZE];
    encode_header(h, (uint32_t)m->dim, (uint32_t)m->nverts, (uint32_t)m->nelems,
                  (uint32_t)m->nfacets, flags);
    sink_bytes(s, h, sizeof h);
    for (uint64_t i = 0; i < nv * d; i++)
        sink_f64(s, coords[i]);
    sink_pad(s);
    for (uint64_t i = 0; i < nv; i++)
        sink_u32(s, (uint32_t)m->vert_refs[i]);
    sink_pad(s);
    for (uint64_t i = 0; i < (uint64_t)m->nelems * (d + 1); i++)
        sink_u32(s, (uint32_t)m->elems[i]);
    sink_pad(s);
    for (uint64_t i = 0; i < (uint64_t)m->nelems; i++)
        sink_u32(s, (uint32_t)m->elem_refs[i]);
    sink_pad(s);
    for (uint64_t i = 0; i < (uint64_t)m->nfacets * d; i++)
        sink_u32(s, (uint32_t)m->facets[i]);
    sink_pad(s);
    for (uint64_t i = 0; i < (uint64_t)m->nfacets; i++)
        sink_u32(s, (uint32_t)m->facet_refs[i]);
    sink_pad(s);
    if (disp) {
        for (uint64_t i = 0; i < nv * d; i++)
            sink_f64(s, disp[i]);
        sink_pad(s);
    }
    if (dist) {
        for (uint64_t i = 0; i < nv; i++)
            sink_f64(s, dist[i]);
        sink_pad(s);
    }
    /* the trailer is not part of its own CRC */
    uint32_t crc = s->crc;
    sink_u32(s, crc);
    sink_flush(s);
}

static uint32_t flags_of(const double *disp, const double *dist)
{
    return (disp ? SM_PAYLOAD_HAS_DISPLACEMENT : 0) | (dist ? SM_PAYLOAD_HAS_DISTANCE : 0);
}

sm_status sm_payload_encode(const sm_mesh *m, const double *coords, const double *displacement,
                            const double *distance, unsigned char **out, size_t *out_len,
                            sm_error *err)
{
    *out = NULL;
    *out_len = 0;
    uint32_t flags = flags_of(displacement, distance);
    layout L;
    if (!coords && m)
        coords = m->coords;
    sm_status st = check_mesh(m, coords, displacement, distance, flags, &L, err);
    if (st != SM_OK)
        return st;
    if (L.total > SIZE_MAX)
        return sm_error_set(err, SM_ERR_NOMEM, "payload: %llu bytes do not fit in memory",
                            (unsigned long long)L.total);
    sink *s = calloc(1, sizeof *s);
    unsigned char *buf = malloc((size_t)L.total);
    if (!s || !buf) {
        free(s);
        free(buf);
        return sm_error_set(err, SM_ERR_NOMEM, "payload: out of memory for %llu bytes",
                            (unsigned long long)L.total);
    }
    s->mem = buf;
    emit(s, m, coords, displacement, distance, flags);
    free(s);
    *out = buf;
    *out_len = (size_t)L.total;
    return SM_OK;
}

sm_status sm_payload_write(FILE *f, const sm_mesh *m, const double *coords,
                           const double *displacement, const double *distance, sm_error *err)
{
    uint32_t flags = flags_of(displacement, distance);
    layout L;
    if (!coords && m)
        coords = m->coords;
    sm_status st = check_mesh(m, coords, displacement, distance, flags, &L, err);
    if (st != SM_OK)
        return st;
    sink *s = calloc(1, sizeof *s);
    if (!s)
        return sm_error_set(err, SM_ERR_NOMEM, "payload: out of memory");
    s->file = f;
    emit(s, m, coords, displacement, distance, flags);
    int failed = s->failed || fflush(f) != 0 || ferror(f);
    free(s);
    if (failed)
        return sm_error_set(err, SM_ERR_IO, "payload: write failed: %s", strerror(errno));
    return SM_OK;
}

sm_status sm_payload_write_file(const char *path, const sm_mesh *m, const double *coords,
                                const double *displacement, const double *distance,
                                sm_error *err)
{
    FILE *f = fopen(path, "wb");
    if (!f)
        return sm_error_set(err, SM_ERR_IO, "%s: cannot create: %s", path, strerror(errno));
    sm_status st = sm_payload_write(f, m, coords, displacement, distance, err);
    if (fclose(f) != 0 && st == SM_OK)
        st = sm_error_set(err, SM_ERR_IO, "%s: write failed: %s", path, strerror(errno));
    else if (st != SM_OK)
        sm_error_prefix(err, "%s", path);
    if (st != SM_OK)
        remove(path);
    return st;
}

/* ---------------------------------------------------------------- reader */

sm_status sm_payload_parse_header(const void *buf, size_t len, sm_payload_header *h,
                                  sm_error *err)
{
    const unsigned char *p = buf;
    memset(h, 0, sizeof *h);
    if (!buf || len == 0)
        return sm_error_set(err, SM_ERR_FORMAT,
                            "payload is empty: expected a %d-byte header starting with "
                            "\"SMMESH\\0\\0\"",
                            SM_PAYLOAD_HEADER_SIZE);
    size_t magic_seen = len < SM_PAYLOAD_MAGIC_LEN ? len : SM_PAYLOAD_MAGIC_LEN;
    if (memcmp(p, SM_PAYLOAD_MAGIC, magic_seen) != 0)
        return sm_error_set(err, SM_ERR_FORMAT,
                            "payload byte 0: bad magic (expected \"SMMESH\\0\\0\"): not an "
                            "application/vnd.shapematch.mesh payload");
    if (len < SM_PAYLOAD_HEADER_SIZE)
        return sm_error_set(err, SM_ERR_FORMAT,
                            "payload truncated at byte %zu: the header needs %d bytes", len,
                            SM_PAYLOAD_HEADER_SIZE);
    h->version = get_u32(p + 8);
    if (h->version != SM_PAYLOAD_VERSION)
        return sm_error_set(err, SM_ERR_FORMAT,
                            "payload byte 8: unsupported version %lu (this reader knows "
                            "version %u)",
                            (unsigned long)h->version, SM_PAYLOAD_VERSION);
    uint32_t stored = get_u32(p + 32), computed = crc_update(0, p, 32);
    if (stored != computed)
        return sm_error_set(err, SM_ERR_FORMAT,
                            "payload byte 32: header CRC32 mismatch (stored 0x%08lx, "
                            "computed 0x%08lx over bytes 0-31): header corrupted",
                            (unsigned long)stored, (unsigned long)computed);
    h->dim = get_u32(p + 12);
    h->nverts = get_u32(p + 16);
    h->nelems = get_u32(p + 20);
    h->nfacets = get_u32(p + 24);
    h->flags = get_u32(p + 28);
    if (h->dim != 2 && h->dim != 3)
        return sm_error_set(err, SM_ERR_FORMAT, "payload byte 12: dimension %lu is not 2 or 3",
                            (unsigned long)h->dim);
    const struct {
        uint32_t value;
        int offset;
        const char *name;
    } counts[] = {{h->nverts, 16, "vertex"}, {h->nelems, 20, "element"},
                  {h->nfacets, 24, "facet"}};
    for (int i = 0; i < 3; i++)
        if (counts[i].value > SM_MAX_ENTITIES)
            return sm_error_set(err, SM_ERR_FORMAT,
                                "payload byte %d: %s count %lu exceeds the limit %d",
                                counts[i].offset, counts[i].name,
                                (unsigned long)counts[i].value, SM_MAX_ENTITIES);
    if (h->flags & ~SM_PAYLOAD_KNOWN_FLAGS)
        return sm_error_set(err, SM_ERR_FORMAT,
                            "payload byte 28: unknown flag bits 0x%08lx (known: 0x%x)",
                            (unsigned long)(h->flags & ~SM_PAYLOAD_KNOWN_FLAGS),
                            SM_PAYLOAD_KNOWN_FLAGS);
    if (get_u32(p + 36) != 0)
        return sm_error_set(err, SM_ERR_FORMAT, "payload byte 36: reserved field must be 0");
    layout L;
    make_layout(h->dim, h->nverts, h->nelems, h->nfacets, h->flags, &L);
    h->total_size = L.total;
    return SM_OK;
}

static sm_status check_padding(const unsigned char *p, uint64_t from, uint64_t to,
                               const char *after, sm_error *err)
{
    for (uint64_t i = from; i < to; i++)
        if (p[i] != 0)
            return sm_error_set(err, SM_ERR_FORMAT,
                                "payload byte %llu: padding after %s must be zero",
                                (unsigned long long)i, after);
    return SM_OK;
}

static sm_status read_doubles(const unsigned char *p, uint64_t offset, uint64_t n,
                              const char *what, double *out, sm_error *err)
{
    for (uint64_t i = 0; i < n; i++) {
        double x = get_f64(p + offset + 8 * i);
        if (!isfinite(x))
            return sm_error_set(err, SM_ERR_FORMAT,
                                "payload byte %llu: %s value %llu is not finite",
                                (unsigned long long)(offset + 8 * i), what,
                                (unsigned long long)i);
        out[i] = x;
    }
    return SM_OK;
}

static sm_status read_indices(const unsigned char *p, uint64_t offset, uint64_t n,
                              uint32_t per, uint32_t nverts, const char *what, int32_t *out,
                              sm_error *err)
{
    for (uint64_t i = 0; i < n; i++) {
        uint32_t v = get_u32(p + offset + 4 * i);
        if (v >= nverts)
            return sm_error_set(err, SM_ERR_FORMAT,
                                "payload byte %llu: %s %llu vertex %llu is index %lu, not < "
                                "nverts %lu",
                                (unsigned long long)(offset + 4 * i), what,
                                (unsigned long long)(i / per), (unsigned long long)(i % per),
                                (unsigned long)v, (unsigned long)nverts);
        out[i] = (int32_t)v;
    }
    return SM_OK;
}

static void read_refs(const unsigned char *p, uint64_t offset, uint64_t n, int32_t *out)
{
    for (uint64_t i = 0; i < n; i++) {
        uint32_t u = get_u32(p + offset + 4 * i);
        int32_t r;
        memcpy(&r, &u, sizeof r); /* two's complement reinterpretation */
        out[i] = r;
    }
}

void sm_payload_free(sm_payload *p)
{
    if (!p)
        return;
    sm_mesh_free(p->mesh);
    free(p->displacement);
    free(p->distance);
    free(p);
}

sm_status sm_payload_decode(const void *buf, size_t len, sm_payload **out, sm_error *err)
{
    const unsigned char *p = buf;
    sm_payload_header h;
    *out = NULL;
    if (!buf && len)
        return sm_error_set(err, SM_ERR_INVALID, "payload: no buffer");
    sm_status st = sm_payload_parse_header(buf, len, &h, err);
    if (st != SM_OK)
        return st;
    if ((uint64_t)len < h.total_size)
        return sm_error_set(err, SM_ERR_FORMAT,
                            "payload truncated: %zu bytes, but the header (dimension %lu, %lu "
                            "vertices, %lu elements, %lu facets, flags 0x%lx) needs %llu",
                            len, (unsigned long)h.dim, (unsigned long)h.nverts,
                            (unsigned long)h.nelems, (unsigned long)h.nfacets,
                            (unsigned long)h.flags, (unsigned long long)h.total_size);
    if ((uint64_t)len > h.total_size)
        return sm_error_set(err, SM_ERR_FORMAT,
                            "payload byte %llu: %llu unexpected bytes after the trailer",
                            (unsigned long long)h.total_size,
                            (unsigned long long)(len - h.total_size));
    layout L;
    make_layout(h.dim, h.nverts, h.nelems, h.nfacets, h.flags, &L);
    uint32_t stored = get_u32(p + L.body_end), computed = crc_update(0, p, (size_t)L.body_end);
    if (stored != computed)
        return sm_error_set(err, SM_ERR_FORMAT,
                            "payload byte %llu: CRC32 mismatch (stored 0x%08lx, computed "
                            "0x%08lx over bytes 0-%llu): payload corrupted",
                            (unsigned long long)L.body_end, (unsigned long)stored,
                            (unsigned long)computed, (unsigned long long)(L.body_end - 1));
    /* padding between arrays (bytes after each array up to the next start) */
    uint64_t prev_end = SM_PAYLOAD_HEADER_SIZE;
    const char *prev_name = "the header";
    for (int a = 0; a < A_COUNT; a++) {
        if (!L.offset[a])
            continue;
        if ((st = check_padding(p, prev_end, L.offset[a], prev_name, err)))
            return st;
        prev_end = L.offset[a] + L.bytes[a];
        prev_name = array_names[a];
    }
    if ((st = check_padding(p, prev_end, L.body_end, prev_name, err)))
        return st;

    sm_payload *pl = calloc(1, sizeof *pl);
    if (!pl)
        return sm_error_set(err, SM_ERR_NOMEM, "payload: out of memory");
    st = sm_mesh_alloc(&pl->mesh, (int)h.dim, (int32_t)h.nverts, (int32_t)h.nelems,
                       (int32_t)h.nfacets, err);
    const uint64_t nv = h.nverts, d = h.dim;
    if (st == SM_OK && (h.flags & SM_PAYLOAD_HAS_DISPLACEMENT) &&
        !(pl->displacement = malloc((size_t)(nv > 0 ? nv * d : 1) * sizeof(double))))
        st = sm_error_set(err, SM_ERR_NOMEM, "payload: out of memory for the displacement");
    if (st == SM_OK && (h.flags & SM_PAYLOAD_HAS_DISTANCE) &&
        !(pl->distance = malloc((size_t)(nv ? nv : 1) * sizeof(double))))
        st = sm_error_set(err, SM_ERR_NOMEM, "payload: out of memory for the distance");
    sm_mesh *m = pl->mesh;
    if (st == SM_OK) {
        (void)((st = read_doubles(p, L.offset[A_COORDS], nv * d, "coordinate", m->coords,
                                  err)) ||
               (st = read_indices(p, L.offset[A_ELEMS], (uint64_t)h.nelems * (d + 1),
                                  (uint32_t)d + 1, h.nverts, "element", m->elems, err)) ||
               (st = read_indices(p, L.offset[A_FACETS], (uint64_t)h.nfacets * d, (uint32_t)d,
                                  h.nverts, "facet", m->facets, err)) ||
               (pl->displacement && (st = read_doubles(p, L.offset[A_DISP], nv * d,
                                                       "displacement", pl->displacement,
                                                       err))) ||
               (pl->distance &&
                (st = read_doubles(p, L.offset[A_DIST], nv, "distance", pl->distance, err))));
    }
    if (st != SM_OK) {
        sm_payload_free(pl);
        return st;
    }
    read_refs(p, L.offset[A_VREFS], nv, m->vert_refs);
    read_refs(p, L.offset[A_EREFS], h.nelems, m->elem_refs);
    read_refs(p, L.offset[A_FREFS], h.nfacets, m->facet_refs);
    *out = pl;
    return SM_OK;
}

sm_status sm_payload_read(FILE *f, uint64_t max_bytes, sm_payload **out, sm_error *err)
{
    unsigned char head[SM_PAYLOAD_HEADER_SIZE];
    sm_payload_header h;
    *out = NULL;
    if (max_bytes == 0)
        max_bytes = SM_PAYLOAD_DEFAULT_MAX_BYTES;
    size_t got = fread(head, 1, sizeof head, f);
    if (got < sizeof head && ferror(f))
        return sm_error_set(err, SM_ERR_IO, "payload: read error: %s", strerror(errno));
    sm_status st = sm_payload_parse_header(head, got, &h, err);
    if (st != SM_OK)
        return st;
    if (h.total_size > max_bytes || h.total_size > SIZE_MAX)
        return sm_error_set(err, SM_ERR_NOMEM,
                            "payload: the header announces %llu bytes, more than the limit of "
                            "%llu",
                            (unsigned long long)h.total_size, (unsigned long long)max_bytes);
    unsigned char *buf = malloc((size_t)h.total_size);
    if (!buf)
        return sm_error_set(err, SM_ERR_NOMEM, "payload: out of memory for %llu bytes",
                            (unsigned long long)h.total_size);
    memcpy(buf, head, sizeof head);
    size_t want = (size_t)h.total_size - sizeof head;
    size_t body = fread(buf + sizeof head, 1, want, f);
    if (body < want) {
        int io = ferror(f);
        free(buf);
        if (io)
            return sm_error_set(err, SM_ERR_IO, "payload: read error at byte %llu: %s",
                                (unsigned long long)(sizeof head + body), strerror(errno));
        return sm_error_set(err, SM_ERR_FORMAT,
                            "payload truncated at byte %llu: the header announces %llu bytes",
                            (unsigned long long)(sizeof head + body),
                            (unsigned long long)h.total_size);
    }
    st = sm_payload_decode(buf, (size_t)h.total_size, out, err);
    free(buf);
    return st;
}

sm_status sm_payload_read_file(const char *path, uint64_t max_bytes, sm_payload **out,
                               sm_error *err)
{
    *out = NULL;
    FILE *f = fopen(path, "rb");
    if (!f)
        return sm_error_set(err, SM_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    sm_status st = sm_payload_read(f, max_bytes, out, err);
    if (st == SM_OK && fgetc(f) != EOF) {
        long at = ftell(f);
        sm_payload_free(*out);
        *out = NULL;
        st = sm_error_set(err, SM_ERR_FORMAT,
                          "payload byte %ld: unexpected bytes after the trailer", at - 1);
    }
    fclose(f);
    if (st != SM_OK)
        sm_error_prefix(err, "%s", path);
    return st;
}
