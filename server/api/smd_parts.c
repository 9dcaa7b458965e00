/* The parts of a multipart upload (see smd_parts.h). */
#include "api/smd_parts.h"

#include <errno.h>
#include <fcntl.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <unistd.h>
#include <zlib.h>

#include "sm_proto_params.h"
#include "sm_proto_text.h"
#include "http/smd_reply.h"
#include "base/smd_util.h"

void smd_parts_init(smd_parts *u, const char *dir)
{
    memset(u, 0, sizeof *u);
    u->dir = dir;
    u->fd = -1;
    u->current = -1;
}

void smd_parts_release(smd_parts *u)
{
    if (u->fd >= 0)
        close(u->fd);
    u->fd = -1;
    free(u->params);
    u->params = NULL;
}

void smd_parts_fail(smd_parts *u, unsigned status, const char *type, const char *fmt, ...)
{
    if (u->err_status)
        return; /* keep the first reason */
    u->err_status = status;
    u->err_type = type;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(u->err_detail, sizeof u->err_detail, fmt, ap);
    va_end(ap);
}

int smd_sniff_medit(const char *path, int *binary, int *gzip)
{
    unsigned char magic[4] = {0};
    FILE *f = fopen(path, "rb");
    if (!f)
        return -1;
    size_t n = fread(magic, 1, 2, f);
    fclose(f);
    *gzip = n == 2 && magic[0] == 0x1f && magic[1] == 0x8b;
    gzFile gz = gzopen(path, "rb");
    if (!gz)
        return -1;
    int got = gzread(gz, magic, 4);
    gzclose(gz);
    *binary = got == 4 && ((magic[0] == 1 && !magic[1] && !magic[2] && !magic[3]) ||
                           (!magic[0] && !magic[1] && !magic[2] && magic[3] == 1));
    return 0;
}


void smd_parts_close(smd_parts *u)
{
    if (u->fd >= 0) {
        if (close(u->fd) != 0)
            smd_parts_fail(u, 507, SMD_PROBLEM_STORAGE, "cannot store part '%s': %s", sm_part_names[u->current],
                 strerror(errno));
        u->fd = -1;
    }
    u->current = -1;
    u->current_bytes = 0;
}

static int open_part(smd_parts *u, sm_part id)
{
    if (smd_pathf(u->path[id], sizeof u->path[id], "%s/inputs/%s.upload", u->dir, sm_part_names[id]) != 0) {
        smd_parts_fail(u, 500, SMD_PROBLEM_INTERNAL, "spool path too long");
        return -1;
    }
    u->fd = open(u->path[id], O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0640);
    if (u->fd < 0) {
        smd_parts_fail(u, 507, SMD_PROBLEM_STORAGE, "cannot store part '%s': %s", sm_part_names[id], strerror(errno));
        return -1;
    }
    return 0;
}

/* What makes two requests "the same" for an Idempotency-Key: the bytes of
 * every part, whatever the multipart boundary and the order of parts. */
uint64_t smd_parts_hash(const smd_parts *u)
{
    uint64_t h = SMD_FNV_OFFSET;
    for (int i = 0; i < SM_NPARTS; i++) {
        if (!u->seen[i])
            continue; /* the hashes of requests without target_surface stay as they were */
        if (i == SM_PART_TARGET_SURFACE || i == SM_PART_TARGET_IMAGE ||
            i == SM_PART_TEMPLATE_SURFACE || i == SM_PART_TEMPLATE_IMAGE)
            h = smd_fnv1a(h, &i, sizeof i); /* tell it from the same bytes as target_mesh */
        h = smd_fnv1a(h, &u->part_hash[i], sizeof u->part_hash[i]);
    }
    return h ? h : 1; /* 0 = unknown (records from before the hash) */
}

