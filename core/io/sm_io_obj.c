/* Wavefront OBJ surfaces: "v x y z [w]" and "f a b c ..." (a vertex
 * reference is "i", "i/t", "i//n" or "i/t/n"; i < 0 counts back from the
 * last vertex read; a polygon is fan-triangulated from its first vertex).
 * A file without faces whose "l a b c ..." polylines lie in the plane
 * z = 0 is a 2D curve: its segments are the surface (Inkscape's and
 * Blender's curve export, a 2D outline); with faces the lines are
 * dropped.  vt, vn, vp, o, g, s, p, usemtl, mtllib and '#' comments are
 * skipped; any other statement is an error (it is probably not an OBJ
 * file).
 * Vertices with equal coordinates are merged (sm__surface_weld), as for
 * STL.  The format is line-based, so this reader reads lines (at most
 * OBJ_LINE_MAX bytes each) rather than the shared tokens. */
#include <ctype.h>
#include <errno.h>
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "shapematch/sm_mesh.h"
#include "io/sm_io_formats.h"

#define OBJ_LINE_MAX 65536

static const char *const skipped[] = {"vt", "vn", "vp", "o", "g", "s", "p",
                                      "usemtl", "mtllib", "cstype", "deg", "curv",
                                      "surf", "parm", "end", "mg", "lod"};

static int is_skipped(const char *w, size_t n)
{
    for (size_t k = 0; k < sizeof skipped / sizeof skipped[0]; k++)
        if (strlen(skipped[k]) == n && memcmp(skipped[k], w, n) == 0)
            return 1;
    return 0;
}

int sm__obj_detect(sm_reader *r)
{
    char head[256];
    size_t got = 0;
    if (sm__reader_peek(r, head, sizeof head - 1, &got) != SM_OK || !got)
        return 0;
    head[got] = '\0';
    /* '#' comments first: a file of comments alone is no OBJ; comments
     * (and blank lines) that run past the peek may be an OBJ's header */
    const char *p = head;
    int comment = 0;
    for (;;) {
        while (*p && isspace((unsigned char)*p))
            p++;
        if (*p != '#')
            break;
        comment = 1;
        const char *nl = strchr(p, '\n');
        if (!nl)
            return got == sizeof head - 1;
        p = nl + 1;
    }
    if (!*p)
        return comment && got == sizeof head - 1;
    size_t n = strcspn(p, " \t\r\n");
    return (n == 1 && (*p == 'v' || *p == 'f' || *p == 'l')) || is_skipped(p, n);
}

typedef struct obj_in {
    sm_reader *r;
    sm_error *err;
    char *line;
    size_t line_cap;     /* OBJ_LINE_MAX, or less for a smaller input */
    long lineno;
    double *x;           /* 3 per vertex */
    int64_t nv, capv;
    int32_t *f;          /* 3 per triangle */
    int64_t nf, capf;
    int32_t *l;          /* 2 per segment of the "l" polylines */
    int64_t nl, capl;
    int64_t *poly;       /* the current face's vertex indices */
} obj_in;

/* Next line into c->line; *eof at the end of the file.  The buffered
 * bytes are scanned with memchr (the newline, then a NUL before it), not
 * one by one. */
static sm_status next_line(obj_in *c, int *eof)
{
    size_t n = 0;
    *eof = 0;
    for (;;) {
        const unsigned char *b;
        size_t avail;
        sm_status st = sm__reader_window(c->r, &b, &avail);
        if (st != SM_OK)
            return sm_error_set(c->err, st, "%s:%ld: %s", c->r->path, c->lineno + 1, c->r->why);
        if (!avail) {
            *eof = n == 0;
            break;
        }
        const unsigned char *nl = memchr(b, '\n', avail);
        size_t span = nl ? (size_t)(nl - b) : avail;
        const unsigned char *nul = memchr(b, '\0', span);
        size_t plain = nul ? (size_t)(nul - b) : span;
        /* a byte is stored at n only while n + 1 < the buffer's size */
        size_t room = c->line_cap - 1 - n;
        if (plain > room)
            return sm_error_set(c->err, SM_ERR_FORMAT, "%s:%ld: line longer than %d bytes",
                                c->r->path, c->lineno + 1, OBJ_LINE_MAX - 1);
        if (nul)
            return sm_error_set(c->err, SM_ERR_FORMAT, "%s:%ld: NUL byte in a line",
                                c->r->path, c->lineno + 1);
        memcpy(c->line + n, b, plain);
        n += plain;
        sm__reader_consume(c->r, plain + (nl != NULL));
        if (nl)
            break;
    }
    c->line[n] = '\0';
    char *hash = strchr(c->line, '#');
    if (hash)
        *hash = '\0';
    c->lineno++;
    return SM_OK;
}

