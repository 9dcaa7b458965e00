/* `shapematch fetch ID -o OUTDIR [--format LIST]`: downloads the results of
 * a successful job into OUTDIR, the same set of files `shapematch run`
 * writes:
 *   result.mesh / result.meshb / result.vtu / result.smmesh
 *                      GET /v1/jobs/{id}/results/mesh?format=...
 *   displacement.sol   GET .../results/displacement?format=sol
 *   history.csv        GET .../results/history?format=csv
 *   summary.json       GET .../results (the summary document)
 * Transfers ask for compression (libcurl decodes it).  Every file is
 * written under a temporary name and renamed into place; summary.json
 * comes last (an older one is removed first), so its presence means the
 * set is complete and from one job. */
#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cli.h"
#include "fsutil.h"
#include "remote.h"
#include "shapematch/sm_atomic.h"
#include "shapematch/sm_path.h"
#include "sm_json.h"
#include "sm_proto_events.h"
#include "sm_proto_vocab.h"

/* --format bits of proto's mesh formats (sm_proto_vocab.h: file names and
 * media types) */
typedef struct mesh_format {
    unsigned bit;
    const char *name;      /* ?format= and --format value */
} mesh_format;

static const mesh_format mesh_formats[] = {
    {FETCH_MESH, "mesh"},
    {FETCH_MESHB, "meshb"},
    {FETCH_VTU, "vtu"},
    {FETCH_BINARY, "binary"},
    {FETCH_SOL, "sol"},
    {FETCH_SOLB, "solb"},
};
#define N_MESH_ONLY 4 /* the first ones are mesh formats, then displacement */
#define N_MESH_FORMATS (sizeof mesh_formats / sizeof mesh_formats[0])

int fetch_parse_formats(const char *flag, const char *text, unsigned *out, char *msg,
                        size_t cap)
{
    unsigned set = 0;
    const char *p = text;
    for (;;) {
        const char *comma = strchr(p, ',');
        size_t len = comma ? (size_t)(comma - p) : strlen(p);
        size_t k;
        for (k = 0; k < N_MESH_FORMATS; k++)
            if (strlen(mesh_formats[k].name) == len && strncmp(mesh_formats[k].name, p, len) == 0)
                break;
        if (k == N_MESH_FORMATS) {
            snprintf(msg, cap, "%s: '%.*s' is not a result format (expected a comma-separated "
                               "list of mesh, meshb, vtu, binary, sol, solb)",
                     flag, (int)(len > 40 ? 40 : len), p);
            return -1;
        }
        set |= mesh_formats[k].bit;
        if (!comma)
            break;
        p = comma + 1;
    }
    *out = set;
    return 0;
}

/* ---------------------------------------------------------- downloads */

typedef struct file_sink {
    FILE *f;
    int err;
} file_sink;

static int write_to_file(void *user, const char *data, size_t len)
{
    file_sink *s = user;
    if (fwrite(data, 1, len, s->f) != len) {
        s->err = errno ? errno : EIO;
        return -1;
    }
    return 0;
}

/* GET /v1/jobs/ID/results/KIND?format=F into outdir/FILE (atomically),
 * checking the media type. */
