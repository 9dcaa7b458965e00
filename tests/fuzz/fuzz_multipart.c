/* The multipart part handling of POST /v1/jobs: libmicrohttpd's
 * PostProcessor, on a real in-process daemon, feeding the daemon's part
 * callbacks (smd_parts.h: part names, duplicates, transfer encodings, the
 * params cap, file parts streamed to disk, then the required-parts check
 * and the naming by content).  The input is a Content-Type value up to
 * its first newline, then the body; it is sent as one HTTP request over
 * loopback.  Checks: the parts layer either keeps a first error that is a
 * status the daemon answers with, with a detail, or accepts a request
 * whose parts are all stored (files present, params within its cap) and
 * whose hash is set; the daemon answers every request. */
#include <arpa/inet.h>
#include <errno.h>
#include <netinet/in.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/time.h>
#include <unistd.h>

#include "sm_proto_params.h"
#include "smd_parts.h"
#include "smd_util.h"

int LLVMFuzzerInitialize(int *argc, char ***argv);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static struct MHD_Daemon *daemon_;
static uint16_t port_;
static char dir_[64];

typedef struct request {
    struct MHD_PostProcessor *pp;
    smd_parts parts;
} request;

static void check_outcome(const smd_parts *p)
{
    static const unsigned allowed[] = {0, 400, 413, 422, 500, 507};
    int known = 0;
    for (size_t i = 0; i < sizeof allowed / sizeof allowed[0]; i++)
        known |= p->err_status == allowed[i];
    if (!known || (p->err_status && (!p->err_type || !p->err_detail[0])))
        abort();
    if (p->params_len > SM_PARAMS_JSON_MAX_BYTES || p->fd >= 0)
        abort();
    if (p->err_status)
        return;
    if (!p->seen[SM_PART_TEMPLATE] || !p->seen[SM_PART_PARAMS] || smd_parts_hash(p) == 0)
        abort();
    struct stat st;
    for (int i = 0; i < SM_PART_PARAMS; i++)
        if (p->seen[i] && stat(p->path[i], &st) != 0)
            abort(); /* an accepted file part is on disk under its final name */
}

static enum MHD_Result finish(struct MHD_Connection *conn, request *r)
{
    smd_parts_close(&r->parts);
    if (r->pp && MHD_destroy_post_processor(r->pp) != MHD_YES)
        smd_parts_fail(&r->parts, 400, "about:blank", "truncated");
    r->pp = NULL;
    if (!r->parts.err_status && smd_parts_check(&r->parts) == 0)
        smd_parts_name_files(&r->parts);
    check_outcome(&r->parts);
    struct MHD_Response *resp = MHD_create_response_from_buffer(0, NULL, MHD_RESPMEM_PERSISTENT);
    enum MHD_Result rc = MHD_queue_response(conn, r->parts.err_status ? r->parts.err_status : 201, resp);
    MHD_destroy_response(resp);
    return rc;
}

static enum MHD_Result on_request(void *cls, struct MHD_Connection *conn, const char *url,
                                  const char *method, const char *version, const char *upload,
                                  size_t *upload_size, void **req_cls)
{
    (void)cls, (void)url, (void)method, (void)version;
    request *r = *req_cls;
    if (!r) {
        r = calloc(1, sizeof *r);
        if (!r)
            abort();
        smd_parts_init(&r->parts, dir_);
        /* a small buffer: parts and headers arrive split in many pieces */
        r->pp = MHD_create_post_processor(conn, 1024, smd_parts_on_part, &r->parts);
        if (!r->pp)
            smd_parts_fail(&r->parts, 400, "about:blank", "no boundary");
        *req_cls = r;
        return MHD_YES;
    }
    if (*upload_size == 0)
        return finish(conn, r);
    if (r->pp && !r->parts.err_status && MHD_post_process(r->pp, upload, *upload_size) != MHD_YES)
        smd_parts_fail(&r->parts, 400, "about:blank", "malformed multipart body");
    if (r->parts.err_status)
        smd_parts_close(&r->parts);
    *upload_size = 0;
    return MHD_YES;
}

