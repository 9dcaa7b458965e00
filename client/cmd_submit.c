/* `shapematch submit`: sends a matching job to the daemon (POST /v1/jobs,
 * multipart/form-data with the parts template, target_mesh, target_sol and
 * params) and prints its id; `--wait -o OUTDIR` then follows it (watch)
 * and downloads its results (fetch).
 *
 * The job parameters are the options of `shapematch run` (args.c), sent as
 * the params JSON of proto/ (sm_params_to_json).  The files are streamed
 * from disk, never read whole into memory; files that are not gzip yet are
 * compressed on the way (the daemon recognises gzip from the content), so
 * an ASCII mesh crosses the network at a fraction of its size
 * (--no-compress sends them as they are). */
#include <errno.h>
#include <limits.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <zlib.h>

#include "cli.h"
#include "curl_api.h"
#include "daemon_ops.h"
#include "remote.h"
#include "submit_job.h"
#include "sm_proto_events.h"
#include "sm_proto_params.h"
#include "sm_proto_vocab.h"
#include "shapematch/sm_io.h"

/* zlib level for the uploads: the fastest; a mesh's text compresses well
 * even so, and the daemon is often on a fast link */
#define UPLOAD_GZIP_LEVEL 1
#define IDEMPOTENCY_KEY_MAX SM_IDEMPOTENCY_KEY_MAX /* proto/sm_proto_vocab.h */

/* ------------------------------------------------------------ uploads */

typedef struct upload {
    const char *part;            /* "template", ... */
    const char *path;
    FILE *f;
    curl_off_t size;             /* of the file on disk */
    int compress;                /* deflate on the fly into gzip */
    z_stream z;
    int z_ready;
    int in_eof, z_done;
    int err;                     /* errno of a failed read, or EIO for zlib */
    unsigned char in[64 * 1024];
} upload;

static size_t upload_read(char *buffer, size_t size, size_t nitems, void *arg)
{
    upload *u = arg;
    size_t max = size * nitems;
    if (!u->compress) {
        size_t n = fread(buffer, 1, max, u->f);
        if (n == 0 && ferror(u->f)) {
            u->err = errno ? errno : EIO;
            return CURL_READFUNC_ABORT;
        }
        return n;
    }
    u->z.next_out = (Bytef *)buffer;
    u->z.avail_out = (uInt)(max > (1u << 30) ? (1u << 30) : max);
    uInt avail = u->z.avail_out;
    while (u->z.avail_out > 0 && !u->z_done) {
        if (u->z.avail_in == 0 && !u->in_eof) {
            size_t n = fread(u->in, 1, sizeof u->in, u->f);
            if (n == 0) {
                if (ferror(u->f)) {
                    u->err = errno ? errno : EIO;
                    return CURL_READFUNC_ABORT;
                }
                u->in_eof = 1;
            }
            u->z.next_in = u->in;
            u->z.avail_in = (uInt)n;
        }
        int rc = deflate(&u->z, u->in_eof ? Z_FINISH : Z_NO_FLUSH);
        if (rc == Z_STREAM_END) {
            u->z_done = 1;
        } else if (rc != Z_OK && rc != Z_BUF_ERROR) {
            u->err = EIO;
            return CURL_READFUNC_ABORT;
        }
    }
    return avail - u->z.avail_out;
}

/* libcurl rewinds a body it must send again (e.g. after a redirect or an
 * authentication round trip); only a rewind to the start is needed. */
static int upload_seek(void *arg, curl_off_t offset, int origin)
{
    upload *u = arg;
    if (offset != 0 || origin != SEEK_SET)
        return CURL_SEEKFUNC_CANTSEEK;
    if (fseek(u->f, 0, SEEK_SET) != 0)
        return CURL_SEEKFUNC_FAIL;
    clearerr(u->f);
    if (u->compress) {
        if (deflateReset(&u->z) != Z_OK)
            return CURL_SEEKFUNC_FAIL;
        u->z.avail_in = 0;
        u->in_eof = u->z_done = 0;
    }
    return CURL_SEEKFUNC_OK;
}

static void upload_close(upload *u)
{
    if (u->z_ready)
        deflateEnd(&u->z);
    if (u->f)
        fclose(u->f);
    u->f = NULL;
    u->z_ready = 0;
}