static int download(http_client *c, const char *cmd, int token_given, const char *outdir,
                    const char *id, const sm_result_format *f)
{
    char what[160], path[192];
    const char *name = f->file, *media = f->media;
    snprintf(what, sizeof what, "downloading %s", name);
    snprintf(path, sizeof path, "/v1/jobs/%s/results/%s?format=%s", id,
             sm_result_kind_name(f->kind), f->name);
    char *final = sm_path_join(outdir, name);
    if (!final) {
        fprintf(stderr, "shapematch %s: error: out of memory\n", cmd);
        return CLI_EXIT_OUTPUT;
    }
    sm_atomic a;
    sm_error err;
    if (sm_atomic_open(&a, final, &err) != SM_OK) {
        fprintf(stderr, "shapematch %s: error: %s\n", cmd, err.msg);
        free(final);
        return CLI_EXIT_OUTPUT;
    }
    file_sink sink = {.f = a.f};
    http_request rq = {.path = path, .gzip = 1, .sink = write_to_file, .sink_user = &sink};
    http_response rs;
    http_outcome out = http_perform(c, &rq, &rs);
    int code = 0;
    if (out == HTTP_LOCAL_ERROR && sink.err) {
        fprintf(stderr, "shapematch %s: error: cannot write '%s': %s\n", cmd, final,
                strerror(sink.err));
        code = CLI_EXIT_OUTPUT;
    } else if (out != HTTP_DONE || rs.status != 200) {
        code = remote_report(cmd, c, token_given, out, &rs, what);
    } else if (!http_content_type_is(&rs, media)) {
        fprintf(stderr, "shapematch %s: error: bad response from %s while %s: content type '%s', "
                        "expected %s\n",
                cmd, c->base, what, rs.content_type, media);
        code = CLI_EXIT_SERVER;
    }
    http_response_free(&rs);
    if (code != 0) {
        sm_atomic_abort(&a);
    } else if (sm_atomic_commit(&a, SM_ATOMIC_FSYNC, &err) != SM_OK) {
        fprintf(stderr, "shapematch %s: error: %s\n", cmd, err.msg);
        code = CLI_EXIT_OUTPUT;
    }
    free(final);
    return code;
}

/* The job's state decides whether there is anything to fetch. */
static int check_job_state(http_client *c, const char *cmd, int token_given, const char *id)
{
    char path[128];
    snprintf(path, sizeof path, "/v1/jobs/%s", id);
    http_request rq = {.path = path, .accept = "application/json", .gzip = 1};
    http_response rs;
    http_outcome out = http_perform(c, &rq, &rs);
    if (out != HTTP_DONE || rs.status != 200) {
        int code = remote_report(cmd, c, token_given, out, &rs, "asking for the job's status");
        http_response_free(&rs);
        return code;
    }
    json_t *doc = remote_json_object(&rs);
    http_response_free(&rs);
    const char *status = doc ? json_string_value(json_object_get(doc, "status")) : NULL;
    const char *message = doc ? json_string_value(json_object_get(doc, "message")) : NULL;
    sm_job_state state;
    int code = 0;
    if (!status || sm_job_state_from_name(status, &state) != 0) {
        fprintf(stderr, "shapematch %s: error: bad response from %s: the job's status document "
                        "has no valid \"status\"\n",
                cmd, c->base);
        code = CLI_EXIT_SERVER;
    } else if (state == SM_JOB_FAILED) {
        fprintf(stderr, "shapematch %s: job %s failed%s%s: it has no results\n", cmd, id,
                message && message[0] ? ": " : "", message ? message : "");
        code = CLI_EXIT_JOB_FAILED;
    } else if (state == SM_JOB_DISMISSED) {
        fprintf(stderr, "shapematch %s: job %s was cancelled (dismissed): it has no results\n",
                cmd, id);
        code = CLI_EXIT_CANCELLED;
    } else if (state != SM_JOB_SUCCESSFUL) {
        fprintf(stderr,
                "shapematch %s: error: job %s is %s: no results yet ('shapematch watch %s' "
                "waits for its end)\n",
                cmd, id, state == SM_JOB_ACCEPTED ? "queued" : "running", id);
        code = CLI_EXIT_REFUSED;
    }
    json_decref(doc);
    return code;
}

/* GET .../results: the summary document, checked. */
static int get_summary(http_client *c, const char *cmd, int token_given, const char *id,
                       json_t **doc_out, sm_result *result)
{
    char path[128];
    snprintf(path, sizeof path, "/v1/jobs/%s/results", id);
    http_request rq = {.path = path, .accept = "application/json", .gzip = 1};
    http_response rs;
    http_outcome out = http_perform(c, &rq, &rs);
    if (out != HTTP_DONE || rs.status != 200) {
        int code = remote_report(cmd, c, token_given, out, &rs, "downloading the result summary");
        http_response_free(&rs);
        return code;
    }
    json_t *doc = remote_json_object(&rs);
    http_response_free(&rs);
    sm_error err;
    sm_error_clear(&err);
    if (!doc || sm_result_from_jansson(doc, "results", result, &err) != SM_OK) {
        fprintf(stderr, "shapematch %s: error: bad response from %s: the result summary %s\n",
                cmd, c->base, doc ? err.msg : "is not a JSON object");
        json_decref(doc);
        return CLI_EXIT_SERVER;
    }
    *doc_out = doc;
    return 0;
}

