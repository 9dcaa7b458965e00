/* The binary mesh payload: exact round trips (2D/3D, optional fields,
 * empty meshes, memory and FILE writers), a golden file written by an
 * independent implementation of proto/PAYLOAD.md, and a corpus of
 * corrupt payloads that must each fail with a clear message (plus every
 * truncation and every single-byte corruption of a small payload). */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <zlib.h>

#include "sm_payload.h"

static uint64_t next_u64(uint64_t *s)
{
    *s ^= *s >> 12;
    *s ^= *s << 25;
    *s ^= *s >> 27;
    return *s * 2685821657736338717ULL;
}

/* n x n (x n) grid of the unit square/cube split into simplices, with its
 * boundary facets; coordinates jittered with awkward doubles and refs
 * random (negative ones included), so a round trip has something to lose. */
static sm_mesh *grid_mesh(int dim, int n, uint64_t *seed)
{
    sm_mesh *m = NULL;
    int32_t nv = dim == 2 ? (n + 1) * (n + 1) : (n + 1) * (n + 1) * (n + 1);
    int32_t ne = dim == 2 ? 2 * n * n : 6 * n * n * n;
    int32_t nf = dim == 2 ? 4 * n : 12 * n * n;
    sm_error err = {0};
    if (sm_mesh_alloc(&m, dim, nv, ne, nf, &err) != SM_OK)
        fail_msg("%s", err.msg);
#define V2(i, j) ((j) * (n + 1) + (i))
#define V3(i, j, k) (((k) * (n + 1) + (j)) * (n + 1) + (i))
    for (int32_t v = 0; v < nv; v++) {
        int32_t i = v % (n + 1), j = (v / (n + 1)) % (n + 1), k = v / ((n + 1) * (n + 1));
        double x[3] = {(double)i / n, (double)j / n, (double)k / n};
        for (int c = 0; c < dim; c++) {
            double jitter = ((double)(next_u64(seed) >> 11) / 9007199254740992.0 - 0.5) * 1e-3;
            m->coords[(size_t)v * (size_t)dim + (size_t)c] = x[c] + jitter;
        }
        m->vert_refs[v] = (int32_t)(uint32_t)next_u64(seed);
    }
    m->coords[0] = -0.0;
    m->coords[1] = 1e-310; /* subnormal */
    int32_t e = 0, f = 0;
    if (dim == 2) {
        for (int j = 0; j < n; j++)
            for (int i = 0; i < n; i++) {
                int32_t a = V2(i, j), b = V2(i + 1, j), c = V2(i + 1, j + 1), d = V2(i, j + 1);
                int32_t t[6] = {a, b, c, a, c, d};
                memcpy(m->elems + 3 * e, t, sizeof t);
                e += 2;
            }
        for (int i = 0; i < n; i++) {
            int32_t s[8] = {V2(i, 0), V2(i + 1, 0), V2(n, i), V2(n, i + 1),
                            V2(i + 1, n), V2(i, n), V2(0, i + 1), V2(0, i)};
            memcpy(m->facets + 2 * f, s, sizeof s);
            f += 4;
        }
    } else {
        for (int k = 0; k < n; k++)
            for (int j = 0; j < n; j++)
                for (int i = 0; i < n; i++) {
                    int32_t c[8];
                    for (int q = 0; q < 8; q++)
                        c[q] = V3(i + (q & 1), j + ((q >> 1) & 1), k + ((q >> 2) & 1));
                    /* 6 tetrahedra around the diagonal c0-c7 */
                    static const int tets[6][4] = {{0, 1, 3, 7}, {0, 3, 2, 7}, {0, 2, 6, 7},
                                                   {0, 6, 4, 7}, {0, 4, 5, 7}, {0, 5, 1, 7}};
                    for (int t = 0; t < 6; t++, e++)
                        for (int q = 0; q < 4; q++)
                            m->elems[4 * e + q] = c[tets[t][q]];
                }
        for (int a = 0; a < n; a++)
            for (int b = 0; b < n; b++) {
                int32_t quads[6][4] = {
                    {V3(a, b, 0), V3(a + 1, b, 0), V3(a + 1, b + 1, 0), V3(a, b + 1, 0)},
                    {V3(a, b, n), V3(a + 1, b, n), V3(a + 1, b + 1, n), V3(a, b + 1, n)},
                    {V3(a, 0, b), V3(a + 1, 0, b), V3(a + 1, 0, b + 1), V3(a, 0, b + 1)},
                    {V3(a, n, b), V3(a + 1, n, b), V3(a + 1, n, b + 1), V3(a, n, b + 1)},
                    {V3(0, a, b), V3(0, a + 1, b), V3(0, a + 1, b + 1), V3(0, a, b + 1)},
                    {V3(n, a, b), V3(n, a + 1, b), V3(n, a + 1, b + 1), V3(n, a, b + 1)}};
                for (int s = 0; s < 6; s++) {
                    int32_t tri[6] = {quads[s][0], quads[s][1], quads[s][2],
                                      quads[s][0], quads[s][2], quads[s][3]};
                    memcpy(m->facets + 3 * f, tri, sizeof tri);
                    f += 2;
                }
            }
    }
#undef V2
#undef V3
    assert_int_equal(e, ne);
    assert_int_equal(f, nf);
    for (int32_t i = 0; i < ne; i++)
        m->elem_refs[i] = (int32_t)(next_u64(seed) % 7) - 3;
    for (int32_t i = 0; i < nf; i++)
        m->facet_refs[i] = (int32_t)(next_u64(seed) % 100000);
    return m;
}

