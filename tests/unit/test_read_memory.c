/* The readers over memory (core/io/sm_read_input.h, sm__reader_open_memory),
 * which the fuzz targets use instead of files: for every input of
 * tests/data/malformed and tests/data/formats, reading its bytes from
 * memory (named by the same path) gives what reading the file gives: the
 * same status and message on error, the same mesh, solution or surface on
 * success.  Gzip bytes are refused from memory with a clear message.  OBJ
 * lines at their limits, from both. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "io/sm_read_input.h"

static const char *root_ = ".";

/* The whole file at path (NULL if unreadable); *size its length. */
static unsigned char *slurp(const char *path, size_t *size)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    size_t cap = 1 << 16, n = 0;
    unsigned char *buf = malloc(cap);
    size_t k;
    while (buf && (k = fread(buf + n, 1, cap - n, f)) > 0) {
        n += k;
        if (n == cap) {
            unsigned char *grown = realloc(buf, cap *= 2);
            if (!grown)
                free(buf);
            buf = grown;
        }
    }
    fclose(f);
    *size = n;
    return buf;
}

static int is_gzip(const unsigned char *b, size_t n)
{
    return n >= 2 && b[0] == 0x1f && b[1] == 0x8b;
}

static void same_error(sm_status a, const sm_error *ea, sm_status b, const sm_error *eb,
                       const char *path)
{
    if (a != b || (a != SM_OK && strcmp(ea->msg, eb->msg) != 0))
        fail_msg("%s: file gives %s \"%s\", memory %s \"%s\"", path, sm_status_name(a),
                 a ? ea->msg : "", sm_status_name(b), b ? eb->msg : "");
}

static void compare_mesh(const char *path, const sm_reader_input *in)
{
    sm_error ef, em;
    sm_error_clear(&ef);
    sm_error_clear(&em);
    sm_mesh *f = NULL, *m = NULL;
    sm_status sf = sm_mesh_read(path, &f, &ef);
    sm_status sm = sm__mesh_read_input(in, NULL, &m, &em);
    same_error(sf, &ef, sm, &em, path);
    if (sf != SM_OK) {
        assert_null(m);
        return;
    }
    assert_int_equal(f->dim, m->dim);
    assert_int_equal(f->nverts, m->nverts);
    assert_int_equal(f->nelems, m->nelems);
    assert_int_equal(f->nfacets, m->nfacets);
    assert_memory_equal(f->coords, m->coords, (size_t)f->nverts * f->dim * sizeof(double));
    assert_memory_equal(f->elems, m->elems, (size_t)f->nelems * (f->dim + 1) * sizeof(int32_t));
    sm_mesh_free(f);
    sm_mesh_free(m);
}

static void compare_sol(const char *path, const sm_reader_input *in)
{
    sm_error ef, em;
    sm_error_clear(&ef);
    sm_error_clear(&em);
    sm_sol *f = NULL, *m = NULL;
    sm_status sf = sm_sol_read(path, &f, &ef);
    sm_status sm = sm__sol_read_input(in, NULL, &m, &em);
    same_error(sf, &ef, sm, &em, path);
    if (sf != SM_OK) {
        assert_null(m);
        return;
    }
    assert_int_equal(f->nverts, m->nverts);
    assert_int_equal(f->ncomp, m->ncomp);
    assert_memory_equal(f->values, m->values, (size_t)f->nverts * f->ncomp * sizeof(double));
    sm_sol_free(f);
    sm_sol_free(m);
}

static void compare_surface(const char *path, const sm_reader_input *in)
{
    sm_error ef, em;
    sm_error_clear(&ef);
    sm_error_clear(&em);
    sm_surface *f = NULL, *m = NULL;
    sm_status sf = sm_surface_read(path, &f, &ef);
    sm_status sm = sm__surface_read_input(in, NULL, &m, &em);
    same_error(sf, &ef, sm, &em, path);
    if (sf != SM_OK) {
        assert_null(m);
        return;
    }
    assert_int_equal(f->dim, m->dim);
    assert_int_equal(f->nverts, m->nverts);
    assert_int_equal(f->nfacets, m->nfacets);
    assert_memory_equal(f->coords, m->coords, (size_t)f->nverts * f->dim * sizeof(double));
    assert_memory_equal(f->facets, m->facets, (size_t)f->nfacets * f->dim * sizeof(int32_t));
    sm_surface_free(f);
    sm_surface_free(m);
}

/* One file, read the way its folder says (surface-* cases, .sol files,
 * meshes); returns 1 when it was compared, 0 for gzip (checked refused). */