/* Opens the file (a bad path is reported now, exit 2) and decides
 * whether it gets compressed. */
static int upload_open(upload *u, const char *part, const char *path, int allow_compress,
                       char *msg, size_t cap)
{
    memset(u, 0, sizeof *u);
    u->part = part;
    u->path = path;
    u->f = fopen(path, "rb");
    struct stat st;
    if (!u->f || fstat(fileno(u->f), &st) != 0) {
        snprintf(msg, cap, "%s: cannot read '%s': %s", part, path, strerror(errno));
        upload_close(u);
        return -1;
    }
    if (!S_ISREG(st.st_mode)) {
        snprintf(msg, cap, "%s: '%s' is not a regular file", part, path);
        upload_close(u);
        return -1;
    }
    u->size = (curl_off_t)st.st_size;
    unsigned char magic[2] = {0, 0};
    size_t n = fread(magic, 1, 2, u->f);
    int gzipped = n == 2 && magic[0] == 0x1f && magic[1] == 0x8b;
    if (fseek(u->f, 0, SEEK_SET) != 0) {
        snprintf(msg, cap, "%s: cannot read '%s': %s", part, path, strerror(errno));
        upload_close(u);
        return -1;
    }
    u->compress = allow_compress && !gzipped && u->size > 0;
    if (u->compress) {
        if (deflateInit2(&u->z, UPLOAD_GZIP_LEVEL, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY) !=
            Z_OK) {
            snprintf(msg, cap, "out of memory");
            upload_close(u);
            return -1;
        }
        u->z_ready = 1;
    }
    return 0;
}

static int add_file_part(curl_mime *mime, upload *u)
{
    curl_mimepart *part = curl_api.mime_addpart(mime);
    if (!part)
        return -1;
    const char *slash = strrchr(u->path, '/');
    const char *base = slash ? slash + 1 : u->path;
    char name[256];
    snprintf(name, sizeof name, "%s%s", base, u->compress ? ".gz" : "");
    if (curl_api.mime_name(part, u->part) != CURLE_OK || curl_api.mime_filename(part, name) != CURLE_OK ||
        curl_api.mime_type(part, u->compress ? "application/gzip" : "application/octet-stream") !=
            CURLE_OK)
        return -1;
    /* compressed: size unknown beforehand (chunked request body) */
    return curl_api.mime_data_cb(part, u->compress ? -1 : u->size, upload_read, upload_seek, NULL,
                             u) == CURLE_OK
               ? 0
               : -1;
}

/* ------------------------------------------------------------ options */

enum {
    SB_TEMPLATE,
    SB_TEMPLATE_SURFACE,
    SB_TEMPLATE_IMAGE,
    SB_TARGET_MESH,
    SB_TARGET_SOL,
    SB_TARGET_SURFACE,
    SB_TARGET_IMAGE,
    SB_LANDMARKS,
    SB_OUTPUT,
    SB_WAIT,
    SB_JSON,
    SB_QUIET,
    SB_KEY,
    SB_FORMAT,
    SB_RECONNECT,
    SB_NO_COMPRESS,
    SB_NAME
};

typedef struct submit_args {
    const char *template_path, *target_mesh_path, *target_sol_path, *target_surface_path,
        *target_image_path, *template_surface_path, *template_image_path;
    char landmarks[2][PATH_MAX]; /* --landmarks A,B: template's, target's ("" when not given) */
    const char *outdir;
    const char *idempotency_key;
    const char *name;
    int wait, json, quiet, no_compress;
    unsigned formats;
    int formats_given;
    double reconnect_timeout;
    job_options job;
} submit_args;

static int key_ok(const char *k)
{
    size_t n = strlen(k);
    if (n < 1 || n > IDEMPOTENCY_KEY_MAX)
        return 0;
    for (size_t i = 0; i < n; i++)
        if ((unsigned char)k[i] < 0x21 || (unsigned char)k[i] > 0x7e)
            return 0;
    return 1;
}