static void assert_bytes_equal(const void *a, const void *b, size_t n)
{
    assert_true(memcmp(a, b, n) == 0);
}

static void assert_same_mesh(const sm_mesh *m, const double *coords, const sm_mesh *r)
{
    assert_int_equal(m->dim, r->dim);
    assert_int_equal(m->nverts, r->nverts);
    assert_int_equal(m->nelems, r->nelems);
    assert_int_equal(m->nfacets, r->nfacets);
    size_t d = (size_t)m->dim;
    /* bitwise: -0.0 and subnormals survive */
    assert_bytes_equal(coords, r->coords, (size_t)m->nverts * d * sizeof(double));
    assert_bytes_equal(m->vert_refs, r->vert_refs, (size_t)m->nverts * sizeof(int32_t));
    assert_bytes_equal(m->elems, r->elems, (size_t)m->nelems * (d + 1) * sizeof(int32_t));
    assert_bytes_equal(m->elem_refs, r->elem_refs, (size_t)m->nelems * sizeof(int32_t));
    assert_bytes_equal(m->facets, r->facets, (size_t)m->nfacets * d * sizeof(int32_t));
    assert_bytes_equal(m->facet_refs, r->facet_refs, (size_t)m->nfacets * sizeof(int32_t));
}

static void round_trip(const sm_mesh *m, const double *coords, const double *disp,
                       const double *dist)
{
    unsigned char *buf;
    size_t len;
    sm_error err = {0};
    uint32_t flags = (disp ? SM_PAYLOAD_HAS_DISPLACEMENT : 0) | (dist ? SM_PAYLOAD_HAS_DISTANCE : 0);
    if (sm_payload_encode(m, coords, disp, dist, &buf, &len, &err) != SM_OK)
        fail_msg("encode: %s", err.msg);
    assert_true(len == sm_payload_size(m->dim, m->nverts, m->nelems, m->nfacets, flags));
    assert_int_equal(len % 4, 0);

    sm_payload *p;
    if (sm_payload_decode(buf, len, &p, &err) != SM_OK)
        fail_msg("decode: %s", err.msg);
    assert_same_mesh(m, coords ? coords : m->coords, p->mesh);
    size_t nv = (size_t)m->nverts, d = (size_t)m->dim;
    if (disp) {
        assert_non_null(p->displacement);
        assert_bytes_equal(disp, p->displacement, nv * d * sizeof(double));
    } else {
        assert_null(p->displacement);
    }
    if (dist) {
        assert_non_null(p->distance);
        assert_bytes_equal(dist, p->distance, nv * sizeof(double));
    } else {
        assert_null(p->distance);
    }
    sm_payload_free(p);

    /* the streamed writer produces the same bytes */
    char *mem = NULL;
    size_t memlen = 0;
    FILE *f = open_memstream(&mem, &memlen);
    assert_non_null(f);
    assert_int_equal(sm_payload_write(f, m, coords, disp, dist, &err), SM_OK);
    fclose(f);
    assert_int_equal(memlen, len);
    assert_bytes_equal(mem, buf, len);
    free(mem);

    /* and the FILE reader reads it back */
    f = fmemopen(buf, len, "rb");
    assert_non_null(f);
    assert_int_equal(sm_payload_read(f, 0, &p, &err), SM_OK);
    fclose(f);
    assert_same_mesh(m, coords ? coords : m->coords, p->mesh);
    sm_payload_free(p);
    free(buf);
}

