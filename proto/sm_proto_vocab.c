/* The wire vocabulary tables (see sm_proto_vocab.h). */
#include "sm_proto_vocab.h"

#include <stdio.h>
#include <string.h>

#include <jansson.h>

#include "sm_payload.h"

const char *const sm_part_names[SM_NPARTS] = {"template", "target_mesh", "target_sol",
                                                SM_PART_NAME_TARGET_SURFACE, "template_landmarks",
                                                "target_landmarks", SM_PART_NAME_TARGET_IMAGE,
                                                SM_PART_NAME_TEMPLATE_SURFACE, SM_PART_NAME_TEMPLATE_IMAGE,
                                                "params", "name"};

const char *sm_part_name(sm_part part)
{
    return part >= 0 && part < SM_NPARTS ? sm_part_names[part] : NULL;
}

const sm_result_format sm_result_formats[SM_RESULT_FORMATS_N] = {
    {SM_RESULT_MESH, "mesh", "application/x-medit-mesh", "result.mesh"},
    {SM_RESULT_MESH, "meshb", "application/x-medit-meshb", "result.meshb"},
    {SM_RESULT_MESH, "vtu", "application/vnd.vtk.vtu+xml", "result.vtu"},
    {SM_RESULT_MESH, "binary", SM_PAYLOAD_MEDIA_TYPE, "result.smmesh"},
    {SM_RESULT_DISPLACEMENT, "sol", "application/x-medit-sol", "displacement.sol"},
    {SM_RESULT_DISPLACEMENT, "solb", "application/x-medit-solb", "displacement.solb"},
    {SM_RESULT_HISTORY, "csv", "text/csv", "history.csv"},
    {SM_RESULT_HISTORY, "json", "application/json", "history.json"},
};

static const char *const kind_names[SM_NRESULT_KINDS] = {"mesh", "displacement", "history"};

const char *sm_result_kind_name(sm_result_kind kind)
{
    return kind >= 0 && kind < SM_NRESULT_KINDS ? kind_names[kind] : NULL;
}

const sm_result_format *sm_result_formats_of(sm_result_kind kind, size_t *n)
{
    const sm_result_format *first = NULL;
    size_t count = 0;
    for (size_t i = 0; i < SM_RESULT_FORMATS_N; i++)
        if (sm_result_formats[i].kind == kind) {
            if (!first)
                first = &sm_result_formats[i];
            count++;
        }
    *n = count;
    return first;
}

const sm_result_format *sm_result_format_find(sm_result_kind kind, const char *name)
{
    for (size_t i = 0; i < SM_RESULT_FORMATS_N; i++)
        if (sm_result_formats[i].kind == kind && strcmp(sm_result_formats[i].name, name) == 0)
            return &sm_result_formats[i];
    return NULL;
}

/* ---- a choice of result files ---- */

unsigned sm_result_outputs_fix(unsigned outputs)
{
    const sm_result_format *csv = sm_result_format_find(SM_RESULT_HISTORY, "csv");
    return outputs | SM_RESULT_OUT_FORMAT((size_t)(csv - sm_result_formats));
}

int sm_result_output_gz(size_t i, unsigned outputs)
{
    return i < SM_RESULT_FORMATS_N && (outputs & SM_RESULT_OUT_GZ) &&
           sm_result_formats[i].kind != SM_RESULT_HISTORY &&
           strcmp(sm_result_formats[i].name, "vtu") != 0;
}

/* The bit of the mesh or displacement format named p[0..len), 0 if none. */
static unsigned output_bit(const char *p, size_t len)
{
    if (len == 2 && strncmp(p, "gz", 2) == 0)
        return SM_RESULT_OUT_GZ;
    if (len == 9 && strncmp(p, "vtu-ascii", 9) == 0)
        return SM_RESULT_OUT_VTU_ASCII | output_bit("vtu", 3);
    for (size_t i = 0; i < SM_RESULT_FORMATS_N; i++) {
        const sm_result_format *f = &sm_result_formats[i];
        if (f->kind != SM_RESULT_HISTORY && strlen(f->name) == len &&
            strncmp(f->name, p, len) == 0)
            return SM_RESULT_OUT_FORMAT(i);
    }
    return 0;
}

int sm_result_outputs_parse(const char *text, unsigned *outputs, char *msg, size_t cap)
{
    unsigned set = 0;
    for (const char *p = text;;) {
        const char *comma = strchr(p, ',');
        size_t len = comma ? (size_t)(comma - p) : strlen(p);
        unsigned bit = output_bit(p, len);
        if (!bit) {
            snprintf(msg, cap, "'%.*s' is not an output format (expected a comma-separated "
                               "list of " SM_RESULT_OUT_NAMES ")",
                     (int)(len > 40 ? 40 : len), p);
            return -1;
        }
        set |= bit;
        if (!comma)
            break;
        p = comma + 1;
    }
    if (!(set & ~SM_RESULT_OUT_GZ)) {
        snprintf(msg, cap, "'gz' compresses the formats it comes with: name at least one");
        return -1;
    }
    if ((set & SM_RESULT_OUT_GZ) && (set & SM_RESULT_OUT_VTU_ASCII)) {
        snprintf(msg, cap, "'vtu-ascii' with 'gz' would make a .vtu.gz, which ParaView does not "
                           "open: name vtu (zlib-compressed inside) or leave gz out");
        return -1;
    }
    *outputs = set;
    return 0;
}

int sm_job_name_check(const char *s, size_t n, char *why, size_t cap)
{
    if (n == 0) {
        snprintf(why, cap, "empty (leave it out for no name)");
        return -1;
    }
    if (n > SM_JOB_NAME_MAX) {
        snprintf(why, cap, "longer than %d bytes", SM_JOB_NAME_MAX);
        return -1;
    }
    for (size_t i = 0; i < n; i++)
        if ((unsigned char)s[i] < 0x20 || s[i] == 0x7f) {
            snprintf(why, cap, "holds a control character (byte %zu)", i + 1);
            return -1;
        }
    json_t *utf8 = json_stringn(s, n); /* NULL: not UTF-8 (jansson checks) */
    if (!utf8) {
        snprintf(why, cap, "not UTF-8 text");
        return -1;
    }
    json_decref(utf8);
    return 0;
}

static const char *const template_from_names[] = {"file", "medoid", "mean"};

const char *sm_template_from_name(sm_template_from f)
{
    return (unsigned)f < 3 ? template_from_names[f] : "?";
}

int sm_template_from_parse(const char *name, sm_template_from *out)
{
    for (int i = 0; name && i < 3; i++)
        if (strcmp(name, template_from_names[i]) == 0) {
            *out = (sm_template_from)i;
            return 0;
        }
    return -1;
}
