#include "io/sm_medit_common.h"

#include <string.h>

#include "shapematch/sm_mesh.h"

/* ------------------------------------------------------------------ */
/* Medit helpers                                                       */
/* ------------------------------------------------------------------ */

sm_status sm__medit_detect(sm_reader *r, int *binary, sm_error *err)
{
    unsigned char head[4];
    size_t got = 0;
    sm_status st = sm__reader_peek(r, head, sizeof head, &got);
    if (st != SM_OK)
        return sm__reader_fail_byte(r, err, st, 0, "%s", r->why);
    if (got == 0)
        return sm_error_set(err, SM_ERR_FORMAT, "%s: empty file", r->path);
    uint32_t code = 0;
    if (got == 4)
        memcpy(&code, head, 4);
    *binary = got == 4 && (code == 1 || sm__bswap32(code) == 1);
    return SM_OK;
}

sm_status sm__meshb_read_header(sm_reader *r, sm_meshb_layout *lay, sm_error *err)
{
    int32_t code, version;
    r->swap = 0;
    sm_status st = sm__reader_i32(r, &code);
    if (st != SM_OK)
        return sm__reader_fail_byte(r, err, st, 0, "header: %s", r->why);
    if (code != 1) {
        if (sm__bswap32((uint32_t)code) != 1)
            return sm__reader_fail_byte(r, err, SM_ERR_FORMAT, 0,
                                       "not a Medit binary file (header code %ld, expected 1)",
                                       (long)code);
        r->swap = 1;
    }
    st = sm__reader_i32(r, &version);
    if (st != SM_OK)
        return sm__reader_fail_byte(r, err, st, 4, "header: %s", r->why);
    if (version < 1 || version > 4)
        return sm__reader_fail_byte(r, err, SM_ERR_FORMAT, 4,
                                   "unsupported version %ld (expected 1 to 4)", (long)version);
    lay->version = version;
    lay->real_size = version == 1 ? 4 : 8;
    lay->int_size = version == 4 ? 8 : 4;
    lay->pos_size = version >= 3 ? 8 : 4;
    return SM_OK;
}

sm_status sm__meshb_read_keyword(sm_reader *r, const sm_meshb_layout *lay,
                                int32_t *code, int64_t *next, sm_error *err)
{
    uint64_t start = sm__reader_offset(r);
    unsigned char probe;
    size_t got = 0;
    sm_status st = sm__reader_peek(r, &probe, 1, &got);
    if (st != SM_OK)
        return sm__reader_fail_byte(r, err, st, start, "%s", r->why);
    if (got == 0) {
        *code = -1;
        *next = 0;
        return SM_OK;
    }
    st = sm__reader_i32(r, code);
    if (st == SM_OK)
        st = sm__reader_int_sized(r, lay->pos_size, next);
    if (st != SM_OK)
        return sm__reader_fail_byte(r, err, st, start, "keyword header: %s", r->why);
    uint64_t here = sm__reader_offset(r);
    if (*next != 0 && (*next < 0 || (uint64_t)*next < here))
        return sm__reader_fail_byte(r, err, SM_ERR_FORMAT, start,
                                   "keyword %ld: next keyword position %lld points backwards",
                                   (long)*code, (long long)*next);
    if (*next != 0 && (uint64_t)*next - here > sm__reader_max_remaining(r))
        return sm__reader_fail_byte(r, err, SM_ERR_FORMAT, start,
                                   "keyword %ld: next keyword position %lld is past the end of "
                                   "the file",
                                   (long)*code, (long long)*next);
    return SM_OK;
}

sm_status sm__meshb_check_block_end(sm_reader *r, const char *section, int64_t next,
                                   sm_error *err)
{
    uint64_t here = sm__reader_offset(r);
    if (next != 0 && (uint64_t)next != here)
        return sm__reader_fail_byte(r, err, SM_ERR_FORMAT, here,
                                   "%s block ends here but the next keyword position says "
                                   "byte %lld (record size inconsistent with the header?)",
                                   section, (long long)next);
    return SM_OK;
}

sm_status sm__medit_check_count(sm_reader *r, int binary, const char *section, int64_t n,
                               uint64_t min_record_bytes, uint64_t where, sm_error *err)
{
    const char *fmt_neg = "negative count %lld for %s";
    const char *fmt_big = "%s count %lld exceeds the limit of %d";
    const char *fmt_fit = "%s count %lld cannot fit in the at most %llu bytes left in the file";
    uint64_t left = sm__reader_max_remaining(r);
    if (n < 0)
        return binary ? sm__reader_fail_byte(r, err, SM_ERR_FORMAT, where, fmt_neg, (long long)n,
                                            section)
                      : sm__reader_fail_line(r, err, SM_ERR_FORMAT, fmt_neg, (long long)n, section);
    if (n > SM_MAX_ENTITIES)
        return binary ? sm__reader_fail_byte(r, err, SM_ERR_FORMAT, where, fmt_big, section,
                                            (long long)n, SM_MAX_ENTITIES)
                      : sm__reader_fail_line(r, err, SM_ERR_FORMAT, fmt_big, section, (long long)n,
                                            SM_MAX_ENTITIES);
    const sm_read_limits *lim = r->limits;
    int vertices = strcmp(section, "Vertices") == 0 || strcmp(section, "SolAtVertices") == 0;
    int64_t most = !lim ? 0 : vertices ? lim->max_vertices : lim->max_elements;
    if (most > 0 && n > most) {
        const char *fmt_lim = "%s count %lld exceeds the limit of %lld %s";
        r->limits->hit = vertices ? SM_LIMIT_VERTICES : SM_LIMIT_ELEMENTS;
        const char *what = vertices ? "vertices" : "records";
        return binary ? sm__reader_fail_byte(r, err, SM_ERR_NOMEM, where, fmt_lim, section,
                                            (long long)n, (long long)most, what)
                      : sm__reader_fail_line(r, err, SM_ERR_NOMEM, fmt_lim, section, (long long)n,
                                            (long long)most, what);
    }
    /* An ASCII record's last token needs no separator after it. */
    uint64_t need = (uint64_t)n * min_record_bytes;
    if (!binary && need > 0)
        need--;
    if (need > left)
        return binary ? sm__reader_fail_byte(r, err, SM_ERR_FORMAT, where, fmt_fit, section,
                                            (long long)n, (unsigned long long)left)
                      : sm__reader_fail_line(r, err, SM_ERR_FORMAT, fmt_fit, section, (long long)n,
                                            (unsigned long long)left);
    return SM_OK;
}
