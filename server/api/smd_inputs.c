/* A job's input files (see smd_inputs.h).
 *
 * The upload stored each part as inputs/<part>.<ext>[.gz], the extension
 * from the content (smd_parts.c name_file): the file served is found by
 * trying those names, built from the part's name in the wire vocabulary,
 * never from the request path.  Sent as it is stored (a gzip upload stays
 * gzip: the client decompresses it), with sendfile. */
#include "api/smd_inputs.h"
#include "jobs/smd_usecases.h"

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include <jansson.h>

#include "sm_proto_vocab.h"
#include "store/spool/smd_store.h"

/* The extensions name_file gives, by part. */
static const char *const mesh_ext[] = {"mesh", "meshb", NULL};
static const char *const sol_ext[] = {"sol", "solb", NULL};
static const char *const surface_ext[] = {"surface", NULL};
static const char *const csv_ext[] = {"csv", NULL};
static const char *const image_ext[] = {"image", NULL};

/* Opens the stored file of part; its name in name[cap].  -1 when the job
 * has none (the part was not sent). */
static int open_part(smd_server *srv, const char *id, int part, char *name, size_t cap)
{
    const char *const *ext = part == SM_PART_TARGET_SOL       ? sol_ext
                             : part == SM_PART_TARGET_SURFACE || part == SM_PART_TEMPLATE_SURFACE
                                 ? surface_ext
                             : part == SM_PART_TARGET_IMAGE || part == SM_PART_TEMPLATE_IMAGE
                                 ? image_ext
                             : part == SM_PART_TEMPLATE_LANDMARKS || part == SM_PART_TARGET_LANDMARKS
                                 ? csv_ext
                                 : mesh_ext;
    for (int i = 0; ext[i]; i++)
        for (int gz = 0; gz < 2; gz++) {
            char rel[64], path[PATH_MAX];
            int n = snprintf(name, cap, "%s.%s%s", sm_part_names[part], ext[i], gz ? ".gz" : "");
            if (n < 0 || (size_t)n >= cap ||
                snprintf(rel, sizeof rel, "inputs/%s", name) >= (int)sizeof rel ||
                smd_store_path(srv->store, id, rel, path, sizeof path) != 0)
                continue;
            int fd = open(path, O_RDONLY | O_CLOEXEC);
            if (fd >= 0)
                return fd;
        }
    return -1;
}

/* 1 when the job is visible to the caller; else the 404 is sent. */
static int visible(struct MHD_Connection *conn, smd_request *req, enum MHD_Result *r)
{
    int exists = smd_jobs_find(req->srv, req->id, req->who.tenant, req->who.admin, NULL);
    if (!exists)
        *r = smd_reply_problem(conn, req, 404, SMD_PROBLEM_NO_SUCH_JOB, "no job %s", req->id);
    return exists;
}

enum MHD_Result smd_route_inputs(struct MHD_Connection *conn, smd_request *req)
{
    enum MHD_Result r;
    if (!visible(conn, req, &r))
        return r;
    json_t *list = json_array();
    for (int part = 0; list && part < SM_PART_PARAMS; part++) {
        char name[48], href[96];
        struct stat st;
        int fd = open_part(req->srv, req->id, part, name, sizeof name);
        if (fd < 0)
            continue;
        int ok = fstat(fd, &st) == 0;
        close(fd);
        snprintf(href, sizeof href, "/v1/jobs/%s/inputs/%s", req->id, sm_part_names[part]);
        if (ok && json_array_append_new(list, json_pack("{s:s,s:s,s:s,s:I}", "part", sm_part_names[part],
                                                        "file", name, "href", href, "bytes",
                                                        (json_int_t)st.st_size)) != 0) {
            json_decref(list);
            list = NULL;
        }
    }
    json_t *doc = list ? json_pack("{s:o}", "inputs", list) : NULL;
    if (!doc)
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE, "out of memory");
    return smd_reply_json(conn, req, 200, doc);
}

enum MHD_Result smd_route_input(struct MHD_Connection *conn, smd_request *req)
{
    /* the job first, as every job route: another tenant's job is "no job"
     * whatever the part asked for */
    enum MHD_Result r;
    if (!visible(conn, req, &r))
        return r;
    int part = -1;
    for (int i = 0; i < SM_PART_PARAMS; i++)
        if (strcmp(req->arg, sm_part_names[i]) == 0)
            part = i;
    if (part < 0)
        return smd_reply_problem(conn, req, 404, SMD_PROBLEM_NOT_FOUND,
                                 "no such input: the inputs are template, target_mesh, target_sol, "
                                 "target_surface, template_landmarks, target_landmarks, "
                                 "target_image, template_surface and template_image (the "
                                 "parameters are in the job's document)");
    smd_server *srv = req->srv;
    char name[48];
    int fd = open_part(srv, req->id, part, name, sizeof name);
    struct stat st;
    if (fd < 0 || fstat(fd, &st) != 0) {
        if (fd >= 0)
            close(fd);
        return smd_reply_problem(conn, req, 404, SMD_PROBLEM_NOT_FOUND,
                                 "job %s has no input %s (not sent, or deleted)", req->id,
                                 sm_part_names[part]);
    }
    struct MHD_Response *resp = MHD_create_response_from_fd((uint64_t)st.st_size, fd);
    if (!resp) {
        close(fd);
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE, "out of memory");
    }
    req->bytes_out += (uint64_t)st.st_size;
    char disposition[96];
    snprintf(disposition, sizeof disposition, "attachment; filename=\"%s\"", name);
    MHD_add_response_header(resp, MHD_HTTP_HEADER_CONTENT_TYPE, "application/octet-stream");
    MHD_add_response_header(resp, MHD_HTTP_HEADER_CONTENT_DISPOSITION, disposition);
    return smd_reply(conn, req, 200, resp);
}