enum MHD_Result smd_parts_on_part(void *cls, enum MHD_ValueKind kind, const char *key,
                               const char *filename, const char *content_type,
                               const char *transfer_encoding, const char *data, uint64_t off,
                               size_t size)
{
    smd_parts *u = cls;
    (void)kind;
    (void)filename;
    (void)content_type;
    if (u->err_status)
        return MHD_NO;
    int id = -1;
    for (int i = 0; i < SM_NPARTS; i++)
        if (key && strcmp(key, sm_part_names[i]) == 0)
            id = i;
    if (id < 0) {
        char shown[64];
        sm_text_printable_copy(shown, sizeof shown, key, "\"");
        smd_parts_fail(u, 400, SMD_PROBLEM_BAD_MULTIPART,
             "unknown part \"%s\": the parts are " SMD_UPLOAD_PARTS, shown);
        return MHD_NO;
    }
    if (id != u->current || (off == 0 && u->current_bytes > 0)) {
        /* a new part begins */
        smd_parts_close(u);
        if (u->seen[id]) {
            smd_parts_fail(u, 400, SMD_PROBLEM_BAD_MULTIPART, "part \"%s\" given more than once", sm_part_names[id]);
            return MHD_NO;
        }
        if (transfer_encoding && strcasecmp(transfer_encoding, "binary") != 0 &&
            strcasecmp(transfer_encoding, "7bit") != 0 && strcasecmp(transfer_encoding, "8bit") != 0) {
            char shown[64];
            sm_text_printable_copy(shown, sizeof shown, transfer_encoding, "\"");
            smd_parts_fail(u, 400, SMD_PROBLEM_BAD_MULTIPART,
                 "part \"%s\": Content-Transfer-Encoding \"%s\" is not supported (send it as binary)",
                 sm_part_names[id], shown);
            return MHD_NO;
        }
        u->seen[id] = 1;
        u->current = id;
        u->part_hash[id] = SMD_FNV_OFFSET;
        if (id < SM_PART_PARAMS && open_part(u, (sm_part)id) != 0)
            return MHD_NO;
    }
    if (size == 0)
        return MHD_YES;
    u->current_bytes += size;
    if ((id == SM_PART_TEMPLATE_LANDMARKS || id == SM_PART_TARGET_LANDMARKS) &&
        u->current_bytes > SM_LANDMARKS_MAX_BYTES) {
        smd_parts_fail(u, 422, SMD_PROBLEM_INVALID_INPUT, "%s: larger than %d bytes", sm_part_names[id],
                       SM_LANDMARKS_MAX_BYTES);
        return MHD_NO;
    }
    u->part_hash[id] = smd_fnv1a(u->part_hash[id], data, size);
    if (id == SM_PART_NAME) {
        if (u->name_len + size > SM_JOB_NAME_MAX) {
            smd_parts_fail(u, 422, SMD_PROBLEM_INVALID_INPUT, "name: longer than %d bytes",
                           SM_JOB_NAME_MAX);
            return MHD_NO;
        }
        memcpy(u->name + u->name_len, data, size);
        u->name_len += size;
        u->name[u->name_len] = '\0';
        return MHD_YES;
    }
    if (id == SM_PART_PARAMS) {
        if (u->params_len + size > SM_PARAMS_JSON_MAX_BYTES) {
            smd_parts_fail(u, 422, SMD_PROBLEM_INVALID_INPUT, "params: larger than %d bytes",
                 SM_PARAMS_JSON_MAX_BYTES);
            return MHD_NO;
        }
        char *p = realloc(u->params, u->params_len + size + 1);
        if (!p) {
            smd_parts_fail(u, 503, SMD_PROBLEM_UNAVAILABLE, "out of memory");
            return MHD_NO;
        }
        u->params = p;
        memcpy(u->params + u->params_len, data, size);
        u->params_len += size;
        u->params[u->params_len] = '\0';
        return MHD_YES;
    }
    while (size > 0) {
        ssize_t n = write(u->fd, data, size);
        if (n < 0 && errno == EINTR)
            continue;
        if (n <= 0) {
            smd_parts_fail(u, 507, SMD_PROBLEM_STORAGE, "cannot store part \"%s\": %s", sm_part_names[id],
                 n < 0 ? strerror(errno) : "short write");
            return MHD_NO;
        }
        data += n;
        size -= (size_t)n;
    }
    return MHD_YES;
}

/* Gives each uploaded file its final name: inputs/<part>.<ext>, with
 * the extension from the content, never from the client. */
static int name_file(smd_parts *u, sm_part id)
{
    int binary = 0, gzip = 0;
    if (smd_sniff_medit(u->path[id], &binary, &gzip) != 0) {
        smd_parts_fail(u, 500, SMD_PROBLEM_INTERNAL, "cannot read back part \"%s\"", sm_part_names[id]);
        return -1;
    }
    int landmarks = id == SM_PART_TEMPLATE_LANDMARKS || id == SM_PART_TARGET_LANDMARKS;
    if (landmarks && gzip) { /* the CSV reader takes plain text only */
        smd_parts_fail(u, 422, SMD_PROBLEM_INVALID_INPUT,
                       "%s: a landmark CSV is sent as plain text, not gzip-compressed",
                       sm_part_names[id]);
        return -1;
    }
    const char *ext = landmarks                      ? "csv"
                      : id == SM_PART_TARGET_SOL       ? (binary ? "solb" : "sol")
                      : id == SM_PART_TARGET_SURFACE || id == SM_PART_TEMPLATE_SURFACE
                          ? "surface" /* any surface format */
                      : id == SM_PART_TARGET_IMAGE || id == SM_PART_TEMPLATE_IMAGE
                          ? "image" /* NIfTI, NRRD, MetaImage */
                                                     : (binary ? "meshb" : "mesh");
    char final[PATH_MAX];
    if (smd_pathf(final, sizeof final, "%s/inputs/%s.%s%s", u->dir, sm_part_names[id], ext,
                  gzip ? ".gz" : "") != 0 ||
        rename(u->path[id], final) != 0) {
        smd_parts_fail(u, 500, SMD_PROBLEM_INTERNAL, "cannot store part \"%s\"", sm_part_names[id]);
        return -1;
    }
    memcpy(u->path[id], final, sizeof final);
    return 0;
}

