/* `shapematch warp`: carries points, a mesh or a field through the map
 * of a finished match, forward (template -> target) or inverse
 * (docs/warp.md).  The map is read from a result folder (result.mesh +
 * displacement.sol, as `run` and `fetch` write them) or downloaded from
 * a daemon job into a temporary folder with fetch's engine; the work is
 * core's sm_warp.h, the points CSV proto's sm_points_csv.h, and the
 * mesh and surface files warp_io.c's. */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cli.h"
#include "daemon_ops.h"
#include "job/sm_job_map.h"
#include "remote.h"
#include "shapematch/sm_atomic.h"
#include "shapematch/sm_io.h"
#include "shapematch/sm_path.h"
#include "shapematch/sm_warp.h"
#include "sm_points_csv.h"
#include "sm_proto_vocab.h"
#include "warp_io.h"

/* A points file is read whole: at most this much. */
#define WARP_POINTS_MAX_BYTES ((size_t)1 << 31)

void cmd_warp_help(void)
{
    printf("Usage: shapematch warp (--result DIR | --job ID [--server URL]) [--inverse]\n"
           "                       [--strict] [--normalize]\n"
           "                       (--points IN.csv | --mesh IN | --field IN.sol) -o OUT\n"
           "\n"
           "Carries points, a mesh or a field through the map of a finished match:\n"
           "forward from the template to the target (the default), or back with\n"
           "--inverse.  The map is the piecewise-linear one of the result: DIR/result.mesh\n"
           "(or .meshb, .gz) with DIR/displacement.sol (or .solb, .gz), as 'run' and\n"
           "'fetch' write them, or a daemon job's (--job ID: downloaded).\n"
           "\n"
           "  --result DIR            a result folder\n"
           "  --job ID                a successful job of the daemon at --server\n"
           "  --inverse               target -> template (located in the deformed mesh)\n"
           "  --points FILE           CSV, one point per line (x,y or x,y,z), an optional\n"
           "                          header line ('#' lines skipped; a header naming\n"
           "                          x,y[,z] among other columns, e.g. label: those pass\n"
           "                          through), or Slicer markups (.fcsv, .mrk.json: put\n"
           "                          in LPS); OUT keeps the order and columns and adds an\n"
           "                          'inside' column (0: outside the mesh, mapped by the\n"
           "                          nearest element's affine map), so it reads back\n"
           "  --mesh FILE             a mesh (Medit, Gmsh, VTK) or surface (STL, OBJ, PLY,\n"
           "                          OFF, VTK, Medit, Gmsh): vertices moved, topology\n"
           "                          kept; OUT by its extension: .mesh/.meshb[.gz], .vtu,\n"
           "                          and for surfaces .stl, .obj, .ply, .off, .vtk\n"
           "  --field FILE            a .sol on the template's vertices (the result's,\n"
           "                          with --inverse): scalars kept, vectors mapped by the\n"
           "                          deformation gradient F, symmetric tensors T (Medit\n"
           "                          type 3) to F T F^T; OUT a .sol/.solb\n"
           "  --strict                refuse points outside the mesh (exit 2, naming the\n"
           "                          first one's CSV line, the header counted) instead\n"
           "                          of flagging them\n"
           "  --normalize             --field: vectors scaled to unit length (directions)\n"
           "  -o, --output FILE       the output ('-': standard output, --points only)\n"
           "  -q, --quiet             no summary line on stderr\n"
           "  -h, --help              this help\n"
           "\n");
    remote_help_connection(stdout);
    printf("\n%s", cli_exit_codes_help);
}

enum { W_RESULT, W_JOB, W_INVERSE, W_STRICT, W_NORMALIZE, W_POINTS, W_MESH, W_FIELD, W_OUTPUT,
       W_QUIET };

typedef struct warp_args {
    const char *result, *job, *points, *mesh, *field, *out;
    int inverse, strict, normalize, quiet;
} warp_args;

static int warp_flag(void *user, int id, const char *flag, const char *value, char *msg,
                     size_t cap)
{
    warp_args *a = user;
    const char **slot = NULL;
    switch (id) {
    case CLI_ARG_POSITIONAL:
        snprintf(msg, cap, "unexpected argument '%.80s'", value);
        return -1;
    case W_RESULT: slot = &a->result; break;
    case W_JOB: slot = &a->job; break;
    case W_POINTS: slot = &a->points; break;
    case W_MESH: slot = &a->mesh; break;
    case W_FIELD: slot = &a->field; break;
    case W_OUTPUT: slot = &a->out; break;
    case W_INVERSE: a->inverse = 1; return 0;
    case W_STRICT: a->strict = 1; return 0;
    case W_NORMALIZE: a->normalize = 1; return 0;
    case W_QUIET: a->quiet = 1; return 0;
    default: return -1;
    }
    if (!value[0]) {
        snprintf(msg, cap, "%s: empty value", flag);
        return -1;
    }
    *slot = value;
    return 0;
}

