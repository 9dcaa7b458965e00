/* POST /v1/jobs: a multipart/form-data upload streamed to disk.
 *
 * Parts (each at most once): template, target_mesh, target_sol,
 * target_surface (files: .mesh/.meshb/.msh/.sol/.solb, STL/OBJ for the
 * surface, any of them gzip'ed: the format is sniffed from the content,
 * the client's file name is never used as a path) and params (JSON text,
 * as a field or a file).  template and params are required, and a
 * target: target_mesh + target_sol, or target_surface with an optional
 * target_mesh; target_surface with target_sol is a 422.  libmicrohttpd's
 * PostProcessor hands the parts over in pieces, which go straight into
 * SPOOL/tmp/up-XXXXXX/inputs/; nothing but params is held in memory.
 *
 * The whole body is capped at --max-upload (413, before reading anything
 * when Content-Length says so).  Too many submissions or unfinished jobs
 * of the tenant (address) get 429 before the body (smd_ratelimit.h).
 * When the body is complete, the connection is suspended and the inputs
 * are validated (sm_job_inputs.h) in a check process off the HTTP threads
 * (smd_check.h, bounded by --check-timeout); resumed, the handler refuses
 * a bad job with 413/422 and the reason, or hands a good one to the state
 * machine (smd_jobs_submit: jobs/<id> by rename, queued), 201.  An
 * unfinished upload (client gone, error) leaves nothing behind. */
#ifndef SMD_UPLOAD_H
#define SMD_UPLOAD_H

#include <stddef.h>

#include "api/smd_parts.h"
#include "http/smd_reply.h"

typedef struct smd_upload smd_upload;

/* First call of the request (headers received).  Replies itself and
 * returns its result when the request is refused at once (413, 415, 400,
 * 503, or the Idempotency-Key names an existing job); otherwise attaches
 * an upload to req and returns MHD_YES. */
enum MHD_Result smd_upload_begin(struct MHD_Connection *conn, smd_request *req);

/* Later calls: a piece of body (size > 0) or the end (size 0). */
enum MHD_Result smd_upload_continue(struct MHD_Connection *conn, smd_request *req,
                                    const char *data, size_t *size);

/* Request over (completed or aborted): removes what was not committed. */
void smd_upload_free(smd_upload *u);

/* Another body than multipart (the OGC execute request, smd_ogc.h): the
 * decoder gets the body's pieces (within --max-upload), and at its end,
 * before the parts are checked and the job submitted exactly as for
 * multipart, stores the parts with smd_upload_part; either reports its
 * first error with smd_upload_fail.  free releases cls (always called,
 * once, also when the request is refused before its body). */
typedef struct smd_upload_decoder {
    void (*piece)(void *cls, smd_upload *u, const char *data, size_t n);
    void (*end)(void *cls, smd_upload *u);
    void (*free)(void *cls);
} smd_upload_decoder;

/* smd_upload_begin for a body of Content-Type ctype (a prefix; 415 with
 * ctype_detail otherwise), decoded by dec. */
enum MHD_Result smd_upload_begin_decoded(struct MHD_Connection *conn, smd_request *req,
                                         const char *ctype, const char *ctype_detail,
                                         const smd_upload_decoder *dec, void *dec_cls);
/* One whole part, as if it came in a multipart body (name: a part name). */
void smd_upload_part(smd_upload *u, const char *name, const void *data, size_t n);
/* The request's problem (the first one reported is kept). */
void smd_upload_fail(smd_upload *u, unsigned status, const char *type, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
/* A header the 201 of a new job carries (Preference-Applied). */
void smd_upload_created_header(smd_upload *u, const char *name, const char *value);

/* smd_sniff_medit (for tests) is in smd_parts.h. */

/* 1 when key is an acceptable Idempotency-Key (1..255 visible ASCII). */
int smd_idempotency_key_valid(const char *key);

#endif