static void on_completed(void *cls, struct MHD_Connection *conn, void **req_cls,
                         enum MHD_RequestTerminationCode toe)
{
    (void)cls, (void)conn, (void)toe;
    request *r = *req_cls;
    if (!r)
        return;
    if (r->pp)
        MHD_destroy_post_processor(r->pp);
    smd_parts_release(&r->parts);
    free(r);
    *req_cls = NULL;
}

static void remove_dir(void)
{
    smd_rmtree(dir_);
}

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void)argc, (void)argv;
    snprintf(dir_, sizeof dir_, "/tmp/fuzz-multipart-XXXXXX");
    if (!mkdtemp(dir_))
        abort();
    atexit(remove_dir);
    struct sockaddr_in sa = {.sin_family = AF_INET, .sin_addr.s_addr = htonl(INADDR_LOOPBACK)};
    daemon_ = MHD_start_daemon(MHD_USE_INTERNAL_POLLING_THREAD | MHD_USE_EPOLL | MHD_USE_TURBO, 0, NULL, NULL, on_request, NULL,
                               MHD_OPTION_SOCK_ADDR, (struct sockaddr *)&sa,
                               MHD_OPTION_NOTIFY_COMPLETED, on_completed, NULL,
                               MHD_OPTION_CONNECTION_TIMEOUT, 10u, MHD_OPTION_END);
    if (!daemon_)
        abort();
    port_ = MHD_get_daemon_info(daemon_, MHD_DAEMON_INFO_BIND_PORT)->port;
    return 0;
}

static void send_all(int fd, const void *data, size_t n)
{
    const char *p = data;
    while (n > 0) {
        ssize_t k = send(fd, p, n, MSG_NOSIGNAL);
        if (k <= 0)
            return; /* the daemon closed early (a refused request) */
        p += k;
        n -= (size_t)k;
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    const uint8_t *nl = memchr(data, '\n', size < 256 ? size : 256);
    if (!nl)
        return 0;
    char ctype[256];
    size_t clen = (size_t)(nl - data);
    for (size_t i = 0; i < clen; i++) /* one header line, no NUL */
        ctype[i] = data[i] == '\r' || data[i] == '\0' ? ' ' : (char)data[i];
    ctype[clen] = '\0';
    const uint8_t *body = nl + 1;
    size_t blen = size - clen - 1;
    char inputs[128];
    snprintf(inputs, sizeof inputs, "%s/inputs", dir_);
    if (mkdir(inputs, 0700) != 0 && errno != EEXIST)
        abort();
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    struct sockaddr_in sa = {.sin_family = AF_INET, .sin_port = htons(port_),
                             .sin_addr.s_addr = htonl(INADDR_LOOPBACK)};
    struct timeval tv = {10, 0};
    setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    if (fd < 0 || connect(fd, (struct sockaddr *)&sa, sizeof sa) != 0)
        abort();
    char head[512];
    int hn = snprintf(head, sizeof head,
                      "POST /v1/jobs HTTP/1.1\r\nHost: x\r\nContent-Type: %s\r\n"
                      "Content-Length: %zu\r\nConnection: close\r\n\r\n",
                      ctype, blen);
    /* one send: no Nagle delay between the headers and the body */
    char *msg = malloc((size_t)hn + blen);
    if (!msg)
        abort();
    memcpy(msg, head, (size_t)hn);
    if (blen)
        memcpy(msg + hn, body, blen);
    send_all(fd, msg, (size_t)hn + blen);
    free(msg);
    char reply[4096];
    ssize_t got = recv(fd, reply, sizeof reply, 0);
    close(fd);
    if (got < 0 && (errno == EAGAIN || errno == EWOULDBLOCK))
        abort(); /* no answer within 10 s */
    smd_rmtree(inputs);
    return 0;
}