static void test_round_trip_2d_3d(void **state)
{
    (void)state;
    uint64_t seed = 12345;
    for (int dim = 2; dim <= 3; dim++) {
        sm_mesh *m = grid_mesh(dim, dim == 2 ? 40 : 8, &seed);
        size_t nv = (size_t)m->nverts, d = (size_t)dim;
        double *moved = malloc(nv * d * sizeof(double));
        double *disp = malloc(nv * d * sizeof(double));
        double *dist = malloc(nv * sizeof(double));
        assert_true(moved && disp && dist);
        for (size_t i = 0; i < nv * d; i++) {
            disp[i] = ((double)(next_u64(&seed) >> 11) - 4e15) * 1e-300;
            moved[i] = m->coords[i] + 0.1 * sin((double)i);
        }
        for (size_t i = 0; i < nv; i++)
            dist[i] = ((double)(next_u64(&seed) >> 11) / 9007199254740992.0 - 0.5) * 1e300;
        round_trip(m, NULL, NULL, NULL);
        round_trip(m, moved, NULL, NULL);
        round_trip(m, NULL, disp, NULL);
        round_trip(m, NULL, NULL, dist);
        round_trip(m, moved, disp, dist);
        print_message("%dD: %ld vertices, %ld elements, %ld facets -> %llu bytes with both fields\n",
                      dim, (long)m->nverts, (long)m->nelems, (long)m->nfacets,
                      (unsigned long long)sm_payload_size(dim, m->nverts, m->nelems, m->nfacets,
                                                          SM_PAYLOAD_KNOWN_FLAGS));
        free(moved);
        free(disp);
        free(dist);
        sm_mesh_free(m);
    }
}

static void test_empty_and_odd_counts(void **state)
{
    (void)state;
    sm_error err = {0};
    /* every combination of zero counts, odd counts (padding) */
    const int32_t sizes[][3] = {{0, 0, 0}, {1, 0, 0}, {3, 1, 0}, {3, 1, 3}, {5, 3, 1}};
    for (size_t s = 0; s < sizeof sizes / sizeof sizes[0]; s++)
        for (int dim = 2; dim <= 3; dim++) {
            sm_mesh *m;
            assert_int_equal(sm_mesh_alloc(&m, dim, sizes[s][0], sizes[s][1], sizes[s][2], &err),
                             SM_OK);
            for (int32_t i = 0; i < m->nverts * dim; i++)
                m->coords[i] = i * 0.5;
            for (int32_t i = 0; i < m->nverts; i++)
                m->vert_refs[i] = -i;
            for (int32_t i = 0; i < m->nelems * (dim + 1); i++)
                m->elems[i] = i % m->nverts;
            for (int32_t i = 0; i < m->nfacets * dim; i++)
                m->facets[i] = (i + 1) % m->nverts;
            double dist[5] = {1, 2, 3, 4, 5};
            round_trip(m, NULL, NULL, m->nverts ? dist : NULL);
            round_trip(m, NULL, m->coords, NULL);
            sm_mesh_free(m);
        }
    assert_true(sm_payload_size(2, 0, 0, 0, 0) == SM_PAYLOAD_HEADER_SIZE + SM_PAYLOAD_TRAILER_SIZE);
    assert_true(sm_payload_size(4, 1, 1, 1, 0) == 0);
    assert_true(sm_payload_size(2, -1, 1, 1, 0) == 0);
    assert_true(sm_payload_size(2, 1, 1, 1, 0x4) == 0);
    assert_true(sm_payload_size(3, SM_MAX_ENTITIES + 1, 0, 0, 0) == 0);
    /* 3 vertices 2D: 40 + 48 coords + 12(+4) refs + trailer */
    assert_true(sm_payload_size(2, 3, 0, 0, 0) == 40 + 48 + 16 + 4);
}

