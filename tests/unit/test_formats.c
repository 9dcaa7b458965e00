/* File formats: exact round trips through every Medit variant (ASCII,
 * binary, gzip), binary files crafted byte by byte in libMeshb versions
 * 1-4 and both byte orders, real Gmsh output, the .vtu writer (read back
 * and checked), and write failures (ENOSPC, missing directory). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <dirent.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "shapematch/sm_io.h"

/* ------------------------------------------------------------------ */
/* helpers                                                             */
/* ------------------------------------------------------------------ */

typedef struct fixture {
    char dir[256];
} fixture;

static int setup_dir(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    if (!f)
        return -1;
    snprintf(f->dir, sizeof f->dir, "/tmp/sm_formats_XXXXXX");
    if (!mkdtemp(f->dir)) {
        free(f);
        return -1;
    }
    *state = f;
    return 0;
}

static int teardown_dir(void **state)
{
    fixture *f = *state;
    DIR *d = opendir(f->dir);
    if (d) {
        struct dirent *e;
        while ((e = readdir(d)) != NULL) {
            if (e->d_name[0] == '.')
                continue;
            char p[600];
            snprintf(p, sizeof p, "%s/%s", f->dir, e->d_name);
            unlink(p);
        }
        closedir(d);
    }
    rmdir(f->dir);
    free(f);
    return 0;
}

static void path_in(const fixture *f, const char *name, char *out, size_t cap)
{
    snprintf(out, cap, "%s/%s", f->dir, name);
}

static void write_file(const char *path, const void *data, size_t n)
{
    FILE *fp = fopen(path, "wb");
    assert_non_null(fp);
    assert_int_equal(fwrite(data, 1, n, fp), n);
    assert_int_equal(fclose(fp), 0);
}

static const char *data_path(const char *rel, char *out, size_t cap)
{
    const char *root = getenv("SM_ROOT");
    snprintf(out, cap, "%s/tests/data/%s", root && *root ? root : ".", rel);
    return out;
}

/* Values that need all 17 digits to round-trip, and references of every
 * sign, so that any loss in a writer or reader shows. */
static double awkward(int i, int j)
{
    return sqrt(2.0 + i) / (3.0 + j) + 1e-13 * i - (j == 1 ? 1.0 / 3.0 : 0.0);
}

/* A structured grid of n^dim cells split into simplices: triangles in 2D
 * (2 per square), tetrahedra in 3D (6 per cube, Kuhn split); facets are
 * a few hand-picked simplices with references. */
static sm_mesh *grid_mesh(int dim, int n)
{
    int np = n + 1;
    int32_t nv = dim == 2 ? np * np : np * np * np;
    int32_t ne = dim == 2 ? 2 * n * n : 6 * n * n * n;
    int32_t nf = 3;
    sm_mesh *m;
    sm_error err;
    assert_int_equal(sm_mesh_alloc(&m, dim, nv, ne, nf, &err), SM_OK);
    for (int32_t v = 0; v < nv; v++) {
        int ix = v % np, iy = (v / np) % np, iz = v / (np * np);
        m->coords[dim * v] = ix + awkward(v, 0) * 1e-3;
        m->coords[dim * v + 1] = iy + awkward(v, 1) * 1e-3;
        if (dim == 3)
            m->coords[dim * v + 2] = iz - awkward(v, 2) * 1e-3;
        m->vert_refs[v] = (v % 5) - 2;
    }
    int32_t e = 0;
    if (dim == 2) {
        for (int j = 0; j < n; j++)
            for (int i = 0; i < n; i++) {
                int32_t a = j * np + i, b = a + 1, c = a + np + 1, d = a + np;
                int32_t t[6] = {a, b, c, a, c, d};
                memcpy(&m->elems[3 * e], t, sizeof t);
                m->elem_refs[e] = e % 3 == 0 ? 2147483647 : -e;
                m->elem_refs[e + 1] = 7;
                e += 2;
            }
        int32_t f[6] = {0, 1, 1, 2, np, 0};
        memcpy(m->facets, f, sizeof f);
    } else {
        static const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2},
                                        {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
        for (int k = 0; k < n; k++)
            for (int j = 0; j < n; j++)
                for (int i = 0; i < n; i++)
                    for (int p = 0; p < 6; p++) {
                        int c[3] = {i, j, k};
                        int32_t *t = &m->elems[4 * e];
                        t[0] = (c[2] * np + c[1]) * np + c[0];
                        for (int s = 0; s < 3; s++) {
                            c[perms[p][s]]++;
                            t[s + 1] = (c[2] * np + c[1]) * np + c[0];
                        }
                        m->elem_refs[e] = (e % 4) - 1;
                        e++;
                    }
        int32_t f[9] = {0, 1, np, 1, np + 1, np, 0, np, np * np};
        memcpy(m->facets, f, sizeof f);
    }
    for (int32_t i = 0; i < nf; i++)
        m->facet_refs[i] = 10 + i * 1000000;
    assert_int_equal(e, ne);
    return m;
}

