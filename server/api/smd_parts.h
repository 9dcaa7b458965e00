/* The parts of one multipart/form-data upload of POST /v1/jobs, below
 * smd_upload.c: libmicrohttpd's PostProcessor hands the parts over in
 * pieces to smd_parts_on_part, which checks each part's name (template,
 * target_mesh, target_sol, target_surface, params; each at most once),
 * its Content-Transfer-Encoding (binary, 7bit, 8bit), keeps params in
 * memory (at most SM_PARAMS_JSON_MAX_BYTES) and streams every other part
 * into DIR/inputs/<part>.upload, hashing each part's bytes (FNV-1a) for the
 * Idempotency-Key comparison.  The client's file name and content type are
 * never used.  The first error is kept (status, problem type, detail) and
 * stops the parsing; the caller replies with it.
 *
 * Kept apart from the request logic so that a fuzz target
 * (tests/fuzz/fuzz_multipart.c) drives it with the real PostProcessor on
 * hostile bodies. */
#ifndef SMD_PARTS_H
#define SMD_PARTS_H

#include <limits.h>
#include <stddef.h>
#include <stdint.h>

#include "http/smd_mhd.h"

#include "sm_proto_vocab.h"

/* For messages: every part, optional ones included. */
#define SMD_UPLOAD_PARTS                                                                   \
    "template, target_mesh, target_sol, target_surface, template_landmarks, target_landmarks, " \
    "target_image, template_surface, template_image, params and name"

typedef struct smd_parts {
    const char *dir;               /* borrowed: the upload folder (with inputs/) */
    int current;                   /* part being received, -1 none */
    uint64_t current_bytes;
    int fd;                        /* its file, -1 none */
    int seen[SM_NPARTS];
    char path[SM_NPARTS][PATH_MAX]; /* files of the file parts */
    char *params;                  /* params text, NUL-terminated */
    size_t params_len;
    char name[SM_JOB_NAME_MAX + 1]; /* the job's name, "" none (checked by
                                    * smd_parts_check) */
    size_t name_len;
    uint64_t part_hash[SM_NPARTS]; /* FNV-1a of each part's bytes */
    /* first error met; replied at the next call */
    unsigned err_status;
    const char *err_type;
    char err_detail[768];
} smd_parts;

void smd_parts_init(smd_parts *p, const char *dir);
/* Closes the open file and frees params (the files stay). */
void smd_parts_release(smd_parts *p);
/* Keeps the first error only. */
void smd_parts_fail(smd_parts *p, unsigned status, const char *type, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
/* The PostProcessor's iterator, cls = the smd_parts. */
enum MHD_Result smd_parts_on_part(void *cls, enum MHD_ValueKind kind, const char *key,
                                  const char *filename, const char *content_type,
                                  const char *transfer_encoding, const char *data, uint64_t off,
                                  size_t size);
/* Closes the part being received (its file). */
void smd_parts_close(smd_parts *p);
/* Which parts a job needs: template and params, and a target:
 * target_mesh + target_sol, or target_surface (+ target_mesh); a name
 * given is valid (sm_job_name_check).  0, or -1 with the error set (400
 * missing part, 422 conflict or bad name). */
int smd_parts_check(smd_parts *p);
/* Gives each file part its final name inputs/<part>.<ext>[.gz], the
 * extension from the content (smd_sniff_medit).  0 or -1 (error set). */
int smd_parts_name_files(smd_parts *p);
/* The request's hash for Idempotency-Key: the bytes of every part,
 * whatever the boundary and the order of parts; never 0. */
uint64_t smd_parts_hash(const smd_parts *p);

/* Sniffs a file's Medit flavour: sets *binary (first int32 is 1 in either
 * byte order) and *gzip (gzip magic).  -1 when unreadable. */
int smd_sniff_medit(const char *path, int *binary, int *gzip);

#endif