static void test_writer_refuses_bad_meshes(void **state)
{
    (void)state;
    uint64_t seed = 7;
    sm_error err = {0};
    unsigned char *buf;
    size_t len;
    sm_mesh *m = grid_mesh(2, 3, &seed);
    m->elems[5] = m->nverts;
    assert_int_equal(sm_payload_encode(m, NULL, NULL, NULL, &buf, &len, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "element entry 5 is vertex index 16"));
    assert_null(buf);
    m->elems[5] = 0;
    m->facets[0] = -1;
    assert_int_equal(sm_payload_encode(m, NULL, NULL, NULL, &buf, &len, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "facet entry 0"));
    m->facets[0] = 0;
    m->coords[3] = NAN;
    assert_int_equal(sm_payload_encode(m, NULL, NULL, NULL, &buf, &len, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "coordinate value 3 is not finite"));
    m->coords[3] = 0;
    double *dist = calloc((size_t)m->nverts, sizeof(double));
    dist[2] = -INFINITY;
    assert_int_equal(sm_payload_encode(m, NULL, NULL, dist, &buf, &len, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "distance value 2"));
    free(dist);
    m->dim = 4;
    assert_int_equal(sm_payload_encode(m, NULL, NULL, NULL, &buf, &len, &err), SM_ERR_INVALID);
    m->dim = 2;
    assert_int_equal(sm_payload_encode(NULL, NULL, NULL, NULL, &buf, &len, &err), SM_ERR_INVALID);

    /* a file that cannot be created; a write error (full device) */
    assert_int_equal(sm_payload_write_file("/nonexistent-dir/x.smmesh", m, NULL, NULL, NULL, &err),
                     SM_ERR_IO);
    assert_non_null(strstr(err.msg, "/nonexistent-dir/x.smmesh"));
    FILE *full = fopen("/dev/full", "wb");
    if (full) {
        assert_int_equal(sm_payload_write(full, m, NULL, NULL, NULL, &err), SM_ERR_IO);
        fclose(full);
    }
    sm_mesh_free(m);
}

/* ------------------------------------------------------------- golden */

static void test_golden_file(void **state)
{
    (void)state;
    char path[1024];
    const char *root = getenv("SM_ROOT");
    snprintf(path, sizeof path, "%s/tests/data/proto/payload/square2d.smmesh",
             root && *root ? root : ".");
    sm_payload *p;
    sm_error err = {0};
    if (sm_payload_read_file(path, 0, &p, &err) != SM_OK)
        fail_msg("%s", err.msg);
    sm_mesh *m = p->mesh;
    assert_int_equal(m->dim, 2);
    assert_int_equal(m->nverts, 4);
    assert_int_equal(m->nelems, 2);
    assert_int_equal(m->nfacets, 4);
    const double coords[] = {0, 0, 1, 0, 1, 1, 0, 1};
    const int32_t elems[] = {0, 1, 2, 0, 2, 3}, facets[] = {0, 1, 1, 2, 2, 3, 3, 0};
    const int32_t frefs[] = {1, 2, 3, -4};
    assert_bytes_equal(m->coords, coords, sizeof coords);
    assert_bytes_equal(m->elems, elems, sizeof elems);
    assert_bytes_equal(m->facets, facets, sizeof facets);
    assert_bytes_equal(m->facet_refs, frefs, sizeof frefs);
    assert_int_equal(m->elem_refs[1], 11);
    assert_int_equal(m->vert_refs[3], 4);
    assert_true(p->displacement[2] == 0.5 && p->displacement[5] == 0.5);
    assert_true(p->distance[0] == -0.25 && p->distance[3] == -1e-300);

    /* the C writer produces the same bytes as the independent script */
    unsigned char *buf;
    size_t len;
    assert_int_equal(sm_payload_encode(m, NULL, p->displacement, p->distance, &buf, &len, &err),
                     SM_OK);
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    unsigned char golden[512];
    size_t glen = fread(golden, 1, sizeof golden, f);
    fclose(f);
    assert_int_equal(glen, 300);
    assert_int_equal(len, glen);
    assert_bytes_equal(buf, golden, len);
    free(buf);
    sm_payload_free(p);

    /* read_file refuses trailing bytes, with the path in the message */
    char tmp[] = "/tmp/sm-payload-XXXXXX";
    int fd = mkstemp(tmp);
    assert_true(fd >= 0);
    f = fdopen(fd, "wb");
    fwrite(golden, 1, glen, f);
    fputc(0, f);
    fclose(f);
    assert_int_equal(sm_payload_read_file(tmp, 0, &p, &err), SM_ERR_FORMAT);
    assert_null(p);
    assert_non_null(strstr(err.msg, tmp));
    assert_non_null(strstr(err.msg, "byte 300: unexpected bytes after the trailer"));
    /* and a limit below the announced size */
    f = fopen(tmp, "wb");
    fwrite(golden, 1, glen, f);
    fclose(f);
    assert_int_equal(sm_payload_read_file(tmp, 299, &p, &err), SM_ERR_NOMEM);
    assert_non_null(strstr(err.msg, "more than the limit of 299"));
    assert_int_equal(sm_payload_read_file(tmp, 300, &p, &err), SM_OK);
    sm_payload_free(p);
    unlink(tmp);
    assert_int_equal(sm_payload_read_file("/nonexistent.smmesh", 0, &p, &err), SM_ERR_IO);
}