static void assert_mesh_identical(const sm_mesh *a, const sm_mesh *b)
{
    assert_int_equal(a->dim, b->dim);
    assert_int_equal(a->nverts, b->nverts);
    assert_int_equal(a->nelems, b->nelems);
    assert_int_equal(a->nfacets, b->nfacets);
    /* bitwise: a round trip must not move any coordinate by one ulp */
    assert_memory_equal(a->coords, b->coords, (size_t)a->nverts * a->dim * sizeof(double));
    assert_memory_equal(a->vert_refs, b->vert_refs, (size_t)a->nverts * sizeof(int32_t));
    assert_memory_equal(a->elems, b->elems, (size_t)a->nelems * (a->dim + 1) * sizeof(int32_t));
    assert_memory_equal(a->elem_refs, b->elem_refs, (size_t)a->nelems * sizeof(int32_t));
    if (a->nfacets) {
        assert_memory_equal(a->facets, b->facets, (size_t)a->nfacets * a->dim * sizeof(int32_t));
        assert_memory_equal(a->facet_refs, b->facet_refs, (size_t)a->nfacets * sizeof(int32_t));
    }
}

static sm_mesh *read_ok(const char *path)
{
    sm_mesh *m = NULL;
    sm_error err;
    sm_error_clear(&err);
    sm_status st = sm_mesh_read(path, &m, &err);
    if (st != SM_OK)
        fail_msg("reading %s: %s", path, err.msg);
    return m;
}

static void write_ok(const char *path, const sm_mesh *m)
{
    sm_error err;
    sm_error_clear(&err);
    if (sm_mesh_write(path, m, &err) != SM_OK)
        fail_msg("writing %s: %s", path, err.msg);
}

static int no_temp_files_left(const fixture *f)
{
    DIR *d = opendir(f->dir);
    int clean = 1;
    struct dirent *e;
    while (d && (e = readdir(d)) != NULL)
        if (strstr(e->d_name, ".tmp-"))
            clean = 0;
    if (d)
        closedir(d);
    return clean;
}

/* ------------------------------------------------------------------ */
/* byte builder for crafted binary files                               */
/* ------------------------------------------------------------------ */

typedef struct bytes {
    unsigned char data[8192];
    size_t len;
    int swap;
} bytes;

static void put(bytes *b, const void *v, size_t n)
{
    assert_true(b->len + n <= sizeof b->data);
    const unsigned char *p = v;
    for (size_t i = 0; i < n; i++)
        b->data[b->len + i] = b->swap ? p[n - 1 - i] : p[i];
    b->len += n;
}

static void put_i32(bytes *b, int32_t v) { put(b, &v, 4); }
static void put_i64(bytes *b, int64_t v) { put(b, &v, 8); }
static void put_f32(bytes *b, float v) { put(b, &v, 4); }
static void put_f64(bytes *b, double v) { put(b, &v, 8); }

typedef struct layout {
    int version, swap;
} layout;

static void put_int(bytes *b, const layout *l, int64_t v)
{
    if (l->version == 4)
        put_i64(b, v);
    else
        put_i32(b, (int32_t)v);
}

static void put_real(bytes *b, const layout *l, double v)
{
    if (l->version == 1)
        put_f32(b, (float)v);
    else
        put_f64(b, v);
}

static void put_pos(bytes *b, const layout *l, int64_t pos)
{
    if (l->version >= 3)
        put_i64(b, pos);
    else
        put_i32(b, (int32_t)pos);
}

/* Appends keyword code + next position + body (built separately). */
static void put_keyword(bytes *b, const layout *l, int32_t code, const bytes *body)
{
    size_t pos_size = l->version >= 3 ? 8 : 4;
    put_i32(b, code);
    put_pos(b, l, (int64_t)(b->len + pos_size + body->len));
    assert_true(b->len + body->len <= sizeof b->data);
    memcpy(b->data + b->len, body->data, body->len);
    b->len += body->len;
}

static void put_header(bytes *b, const layout *l, int dim)
{
    put_i32(b, 1);
    put_i32(b, l->version);
    bytes body = {.swap = l->swap};
    put_i32(&body, dim); /* the Dimension value is 32-bit in every version */
    put_keyword(b, l, 3, &body);
}

static void put_end(bytes *b, const layout *l)
{
    put_i32(b, 54);
    put_pos(b, l, 0);
}

/* The two-triangle unit square with references, as a crafted meshb. */
static const double sq_xy[4][2] = {{0, 0}, {1.5, 0}, {1.5, 0.25}, {0, 0.25}};
static const int sq_tri[2][4] = {{1, 2, 3, 11}, {1, 3, 4, -12}};
static const int sq_edge[2][3] = {{1, 2, 21}, {3, 4, 22}};