static int write_summary(const char *cmd, const char *outdir, const json_t *doc)
{
    char *text = sm_json_dumps(doc, 2);
    char *path = sm_path_join(outdir, SM_RESULT_SUMMARY_FILE);
    int code = 0;
    sm_error err;
    if (!text || !path) {
        fprintf(stderr, "shapematch %s: error: out of memory\n", cmd);
        code = CLI_EXIT_OUTPUT;
    } else {
        size_t n = strlen(text);
        text[n] = '\n'; /* replaces the NUL: written with its length */
        if (sm_atomic_write_file(path, text, n + 1, SM_ATOMIC_FSYNC, &err) != SM_OK) {
            fprintf(stderr, "shapematch %s: error: %s\n", cmd, err.msg);
            code = CLI_EXIT_OUTPUT;
        }
    }
    free(text);
    free(path);
    return code;
}

int remote_fetch(http_client *c, const char *cmd, int token_given, const char *id,
                 const fetch_options *o)
{
    char msg[ARGS_MSG_LEN];
    int code = check_job_state(c, cmd, token_given, id);
    if (code != 0)
        return code;
    if (fs_output_dir(o->outdir, msg, sizeof msg) != 0) {
        fprintf(stderr, "shapematch %s: error: output directory: %s\n", cmd, msg);
        return CLI_EXIT_OUTPUT;
    }
    /* an older summary.json must not vouch for files only partly replaced */
    char *old_summary = sm_path_join(o->outdir, SM_RESULT_SUMMARY_FILE);
    if (!old_summary) {
        fprintf(stderr, "shapematch %s: error: out of memory\n", cmd);
        return CLI_EXIT_OUTPUT;
    }
    if (unlink(old_summary) != 0 && errno != ENOENT) {
        fprintf(stderr, "shapematch %s: error: cannot remove the previous '%s': %s\n", cmd,
                old_summary, strerror(errno));
        free(old_summary);
        return CLI_EXIT_OUTPUT;
    }
    free(old_summary);

    json_t *summary = NULL;
    sm_result result;
    memset(&result, 0, sizeof result);
    code = get_summary(c, cmd, token_given, id, &summary, &result);
    if (code != 0)
        return code;
    char files[256] = "";
    unsigned formats = o->formats;
    if (!(formats & (FETCH_SOL | FETCH_SOLB)))
        formats |= FETCH_SOL; /* the displacement always comes */
    for (size_t k = 0; k < N_MESH_FORMATS && code == 0; k++) {
        if (!(formats & mesh_formats[k].bit))
            continue;
        const sm_result_format *f = sm_result_format_find(
            k < N_MESH_ONLY ? SM_RESULT_MESH : SM_RESULT_DISPLACEMENT, mesh_formats[k].name);
        code = download(c, cmd, token_given, o->outdir, id, f);
        strncat(files, f->file, sizeof files - strlen(files) - 1);
        strncat(files, ", ", sizeof files - strlen(files) - 1);
    }
    const sm_result_format *history = sm_result_format_find(SM_RESULT_HISTORY, "csv");
    if (code == 0)
        code = download(c, cmd, token_given, o->outdir, id, history);
    if (code == 0)
        code = write_summary(cmd, o->outdir, summary);
    json_decref(summary);
    if (code == 0 && !o->quiet) {
        if (o->show_result) {
            char line[512];
            remote_format_result(line, sizeof line, &result);
            fprintf(stderr, "shapematch: job %s: %s\n", id, line);
        }
        fprintf(stderr, "shapematch: results in %s: %s%s, %s\n", o->outdir, files,
                history->file, SM_RESULT_SUMMARY_FILE);
    }
    return code;
}

