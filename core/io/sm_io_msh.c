/* Gmsh .msh reader: 4.1 ASCII and binary, 2.2 ASCII (see sm_io_msh.h).
 * The ASCII and binary layouts of format 4.1 carry the same fields in
 * the same order, so each field is read by one primitive (rd_size,
 * rd_int, rd_real) that looks at whether the current section is binary;
 * $MeshFormat and $PhysicalNames are ASCII even in binary files. */
#include "io/sm_io_msh.h"

#include <inttypes.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "io/sm_medit_common.h"

/* first physical tag of one entity */
typedef struct ent_phys {
    int32_t tag, phys;
} ent_phys;

/* node tag -> index, sorted by tag */
typedef struct tag_idx {
    int64_t tag, idx;
} tag_idx;

typedef struct msh_in {
    sm_reader *r;
    sm_error *err;
    sm_msh_data *d;
    int file_binary;     /* the file's type (4.1 binary) */
    int bin;             /* the current field is binary */
    int major;           /* 4 or 2 */
    uint64_t where;      /* offset of the field being read (binary) */
    ent_phys *ents[4];
    int64_t nents[4];
    tag_idx *tags;       /* nnodes, sorted once $Nodes is read */
    int have_nodes, have_elements;
} msh_in;

static sm_status fail(msh_in *c, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static sm_status fail(msh_in *c, const char *fmt, ...)
{
    char msg[SM_ERROR_MSG_LEN];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    if (c->bin)
        return sm__reader_fail_byte(c->r, c->err, SM_ERR_FORMAT, c->where, "%s", msg);
    return sm__reader_fail_line(c->r, c->err, SM_ERR_FORMAT, "%s", msg);
}

/* A failed primitive read: "expected <what>, <why>". */
static sm_status fail_read(msh_in *c, sm_status st, const char *what)
{
    if (st == SM_ERR_IO)
        return sm_error_set(c->err, st, "%s: %s", c->r->path, c->r->why);
    return fail(c, "expected %s, %s", what, c->r->why);
}

/* ---- primitives ---- */

static sm_status rd_size(msh_in *c, const char *what, int64_t *out)
{
    c->where = sm__reader_offset(c->r);
    sm_status st;
    if (c->bin) {
        st = sm__reader_i64(c->r, out);
        if (st == SM_OK && *out < 0)
            return fail(c, "%s is %" PRId64 ", negative", what, *out);
    } else {
        st = sm__reader_int(c->r, 0, INT64_MAX, out);
    }
    return st == SM_OK ? SM_OK : fail_read(c, st, what);
}

static sm_status rd_int(msh_in *c, const char *what, int32_t *out)
{
    c->where = sm__reader_offset(c->r);
    sm_status st;
    if (c->bin) {
        st = sm__reader_i32(c->r, out);
    } else {
        int64_t v;
        st = sm__reader_int(c->r, INT32_MIN, INT32_MAX, &v);
        *out = (int32_t)v;
    }
    return st == SM_OK ? SM_OK : fail_read(c, st, what);
}

static sm_status rd_real(msh_in *c, const char *what, double *out)
{
    c->where = sm__reader_offset(c->r);
    sm_status st;
    if (c->bin) {
        st = sm__reader_f64(c->r, out);
        if (st == SM_OK && !isfinite(*out))
            return fail(c, "%s is not a finite number", what);
    } else {
        st = sm__reader_real(c->r, out);
    }
    return st == SM_OK ? SM_OK : fail_read(c, st, what);
}

static sm_status expect_token(msh_in *c, const char *want)
{
    int found;
    sm_status st = sm__reader_token(c->r, &found);
    if (st != SM_OK)
        return fail_read(c, st, want);
    if (!found || strcmp(c->r->token, want) != 0) {
        char q[64];
        sm__quote_token(found ? c->r->token : "end of file", q, sizeof q);
        c->bin = 0;
        return sm__reader_fail_line(c->r, c->err, SM_ERR_FORMAT, "expected %s, found %s", want, q);
    }
    return SM_OK;
}

/* The newline that ends an ASCII header line before binary data. */
static sm_status binary_start(msh_in *c, const char *section)
{
    if (!c->file_binary)
        return SM_OK;
    unsigned char nl = 0;
    uint64_t at = sm__reader_offset(c->r);
    if (sm__reader_bytes(c->r, &nl, 1) != SM_OK || nl != '\n')
        return sm__reader_fail_byte(c->r, c->err, SM_ERR_FORMAT, at,
                                   "expected a newline before the binary data of %s", section);
    c->bin = 1;
    return SM_OK;
}

static sm_status check_count(msh_in *c, const char *what, int64_t n, uint64_t ascii_bytes,
                             uint64_t binary_bytes)
{
    return sm__medit_check_count(c->r, c->bin, what, n, c->bin ? binary_bytes : ascii_bytes,
                                c->where, c->err);
}

/* ---- $MeshFormat ---- */

static sm_status read_format(msh_in *c)
{
    sm_status st = expect_token(c, "$MeshFormat");
    if (st != SM_OK)
        return st;
    int found;
    if ((st = sm__reader_token(c->r, &found)) != SM_OK)
        return fail_read(c, st, "the format version");
    if (found && strcmp(c->r->token, "4.1") == 0)
        c->major = 4;
    else if (found && (strcmp(c->r->token, "2.2") == 0 || strcmp(c->r->token, "2.1") == 0 ||
                       strcmp(c->r->token, "2") == 0))
        c->major = 2;
    else {
        char q[64];
        sm__quote_token(found ? c->r->token : "end of file", q, sizeof q);
        return sm__reader_fail_line(c->r, c->err, SM_ERR_FORMAT,
                                   "unsupported .msh version %s (read: 4.1 ASCII and binary, "
                                   "2.2 ASCII)",
                                   q);
    }
    int32_t type, size;
    if ((st = rd_int(c, "the file type (0 ASCII, 1 binary)", &type)) != SM_OK ||
        (st = rd_int(c, "the data size", &size)) != SM_OK)
        return st;
    if (type != 0 && type != 1)
        return fail(c, "file type %d is neither 0 (ASCII) nor 1 (binary)", (int)type);
    if (type == 1 && c->major != 4)
        return fail(c, "binary .msh %s is not supported (read: 4.1 ASCII and binary, 2.2 ASCII)",
                    "2.2");
    if (type == 1 && size != 8)
        return fail(c, "data size %d is not supported (binary files need 8)", (int)size);
    c->file_binary = type == 1;
    if (c->file_binary) {
        if ((st = binary_start(c, "$MeshFormat")) != SM_OK)
            return st;
        int32_t one;
        c->where = sm__reader_offset(c->r);
        if ((st = sm__reader_i32(c->r, &one)) != SM_OK)
            return fail_read(c, st, "the endianness word 1");
        if (one != 1 && (int32_t)sm__bswap32((uint32_t)one) != 1)
            return fail(c, "endianness word is %d, not 1 in either byte order", (int)one);
        c->r->swap = one != 1;
        c->bin = 0;
    }
    return expect_token(c, "$EndMeshFormat");
}

/* ---- $PhysicalNames (ASCII in every file type) ---- */

/* One entry: dimension, tag, quoted name (kept in d->names[i]). */
static sm_status read_name(msh_in *c, sm_mesh_name *e)
{
    sm_status st;
    if ((st = rd_int(c, "a physical dimension", &e->dim)) != SM_OK ||
        (st = rd_int(c, "a physical tag", &e->tag)) != SM_OK)
        return st;
    if (e->dim < 0 || e->dim > 3)
        return fail(c, "physical dimension %d is not in [0, 3]", (int)e->dim);
    char buf[SM_MESH_NAME_MAX + 1];
    if ((st = sm__reader_string(c->r, buf, sizeof buf)) != SM_OK)
        return fail_read(c, st, "a physical name");
    e->name = strdup(buf);
    return e->name ? SM_OK : sm_error_set(c->err, SM_ERR_NOMEM, "out of memory");
}

static sm_status read_names(msh_in *c)
{
    if (c->d->names)
        return fail(c, "a second $PhysicalNames section");
    int64_t n;
    sm_status st = rd_size(c, "the number of physical names", &n);
    if (st == SM_OK)
        st = check_count(c, "$PhysicalNames", n, 8, 8);
    if (st != SM_OK)
        return st;
    c->d->names = calloc(n > 0 ? (size_t)n : 1, sizeof *c->d->names);
    if (!c->d->names)
        return sm_error_set(c->err, SM_ERR_NOMEM, "out of memory for %lld physical names",
                            (long long)n);
    for (int64_t i = 0; i < n; i++) {
        c->d->nnames = (int32_t)i + 1; /* freed with d whatever happens */
        if ((st = read_name(c, &c->d->names[i])) != SM_OK)
            return st;
    }
    return expect_token(c, "$EndPhysicalNames");
}

/* ---- $Entities (4.1) ---- */

static sm_status read_entity(msh_in *c, int dim, ent_phys *e)
{
    sm_status st = rd_int(c, "an entity tag", &e->tag);
    double x;
    for (int k = 0; st == SM_OK && k < (dim == 0 ? 3 : 6); k++)
        st = rd_real(c, "an entity bounding-box coordinate", &x);
    int64_t n;
    if (st != SM_OK || (st = rd_size(c, "the number of physical tags", &n)) != SM_OK ||
        (st = check_count(c, "physical tags", n, 2, 4)) != SM_OK)
        return st;
    e->phys = 0;
    for (int64_t k = 0; k < n; k++) {
        int32_t p;
        if ((st = rd_int(c, "a physical tag", &p)) != SM_OK)
            return st;
        if (k == 0)
            e->phys = p;
    }
    if (dim == 0)
        return SM_OK;
    if ((st = rd_size(c, "the number of bounding entities", &n)) != SM_OK ||
        (st = check_count(c, "bounding entities", n, 2, 4)) != SM_OK)
        return st;
    for (int64_t k = 0; k < n; k++) {
        int32_t b;
        if ((st = rd_int(c, "a bounding entity tag", &b)) != SM_OK)
            return st;
    }
    return SM_OK;
}

static sm_status read_entities(msh_in *c)
{
    if (c->major != 4)
        return fail(c, "$Entities in a version 2 file");
    for (int d = 0; d < 4; d++)
        if (c->ents[d])
            return fail(c, "a second $Entities section");
    sm_status st = binary_start(c, "$Entities");
    int64_t n[4];
    for (int d = 0; st == SM_OK && d < 4; d++)
        if ((st = rd_size(c, "an entity count", &n[d])) == SM_OK)
            st = check_count(c, "$Entities", n[d], 16, 36);
    for (int d = 0; st == SM_OK && d < 4; d++) {
        c->ents[d] = calloc((size_t)n[d] + 1, sizeof(ent_phys));
        if (!c->ents[d])
            return sm_error_set(c->err, SM_ERR_NOMEM, "%s: out of memory", c->r->path);
        c->nents[d] = n[d];
        for (int64_t i = 0; st == SM_OK && i < n[d]; i++)
            st = read_entity(c, d, &c->ents[d][i]);
    }
    c->bin = 0;
    return st == SM_OK ? expect_token(c, "$EndEntities") : st;
}

static int32_t entity_phys(const msh_in *c, int32_t dim, int32_t tag)
{
    if (dim < 0 || dim > 3)
        return 0;
    for (int64_t i = 0; i < c->nents[dim]; i++)
        if (c->ents[dim][i].tag == tag)
            return c->ents[dim][i].phys;
    return 0;
}

/* ---- $Nodes ---- */

static int cmp_tag(const void *a, const void *b)
{
    int64_t x = ((const tag_idx *)a)->tag, y = ((const tag_idx *)b)->tag;
    return (x > y) - (x < y);
}

static sm_status alloc_nodes(msh_in *c, int64_t n)
{
    c->d->coords = malloc((size_t)n * 3 * sizeof(double) + 1);
    c->tags = malloc((size_t)n * sizeof(tag_idx) + 1);
    if (!c->d->coords || !c->tags)
        return sm_error_set(c->err, SM_ERR_NOMEM, "%s: out of memory for %lld nodes",
                            c->r->path, (long long)n);
    return SM_OK;
}

static sm_status read_node_xyz(msh_in *c, int64_t i)
{
    sm_status st = SM_OK;
    for (int k = 0; st == SM_OK && k < 3; k++)
        st = rd_real(c, "a node coordinate", &c->d->coords[3 * i + k]);
    return st;
}

static sm_status read_node_block(msh_in *c, int64_t *filled, int64_t total)
{
    int32_t edim, etag, param;
    int64_t n;
    sm_status st;
    if ((st = rd_int(c, "the entity dimension of a node block", &edim)) != SM_OK ||
        (st = rd_int(c, "the entity tag of a node block", &etag)) != SM_OK ||
        (st = rd_int(c, "the parametric flag of a node block", &param)) != SM_OK ||
        (st = rd_size(c, "the node count of a node block", &n)) != SM_OK)
        return st;
    if (param != 0)
        return fail(c, "parametric nodes are not supported (save without Mesh.SaveParametric)");
    if (n > total - *filled)
        return fail(c, "node block of %" PRId64 " nodes exceeds the %" PRId64
                       " nodes the $Nodes header announces", n, total);
    for (int64_t i = 0; i < n; i++) {
        if ((st = rd_size(c, "a node tag", &c->tags[*filled + i].tag)) != SM_OK)
            return st;
        c->tags[*filled + i].idx = *filled + i;
    }
    for (int64_t i = 0; i < n; i++)
        if ((st = read_node_xyz(c, *filled + i)) != SM_OK)
            return st;
    *filled += n;
    return SM_OK;
}

static sm_status finish_nodes(msh_in *c)
{
    int64_t n = c->d->nnodes;
    qsort(c->tags, (size_t)n, sizeof *c->tags, cmp_tag);
    for (int64_t i = 1; i < n; i++)
        if (c->tags[i].tag == c->tags[i - 1].tag)
            return sm__reader_fail_line(c->r, c->err, SM_ERR_FORMAT, "node tag %" PRId64
                                       " appears twice in $Nodes", c->tags[i].tag);
    c->have_nodes = 1;
    return expect_token(c, "$EndNodes");
}

static sm_status read_nodes(msh_in *c)
{
    if (c->have_nodes)
        return fail(c, "a second $Nodes section");
    sm_status st = binary_start(c, "$Nodes");
    int64_t nblocks = 0, n = 0, lo, hi;
    if (st == SM_OK && c->major == 4 &&
        ((st = rd_size(c, "the number of node blocks", &nblocks)) != SM_OK ||
         (st = check_count(c, "node blocks", nblocks, 8, 20)) != SM_OK))
        return st;
    if (st != SM_OK || (st = rd_size(c, "the number of nodes", &n)) != SM_OK ||
        (st = check_count(c, "$Nodes", n, 8, 32)) != SM_OK)
        return st;
    if (c->major == 4 && ((st = rd_size(c, "the minimum node tag", &lo)) != SM_OK ||
                          (st = rd_size(c, "the maximum node tag", &hi)) != SM_OK))
        return st;
    if ((st = alloc_nodes(c, n)) != SM_OK)
        return st;
    c->d->nnodes = n;
    int64_t filled = 0;
    if (c->major == 4) {
        for (int64_t b = 0; st == SM_OK && b < nblocks; b++)
            st = read_node_block(c, &filled, n);
        if (st == SM_OK && filled != n)
            st = fail(c, "the node blocks hold %" PRId64 " nodes, the $Nodes header announces %"
                         PRId64, filled, n);
    } else {
        for (int64_t i = 0; st == SM_OK && i < n; i++) {
            c->tags[i].idx = i;
            if ((st = rd_size(c, "a node tag", &c->tags[i].tag)) == SM_OK)
                st = read_node_xyz(c, i);
        }
    }
    c->bin = 0;
    return st == SM_OK ? finish_nodes(c) : st;
}

/* ---- $Elements ---- */

static int nodes_of_type(int32_t type)
{
    switch (type) {
    case 1: return 2;
    case 2: return 3;
    case 4: return 4;
    case 15: return 1;
    default: return 0;
    }
}

static const char *type_name(int32_t type)
{
    switch (type) {
    case 3: return "4-node quadrangle";
    case 5: return "8-node hexahedron";
    case 6: return "6-node prism";
    case 7: return "5-node pyramid";
    case 8: return "3-node second-order line";
    case 9: return "6-node second-order triangle";
    case 11: return "10-node second-order tetrahedron";
    default: return "unknown";
    }
}

static sm_status unsupported_type(msh_in *c, int32_t type)
{
    return fail(c, "element type %d (%s) is not supported: shapematch reads 2-node lines (1), "
                   "3-node triangles (2), 4-node tetrahedra (4) and points (15)",
                (int)type, type_name(type));
}

static sm_msh_block *block_of_type(sm_msh_data *d, int32_t type)
{
    return type == 1 ? &d->lines : type == 2 ? &d->triangles : type == 4 ? &d->tetrahedra : NULL;
}

/* Room for extra more records (capacity doubles; extra already bounded). */
static sm_status reserve(msh_in *c, sm_msh_block *b, int64_t extra)
{
    if (b->count + extra <= b->cap)
        return SM_OK;
    int64_t cap = b->cap * 2 > b->count + extra ? b->cap * 2 : b->count + extra;
    if (cap > SM_MAX_ENTITIES)
        return fail(c, "more than %d elements of one kind", SM_MAX_ENTITIES);
    int32_t *idx = realloc(b->idx, (size_t)cap * (size_t)b->nidx * sizeof(int32_t));
    if (idx)
        b->idx = idx;
    int32_t *refs = realloc(b->refs, (size_t)cap * sizeof(int32_t));
    if (refs)
        b->refs = refs;
    if (!idx || !refs)
        return sm_error_set(c->err, SM_ERR_NOMEM, "%s: out of memory", c->r->path);
    b->cap = cap;
    return SM_OK;
}

static sm_status node_index(msh_in *c, int64_t tag, int32_t *out)
{
    tag_idx key = {tag, 0};
    const tag_idx *hit = bsearch(&key, c->tags, (size_t)c->d->nnodes, sizeof key, cmp_tag);
    if (!hit)
        return fail(c, "node tag %" PRId64 " is not in $Nodes", tag);
    *out = (int32_t)hit->idx;
    return SM_OK;
}

/* The node tags of one element; b is NULL for points (discarded). */
static sm_status read_element_nodes(msh_in *c, sm_msh_block *b, int nn, int32_t ref)
{
    int32_t idx[4];
    for (int k = 0; k < nn; k++) {
        int64_t tag;
        sm_status st = rd_size(c, "a node tag of an element", &tag);
        if (st == SM_OK)
            st = node_index(c, tag, &idx[k]);
        if (st != SM_OK)
            return st;
    }
    if (!b)
        return SM_OK;
    memcpy(b->idx + b->count * b->nidx, idx, (size_t)nn * sizeof(int32_t));
    b->refs[b->count++] = ref;
    return SM_OK;
}

static sm_status read_element_block(msh_in *c, int64_t *left)
{
    int32_t edim, etag, type;
    int64_t n, tag;
    sm_status st;
    if ((st = rd_int(c, "the entity dimension of an element block", &edim)) != SM_OK ||
        (st = rd_int(c, "the entity tag of an element block", &etag)) != SM_OK ||
        (st = rd_int(c, "the element type of an element block", &type)) != SM_OK ||
        (st = rd_size(c, "the element count of an element block", &n)) != SM_OK)
        return st;
    int nn = nodes_of_type(type);
    if (!nn)
        return unsupported_type(c, type);
    if (n > *left)
        return fail(c, "element block of %" PRId64 " elements exceeds the count the $Elements "
                       "header announces", n);
    *left -= n;
    sm_msh_block *b = block_of_type(c->d, type);
    if (b && (st = reserve(c, b, n)) != SM_OK)
        return st;
    int32_t ref = entity_phys(c, edim, etag);
    for (int64_t i = 0; i < n; i++)
        if ((st = rd_size(c, "an element tag", &tag)) != SM_OK ||
            (st = read_element_nodes(c, b, nn, ref)) != SM_OK)
            return st;
    return SM_OK;
}

/* Version 2.2: "tag type ntags tag... node..." per line. */
static sm_status read_element_v2(msh_in *c, int64_t left)
{
    int64_t tag;
    int32_t type, ntags, t, ref = 0;
    sm_status st;
    if ((st = rd_size(c, "an element tag", &tag)) != SM_OK ||
        (st = rd_int(c, "an element type", &type)) != SM_OK ||
        (st = rd_int(c, "the number of element tags", &ntags)) != SM_OK)
        return st;
    int nn = nodes_of_type(type);
    if (!nn)
        return unsupported_type(c, type);
    if (ntags < 0 || ntags > 64)
        return fail(c, "%d element tags is not in [0, 64]", (int)ntags);
    for (int32_t k = 0; k < ntags; k++) {
        if ((st = rd_int(c, "an element tag", &t)) != SM_OK)
            return st;
        if (k == 0)
            ref = t;
    }
    sm_msh_block *b = block_of_type(c->d, type);
    if (b && (st = reserve(c, b, b->cap > b->count ? 1 : left)) != SM_OK)
        return st;
    return read_element_nodes(c, b, nn, ref);
}

static sm_status read_elements(msh_in *c)
{
    if (!c->have_nodes)
        return fail(c, "$Elements before $Nodes");
    if (c->have_elements)
        return fail(c, "a second $Elements section");
    sm_status st = binary_start(c, "$Elements");
    int64_t nblocks = 0, n = 0, lo, hi;
    if (st == SM_OK && c->major == 4 &&
        ((st = rd_size(c, "the number of element blocks", &nblocks)) != SM_OK ||
         (st = check_count(c, "element blocks", nblocks, 8, 20)) != SM_OK))
        return st;
    if (st != SM_OK || (st = rd_size(c, "the number of elements", &n)) != SM_OK ||
        (st = check_count(c, "$Elements", n, 4, 16)) != SM_OK)
        return st;
    if (c->major == 4 && ((st = rd_size(c, "the minimum element tag", &lo)) != SM_OK ||
                          (st = rd_size(c, "the maximum element tag", &hi)) != SM_OK))
        return st;
    int64_t left = n;
    if (c->major == 4) {
        for (int64_t b = 0; st == SM_OK && b < nblocks; b++)
            st = read_element_block(c, &left);
        if (st == SM_OK && left != 0)
            st = fail(c, "the element blocks hold %" PRId64 " elements, the $Elements header "
                         "announces %" PRId64, n - left, n);
    } else {
        for (int64_t i = 0; st == SM_OK && i < n; i++)
            st = read_element_v2(c, n - i);
    }
    c->bin = 0;
    c->have_elements = 1;
    return st == SM_OK ? expect_token(c, "$EndElements") : st;
}

/* ---- other sections ---- */

/* Skips to the line "$End<name>" (the section may be binary): memchr to
 * each newline, then byte by byte while "\n$End" matches. */
static sm_status skip_section(msh_in *c, const char *name)
{
    static const char end[] = "\n$End";
    size_t matched = 1; /* the section line ended with a newline */
    long start_line = c->r->token_line;
    for (;;) {
        unsigned char ch;
        if (matched == 0) {
            /* outside a match only a newline matters: memchr to it */
            const unsigned char *b;
            size_t avail;
            (void)sm__reader_window(c->r, &b, &avail); /* errors: at the end, as below */
            if (avail == 0)
                return sm_error_set(c->err, SM_ERR_FORMAT, "%s:%ld: section $%s has no $End%s",
                                    c->r->path, start_line, name, name);
            const unsigned char *nl = memchr(b, '\n', avail);
            sm__reader_consume(c->r, nl ? (size_t)(nl - b) : avail);
            if (!nl)
                continue;
        }
        if (sm__reader_bytes(c->r, &ch, 1) != SM_OK)
            return sm_error_set(c->err, SM_ERR_FORMAT, "%s:%ld: section $%s has no $End%s",
                                c->r->path, start_line, name, name);
        if (ch == '\n')
            c->r->line++;
        matched = ch == (unsigned char)end[matched] ? matched + 1 : (ch == '\n' ? 1 : 0);
        if (matched < sizeof end - 1)
            continue;
        /* the name follows "$End" at once: a token after whitespace (or a
         * '#' comment) would swallow the next line, maybe the real end */
        unsigned char next = ' ';
        size_t got = 0;
        int found = 0;
        if (sm__reader_peek(c->r, &next, 1, &got) == SM_OK && got == 1 && next != ' ' &&
            (unsigned)(next - '\t') > (unsigned)('\r' - '\t') && next != '#' &&
            sm__reader_token(c->r, &found) == SM_OK && found && strcmp(c->r->token, name) == 0)
            return SM_OK;
        matched = 0;
    }
}

static sm_status read_section(msh_in *c, const char *tok)
{
    if (strcmp(tok, "$PhysicalNames") == 0)
        return read_names(c);
    if (strcmp(tok, "$Entities") == 0)
        return read_entities(c);
    if (strcmp(tok, "$Nodes") == 0)
        return read_nodes(c);
    if (strcmp(tok, "$Elements") == 0)
        return read_elements(c);
    if (tok[0] != '$' || strncmp(tok, "$End", 4) == 0 || strcmp(tok, "$MeshFormat") == 0) {
        char q[64];
        sm__quote_token(tok, q, sizeof q);
        return sm__reader_fail_line(c->r, c->err, SM_ERR_FORMAT,
                                   "expected a section such as $Nodes, found %s", q);
    }
    char name[SM_TOKEN_LEN];
    snprintf(name, sizeof name, "%s", tok + 1);
    return skip_section(c, name);
}

int sm__msh_detect(sm_reader *r)
{
    char head[11];
    size_t got = 0;
    return sm__reader_peek(r, head, sizeof head, &got) == SM_OK && got == sizeof head &&
           memcmp(head, "$MeshFormat", sizeof head) == 0;
}

sm_status sm__msh_parse(sm_reader *r, sm_msh_data *d, sm_error *err)
{
    memset(d, 0, sizeof *d);
    d->lines.nidx = 2;
    d->triangles.nidx = 3;
    d->tetrahedra.nidx = 4;
    msh_in c;
    memset(&c, 0, sizeof c);
    c.r = r;
    c.err = err;
    c.d = d;
    sm_status st = read_format(&c);
    while (st == SM_OK) {
        int found;
        if ((st = sm__reader_token(r, &found)) != SM_OK) {
            st = fail_read(&c, st, "a section");
            break;
        }
        if (!found)
            break;
        st = read_section(&c, r->token);
    }
    if (st == SM_OK && !c.have_nodes)
        st = sm_error_set(err, SM_ERR_FORMAT, "%s: no $Nodes section", r->path);
    if (st == SM_OK && !c.have_elements)
        st = sm_error_set(err, SM_ERR_FORMAT, "%s: no $Elements section", r->path);
    for (int k = 0; k < 4; k++)
        free(c.ents[k]);
    free(c.tags);
    return st;
}

void sm__msh_data_free(sm_msh_data *d)
{
    free(d->coords);
    sm_msh_block *b[] = {&d->lines, &d->triangles, &d->tetrahedra};
    for (int k = 0; k < 3; k++) {
        free(b[k]->idx);
        free(b[k]->refs);
    }
    sm_mesh_names_free(d->names, d->nnames);
    memset(d, 0, sizeof *d);
}

/* ---- the volume mesh ---- */

static void copy_block(const sm_msh_block *b, int32_t *idx, int32_t *refs)
{
    if (b->count == 0)
        return;
    memcpy(idx, b->idx, (size_t)b->count * (size_t)b->nidx * sizeof(int32_t));
    memcpy(refs, b->refs, (size_t)b->count * sizeof(int32_t));
}

sm_status sm__msh_to_mesh(const char *path, sm_msh_data *d, sm_mesh **out,
                          sm_error *err)
{
    *out = NULL;
    int dim = d->tetrahedra.count > 0 ? 3 : 2;
    const sm_msh_block *elems = dim == 3 ? &d->tetrahedra : &d->triangles;
    const sm_msh_block *facets = dim == 3 ? &d->triangles : &d->lines;
    if (elems->count == 0)
        return sm_error_set(err, SM_ERR_FORMAT,
                            "%s: no elements (triangles in 2D or tetrahedra in 3D)", path);
    if (d->nnodes > SM_MAX_ENTITIES)
        return sm_error_set(err, SM_ERR_FORMAT, "%s: too many nodes", path);
    for (int64_t i = 0; dim == 2 && i < d->nnodes; i++)
        if (d->coords[3 * i + 2] != 0.0)
            return sm_error_set(err, SM_ERR_FORMAT,
                                "%s: triangles without tetrahedra and node %lld has z = %g: a "
                                "surface mesh is not a volume mesh (shapematch needs "
                                "tetrahedra in 3D, or a planar triangle mesh)",
                                path, (long long)i + 1, d->coords[3 * i + 2]);
    sm_mesh *m;
    sm_status st = sm_mesh_alloc(&m, dim, (int32_t)d->nnodes, (int32_t)elems->count,
                                 (int32_t)facets->count, err);
    if (st != SM_OK)
        return st;
    for (int64_t i = 0; i < d->nnodes; i++)
        for (int k = 0; k < dim; k++)
            m->coords[dim * i + k] = d->coords[3 * i + k];
    copy_block(elems, m->elems, m->elem_refs);
    copy_block(facets, m->facets, m->facet_refs);
    m->names = d->names;
    m->nnames = d->nnames;
    d->names = NULL;
    d->nnames = 0;
    *out = m;
    return SM_OK;
}