static void craft_square(bytes *b, const layout *l)
{
    b->len = 0;
    b->swap = l->swap;
    put_header(b, l, 2);
    bytes body = {.swap = l->swap};
    put_int(&body, l, 4);
    for (int i = 0; i < 4; i++) {
        put_real(&body, l, sq_xy[i][0]);
        put_real(&body, l, sq_xy[i][1]);
        put_int(&body, l, 100 + i);
    }
    put_keyword(b, l, 4, &body);
    /* An unknown keyword (code 50, BoundingBox) and Corners must be
     * skipped through their next-keyword positions. */
    body.len = 0;
    for (int i = 0; i < 4; i++)
        put_real(&body, l, i);
    put_keyword(b, l, 50, &body);
    body.len = 0;
    put_int(&body, l, 2);
    put_int(&body, l, 1);
    put_int(&body, l, 3);
    put_keyword(b, l, 13, &body);
    body.len = 0;
    put_int(&body, l, 2);
    for (int i = 0; i < 2; i++)
        for (int j = 0; j < 3; j++)
            put_int(&body, l, sq_edge[i][j]);
    put_keyword(b, l, 5, &body);
    body.len = 0;
    put_int(&body, l, 2);
    for (int i = 0; i < 2; i++)
        for (int j = 0; j < 4; j++)
            put_int(&body, l, sq_tri[i][j]);
    put_keyword(b, l, 6, &body);
    put_end(b, l);
}

static void assert_is_square(const sm_mesh *m)
{
    assert_int_equal(m->dim, 2);
    assert_int_equal(m->nverts, 4);
    assert_int_equal(m->nelems, 2);
    assert_int_equal(m->nfacets, 2);
    for (int i = 0; i < 4; i++) {
        assert_true(m->coords[2 * i] == sq_xy[i][0]);
        assert_true(m->coords[2 * i + 1] == sq_xy[i][1]);
        assert_int_equal(m->vert_refs[i], 100 + i);
    }
    for (int e = 0; e < 2; e++) {
        for (int j = 0; j < 3; j++)
            assert_int_equal(m->elems[3 * e + j], sq_tri[e][j] - 1);
        assert_int_equal(m->elem_refs[e], sq_tri[e][3]);
        for (int j = 0; j < 2; j++)
            assert_int_equal(m->facets[2 * e + j], sq_edge[e][j] - 1);
        assert_int_equal(m->facet_refs[e], sq_edge[e][2]);
    }
}

/* ------------------------------------------------------------------ */
/* mesh tests                                                          */
/* ------------------------------------------------------------------ */

static void round_trip(void **state, int dim)
{
    fixture *f = *state;
    sm_mesh *orig = grid_mesh(dim, 3);
    const char *names[] = {"a.mesh", "a.meshb", "a.mesh.gz", "a.meshb.gz"};
    char path[600], path2[600];
    for (int i = 0; i < 4; i++) {
        path_in(f, names[i], path, sizeof path);
        write_ok(path, orig);
        sm_mesh *back = read_ok(path);
        assert_mesh_identical(orig, back);
        /* and on through every other format, chained */
        for (int j = 0; j < 4; j++) {
            char name2[32];
            snprintf(name2, sizeof name2, "b%d%d.%s", i, j, strchr(names[j], '.') + 1);
            path_in(f, name2, path2, sizeof path2);
            write_ok(path2, back);
            sm_mesh *again = read_ok(path2);
            assert_mesh_identical(orig, again);
            sm_mesh_free(again);
        }
        sm_mesh_free(back);
    }
    assert_true(no_temp_files_left(f));
    sm_mesh_free(orig);
}

static void test_round_trip_2d(void **state) { round_trip(state, 2); }
static void test_round_trip_3d(void **state) { round_trip(state, 3); }

static void test_write_coords(void **state)
{
    fixture *f = *state;
    sm_mesh *m = grid_mesh(2, 2);
    double *moved = malloc((size_t)m->nverts * 2 * sizeof(double));
    assert_non_null(moved);
    for (int32_t i = 0; i < 2 * m->nverts; i++)
        moved[i] = m->coords[i] * 3.0 + 0.1;
    char path[600];
    sm_error err;
    path_in(f, "moved.meshb", path, sizeof path);
    assert_int_equal(sm_mesh_write_coords(path, m, moved, &err), SM_OK);
    sm_mesh *back = read_ok(path);
    assert_memory_equal(back->coords, moved, (size_t)m->nverts * 2 * sizeof(double));
    assert_memory_equal(back->elems, m->elems, (size_t)m->nelems * 3 * sizeof(int32_t));
    sm_mesh_free(back);
    free(moved);
    sm_mesh_free(m);
}