static int compare_file(const char *path, const char *case_name)
{
    size_t size = 0;
    unsigned char *bytes = slurp(path, &size);
    assert_non_null(bytes);
    sm_reader_input in = {.path = path, .data = bytes, .size = size};
    int compared = 1;
    if (is_gzip(bytes, size)) {
        sm_error err;
        sm_error_clear(&err);
        sm_mesh *m = NULL;
        assert_int_equal(sm__mesh_read_input(&in, NULL, &m, &err), SM_ERR_INVALID);
        assert_null(m);
        assert_non_null(strstr(err.msg, "gzip data is read from files only"));
        compared = 0;
    } else if (strncmp(case_name, "surface-", 8) == 0) {
        compare_surface(path, &in);
    } else if (strstr(path, ".sol")) {
        compare_sol(path, &in);
    } else {
        compare_mesh(path, &in);
        if (strncmp(case_name, "formats", 7) == 0)
            compare_surface(path, &in);
    }
    free(bytes);
    return compared;
}

/* Every input.* of tests/data/malformed/<case>/. */
static void test_malformed_corpus(void **state)
{
    (void)state;
    char dir[4096];
    snprintf(dir, sizeof dir, "%s/tests/data/malformed", root_);
    DIR *d = opendir(dir);
    assert_non_null(d);
    int compared = 0, refused = 0;
    struct dirent *e;
    while ((e = readdir(d)) != NULL) {
        if (e->d_name[0] == '.')
            continue;
        char cdir[4400];
        snprintf(cdir, sizeof cdir, "%s/%s", dir, e->d_name);
        DIR *cd = opendir(cdir);
        if (!cd)
            continue;
        struct dirent *f;
        while ((f = readdir(cd)) != NULL) {
            if (strncmp(f->d_name, "input.", 6) != 0)
                continue;
            char path[4700];
            snprintf(path, sizeof path, "%s/%s", cdir, f->d_name);
            if (compare_file(path, e->d_name))
                compared++;
            else
                refused++;
        }
        closedir(cd);
    }
    closedir(d);
    print_message("# %d malformed inputs compared, %d gzip inputs refused from memory\n",
                  compared, refused);
    assert_true(compared >= 30); /* guards against a wrong SM_ROOT */
    assert_true(refused >= 1);
}

/* The well-formed samples: the same meshes (and surfaces). */
static void test_format_samples(void **state)
{
    (void)state;
    char dir[4096];
    snprintf(dir, sizeof dir, "%s/tests/data/formats", root_);
    DIR *d = opendir(dir);
    assert_non_null(d);
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d)) != NULL) {
        size_t len = strlen(e->d_name);
        if (len < 5 || strcmp(e->d_name + len - 5, ".mesh") != 0)
            continue;
        char path[4400];
        snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        n += compare_file(path, "formats");
    }
    closedir(d);
    assert_true(n >= 2);
}

/* Empty input, and a buffer read in place: nothing is copied or freed. */
static void test_edges(void **state)
{
    (void)state;
    sm_reader r;
    sm_error err;
    sm_error_clear(&err);
    assert_int_equal(sm__reader_open_memory(&r, "empty", NULL, 0, &err), SM_OK);
    int found = 1;
    assert_int_equal(sm__reader_token(&r, &found), SM_OK);
    assert_int_equal(found, 0);
    sm__reader_close(&r);
    static const char text[] = "Dimension 3 # c\n 7 0.5";
    assert_int_equal(sm__reader_open_memory(&r, "text", text, sizeof text - 1, &err), SM_OK);
    assert_ptr_equal(r.buf, (const unsigned char *)text);
    assert_int_equal(sm__reader_max_remaining(&r), sizeof text - 1);
    assert_int_equal(sm__reader_token(&r, &found), SM_OK);
    assert_string_equal(r.token, "Dimension");
    int64_t v;
    double x;
    assert_int_equal(sm__reader_int(&r, 0, 10, &v), SM_OK);
    assert_int_equal(v, 3);
    assert_int_equal(sm__reader_int(&r, 0, 10, &v), SM_OK);
    assert_int_equal(v, 7);
    assert_int_equal(r.token_line, 2);
    assert_int_equal(sm__reader_real(&r, &x), SM_OK);
    assert_true(x == 0.5);
    assert_int_equal(sm__reader_real(&r, &x), SM_ERR_FORMAT);
    assert_non_null(strstr(r.why, "end of file"));
    sm__reader_close(&r);
    sm_mesh *m = NULL;
    sm_reader_input in = {.path = "empty.mesh", .data = "", .size = 0};
    assert_int_not_equal(sm__mesh_read_input(&in, NULL, &m, &err), SM_OK);
    assert_null(m);
    assert_non_null(strstr(err.msg, "empty.mesh"));
}