static int warp_check(const warp_args *a, char *msg, size_t cap)
{
    int inputs = !!a->points + !!a->mesh + !!a->field;
    if (!a->result == !a->job)
        snprintf(msg, cap, "give the map with exactly one of --result DIR and --job ID");
    else if (inputs != 1)
        snprintf(msg, cap, "give exactly one of --points, --mesh and --field");
    else if (!a->out)
        snprintf(msg, cap, "missing required option -o/--output");
    else if (a->normalize && !a->field)
        snprintf(msg, cap, "--normalize is for --field");
    else if (strcmp(a->out, "-") == 0 && !a->points)
        snprintf(msg, cap, "-o -: standard output is for --points only");
    else if (a->job && remote_check_id(a->job, msg, cap) != 0)
        return -1;
    else
        return 0;
    return -1;
}

/* ------------------------------------------------------------ the map */

/* Reads the result's map (job/sm_job_map.h); an exit code. */
static int load_map(const char *cmd, const char *dir, sm_mesh **m, double **deformed)
{
    sm_error err;
    sm_error_clear(&err);
    if (sm_job_map_read(dir, m, deformed, &err) == SM_OK)
        return 0;
    fprintf(stderr, "shapematch %s: %s\n", cmd, err.msg);
    return err.code == SM_ERR_NOMEM ? CLI_EXIT_NUMERIC : CLI_EXIT_INPUT;
}

/* Removes the files of a temporary download folder, then the folder. */
static void remove_download(const char *dir)
{
    static const char *const files[] = {"result.mesh", "displacement.sol", "history.csv",
                                        SM_RESULT_SUMMARY_FILE};
    for (size_t i = 0; i < sizeof files / sizeof files[0]; i++) {
        char *p = sm_path_join(dir, files[i]);
        if (p)
            unlink(p);
        free(p);
    }
    rmdir(dir);
}

/* --job: the result downloaded into a fresh temporary folder. */
static int download_map(const warp_args *a, const remote_options *conn, char *dir, size_t cap)
{
    const char *tmp = getenv("TMPDIR");
    snprintf(dir, cap, "%s/shapematch-warp-XXXXXX", tmp && tmp[0] ? tmp : "/tmp");
    if (!mkdtemp(dir)) {
        fprintf(stderr, "shapematch warp: cannot create a temporary folder %s: %s\n", dir,
                strerror(errno));
        dir[0] = '\0';
        return CLI_EXIT_OUTPUT;
    }
    http_client c;
    int code = remote_open("warp", conn, &c);
    if (code != 0)
        return code;
    fetch_options fo = {.outdir = dir, .formats = FETCH_MESH | FETCH_SOL, .quiet = 1};
    code = remote_fetch(&c, "warp", conn->token != NULL, a->job, &fo);
    remote_close(&c);
    return code;
}

/* ------------------------------------------------------------- inputs */

static int warp_points(const warp_args *a, const sm_warp *w, sm_warp_direction dir)
{
    char *text = NULL;
    size_t len = 0;
    sm_error err;
    sm_error_clear(&err);
    sm_points p = {0};
    double *out = NULL;
    uint8_t *inside = NULL;
    char *csv = NULL;
    int rc = CLI_EXIT_INPUT;
    if (warp_read_file(a->points, WARP_POINTS_MAX_BYTES, &text, &len, &err) != SM_OK ||
        sm_points_csv_parse(text, len, 0, &p, &err) != SM_OK) {
        fprintf(stderr, "shapematch warp: %s%s%s\n", err.code == SM_ERR_IO ? "" : a->points,
                err.code == SM_ERR_IO ? "" : ": ", err.msg);
        goto done;
    }
    sm_points_to_frame(&p, SM_POINTS_FRAME_LPS); /* Slicer's RAS markups */
    if (p.dim != sm_warp_dim(w)) {
        fprintf(stderr, "shapematch warp: %s has %dD points and the map is %dD\n", a->points,
                p.dim, sm_warp_dim(w));
        goto done;
    }
    out = malloc((size_t)p.n * (size_t)p.dim * sizeof *out);
    inside = malloc((size_t)p.n);
    int64_t nout = 0;
    if (!out || !inside) {
        rc = CLI_EXIT_NUMERIC;
        fprintf(stderr, "shapematch warp: out of memory for %lld points\n", (long long)p.n);
        goto done;
    }
    if (sm_points_warp(w, dir, a->strict, &p, text, len, out, inside, &nout, &err) != SM_OK) {
        fprintf(stderr, "shapematch warp: %s: %s\n", a->points, err.msg);
        goto done;
    }
    size_t n;
    if (!(csv = sm_points_csv_format(&p, out, inside, &n))) {
        rc = CLI_EXIT_NUMERIC;
        fprintf(stderr, "shapematch warp: out of memory\n");
        goto done;
    }
    rc = CLI_EXIT_OUTPUT;
    if (strcmp(a->out, "-") == 0) {
        if (fwrite(csv, 1, n, stdout) != n || fflush(stdout) != 0) {
            fprintf(stderr, "shapematch warp: cannot write to standard output\n");
            goto done;
        }
    } else if (sm_atomic_write_file(a->out, csv, n, 0, &err) != SM_OK) {
        fprintf(stderr, "shapematch warp: %s\n", err.msg);
        goto done;
    }
    if (!a->quiet)
        fprintf(stderr, "shapematch warp: %lld points %s, %lld outside the %s (extrapolated)\n",
                (long long)p.n, dir == SM_WARP_FORWARD ? "forward" : "back", (long long)nout,
                dir == SM_WARP_FORWARD ? "template" : "deformed mesh");
    rc = 0;
done:
    free(text);
    free(csv);
    free(out);
    free(inside);
    sm_points_release(&p);
    return rc;
}