static int submit_flag(void *user, int id, const char *flag, const char *value, char *msg,
                       size_t cap)
{
    submit_args *a = user;
    switch (id) {
    case CLI_ARG_POSITIONAL:
        snprintf(msg, cap, "unexpected argument '%.80s' (submit takes options only)", value);
        return -1;
    case CLI_ARG_JOB:
        return job_option_apply(&a->job, flag, value, msg, cap);
    case SB_TEMPLATE:
    case SB_TEMPLATE_SURFACE:
    case SB_TEMPLATE_IMAGE:
    case SB_TARGET_MESH:
    case SB_TARGET_SOL:
    case SB_TARGET_SURFACE:
    case SB_TARGET_IMAGE:
    case SB_OUTPUT:
        if (!value[0]) {
            snprintf(msg, cap, "%s: empty path", flag);
            return -1;
        }
        if (id == SB_TEMPLATE)
            a->template_path = value;
        else if (id == SB_TEMPLATE_SURFACE)
            a->template_surface_path = value;
        else if (id == SB_TEMPLATE_IMAGE)
            a->template_image_path = value;
        else if (id == SB_TARGET_MESH)
            a->target_mesh_path = value;
        else if (id == SB_TARGET_SOL)
            a->target_sol_path = value;
        else if (id == SB_TARGET_SURFACE)
            a->target_surface_path = value;
        else if (id == SB_TARGET_IMAGE)
            a->target_image_path = value;
        else
            a->outdir = value;
        return 0;
    case SB_WAIT:
        a->wait = 1;
        return 0;
    case SB_JSON:
        a->json = 1;
        return 0;
    case SB_QUIET:
        a->quiet = 1;
        return 0;
    case SB_NO_COMPRESS:
        a->no_compress = 1;
        return 0;
    case SB_LANDMARKS: {
        /* split at the first comma, as `run` does */
        const char *comma = strchr(value, ',');
        size_t n = comma ? (size_t)(comma - value) : 0;
        if (!comma || n == 0 || !comma[1]) {
            snprintf(msg, cap, "%s: give TEMPLATE.csv,TARGET.csv (two files)", flag);
            return -1;
        }
        if (n >= sizeof a->landmarks[0] || strlen(comma + 1) >= sizeof a->landmarks[1]) {
            snprintf(msg, cap, "%s: path too long", flag);
            return -1;
        }
        memcpy(a->landmarks[0], value, n);
        a->landmarks[0][n] = '\0';
        snprintf(a->landmarks[1], sizeof a->landmarks[1], "%s", comma + 1);
        return 0;
    }
    case SB_KEY:
        if (!key_ok(value)) {
            snprintf(msg, cap, "%s: a key is 1 to %d printable ASCII characters without spaces",
                     flag, IDEMPOTENCY_KEY_MAX);
            return -1;
        }
        a->idempotency_key = value;
        return 0;
    case SB_NAME: {
        char why[96];
        if (sm_job_name_check(value, strlen(value), why, sizeof why) != 0) {
            snprintf(msg, cap, "%s: %s (a name is 1 to %d bytes of UTF-8 text)", flag, why,
                     SM_JOB_NAME_MAX);
            return -1;
        }
        a->name = value;
        return 0;
    }
    case SB_FORMAT:
        a->formats_given = 1;
        return fetch_parse_formats(flag, value, &a->formats, msg, cap);
    case SB_RECONNECT:
        return watch_parse_reconnect(flag, value, &a->reconnect_timeout, msg, cap);
    }
    return -1;
}