static sm_status grow(obj_in *c, void **a, int64_t *cap, int64_t need, size_t item)
{
    sm_status st = sm__reader_limit_count(c->r, c->err, need, cap == &c->capv,
                                         cap == &c->capv ? "vertices" : cap == &c->capf
                                                                        ? "facets" : "segments");
    if (st != SM_OK || need <= *cap)
        return st;
    int64_t n = *cap ? *cap * 2 : 64; /* small inputs, small buffers */
    while (n < need)
        n *= 2;
    if (n > SM_MAX_ENTITIES)
        return sm_error_set(c->err, SM_ERR_FORMAT, "%s:%ld: more than %d vertices or facets",
                            c->r->path, c->lineno, SM_MAX_ENTITIES);
    void *p = realloc(*a, (size_t)n * item);
    if (!p)
        return sm_error_set(c->err, SM_ERR_NOMEM, "%s: out of memory", c->r->path);
    *a = p;
    *cap = n;
    return SM_OK;
}

static sm_status vertex(obj_in *c, char *p)
{
    sm_status st = grow(c, (void **)&c->x, &c->capv, c->nv + 1, 3 * sizeof(double));
    if (st != SM_OK)
        return st;
    for (int k = 0; k < 3; k++) {
        char *end;
        errno = 0;
        double v = strtod(p, &end);
        if (end == p || (*end && !isspace((unsigned char)*end)) || !isfinite(v))
            return sm_error_set(c->err, SM_ERR_FORMAT, "%s:%ld: vertex needs 3 finite "
                                "coordinates (coordinate %d)", c->r->path, c->lineno, k + 1);
        c->x[3 * c->nv + k] = v;
        p = end;
    }
    c->nv++;
    return SM_OK;
}

/* One vertex reference "i[/t[/n]]" into a 0-based index. */
static sm_status face_ref(obj_in *c, char **pp, int64_t *out)
{
    char *end;
    errno = 0;
    long long i = strtoll(*pp, &end, 10);
    if (end == *pp || (*end && *end != '/' && !isspace((unsigned char)*end)) || errno)
        return sm_error_set(c->err, SM_ERR_FORMAT, "%s:%ld: bad vertex reference in a face",
                            c->r->path, c->lineno);
    int64_t idx = i < 0 ? c->nv + i : i - 1;
    if (i == 0 || idx < 0 || idx >= c->nv)
        return sm_error_set(c->err, SM_ERR_FORMAT, "%s:%ld: vertex index %lld out of range "
                            "(%lld vertices so far)", c->r->path, c->lineno, i,
                            (long long)c->nv);
    while (*end && !isspace((unsigned char)*end))
        end++;
    *pp = end;
    *out = idx;
    return SM_OK;
}

/* The vertex references of a face or polyline into c->poly. */
static sm_status refs(obj_in *c, char *p, int64_t *n)
{
    *n = 0;
    for (;;) {
        while (*p && isspace((unsigned char)*p))
            p++;
        if (!*p)
            return SM_OK;
        sm_status st = face_ref(c, &p, &c->poly[*n]);
        if (st != SM_OK)
            return st;
        (*n)++;
    }
}

/* "l a b c ...": a polyline, kept as its segments. */
static sm_status polyline(obj_in *c, char *p)
{
    int64_t n;
    sm_status st = refs(c, p, &n);
    if (st != SM_OK)
        return st;
    if (n < 2)
        return sm_error_set(c->err, SM_ERR_FORMAT, "%s:%ld: a line needs at least 2 vertices, "
                            "found %lld", c->r->path, c->lineno, (long long)n);
    st = grow(c, (void **)&c->l, &c->capl, c->nl + n - 1, 2 * sizeof(int32_t));
    for (int64_t k = 0; st == SM_OK && k + 1 < n; k++) {
        c->l[2 * c->nl] = (int32_t)c->poly[k];
        c->l[2 * c->nl + 1] = (int32_t)c->poly[k + 1];
        c->nl++;
    }
    return st;
}

