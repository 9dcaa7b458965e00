/* The live mesh route (see smd_live.h). */
#include "api/smd_live.h"
#include "jobs/smd_usecases.h"
#include "store/spool/smd_store.h"

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "sm_payload.h"
#include "sm_proto_vocab.h"
#include "worker/smd_worker.h"

typedef struct live_format {
    const char *name, *file, *media, *download;
} live_format;

static const live_format live_formats[] = {
    {"binary", SMD_LIVE_PAYLOAD, SM_PAYLOAD_MEDIA_TYPE, "latest.smmesh"},
    {"mesh", SMD_LIVE_MESH, SM_SNAPSHOT_MEDIA, "latest.mesh"},
};

/* The open live file of the job (fd >= 0), or -1 after replying. */
static int open_live(struct MHD_Connection *conn, smd_request *req, const live_format *f,
                     struct stat *st, enum MHD_Result *replied)
{
    smd_server *srv = req->srv;
    char path[PATH_MAX];
    /* another tenant's job does not exist for this one (as on every route) */
    int exists = smd_jobs_find(srv, req->id, req->who.tenant, req->who.admin, NULL);
    if (!exists) {
        *replied = smd_reply_problem(conn, req, 404, SMD_PROBLEM_NO_SUCH_JOB, "no job %s", req->id);
        return -1;
    }
    if (smd_store_path(srv->store, req->id, f->file, path, sizeof path) != 0) {
        *replied = smd_reply_problem(conn, req, 500, SMD_PROBLEM_INTERNAL, "path too long");
        return -1;
    }
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd >= 0 && fstat(fd, st) == 0)
        return fd;
    int e = errno;
    if (fd >= 0)
        close(fd);
    if (e == ENOENT)
        *replied = smd_reply_problem(conn, req, 404, SMD_PROBLEM_RESULT_NOT_READY,
                                     "job %s has published no shape yet (it is queued, or its "
                                     "run has not started)", req->id);
    else
        *replied = smd_reply_problem(conn, req, 500, SMD_PROBLEM_INTERNAL, "%s: %s", f->file,
                                     strerror(e));
    return -1;
}

enum MHD_Result smd_route_live_mesh(struct MHD_Connection *conn, smd_request *req)
{
    const char *format = MHD_lookup_connection_value(conn, MHD_GET_ARGUMENT_KIND, "format");
    const live_format *f = &live_formats[0];
    if (format) {
        f = NULL;
        for (size_t i = 0; i < sizeof live_formats / sizeof live_formats[0]; i++)
            if (strcmp(format, live_formats[i].name) == 0)
                f = &live_formats[i];
        if (!f)
            return smd_reply_problem(conn, req, 400, SMD_PROBLEM_BAD_REQUEST,
                                     "format: expected binary or mesh");
    }
    struct stat st;
    enum MHD_Result replied = MHD_YES;
    int fd = open_live(conn, req, f, &st, &replied);
    if (fd < 0)
        return replied;
    /* the open descriptor keeps this version whole while the worker
     * renames the next one over it */
    struct MHD_Response *resp = MHD_create_response_from_fd((uint64_t)st.st_size, fd);
    if (!resp) {
        close(fd);
        return smd_reply_problem(conn, req, 503, SMD_PROBLEM_UNAVAILABLE, "out of memory");
    }
    req->bytes_out += (uint64_t)st.st_size;
    char disposition[96];
    snprintf(disposition, sizeof disposition, "inline; filename=\"%s\"", f->download);
    MHD_add_response_header(resp, MHD_HTTP_HEADER_CONTENT_TYPE, f->media);
    MHD_add_response_header(resp, MHD_HTTP_HEADER_CONTENT_DISPOSITION, disposition);
    MHD_add_response_header(resp, MHD_HTTP_HEADER_CACHE_CONTROL, "no-store");
    return smd_reply(conn, req, 200, resp);
}