void cmd_submit_help(void)
{
    printf("Usage: shapematch submit --template T.mesh --target-mesh B.mesh --target-sol B.sol\n"
           "       shapematch submit --template T.mesh --target-surface S.stl [--target-mesh B.mesh]\n"
           "       shapematch submit --template T.mesh --target-image IMG [--label N]\n"
           "       shapematch submit --template-surface A.stl --target-surface B.stl\n"
           "       shapematch submit --template-image A.nii.gz [--template-label N] TARGET\n"
           "                         CLAMP [PARAMETERS] [--name NAME] [--json]\n"
           "                         [--idempotency-key K]\n"
           "       shapematch submit ... --wait -o OUTDIR [--format LIST]\n"
           "\n"
           "Sends a matching job to the daemon and prints its id on stdout.  The inputs\n"
           "and parameters are those of 'shapematch run'; the daemon checks them before it\n"
           "accepts the job (422 and exit code 7 when they cannot make a job).\n"
           "With --wait, follows the job to its end like 'shapematch watch' and downloads\n"
           "its results into OUTDIR like 'shapematch fetch'.\n"
           "\n"
           "Inputs:\n"
           "  --template FILE         template mesh: Medit .mesh/.meshb, Gmsh .msh, or VTK\n"
           "                          .vtk/.vtu (tetrahedra; planar triangles in 2D),\n"
           "                          optionally .gz\n"
           "  --template-surface FILE or a closed surface the daemon meshes into the\n"
           "                          template (nglib; --template-size H), the result's\n"
           "                          template.mesh\n"
           "  --template-image FILE   or a label map (the --target-image formats) whose\n"
           "                          --template-label the daemon meshes likewise\n"
           "  --target-mesh FILE      background mesh carrying the target distance\n"
           "  --target-sol FILE       signed distance, one value per background vertex\n"
           "                          (Medit .sol/.solb, optionally .gz)\n"
           "  --target-surface FILE   instead of --target-sol: the target's surface (STL, OBJ,\n"
           "                          PLY, OFF, PLY2, VTK .vtk/.vtu/.vtp, Medit, Gmsh .msh,\n"
           "                          optionally .gz); the daemon computes its signed\n"
           "                          distance on --target-mesh, or on a background it\n"
           "                          generates when --target-mesh is not given\n"
           "  --target-image FILE     instead of --target-sol: a label map in one file (NIfTI\n"
           "                          .nii/.nii.gz, NRRD .nrrd, MetaImage .mha; a detached\n"
           "                          .nhdr/.mhd is refused): the boundary of --label\n"
           "  --landmarks A.csv,B.csv matching points (template's, target's) that start\n"
           "                          --align (Kabsch/Umeyama), as for 'shapematch run'\n");
    job_options_help_background(stdout);
    printf("  --no-compress           send the files as they are (by default files that are\n"
           "                          not gzip yet are compressed on the way)\n"
           "\n");
    job_options_help(stdout);
    printf("\n"
           "Submission:\n"
           "  --name NAME             the job's name, shown by 'list', 'status', 'watch' and\n"
           "                          the web app (1 to 200 bytes of text)\n"
           "  --idempotency-key K     a retried submission with the same key returns the\n"
           "                          job the first one created instead of a new one\n"
           "  --json                  print the job's status document (JSON) instead of its\n"
           "                          id; with --wait, every event as one JSON line\n"
           "  --wait                  follow the job to its end, then fetch its results\n"
           "  -o, --output DIR        with --wait: where the results go (as for fetch)\n"
           "  --format LIST           with --wait: mesh formats to fetch (default "
           FETCH_DEFAULT_FORMATS_TEXT ")\n"
           "  --reconnect-timeout S   with --wait: as for watch (default %g)\n"
           "  -q, --quiet             no progress display\n"
           "  -h, --help              this help\n"
           "\n",
           REMOTE_RECONNECT_DEFAULT);
    remote_help_connection(stdout);
    printf("\n");
    remote_help_exit_codes(stdout);
}

/* ------------------------------------------------------------ command */