/* OBJ's lines (read with memchr over the buffer): a NUL byte, and the
 * longest line accepted (65535 bytes) and one byte more, from memory and
 * from a file (whose 64 KiB buffer the long line crosses). */
static sm_status read_obj(const char *text, size_t n, int from_file, sm_error *err)
{
    char path[] = "/tmp/sm-test-read-memory-XXXXXX";
    sm_reader_input in = {.path = "lines.obj", .data = text, .size = n};
    if (from_file) {
        int fd = mkstemp(path);
        assert_true(fd >= 0);
        assert_int_equal(write(fd, text, n), (ssize_t)n);
        close(fd);
        in = (sm_reader_input){.path = path};
    }
    sm_surface *s = NULL;
    sm_error_clear(err);
    sm_status st = sm__surface_read_input(&in, NULL, &s, err);
    if (st == SM_OK) {
        assert_int_equal(s->nfacets, 1);
        sm_surface_free(s);
    }
    if (from_file)
        unlink(path);
    return st;
}

static void test_obj_lines(void **state)
{
    (void)state;
    static const char tail[] = "\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    size_t cap = 70000 + sizeof tail;
    char *text = malloc(cap);
    assert_non_null(text);
    sm_error err;
    for (int from_file = 0; from_file < 2; from_file++) {
        static const char nul[] = "v 0 0 0\nv 1 0 0 \0 x\n";
        assert_int_equal(read_obj(nul, sizeof nul - 1, from_file, &err), SM_ERR_FORMAT);
        assert_non_null(strstr(err.msg, ":2: NUL byte in a line"));
        for (size_t len = 65535; len <= 65536; len++) {
            memcpy(text, "# ", 2);
            memset(text + 2, 'x', len - 2);
            memcpy(text + len, tail, sizeof tail - 1);
            sm_status st = read_obj(text, len + sizeof tail - 1, from_file, &err);
            if (len == 65535) {
                assert_int_equal(st, SM_OK);
            } else {
                assert_int_equal(st, SM_ERR_FORMAT);
                assert_non_null(strstr(err.msg, ":1: line longer than 65535 bytes"));
            }
        }
    }
    free(text);
}

/* A .msh section the reader skips (binary bytes, false "$End"s: alone on
 * a line, before a comment, another name, indented) and the line numbers
 * after it: the same from memory and from a file. */
static void test_msh_skipped_section(void **state)
{
    (void)state;
    static const char head[] = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$NodeData\n1\n\"d\"\n"
                               "\x01\x02\xff\n$End#c\n$EndNodeDatax 1\n  $EndNodeData\n$End\n"
                               "$EndNodeData\n";
    static const char good[] = "$Entities\n0 0 1 0\n1 0 0 0 1 1 0 1 5 0\n$EndEntities\n"
                               "$Nodes\n1 4 1 4\n2 1 0 4\n1\n2\n3\n4\n0.0 0.0 0\n1.0 0.0 0\n"
                               "1.0 1.0 0\n0.0 1.0 0\n$EndNodes\n$Elements\n1 2 1 2\n2 1 2 2\n"
                               "1 1 2 3\n2 1 3 4\n$EndElements\n";
    static const char bad[] = "$Entities\n0 0 1 0\nx\n";
    char text[1024], path[] = "/tmp/sm-test-read-memory-XXXXXX";
    for (int k = 0; k < 2; k++) {
        int n = snprintf(text, sizeof text, "%s%s", head, k ? bad : good);
        int fd = mkstemp(path);
        assert_true(fd >= 0);
        assert_int_equal(write(fd, text, (size_t)n), n);
        close(fd);
        sm_reader_input in = {.path = path, .data = text, .size = (size_t)n};
        compare_mesh(path, &in);
        sm_mesh *m = NULL;
        sm_error err;
        sm_error_clear(&err);
        sm_status st = sm__mesh_read_input(&in, NULL, &m, &err);
        if (k == 0) {
            if (st != SM_OK)
                fail_msg("%s", err.msg);
            assert_int_equal(m->nverts, 4);
            assert_int_equal(m->nelems, 2);
            sm_mesh_free(m);
        } else {
            assert_int_not_equal(st, SM_OK);
            if (!strstr(err.msg, ":14:")) /* the counts are on line 14 */
                fail_msg("expected line 14 in \"%s\"", err.msg);
        }
        unlink(path);
        memcpy(path + strlen(path) - 6, "XXXXXX", 6);
    }
}

int main(void)
{
    const char *root = getenv("SM_ROOT");
    if (root && *root)
        root_ = root;
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_malformed_corpus),
        cmocka_unit_test(test_format_samples),
        cmocka_unit_test(test_edges),
        cmocka_unit_test(test_obj_lines),
        cmocka_unit_test(test_msh_skipped_section),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