/* Which parts a job needs: template and params, and a target: target_mesh
 * + target_sol, or target_surface (+ target_mesh optionally).  A missing
 * part is a 400 (a malformed request), a conflict a 422. */
int smd_parts_check(smd_parts *u)
{
    static const sm_part always[] = {SM_PART_TEMPLATE, SM_PART_PARAMS};
    for (size_t i = 0; i < sizeof always / sizeof always[0]; i++)
        if (!u->seen[always[i]] &&
            !(always[i] == SM_PART_TEMPLATE &&
              (u->seen[SM_PART_TEMPLATE_SURFACE] || u->seen[SM_PART_TEMPLATE_IMAGE]))) {
            smd_parts_fail(u, 400, SMD_PROBLEM_BAD_MULTIPART, "missing part \"%s\": the parts are " SMD_UPLOAD_PARTS,
                 sm_part_names[always[i]]);
            return -1;
        }
    char why[96];
    if (u->seen[SM_PART_NAME] && sm_job_name_check(u->name, u->name_len, why, sizeof why) != 0) {
        smd_parts_fail(u, 422, SMD_PROBLEM_INVALID_INPUT, "name: %s", why);
        return -1;
    }
    if (u->seen[SM_PART_TARGET_SURFACE] && u->seen[SM_PART_TARGET_SOL]) {
        smd_parts_fail(u, 422, SMD_PROBLEM_INVALID_INPUT,
             "target_surface excludes target_sol: give one target (target_surface with an optional "
             "target_mesh, or target_mesh and target_sol)");
        return -1;
    }
    if (u->seen[SM_PART_TARGET_IMAGE] &&
        (u->seen[SM_PART_TARGET_SOL] || u->seen[SM_PART_TARGET_SURFACE])) {
        smd_parts_fail(u, 422, SMD_PROBLEM_INVALID_INPUT,
                       "target_image excludes %s: give one target (target_image with an optional "
                       "target_mesh)",
                       sm_part_names[u->seen[SM_PART_TARGET_SOL] ? SM_PART_TARGET_SOL
                                                                  : SM_PART_TARGET_SURFACE]);
        return -1;
    }
    if (u->seen[SM_PART_TEMPLATE] + u->seen[SM_PART_TEMPLATE_SURFACE] +
            u->seen[SM_PART_TEMPLATE_IMAGE] > 1) {
        sm_part made = u->seen[SM_PART_TEMPLATE_SURFACE] ? SM_PART_TEMPLATE_SURFACE
                                                         : SM_PART_TEMPLATE_IMAGE;
        smd_parts_fail(u, 422, SMD_PROBLEM_INVALID_INPUT,
                       "%s excludes %s: give one template (a volume mesh, a closed surface or "
                       "a label map to mesh)",
                       sm_part_names[made],
                       sm_part_names[u->seen[SM_PART_TEMPLATE] ? SM_PART_TEMPLATE
                                                               : SM_PART_TEMPLATE_SURFACE]);
        return -1;
    }
    if (u->seen[SM_PART_TEMPLATE_LANDMARKS] != u->seen[SM_PART_TARGET_LANDMARKS]) {
        smd_parts_fail(u, 422, SMD_PROBLEM_INVALID_INPUT,
                       "%s: give both landmark parts, template_landmarks and target_landmarks",
                       sm_part_names[u->seen[SM_PART_TEMPLATE_LANDMARKS] ? SM_PART_TARGET_LANDMARKS
                                                                        : SM_PART_TEMPLATE_LANDMARKS]);
        return -1;
    }
    if (u->seen[SM_PART_TARGET_SURFACE] || u->seen[SM_PART_TARGET_IMAGE])
        return 0;
    for (int i = SM_PART_TARGET_MESH; i <= SM_PART_TARGET_SOL; i++)
        if (!u->seen[i]) {
            smd_parts_fail(u, 400, SMD_PROBLEM_BAD_MULTIPART,
                 "missing part \"%s\": the target is target_mesh and target_sol, or "
                 "target_surface or target_image (with an optional target_mesh)",
                 sm_part_names[i]);
            return -1;
        }
    return 0;
}

int smd_parts_name_files(smd_parts *u)
{
    for (int i = 0; i < SM_PART_PARAMS; i++)
        if (u->seen[i] && name_file(u, (sm_part)i) != 0)
            return -1;
    return 0;
}