static int warp_field(const warp_args *a, const sm_mesh *m, const sm_warp *w,
                      sm_warp_direction dir)
{
    sm_error err;
    sm_error_clear(&err);
    sm_sol *s = NULL;
    int rc = CLI_EXIT_INPUT;
    if (sm_sol_read(a->field, &s, &err) != SM_OK) {
        fprintf(stderr, "shapematch warp: %s\n", err.msg);
        goto done;
    }
    if (s->nverts != m->nverts || s->dim != m->dim) {
        fprintf(stderr, "shapematch warp: %s is a %dD field on %ld vertices; the %s has %ld in %dD\n",
                a->field, s->dim, (long)s->nverts,
                dir == SM_WARP_FORWARD ? "template" : "result", (long)m->nverts, m->dim);
        goto done;
    }
    if (sm_warp_field(w, dir, s->ncomp, a->normalize, s->values, &err) != SM_OK) {
        fprintf(stderr, "shapematch warp: %s: %s\n", a->field, err.msg);
        goto done;
    }
    rc = CLI_EXIT_OUTPUT;
    if (sm_sol_write(a->out, s, &err) != SM_OK) {
        fprintf(stderr, "shapematch warp: %s\n", err.msg);
        goto done;
    }
    if (!a->quiet)
        fprintf(stderr, "shapematch warp: %s field on %ld vertices carried %s\n",
                s->ncomp == 1 ? "scalar" : s->ncomp == s->dim ? "vector" : "symmetric tensor",
                (long)s->nverts,
                dir == SM_WARP_FORWARD ? "forward" : "back");
    rc = 0;
done:
    sm_sol_free(s);
    return rc;
}

static int warp_run(const warp_args *a, const char *dir)
{
    sm_mesh *m = NULL;
    double *deformed = NULL;
    int rc = load_map("warp", dir, &m, &deformed);
    if (rc != 0)
        return rc;
    sm_warp_direction d = a->inverse ? SM_WARP_INVERSE : SM_WARP_FORWARD;
    unsigned locate = a->field ? 0u : 1u << d;
    sm_warp *w = NULL;
    sm_error err;
    sm_error_clear(&err);
    if (sm_warp_new(m, deformed, locate, &w, &err) != SM_OK) {
        fprintf(stderr, "shapematch warp: %s: %s\n", dir, err.msg);
        rc = CLI_EXIT_INPUT;
    } else if (a->points) {
        rc = warp_points(a, w, d);
    } else if (a->mesh) {
        rc = warp_mesh_file(a->mesh, a->out, w, d, a->strict, a->quiet);
    } else {
        rc = warp_field(a, m, w, d);
    }
    sm_warp_free(w);
    free(deformed);
    sm_mesh_free(m);
    return rc;
}

int cmd_warp(int argc, char **argv)
{
    static const cli_flag flags[] = {
        {"--result", 1, W_RESULT},       {"--job", 1, W_JOB},         {"--inverse", 0, W_INVERSE},
        {"--strict", 0, W_STRICT},       {"--normalize", 0, W_NORMALIZE}, {"--points", 1, W_POINTS},
        {"--mesh", 1, W_MESH},           {"--field", 1, W_FIELD},     {"--output", 1, W_OUTPUT},
        {"-o", 1, W_OUTPUT},             {"--quiet", 0, W_QUIET},     {"-q", 0, W_QUIET},
    };
    warp_args a;
    memset(&a, 0, sizeof a);
    remote_options conn;
    char msg[ARGS_MSG_LEN];
    switch (remote_parse(argc, argv, flags, sizeof flags / sizeof flags[0], 0, &conn, warp_flag,
                         &a, msg, sizeof msg)) {
    case ARGS_HELP:
        cmd_warp_help();
        return CLI_EXIT_OK;
    case ARGS_ERROR:
        return remote_usage_error("warp", msg);
    case ARGS_OK:
        break;
    }
    if (warp_check(&a, msg, sizeof msg) != 0)
        return remote_usage_error("warp", msg);
    if (a.result)
        return warp_run(&a, a.result);
    char dir[4096];
    int rc = download_map(&a, &conn, dir, sizeof dir);
    if (rc == 0)
        rc = warp_run(&a, dir);
    if (dir[0])
        remove_download(dir);
    return rc;
}