static void test_meshb_versions_and_byte_orders(void **state)
{
    fixture *f = *state;
    char path[600];
    path_in(f, "crafted.meshb", path, sizeof path);
    bytes b;
    for (int version = 1; version <= 4; version++)
        for (int swap = 0; swap <= 1; swap++) {
            layout l = {version, swap};
            craft_square(&b, &l);
            write_file(path, b.data, b.len);
            sm_mesh *m = read_ok(path);
            assert_is_square(m);
            sm_mesh_free(m);
        }
    /* The same swapped v4 file, gzip-compressed by our own writer path:
     * compression and byte order are independent. */
    layout l = {4, 1};
    craft_square(&b, &l);
    write_file(path, b.data, b.len);
    sm_mesh *m = read_ok(path);
    char gz[600];
    path_in(f, "crafted.meshb.gz", gz, sizeof gz);
    write_ok(gz, m);
    sm_mesh *back = read_ok(gz);
    assert_is_square(back);
    sm_mesh_free(back);
    sm_mesh_free(m);
}

static void test_meshb_header_layout(void **state)
{
    /* What we write is what libMeshb writes for version 2: code 1,
     * version 2, Dimension keyword (3) whose next position is byte 20. */
    fixture *f = *state;
    sm_mesh *m = grid_mesh(2, 1);
    char path[600];
    path_in(f, "layout.meshb", path, sizeof path);
    write_ok(path, m);
    FILE *fp = fopen(path, "rb");
    assert_non_null(fp);
    int32_t w[8];
    assert_int_equal(fread(w, 4, 8, fp), 8);
    fclose(fp);
    assert_int_equal(w[0], 1);
    assert_int_equal(w[1], 2);
    assert_int_equal(w[2], 3);
    assert_int_equal(w[3], 20);
    assert_int_equal(w[4], 2);
    assert_int_equal(w[5], 4);                      /* Vertices */
    assert_int_equal(w[6], 20 + 12 + 4 * 20);       /* 4 vertices of 2 doubles + ref */
    assert_int_equal(w[7], 4);
    sm_mesh_free(m);
}

static void test_ascii_features(void **state)
{
    fixture *f = *state;
    /* Comments, keyword case, CRLF, Triangles before Vertices, sections
     * that are skipped, quoted strings, and no End keyword. */
    const char *text =
        "# written by hand\r\n"
        "meshversionformatted 1\r\n"
        "Identifier \"a square # not a comment\"\r\n"
        "DIMENSION\r\n  2 # two\r\n"
        "Geometry square.geom\r\n"
        "Triangles 2\r\n 1 2 3 11\r\n 1 3 4 -12\r\n"
        "Vertices # the points\r\n4\r\n"
        "0 0 100\r\n1.5 0 101\r\n1.5e0 .25 102\r\n0 2.5E-1 103\r\n"
        "Corners 2 1 3\r\nRidges 1 1\r\nRequiredVertices 1 2\r\n"
        "Normals 2 0 1 1 0\r\nNormalAtVertices 1 1 1\r\n"
        "Tangents 1 1 0\r\nTangentAtVertices 1 2 1\r\nAngleOfCornerBound 45\r\n"
        "Edges\r\n2\r\n1 2 21\r\n3 4 22\r\n";
    char path[600];
    path_in(f, "features.mesh", path, sizeof path);
    write_file(path, text, strlen(text));
    sm_mesh *m = read_ok(path);
    assert_is_square(m);
    sm_mesh_free(m);
}

static void test_planar_3d_reads_as_2d(void **state)
{
    fixture *f = *state;
    const char *text = "MeshVersionFormatted 2\nDimension 3\nVertices\n4\n"
                       "0 0 0 100\n1.5 0 0 101\n1.5 0.25 -0 102\n0 0.25 0 103\n"
                       "Edges\n2\n1 2 21\n3 4 22\n"
                       "Triangles\n2\n1 2 3 11\n1 3 4 -12\nEnd\n";
    char path[600];
    path_in(f, "planar.mesh", path, sizeof path);
    write_file(path, text, strlen(text));
    sm_mesh *m = read_ok(path);
    assert_is_square(m);
    /* written back as a 2D mesh */
    write_ok(path, m);
    FILE *fp = fopen(path, "r");
    char line[256];
    int dim = 0;
    while (fgets(line, sizeof line, fp))
        if (strncmp(line, "Dimension", 9) == 0)
            dim = atoi(line + 9);
    fclose(fp);
    assert_int_equal(dim, 2);
    sm_mesh_free(m);
}

/* Sum of |simplex measures|: exact for a mesh of the unit square/cube. */
static double total_measure(const sm_mesh *m)
{
    double sum = 0;
    for (int32_t e = 0; e < m->nelems; e++) {
        const int32_t *v = &m->elems[(m->dim + 1) * e];
        const double *x = m->coords;
        int d = m->dim;
        if (d == 2) {
            double ax = x[2 * v[1]] - x[2 * v[0]], ay = x[2 * v[1] + 1] - x[2 * v[0] + 1];
            double bx = x[2 * v[2]] - x[2 * v[0]], by = x[2 * v[2] + 1] - x[2 * v[0] + 1];
            sum += fabs(ax * by - ay * bx) / 2;
        } else {
            double a[3], b[3], c[3];
            for (int k = 0; k < 3; k++) {
                a[k] = x[3 * v[1] + k] - x[3 * v[0] + k];
                b[k] = x[3 * v[2] + k] - x[3 * v[0] + k];
                c[k] = x[3 * v[3] + k] - x[3 * v[0] + k];
            }
            sum += fabs(a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) +
                        a[2] * (b[0] * c[1] - b[1] * c[0])) /
                   6;
        }
    }
    return sum;
}