/* ------------------------------------------------------------ corruption */

static void put_u32(unsigned char *p, uint32_t v)
{
    for (int i = 0; i < 4; i++)
        p[i] = (unsigned char)(v >> (8 * i));
}
static void fix_header_crc(unsigned char *p) { put_u32(p + 32, (uint32_t)crc32(0, p, 32)); }
static void fix_body_crc(unsigned char *p, size_t len)
{
    put_u32(p + len - 4, (uint32_t)crc32(0, p, (uInt)(len - 4)));
}
static void put_f64(unsigned char *p, double x)
{
    uint64_t b;
    memcpy(&b, &x, 8);
    put_u32(p, (uint32_t)b);
    put_u32(p + 4, (uint32_t)(b >> 32));
}

/* The golden layout: 4 vertices 2D, 2 triangles, 4 edges, both fields. */
enum {
    OFF_COORDS = 40, OFF_VREFS = 104, OFF_ELEMS = 120, OFF_EREFS = 144, OFF_FACETS = 152,
    OFF_FREFS = 184, OFF_DISP = 200, OFF_DIST = 264, OFF_TRAILER = 296, GOLDEN_LEN = 300
};

typedef struct corrupt_case {
    const char *name;
    size_t len;                 /* bytes handed to the decoder */
    unsigned char data[GOLDEN_LEN + 16];
    const char *expect;         /* substring of the message */
} corrupt_case;

static void load_golden(unsigned char *out)
{
    sm_error err = {0};
    sm_payload *p;
    char path[1024];
    const char *root = getenv("SM_ROOT");
    snprintf(path, sizeof path, "%s/tests/data/proto/payload/square2d.smmesh",
             root && *root ? root : ".");
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    assert_int_equal(fread(out, 1, GOLDEN_LEN, f), GOLDEN_LEN);
    fclose(f);
    assert_int_equal(sm_payload_decode(out, GOLDEN_LEN, &p, &err), SM_OK);
    sm_payload_free(p);
}

