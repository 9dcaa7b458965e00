/* The multipart part handling of POST /v1/jobs: libmicrohttpd's
 * PostProcessor, on a real in-process daemon, feeding the daemon's part
 * callbacks (smd_parts.h: part names, duplicates, transfer encodings, the
 * params cap, file parts streamed to disk, then the required-parts check
 * and the naming by content).  The input is a Content-Type value up to
 * its first newline, then the body; it is sent as one HTTP request.
 * Checks: the parts layer either keeps a first error that is a status the
 * daemon answers with, with a detail, or accepts a request whose parts
 * are all stored (files present, params within its cap) and whose hash is
 * set; the daemon answers every request.
 *
 * Speed: the daemon has no listening socket and no thread of its own;
 * each request is one end of a socketpair handed over with
 * MHD_add_connection, and MHD_run is called from the fuzzing thread until
 * the answer is complete (no TCP, no thread switch, no poll timeouts).
 * The upload folder is on tmpfs (/dev/shm) when there is one. */
#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include "fuzz_parts_check.h"
#include "api/smd_parts.h"
#include "base/smd_util.h"

int LLVMFuzzerInitialize(int *argc, char ***argv);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static struct MHD_Daemon *daemon_;
static const char *dir_;

typedef struct request {
    struct MHD_PostProcessor *pp;
    smd_parts parts;
} request;

static enum MHD_Result finish(struct MHD_Connection *conn, request *r)
{
    smd_parts_close(&r->parts);
    if (r->pp && MHD_destroy_post_processor(r->pp) != MHD_YES)
        smd_parts_fail(&r->parts, 400, "about:blank", "truncated");
    r->pp = NULL;
    fuzz_parts_finish(&r->parts);
    fuzz_parts_check(&r->parts);
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

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void)argc, (void)argv;
    dir_ = fuzz_parts_upload_dir("multipart");
    daemon_ = MHD_start_daemon(MHD_USE_NO_LISTEN_SOCKET, 0, NULL, NULL, on_request, NULL,
                               MHD_OPTION_NOTIFY_COMPLETED, on_completed, NULL,
                               MHD_OPTION_CONNECTION_TIMEOUT, 10u, MHD_OPTION_END);
    if (!daemon_)
        abort();
    return 0;
}

/* Sends what fits without blocking; returns the bytes sent (all, or
 * fewer when the daemon closed early: a refused request). */
static size_t send_some(int fd, const char *p, size_t n)
{
    ssize_t k = send(fd, p, n, MSG_NOSIGNAL | MSG_DONTWAIT);
    return k > 0 ? (size_t)k : 0;
}

/* Runs the daemon until the client end sees the answer and the close
 * (Connection: close), sending msg as the socket takes it.  The number of
 * rounds is bounded: a daemon that stops answering is a crash. */
static void exchange(int fd, const char *msg, size_t len)
{
    size_t sent = 0;
    char reply[4096];
    for (long round = 0; round < 1000000; round++) {
        if (sent < len)
            sent += send_some(fd, msg + sent, len - sent);
        if (MHD_run(daemon_) != MHD_YES)
            abort();
        ssize_t got = recv(fd, reply, sizeof reply, MSG_DONTWAIT);
        if (got == 0 || (got < 0 && errno != EAGAIN && errno != EWOULDBLOCK))
            return; /* answered and closed (or reset) */
    }
    abort(); /* no answer */
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
    int sv[2];
    if (socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, sv) != 0 ||
        fcntl(sv[1], F_SETFL, O_NONBLOCK) != 0)
        abort();
    /* the peer address MHD is given: loopback, as a local client's */
    struct sockaddr_in sa = {.sin_family = AF_INET, .sin_port = htons(40000),
                             .sin_addr.s_addr = htonl(INADDR_LOOPBACK)};
    if (MHD_add_connection(daemon_, sv[1], (struct sockaddr *)&sa, sizeof sa) != MHD_YES)
        abort();
    char head[512];
    int hn = snprintf(head, sizeof head,
                      "POST /v1/jobs HTTP/1.1\r\nHost: x\r\nContent-Type: %s\r\n"
                      "Content-Length: %zu\r\nConnection: close\r\n\r\n",
                      ctype, blen);
    char *msg = malloc((size_t)hn + blen);
    if (!msg)
        abort();
    memcpy(msg, head, (size_t)hn);
    if (blen)
        memcpy(msg + hn, body, blen);
    exchange(sv[0], msg, (size_t)hn + blen);
    free(msg);
    close(sv[0]);
    (void)MHD_run(daemon_); /* the closed connection's clean-up */
    smd_rmtree(inputs);
    return 0;
}