/* The usage rules beyond what each flag checks alone; NULL when fine. */
static const char *submit_usage_problem(submit_args *a, char *msg, size_t cap)
{
    int templates = !!a->template_path + !!a->template_surface_path + !!a->template_image_path;
    if (templates == 0)
        return "missing required option --template (or --template-surface, --template-image)";
    if (templates > 1)
        return "give one template: --template, --template-surface or --template-image";
    if (a->job.background.template_size > 0 && !a->template_surface_path && !a->template_image_path)
        return "--template-size sizes a template meshed from --template-surface or "
               "--template-image";
    if (a->job.background.template_label > 0 && !a->template_image_path)
        return "--template-label is the label of --template-image";
    if (a->target_surface_path && a->target_sol_path)
        return "--target-surface excludes --target-sol: give one target";
    if (a->target_image_path && (a->target_sol_path || a->target_surface_path))
        return a->target_sol_path ? "--target-image excludes --target-sol: give one target"
                                  : "--target-image excludes --target-surface: give one target";
    /* a surface or an image makes its own background */
    const char *own = a->target_surface_path ? a->target_surface_path : a->target_image_path;
    if (!own && !a->target_mesh_path)
        return "missing required option --target-mesh (or --target-surface, --target-image)";
    if (!own && !a->target_sol_path)
        return "missing required option --target-sol (or --target-surface, --target-image)";
    if (job_options_finish(&a->job, msg, cap) != 0 ||
        job_options_check_background(&a->job, own, a->target_mesh_path, msg, cap) != 0)
        return msg;
    if (a->landmarks[0][0] && a->job.params.align == SM_ALIGN_NONE)
        return "--landmarks needs an alignment: add --align rigid, similarity or affine";
    if (a->wait && !a->outdir)
        return "--wait needs -o/--output DIR for the results";
    if (!a->wait && a->outdir)
        return "-o/--output is for --wait (or use 'shapematch fetch ID -o DIR' later)";
    if (!a->wait && a->formats_given)
        return "--format is for --wait";
    return NULL;
}

/* What one submission holds between its steps; released by
 * submission_release_files whatever step failed. */
typedef struct submission {
    upload up[SM_PART_PARAMS]; /* the file parts by sm_part; part NULL when not sent */
    curl_mime *mime;
} submission;

static void submission_release_files(submission *s)
{
    for (int i = 0; i < SM_PART_PARAMS; i++)
        upload_close(&s->up[i]);
    if (s->mime)
        curl_api.mime_free(s->mime);
    s->mime = NULL;
}

/* Opens the files given (a bad path is an input error, exit 2, before any
 * request is made). */
static int submission_open_files(submission *s, const char *cmd, const submit_job *j)
{
    const char *paths[SM_PART_PARAMS] = {
        [SM_PART_TEMPLATE] = j->template_path, [SM_PART_TARGET_MESH] = j->target_mesh,
        [SM_PART_TARGET_SOL] = j->target_sol, [SM_PART_TARGET_SURFACE] = j->target_surface,
        [SM_PART_TEMPLATE_LANDMARKS] = j->landmarks[0],
        [SM_PART_TARGET_LANDMARKS] = j->landmarks[1], [SM_PART_TARGET_IMAGE] = j->target_image,
        [SM_PART_TEMPLATE_SURFACE] = j->template_surface,
        [SM_PART_TEMPLATE_IMAGE] = j->template_image};
    char msg[ARGS_MSG_LEN];
    for (int i = 0; i < SM_PART_PARAMS; i++) {
        /* the daemon reads landmark CSV as plain text: never compressed */
        int compress = !j->no_compress && i != SM_PART_TEMPLATE_LANDMARKS && i != SM_PART_TARGET_LANDMARKS;
        if (paths[i] && upload_open(&s->up[i], sm_part_names[i], paths[i], compress, msg,
                        sizeof msg) != 0) {
            fprintf(stderr, "shapematch %s: error: %s\n", cmd, msg);
            return CLI_EXIT_INPUT;
        }
    }
    return 0;
}

/* The multipart body: the file parts (streamed), params and the name. */
static int submission_build_form(submission *s, http_client *c, const char *cmd,
                                 const char *params, const char *name)
{
    s->mime = curl_api.mime_init(c->curl);
    int bad = !s->mime;
    for (int i = 0; i < SM_PART_PARAMS && !bad; i++)
        bad = s->up[i].part && add_file_part(s->mime, &s->up[i]) != 0;
    if (!bad) {
        curl_mimepart *pp = curl_api.mime_addpart(s->mime);
        bad = !pp || curl_api.mime_name(pp, sm_part_name(SM_PART_PARAMS)) != CURLE_OK ||
              curl_api.mime_data(pp, params, CURL_ZERO_TERMINATED) != CURLE_OK ||
              curl_api.mime_type(pp, "application/json") != CURLE_OK;
    }
    if (!bad && name) {
        curl_mimepart *np = curl_api.mime_addpart(s->mime);
        bad = !np || curl_api.mime_name(np, sm_part_name(SM_PART_NAME)) != CURLE_OK ||
              curl_api.mime_data(np, name, CURL_ZERO_TERMINATED) != CURLE_OK ||
              curl_api.mime_type(np, "text/plain; charset=utf-8") != CURLE_OK;
    }
    if (bad) {
        fprintf(stderr, "shapematch %s: error: out of memory\n", cmd);
        return CLI_EXIT_INPUT;
    }
    return 0;
}