static void test_corrupt_corpus(void **state)
{
    (void)state;
    unsigned char golden[GOLDEN_LEN];
    load_golden(golden);
    static corrupt_case cases[32];
    int n = 0;
#define NEW(nm, ex)                                                                               \
    (cases[n].name = (nm), cases[n].expect = (ex), cases[n].len = GOLDEN_LEN,                     \
     memcpy(cases[n].data, golden, GOLDEN_LEN), cases[n].data)
    unsigned char *d;

    d = NEW("empty", "payload is empty");
    cases[n++].len = 0;
    d = NEW("truncated header", "payload truncated at byte 20: the header needs 40 bytes");
    cases[n++].len = 20;
    d = NEW("bad magic", "payload byte 0: bad magic");
    d[3] = 'X';
    n++;
    d = NEW("not a payload at all (a Medit file)", "bad magic");
    memcpy(d, "MeshVersionFormatted 2\nDimension 2\n", 35);
    n++;
    d = NEW("bad version", "payload byte 8: unsupported version 2");
    put_u32(d + 8, 2);
    n++;
    d = NEW("header CRC mismatch", "payload byte 32: header CRC32 mismatch");
    d[16] ^= 1;
    n++;
    d = NEW("dimension 4", "payload byte 12: dimension 4 is not 2 or 3");
    put_u32(d + 12, 4);
    fix_header_crc(d);
    n++;
    d = NEW("vertex count over the limit", "payload byte 16: vertex count 4294967295 exceeds");
    put_u32(d + 16, 0xffffffffu);
    fix_header_crc(d);
    n++;
    d = NEW("unknown flag", "payload byte 28: unknown flag bits 0x00000004");
    put_u32(d + 28, 7);
    fix_header_crc(d);
    n++;
    d = NEW("reserved not zero", "payload byte 36: reserved field must be 0");
    d[36] = 1;
    n++;
    d = NEW("counts larger than the body", "payload truncated: 300 bytes, but the header");
    put_u32(d + 20, 1000); /* 1000 elements */
    fix_header_crc(d);
    n++;
    d = NEW("huge consistent counts", "200000000 vertices, 200000000 elements, 4 facets, flags 0x3) needs 12000000092");
    put_u32(d + 16, 200000000);
    put_u32(d + 20, 200000000);
    fix_header_crc(d);
    n++;
    d = NEW("truncated body", "payload truncated: 150 bytes");
    cases[n++].len = 150;
    d = NEW("truncated trailer", "payload truncated: 298 bytes");
    cases[n++].len = 298;
    d = NEW("trailing bytes", "payload byte 300: 8 unexpected bytes after the trailer");
    cases[n++].len = GOLDEN_LEN + 8;
    d = NEW("body CRC mismatch", "payload byte 296: CRC32 mismatch");
    d[OFF_COORDS + 13] ^= 0x40;
    n++;
    d = NEW("flags lack a field the body has", "payload byte 268: 32 unexpected bytes after the trailer");
    put_u32(d + 28, 1); /* drop the distance flag: the body is 32 bytes too long */
    fix_header_crc(d);
    n++;
    d = NEW("element index out of range", "payload byte 136: element 1 vertex 1 is index 4, not < nverts 4");
    put_u32(d + OFF_ELEMS + 16, 4);
    fix_body_crc(d, GOLDEN_LEN);
    n++;
    d = NEW("negative element index", "is index 4294967295");
    put_u32(d + OFF_ELEMS, 0xffffffffu);
    fix_body_crc(d, GOLDEN_LEN);
    n++;
    d = NEW("facet index out of range", "payload byte 180: facet 3 vertex 1 is index 9");
    put_u32(d + OFF_FACETS + 28, 9);
    fix_body_crc(d, GOLDEN_LEN);
    n++;
    d = NEW("NaN coordinate", "payload byte 80: coordinate value 5 is not finite");
    put_f64(d + OFF_COORDS + 40, NAN);
    fix_body_crc(d, GOLDEN_LEN);
    n++;
    d = NEW("infinite displacement", "payload byte 208: displacement value 1 is not finite");
    put_f64(d + OFF_DISP + 8, -INFINITY);
    fix_body_crc(d, GOLDEN_LEN);
    n++;
    d = NEW("NaN distance", "payload byte 288: distance value 3 is not finite");
    put_f64(d + OFF_DIST + 24, NAN);
    fix_body_crc(d, GOLDEN_LEN);
    n++;
#undef NEW
    /* the golden payload happens to need no padding: use 3 vertices, whose
     * vert_refs (12 bytes at 88..99) are padded to 104 */
    {
        sm_mesh *m;
        sm_error err = {0};
        assert_int_equal(sm_mesh_alloc(&m, 2, 3, 1, 0, &err), SM_OK);
        m->elems[0] = 0, m->elems[1] = 1, m->elems[2] = 2;
        unsigned char *buf;
        size_t len;
        assert_int_equal(sm_payload_encode(m, NULL, NULL, NULL, &buf, &len, &err), SM_OK);
        sm_mesh_free(m);
        assert_true(len <= sizeof cases[0].data);
        corrupt_case *c = &cases[n++];
        c->name = "padding not zero";
        c->expect = "payload byte 101: padding after vert_refs must be zero";
        c->len = len;
        memcpy(c->data, buf, len);
        c->data[101] = 0xAA;
        fix_body_crc(c->data, len);
        free(buf);
    }

    for (int i = 0; i < n; i++) {
        sm_payload *p = (sm_payload *)1;
        sm_error err = {0};
        sm_status st = sm_payload_decode(cases[i].data, cases[i].len, &p, &err);
        if (st != SM_ERR_FORMAT)
            fail_msg("case \"%s\": status %d (%s)", cases[i].name, (int)st, err.msg);
        assert_null(p);
        if (!strstr(err.msg, cases[i].expect))
            fail_msg("case \"%s\": message \"%s\" lacks \"%s\"", cases[i].name, err.msg,
                     cases[i].expect);
        /* the FILE reader agrees (or stops earlier, at the announced size) */
        if (cases[i].len > 0) {
            FILE *f = fmemopen(cases[i].data, cases[i].len, "rb");
            assert_non_null(f);
            st = sm_payload_read(f, 1 << 20, &p, &err);
            fclose(f);
            /* a stream may go on after a payload: the FILE reader stops at
             * the trailer (sm_payload_read_file refuses the extra bytes) */
            int stream_ok = strcmp(cases[i].name, "trailing bytes") == 0;
            if ((st == SM_OK) != stream_ok)
                fail_msg("case \"%s\": FILE reader status %d", cases[i].name, (int)st);
            if (st == SM_OK)
                sm_payload_free(p);
            else
                assert_null(p);
        }
    }
    print_message("%d corrupt payloads rejected with the expected message\n", n);
    assert_true(n >= 10);
}