/* tests/data/formats/{square,cube}-gmsh.mesh were made from the .geo files next to
 * them by `gmsh -2|-3 X.geo -setnumber Mesh.SaveElementTagType 2 -o X.mesh`
 * (Gmsh 4.8), so references are the physical tags. */
static void test_gmsh_files(void **state)
{
    (void)state;
    char path[4096];
    /* Gmsh writes planar meshes with Dimension 3 and z = 0. */
    sm_mesh *sq = read_ok(data_path("formats/square-gmsh.mesh", path, sizeof path));
    assert_int_equal(sq->dim, 2);
    assert_int_equal(sq->nverts, 30);
    assert_int_equal(sq->nelems, 42);
    assert_int_equal(sq->nfacets, 16);
    assert_true(fabs(total_measure(sq) - 1.0) < 1e-12);
    for (int32_t e = 0; e < sq->nelems; e++)
        assert_int_equal(sq->elem_refs[e], 3); /* Physical Surface(3) */
    for (int32_t e = 0; e < sq->nfacets; e++)
        assert_int_equal(sq->facet_refs[e], 7); /* Physical Curve(7) */
    sm_mesh_free(sq);

    sm_mesh *cube = read_ok(data_path("formats/cube-gmsh.mesh", path, sizeof path));
    assert_int_equal(cube->dim, 3);
    assert_int_equal(cube->nverts, 45);
    assert_int_equal(cube->nelems, 101);
    assert_int_equal(cube->nfacets, 84);
    assert_true(fabs(total_measure(cube) - 1.0) < 1e-12);
    for (int32_t e = 0; e < cube->nfacets; e++)
        assert_int_equal(cube->facet_refs[e], 5); /* Physical Surface(5) */
    for (int32_t e = 0; e < cube->nelems; e++)
        assert_int_equal(cube->elem_refs[e], 2); /* Physical Volume(2) */
    sm_mesh_free(cube);
}

/* ------------------------------------------------------------------ */
/* solutions                                                           */
/* ------------------------------------------------------------------ */

static void test_sol_round_trips(void **state)
{
    fixture *f = *state;
    const char *names[] = {"s.sol", "s.solb", "s.sol.gz", "s.solb.gz"};
    for (int dim = 2; dim <= 3; dim++)
        for (int kind = 0; kind < 3; kind++) { /* scalar, vector, symmetric tensor */
            const int ncomp = kind == 0 ? 1 : kind == 1 ? dim : dim * (dim + 1) / 2;
            sm_sol *s;
            sm_error err;
            assert_int_equal(sm_sol_alloc(&s, dim, 57, ncomp, &err), SM_OK);
            for (int i = 0; i < 57 * ncomp; i++)
                s->values[i] = awkward(i, i % 3) * (i % 2 ? -1e-300 : 1e300) + (i == 5 ? 0 : 1);
            s->values[5] = -0.0;
            for (int k = 0; k < 4; k++) {
                char path[600];
                path_in(f, names[k], path, sizeof path);
                if (sm_sol_write(path, s, &err) != SM_OK)
                    fail_msg("%s", err.msg);
                sm_sol *back = NULL;
                if (sm_sol_read(path, &back, &err) != SM_OK)
                    fail_msg("%s", err.msg);
                assert_int_equal(back->dim, dim);
                assert_int_equal(back->ncomp, ncomp);
                assert_int_equal(back->nverts, 57);
                assert_memory_equal(back->values, s->values, 57 * ncomp * sizeof(double));
                sm_sol_free(back);
            }
            sm_sol_free(s);
        }
    assert_true(no_temp_files_left(f));
}

static void test_solb_versions_and_byte_orders(void **state)
{
    fixture *f = *state;
    char path[600];
    path_in(f, "crafted.solb", path, sizeof path);
    const double vals[6] = {0.5, -1.25, 3, 1024, -0.0625, 7};
    for (int version = 1; version <= 4; version++)
        for (int swap = 0; swap <= 1; swap++) {
            layout l = {version, swap};
            bytes b = {.swap = swap};
            put_header(&b, &l, 3);
            bytes body = {.swap = swap};
            put_int(&body, &l, 2);
            put_i32(&body, 1); /* one field: the type table is 32-bit */
            put_i32(&body, 2); /* vector */
            for (int i = 0; i < 6; i++)
                put_real(&body, &l, vals[i]);
            put_keyword(&b, &l, 62, &body);
            put_end(&b, &l);
            write_file(path, b.data, b.len);
            sm_sol *s = NULL;
            sm_error err;
            if (sm_sol_read(path, &s, &err) != SM_OK)
                fail_msg("version %d swap %d: %s", version, swap, err.msg);
            assert_int_equal(s->dim, 3);
            assert_int_equal(s->ncomp, 3);
            assert_int_equal(s->nverts, 2);
            for (int i = 0; i < 6; i++)
                assert_true(s->values[i] == vals[i]);
            sm_sol_free(s);
        }
}