/* POST /v1/jobs and its answer's job id. */
static int submission_post(submission *s, http_client *c, const char *cmd, int token_given,
                           const char *key, http_response *rs, char *id, size_t cap)
{
    char key_header[IDEMPOTENCY_KEY_MAX + 32];
    http_request rq = {.method = "POST", .path = "/v1/jobs", .accept = "application/json",
                       .mime = s->mime, .gzip = 1};
    if (key) {
        snprintf(key_header, sizeof key_header, "Idempotency-Key: %s", key);
        rq.headers[0] = key_header;
    }
    http_outcome out = http_perform(c, &rq, rs);
    const upload *failed = NULL;
    for (int i = 0; i < SM_PART_PARAMS && !failed; i++)
        if (s->up[i].part && s->up[i].err)
            failed = &s->up[i];
    if (failed) {
        fprintf(stderr, "shapematch %s: error: %s: cannot read '%s': %s\n", cmd, failed->part,
                failed->path, strerror(failed->err));
        return CLI_EXIT_INPUT;
    }
    if (out != HTTP_DONE || (rs->status != 201 && rs->status != 200))
        return remote_report(cmd, c, token_given, out, rs, "submitting the job");
    char msg[ARGS_MSG_LEN];
    json_t *doc = remote_json_object(rs);
    const char *jid = doc ? json_string_value(json_object_get(doc, "jobID")) : NULL;
    int ok = jid && remote_check_id(jid, msg, sizeof msg) == 0;
    if (ok)
        snprintf(id, cap, "%s", jid);
    json_decref(doc);
    if (!ok) {
        fprintf(stderr, "shapematch %s: error: bad response from %s: no valid jobID in the "
                        "job's status document\n", cmd, c->base);
        return CLI_EXIT_SERVER;
    }
    return 0;
}

int remote_submit_job(http_client *c, const char *cmd, int token_given, const submit_job *j,
                      http_response *rs, char *id, size_t cap)
{
    submission s;
    memset(&s, 0, sizeof s);
    memset(rs, 0, sizeof *rs);
    int code = submission_open_files(&s, cmd, j);
    if (code == 0)
        code = submission_build_form(&s, c, cmd, j->params_json, j->name);
    if (code == 0)
        code = submission_post(&s, c, cmd, token_given, j->idempotency_key, rs, id, cap);
    submission_release_files(&s);
    if (code != 0)
        http_response_free(rs);
    return code;
}

/* Prints the job's id (or the status document with --json). */
static void submission_print(const char *id, const submit_args *a, const http_response *rs)
{
    if (rs->status == 200 && !a->quiet)
        fprintf(stderr, "shapematch: the daemon already has a job for this "
                        "Idempotency-Key: %s (not submitted again)\n", id);
    if (a->json && !a->wait)
        remote_print_body(rs);
    else if (!a->json) {
        printf("%s\n", id);
        fflush(stdout);
    }
}

/* --wait: follow the job to its end like watch, then download like fetch. */
static int submission_wait(const char *id, const submit_args *a, http_client *c,
                           const remote_options *conn)
{
    watch_options wo = {.quiet = a->quiet, .json = a->json,
                        .reconnect_timeout = a->reconnect_timeout};
    int code = remote_watch(c, "submit", conn->token != NULL, id, &wo);
    if (code != CLI_EXIT_OK && code != CLI_EXIT_NOT_CONVERGED)
        return code;
    /* not converged: every output is still there to look at, as `run`
     * writes them; the exit code stays 10 unless the download fails */
    fetch_options fo = {.outdir = a->outdir, .formats = a->formats, .quiet = a->quiet,
                        .show_result = 0};
    int fetched = remote_fetch(c, "submit", conn->token != NULL, id, &fo);
    return fetched != CLI_EXIT_OK ? fetched : code;
}