/* Every truncation and every single-byte change of the golden payload is
 * rejected (CRC32 detects all of them); no change crashes the reader. */
static void test_exhaustive_small_corruptions(void **state)
{
    (void)state;
    unsigned char golden[GOLDEN_LEN], work[GOLDEN_LEN];
    load_golden(golden);
    sm_error err = {0};
    sm_payload *p;
    int rejected = 0;
    for (size_t len = 0; len < GOLDEN_LEN; len++) {
        unsigned char *copy = malloc(len ? len : 1); /* exact size: ASan sees overreads */
        memcpy(copy, golden, len);
        assert_int_not_equal(sm_payload_decode(copy, len, &p, &err), SM_OK);
        free(copy);
        rejected++;
    }
    static const unsigned char deltas[] = {0x01, 0x80, 0xff, 0x55};
    for (size_t at = 0; at < GOLDEN_LEN; at++)
        for (size_t k = 0; k < sizeof deltas; k++) {
            memcpy(work, golden, GOLDEN_LEN);
            work[at] ^= deltas[k];
            if (sm_payload_decode(work, GOLDEN_LEN, &p, &err) == SM_OK)
                fail_msg("byte %zu ^ 0x%02x accepted", at, deltas[k]);
            rejected++;
        }
    /* with both CRCs recomputed, structural checks alone must hold the
     * line: decode either succeeds with in-range data or fails cleanly */
    uint64_t seed = 99;
    int structural = 0, accepted = 0;
    for (int trial = 0; trial < 20000; trial++) {
        memcpy(work, golden, GOLDEN_LEN);
        int flips = 1 + (int)(next_u64(&seed) % 4);
        for (int k = 0; k < flips; k++)
            work[next_u64(&seed) % GOLDEN_LEN] ^= (unsigned char)(1u << (next_u64(&seed) % 8));
        fix_header_crc(work);
        fix_body_crc(work, GOLDEN_LEN);
        if (sm_payload_decode(work, GOLDEN_LEN, &p, &err) == SM_OK) {
            sm_mesh *m = p->mesh;
            for (int32_t i = 0; i < m->nelems * (m->dim + 1); i++)
                assert_true(m->elems[i] >= 0 && m->elems[i] < m->nverts);
            for (int32_t i = 0; i < m->nverts * m->dim; i++)
                assert_true(isfinite(m->coords[i]));
            sm_payload_free(p);
            accepted++;
        } else {
            structural++;
        }
    }
    print_message("%d truncations/byte changes rejected; with CRCs fixed: %d rejected, %d "
                  "accepted as valid data\n",
                  rejected, structural, accepted);
    assert_true(structural > 0 && accepted > 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_round_trip_2d_3d),
        cmocka_unit_test(test_empty_and_odd_counts),
        cmocka_unit_test(test_writer_refuses_bad_meshes),
        cmocka_unit_test(test_golden_file),
        cmocka_unit_test(test_corrupt_corpus),
        cmocka_unit_test(test_exhaustive_small_corruptions),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