static char *slurp(const char *path);

/* A symmetric tensor field (type 3) as Medit and Mmg write it: the lower
 * triangle row by row, xx xy yy xz yz zz; read in that order and written
 * back as type 3. */
static void test_sol_symmetric_tensor(void **state)
{
    fixture *f = *state;
    const char *text = "MeshVersionFormatted 2\nDimension 3\nSolAtVertices\n2\n1 3\n"
                       "1 2 3 4 5 6\n-1 0.5 2 0 0 7\nEnd\n";
    char path[600], out[600];
    path_in(f, "t.sol", path, sizeof path);
    path_in(f, "t-out.sol", out, sizeof out);
    write_file(path, text, strlen(text));
    sm_sol *s = NULL;
    sm_error err;
    if (sm_sol_read(path, &s, &err) != SM_OK)
        fail_msg("%s", err.msg);
    assert_int_equal(s->ncomp, 6);
    const double want[12] = {1, 2, 3, 4, 5, 6, -1, 0.5, 2, 0, 0, 7};
    for (int i = 0; i < 12; i++)
        assert_true(s->values[i] == want[i]);
    if (sm_sol_write(out, s, &err) != SM_OK)
        fail_msg("%s", err.msg);
    char *back = slurp(out);
    assert_non_null(strstr(back, "\n1 3\n"));
    free(back);
    sm_sol_free(s);
    /* a 2D tensor has 3 components; a count of 6 is not a tensor */
    assert_int_equal(sm_sol_alloc(&s, 2, 1, 3, &err), SM_OK);
    sm_sol_free(s);
    assert_int_equal(sm_sol_alloc(&s, 2, 1, 6, &err), SM_ERR_INVALID);
    assert_null(s);
}

static void test_sol_ascii_variants(void **state)
{
    fixture *f = *state;
    const char *text = "MeshVersionFormatted 2\n# comment\nDimension 2\nTime 0.5\n"
                       "solatvertices\n3\n1 2\n1 2\n3 4 # third\n5 6\nEnd\n";
    char path[600];
    path_in(f, "v.sol", path, sizeof path);
    write_file(path, text, strlen(text));
    sm_sol *s = NULL;
    sm_error err;
    if (sm_sol_read(path, &s, &err) != SM_OK)
        fail_msg("%s", err.msg);
    assert_int_equal(s->ncomp, 2);
    for (int i = 0; i < 6; i++)
        assert_true(s->values[i] == i + 1);
    sm_sol_free(s);
}

/* ------------------------------------------------------------------ */
/* vtu                                                                 */
/* ------------------------------------------------------------------ */

static char *slurp(const char *path)
{
    FILE *fp = fopen(path, "rb");
    assert_non_null(fp);
    fseek(fp, 0, SEEK_END);
    long n = ftell(fp);
    fseek(fp, 0, SEEK_SET);
    char *s = malloc((size_t)n + 1);
    assert_non_null(s);
    assert_int_equal(fread(s, 1, (size_t)n, fp), (size_t)n);
    s[n] = '\0';
    fclose(fp);
    return s;
}

/* Parses the numbers between the '>' ending the tag at p and the next
 * </DataArray>; returns how many, storing up to cap of them. */
static long numbers_after(const char *p, double *out, long cap)
{
    if (!p)
        return -1;
    p = strchr(p, '>');
    const char *end = strstr(p, "</DataArray>");
    long n = 0;
    p++;
    while (p < end) {
        char *q;
        double v = strtod(p, &q);
        if (q == p) {
            p++;
            continue;
        }
        if (n < cap)
            out[n] = v;
        n++;
        p = q;
    }
    return n;
}

static long data_array(const char *xml, const char *name, double *out, long cap)
{
    char key[64];
    snprintf(key, sizeof key, "Name=\"%s\"", name);
    return numbers_after(strstr(xml, key), out, cap);
}

static long count_of(const char *s, const char *needle)
{
    long n = 0;
    for (const char *p = strstr(s, needle); p; p = strstr(p + 1, needle))
        n++;
    return n;
}

/* The ASCII encoding, parsed here as text (the binary one is read back by
 * test_cell_formats and decoded independently by tests/cli/vtu_files.sh). */