int cmd_submit(int argc, char **argv)
{
    static const cli_flag flags[] = {
        {"--template", 1, SB_TEMPLATE},
        {"--template-surface", 1, SB_TEMPLATE_SURFACE},
        {"--template-image", 1, SB_TEMPLATE_IMAGE},
        {"--target-mesh", 1, SB_TARGET_MESH},
        {"--target-sol", 1, SB_TARGET_SOL},
        {"--target-surface", 1, SB_TARGET_SURFACE},
        {"--target-image", 1, SB_TARGET_IMAGE},
        {"--landmarks", 1, SB_LANDMARKS},
        {"--output", 1, SB_OUTPUT},
        {"-o", 1, SB_OUTPUT},
        {"--wait", 0, SB_WAIT},
        {"--json", 0, SB_JSON},
        {"--quiet", 0, SB_QUIET},
        {"-q", 0, SB_QUIET},
        {"--idempotency-key", 1, SB_KEY},
        {"--name", 1, SB_NAME},
        {"--format", 1, SB_FORMAT},
        {"--reconnect-timeout", 1, SB_RECONNECT},
        {"--no-compress", 0, SB_NO_COMPRESS},
    };
    submit_args a;
    memset(&a, 0, sizeof a);
    job_options_init(&a.job);
    a.formats = FETCH_DEFAULT_FORMATS;
    a.reconnect_timeout = REMOTE_RECONNECT_DEFAULT;
    remote_options conn;
    char msg[ARGS_MSG_LEN];
    switch (remote_parse(argc, argv, flags, sizeof flags / sizeof flags[0], 1, &conn, submit_flag,
                         &a, msg, sizeof msg)) {
    case ARGS_HELP:
        cmd_submit_help();
        return CLI_EXIT_OK;
    case ARGS_ERROR:
        return remote_usage_error("submit", msg);
    case ARGS_OK:
        break;
    }
    const char *problem = submit_usage_problem(&a, msg, sizeof msg);
    if (problem)
        return remote_usage_error("submit", problem);
    if (a.job.params.save_every > 0 && !a.quiet)
        fprintf(stderr, "shapematch submit: warning: --save-every: the daemon does not serve "
                        "intermediate meshes\n");
    /* physical names: the daemon takes numbers, the template has the names */
    int named = a.template_path ? job_options_resolve_names_at(&a.job, a.template_path, msg, sizeof msg)
                                : 0;
    if (named == CLI_EXIT_INPUT)
        fprintf(stderr, "shapematch submit: %s\n", msg);
    if (named)
        return named == CLI_EXIT_INPUT ? named : remote_usage_error("submit", msg);

    /* the daemon learns the dimension from the template; a ball clamp
     * already says how many coordinates it has */
    int dim = a.job.params.clamp == SM_CLAMP_BALL ? a.job.clamp_ball_dim : 0;
    char *params = sm_job_params_to_json(&a.job.params, &a.job.background, dim);
    if (!params)
        return remote_usage_error("submit", "the parameters cannot be encoded as JSON");
    submit_job j = {.template_path = a.template_path, .target_mesh = a.target_mesh_path,
                    .target_sol = a.target_sol_path, .target_surface = a.target_surface_path,
                    .target_image = a.target_image_path,
                    .template_surface = a.template_surface_path,
                    .template_image = a.template_image_path,
                    .landmarks = {a.landmarks[0][0] ? a.landmarks[0] : NULL,
                                  a.landmarks[1][0] ? a.landmarks[1] : NULL},
                    .params_json = params, .idempotency_key = a.idempotency_key, .name = a.name,
                    .no_compress = a.no_compress};
    http_client c;
    /* opening the client makes no connection: an unreadable file is still
     * refused (exit 2) before any request */
    int code = remote_open("submit", &conn, &c);
    int client_open = code == 0;
    char id[SM_JOB_ID_MAX + 1];
    http_response rs;
    if (code == 0 && (code = remote_submit_job(&c, "submit", conn.token != NULL, &j, &rs, id,
                                               sizeof id)) == 0) {
        submission_print(id, &a, &rs);
        http_response_free(&rs);
    }
    free(params);
    if (code == 0 && a.wait)
        code = submission_wait(id, &a, &c, &conn);
    if (client_open)
        remote_close(&c);
    return code;
}