static sm_status face(obj_in *c, char *p)
{
    int64_t n;
    sm_status st = refs(c, p, &n);
    if (st != SM_OK)
        return st;
    if (n < 3)
        return sm_error_set(c->err, SM_ERR_FORMAT, "%s:%ld: a face needs at least 3 vertices, "
                            "found %lld", c->r->path, c->lineno, (long long)n);
    st = grow(c, (void **)&c->f, &c->capf, c->nf + n - 2, 3 * sizeof(int32_t));
    for (int64_t k = 1; st == SM_OK && k + 1 < n; k++) {
        c->f[3 * c->nf] = (int32_t)c->poly[0];
        c->f[3 * c->nf + 1] = (int32_t)c->poly[k];
        c->f[3 * c->nf + 2] = (int32_t)c->poly[k + 1];
        c->nf++;
    }
    return st;
}

static sm_status statement(obj_in *c)
{
    char *p = c->line;
    while (*p && isspace((unsigned char)*p))
        p++;
    size_t n = strcspn(p, " \t\r");
    if (n == 0)
        return SM_OK;
    if (n == 1 && *p == 'v')
        return vertex(c, p + 1);
    if (n == 1 && *p == 'f')
        return face(c, p + 1);
    if (n == 1 && *p == 'l')
        return polyline(c, p + 1);
    if (is_skipped(p, n))
        return SM_OK;
    char w[40];
    snprintf(w, sizeof w, "%.*s", (int)(n < 32 ? n : 32), p);
    char q[64];
    sm__quote_token(w, q, sizeof q);
    return sm_error_set(c->err, SM_ERR_FORMAT, "%s:%ld: unknown OBJ statement %s", c->r->path,
                        c->lineno, q);
}

static sm_status triangles(obj_in *c, sm_surface **out)
{
    sm_surface *s = NULL;
    sm_status st = sm_surface_alloc(&s, 3, (int32_t)c->nv, (int32_t)c->nf, c->err);
    if (st != SM_OK)
        return st;
    memcpy(s->coords, c->x, (size_t)c->nv * 3 * sizeof(double));
    memcpy(s->facets, c->f, (size_t)c->nf * 3 * sizeof(int32_t));
    if ((st = sm__surface_weld(s, c->err)) == SM_OK)
        *out = s;
    else
        sm_surface_free(s);
    return st;
}

/* Lines and no faces: a 2D curve, when every vertex has z = 0. */
static sm_status curve(obj_in *c, sm_surface **out)
{
    for (int64_t v = 0; v < c->nv; v++)
        if (c->x[3 * v + 2] != 0.0)
            return sm_error_set(c->err, SM_ERR_FORMAT, "%s: OBJ with %lld line segments and no "
                                "faces is read as a 2D curve, which needs z = 0 on every vertex "
                                "(vertex %lld has z = %g); a 3D surface needs faces",
                                c->r->path, (long long)c->nl, (long long)v + 1, c->x[3 * v + 2]);
    sm_surface *s = NULL;
    sm_status st = sm_surface_alloc(&s, 2, (int32_t)c->nv, (int32_t)c->nl, c->err);
    if (st != SM_OK)
        return st;
    for (int64_t v = 0; v < c->nv; v++) {
        s->coords[2 * v] = c->x[3 * v];
        s->coords[2 * v + 1] = c->x[3 * v + 1];
    }
    memcpy(s->facets, c->l, (size_t)c->nl * 2 * sizeof(int32_t));
    if ((st = sm__surface_weld(s, c->err)) == SM_OK)
        *out = s;
    else
        sm_surface_free(s);
    return st;
}

sm_status sm__obj_read(sm_reader *r, sm_surface **out, sm_error *err)
{
    *out = NULL;
    obj_in c;
    memset(&c, 0, sizeof c);
    c.r = r;
    c.err = err;
    /* Sized to the input (no line is longer than what is left of it), so
     * a small file costs small buffers; a face has at most half as many
     * vertices as its line has bytes. */
    uint64_t left = sm__reader_max_remaining(r) + 1;
    c.line_cap = left < OBJ_LINE_MAX ? (size_t)left : OBJ_LINE_MAX;
    c.line = malloc(c.line_cap);
    c.poly = malloc((c.line_cap / 2 + 1) * sizeof(int64_t));
    sm_status st = c.line && c.poly ? SM_OK : sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    for (int eof = 0; st == SM_OK;) {
        if ((st = next_line(&c, &eof)) != SM_OK || eof)
            break;
        st = statement(&c);
    }
    if (st == SM_OK && c.nf == 0)
        st = c.nl ? curve(&c, out) : sm_error_set(err, SM_ERR_FORMAT, "%s: OBJ without faces or "
                                                   "lines (%lld vertices and nothing joining "
                                                   "them)", r->path, (long long)c.nv);
    else if (st == SM_OK)
        st = triangles(&c, out);
    free(c.line);
    free(c.poly);
    free(c.x);
    free(c.f);
    free(c.l);
    return st;
}