/* ------------------------------------------------------------ command */

void cmd_fetch_help(void)
{
    printf("Usage: shapematch fetch [--format LIST] [--quiet] -o OUTDIR ID\n"
           "\n"
           "Downloads the results of the successful job ID into OUTDIR (created if\n"
           "missing), the same files as 'shapematch run' writes:\n"
           "  result.mesh, result.meshb, result.vtu, result.smmesh  (by --format)\n"
           "  displacement.sol, displacement.solb   cumulative displacement per vertex\n"
           "  history.csv        one row per iteration\n"
           "  summary.json       stop reason, figures, timings, parameters\n"
           "Transfers are compressed when the daemon allows it.  Files are written under\n"
           "temporary names and renamed; summary.json comes last.\n"
           "\n"
           "Options:\n"
           "  -o, --output DIR        output directory (required)\n"
           "  --format LIST           mesh formats, comma-separated: mesh (Medit ASCII),\n"
           "                          meshb (Medit binary), vtu (ParaView, with the fields\n"
           "                          displacement and distance), binary (the API payload,\n"
           "                          proto/PAYLOAD.md), sol, solb (displacement; sol\n"
           "                          when neither is named); default " FETCH_DEFAULT_FORMATS_TEXT "\n"
           "  -q, --quiet             print nothing on success\n"
           "  -h, --help              this help\n"
           "\n");
    remote_help_connection(stdout);
    printf("\n");
    remote_help_exit_codes(stdout);
}

enum { F_OUTPUT, F_FORMAT, F_QUIET };

typedef struct fetch_args {
    const char *id;
    fetch_options opt;
} fetch_args;

static int fetch_flag(void *user, int id, const char *flag, const char *value, char *msg,
                      size_t cap)
{
    fetch_args *a = user;
    switch (id) {
    case CLI_ARG_POSITIONAL:
        if (a->id) {
            snprintf(msg, cap, "unexpected argument '%.80s' (fetch takes one job id)", value);
            return -1;
        }
        a->id = value;
        return 0;
    case F_OUTPUT:
        if (!value[0]) {
            snprintf(msg, cap, "%s: empty path", flag);
            return -1;
        }
        a->opt.outdir = value;
        return 0;
    case F_FORMAT:
        return fetch_parse_formats(flag, value, &a->opt.formats, msg, cap);
    case F_QUIET:
        a->opt.quiet = 1;
        return 0;
    }
    return -1;
}

int cmd_fetch(int argc, char **argv)
{
    static const cli_flag flags[] = {
        {"--output", 1, F_OUTPUT},
        {"-o", 1, F_OUTPUT},
        {"--format", 1, F_FORMAT},
        {"--quiet", 0, F_QUIET},
        {"-q", 0, F_QUIET},
    };
    fetch_args a;
    memset(&a, 0, sizeof a);
    a.opt.formats = FETCH_DEFAULT_FORMATS;
    a.opt.show_result = 1;
    remote_options conn;
    char msg[ARGS_MSG_LEN];
    switch (remote_parse(argc, argv, flags, sizeof flags / sizeof flags[0], 0, &conn, fetch_flag,
                         &a, msg, sizeof msg)) {
    case ARGS_HELP:
        cmd_fetch_help();
        return CLI_EXIT_OK;
    case ARGS_ERROR:
        return remote_usage_error("fetch", msg);
    case ARGS_OK:
        break;
    }
    if (!a.id)
        return remote_usage_error("fetch", "missing the job id");
    if (!a.opt.outdir)
        return remote_usage_error("fetch", "missing required option -o/--output");
    if (remote_check_id(a.id, msg, sizeof msg) != 0)
        return remote_usage_error("fetch", msg);
    http_client c;
    int code = remote_open("fetch", &conn, &c);
    if (code != 0)
        return code;
    code = remote_fetch(&c, "fetch", conn.token != NULL, a.id, &a.opt);
    remote_close(&c);
    return code;
}