static void check_vtu(const fixture *f, int dim)
{
    sm_mesh *m = grid_mesh(dim, 2);
    int32_t nv = m->nverts, ne = m->nelems, nf = m->nfacets;
    assert_true(nf > 0);
    double *disp = malloc((size_t)nv * dim * sizeof(double));
    double *dist = malloc((size_t)nv * sizeof(double));
    double *buf = malloc((size_t)(4 * ne + 3 * nv + 16) * sizeof(double));
    for (int32_t i = 0; i < nv * dim; i++)
        disp[i] = awkward(i, 1);
    for (int32_t i = 0; i < nv; i++)
        dist[i] = -awkward(i, 2);
    char path[600];
    path_in(f, dim == 2 ? "m2.vtu" : "m3.vtu", path, sizeof path);
    sm_error err;
    assert_int_equal(sm_vtu_write_as(path, m, NULL, disp, dist, SM_VTU_ASCII, &err), SM_OK);
    char *xml = slurp(path);
    assert_true(strncmp(xml, "<?xml version=\"1.0\"?>", 21) == 0);
    char piece[128];
    /* the elements, then the facets with their references */
    snprintf(piece, sizeof piece, "NumberOfPoints=\"%ld\" NumberOfCells=\"%ld\"", (long)nv,
             (long)(ne + nf));
    assert_non_null(strstr(xml, piece));
    /* balanced elements */
    const char *tags[] = {"VTKFile", "UnstructuredGrid", "Piece", "PointData", "CellData",
                          "Points", "Cells", "DataArray"};
    for (size_t t = 0; t < sizeof tags / sizeof tags[0]; t++) {
        char open[40], close[40];
        snprintf(open, sizeof open, "<%s ", tags[t]);
        snprintf(close, sizeof close, "</%s>", tags[t]);
        long no = count_of(xml, open), nc = count_of(xml, close);
        snprintf(open, sizeof open, "<%s>", tags[t]);
        no += count_of(xml, open);
        assert_int_equal(no, nc);
        assert_true(nc >= 1);
    }
    int k = dim + 1;
    long ncells = (long)ne + nf, nconn = (long)ne * k + (long)nf * dim;
    assert_int_equal(data_array(xml, "connectivity", buf, 4 * ne + 3 * nv), nconn);
    for (long i = 0; i < (long)ne * k; i++)
        assert_true(buf[i] == m->elems[i]);
    for (long i = 0; i < (long)nf * dim; i++)
        assert_true(buf[(long)ne * k + i] == m->facets[i]);
    assert_int_equal(data_array(xml, "offsets", buf, ncells), ncells);
    for (long i = 0; i < ne; i++)
        assert_true(buf[i] == (double)(i + 1) * k);
    for (long i = 0; i < nf; i++)
        assert_true(buf[ne + i] == (double)ne * k + (double)(i + 1) * dim);
    assert_int_equal(data_array(xml, "types", buf, ncells), ncells);
    for (long i = 0; i < ne; i++)
        assert_true(buf[i] == (dim == 2 ? 5 : 10));
    for (long i = 0; i < nf; i++)
        assert_true(buf[ne + i] == (dim == 2 ? 3 : 5));
    assert_int_equal(data_array(xml, "ref", buf, ncells), ncells);
    for (long i = 0; i < ne; i++)
        assert_true(buf[i] == m->elem_refs[i]);
    for (long i = 0; i < nf; i++)
        assert_true(buf[ne + i] == m->facet_refs[i]);
    assert_int_equal(data_array(xml, "cell_dim", buf, ncells), ncells);
    for (long i = 0; i < ncells; i++)
        assert_true(buf[i] == (i < ne ? dim : dim - 1));
    assert_int_equal(data_array(xml, "displacement", buf, 3 * nv), 3 * nv);
    for (int32_t i = 0; i < nv; i++)
        for (int c = 0; c < 3; c++)
            assert_true(buf[3 * i + c] == (c < dim ? disp[dim * i + c] : 0.0));
    assert_int_equal(data_array(xml, "distance", buf, nv), nv);
    for (int32_t i = 0; i < nv; i++)
        assert_true(buf[i] == dist[i]);
    /* Points: the unnamed array inside <Points> */
    const char *pts = strstr(xml, "<Points>");
    assert_non_null(pts);
    assert_int_equal(numbers_after(strstr(pts, "<DataArray"), buf, 3 * nv), 3 * nv);
    for (int32_t i = 0; i < nv; i++)
        for (int c = 0; c < 3; c++)
            assert_true(buf[3 * i + c] == (c < dim ? m->coords[dim * i + c] : 0.0));
    free(xml);
    /* without point data: no PointData element */
    assert_int_equal(sm_vtu_write_as(path, m, NULL, NULL, NULL, SM_VTU_ASCII, &err), SM_OK);
    xml = slurp(path);
    assert_null(strstr(xml, "PointData"));
    free(xml);
    free(buf);
    free(disp);
    free(dist);
    sm_mesh_free(m);
}

static void test_vtu_2d(void **state) { check_vtu(*state, 2); }
static void test_vtu_3d(void **state) { check_vtu(*state, 3); }

/* ------------------------------------------------------------------ */
/* write failures                                                      */
/* ------------------------------------------------------------------ */

static void test_write_errors(void **state)
{
    fixture *f = *state;
    sm_mesh *m = grid_mesh(2, 2);
    sm_error err;
    char path[600];
    /* a full disk: the error surfaces, with errno's text */
    if (access("/dev/full", W_OK) == 0) {
        sm_sol *s;
        assert_int_equal(sm_sol_alloc(&s, 2, 10, 1, &err), SM_OK);
        /* /dev/full has no extension: write through a symlink named .sol */
        path_in(f, "full.sol", path, sizeof path);
        assert_int_equal(symlink("/dev/full", path), 0);
        assert_int_equal(sm_sol_write(path, s, &err), SM_ERR_IO);
        assert_non_null(strstr(err.msg, strerror(ENOSPC)));
        unlink(path);
        path_in(f, "full.meshb.gz", path, sizeof path);
        assert_int_equal(symlink("/dev/full", path), 0);
        assert_int_equal(sm_mesh_write(path, m, &err), SM_ERR_IO);
        assert_non_null(strstr(err.msg, strerror(ENOSPC)));
        unlink(path);
        sm_sol_free(s);
    }
    /* a missing directory */
    path_in(f, "no/such/dir/x.mesh", path, sizeof path);
    assert_int_equal(sm_mesh_write(path, m, &err), SM_ERR_IO);
    assert_non_null(strstr(err.msg, "x.mesh"));
    /* an unknown extension */
    path_in(f, "x.obj", path, sizeof path);
    assert_int_equal(sm_mesh_write(path, m, &err), SM_ERR_INVALID);
    assert_int_equal(access(path, F_OK), -1);
    /* an inconsistent mesh is refused before anything is written */
    m->elems[4] = m->nverts;
    path_in(f, "bad.mesh", path, sizeof path);
    assert_int_equal(sm_mesh_write(path, m, &err), SM_ERR_INVALID);
    assert_int_equal(access(path, F_OK), -1);
    m->elems[4] = 0;
    m->coords[3] = NAN;
    assert_int_equal(sm_mesh_write(path, m, &err), SM_ERR_INVALID);
    /* reading a missing file or a directory is an I/O error */
    sm_mesh *r = NULL;
    path_in(f, "missing.mesh", path, sizeof path);
    assert_int_equal(sm_mesh_read(path, &r, &err), SM_ERR_IO);
    assert_non_null(strstr(err.msg, "missing.mesh"));
    assert_int_equal(sm_mesh_read(f->dir, &r, &err), SM_ERR_IO);
    assert_null(r);
    assert_true(no_temp_files_left(f));
    sm_mesh_free(m);
}

static void test_overwrite_keeps_old_file_on_failure(void **state)
{
    fixture *f = *state;
    sm_mesh *m = grid_mesh(2, 1);
    char path[600];
    sm_error err;
    path_in(f, "keep.mesh", path, sizeof path);
    write_ok(path, m);
    m->coords[0] = INFINITY;
    assert_int_equal(sm_mesh_write(path, m, &err), SM_ERR_INVALID);
    m->coords[0] = 0;
    sm_mesh *back = read_ok(path);
    assert_int_equal(back->nverts, m->nverts);
    sm_mesh_free(back);
    sm_mesh_free(m);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_round_trip_2d, setup_dir, teardown_dir),
        cmocka_unit_test_setup_teardown(test_round_trip_3d, setup_dir, teardown_dir),
        cmocka_unit_test_setup_teardown(test_write_coords, setup_dir, teardown_dir),
        cmocka_unit_test_setup_teardown(test_meshb_versions_and_byte_orders, setup_dir,
                                        teardown_dir),
        cmocka_unit_test_setup_teardown(test_meshb_header_layout, setup_dir, teardown_dir),
        cmocka_unit_test_setup_teardown(test_ascii_features, setup_dir, teardown_dir),
        cmocka_unit_test_setup_teardown(test_planar_3d_reads_as_2d, setup_dir, teardown_dir),
        cmocka_unit_test(test_gmsh_files),
        cmocka_unit_test_setup_teardown(test_sol_round_trips, setup_dir, teardown_dir),
        cmocka_unit_test_setup_teardown(test_solb_versions_and_byte_orders, setup_dir,
                                        teardown_dir),
        cmocka_unit_test_setup_teardown(test_sol_ascii_variants, setup_dir, teardown_dir),
        cmocka_unit_test_setup_teardown(test_sol_symmetric_tensor, setup_dir, teardown_dir),
        cmocka_unit_test_setup_teardown(test_vtu_2d, setup_dir, teardown_dir),
        cmocka_unit_test_setup_teardown(test_vtu_3d, setup_dir, teardown_dir),
        cmocka_unit_test_setup_teardown(test_write_errors, setup_dir, teardown_dir),
        cmocka_unit_test_setup_teardown(test_overwrite_keeps_old_file_on_failure, setup_dir,
                                        teardown_dir),
    };
    return cmocka_run_group_tests_name("formats", tests, NULL, NULL);
}
