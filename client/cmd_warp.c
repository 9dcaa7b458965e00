/* `shapematch warp`: carries points, a mesh or a field through the map
 * of a finished match, forward (template -> target) or inverse
 * (docs/warp.md).  The map is read from a result folder (result.mesh +
 * displacement.sol, as `run` and `fetch` write them) or downloaded from
 * a daemon job into a temporary folder with fetch's engine; the work is
 * the job layer's warp use case (job/sm_job_warp.h), as the daemon's and
 * Python's. */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cli.h"
#include "daemon_ops.h"
#include "job/sm_job_warp.h"
#include "remote.h"
#include "shapematch/sm_atomic.h"
#include "shapematch/sm_io.h"
#include "shapematch/sm_path.h"
#include "shapematch/sm_surface.h"
#include "sm_proto_vocab.h"
#include "warp_io.h"

/* A points file is read whole: at most this much. */
#define WARP_POINTS_MAX_BYTES ((size_t)1 << 31)

void cmd_warp_help(void)
{
    printf("Usage: shapematch warp (--result DIR | --job ID [--server URL]) [--inverse]\n"
           "                       [--strict | --outside extrapolate|flag|skip] [--normalize]\n"
           "                       (--points IN.csv|IN.npy | --mesh IN | --field IN.sol) -o OUT\n"
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
           "                          nearest element's affine map), so it reads back;\n"
           "                          or a NumPy .npy of shape (N, 2|3), float64 or\n"
           "                          float32 little-endian, C order.  OUT by its\n"
           "                          extension: .npy (the images, float64, no inside\n"
           "                          column), else CSV\n"
           "  --mesh FILE             a mesh (Medit, Gmsh, VTK) or surface (STL, OBJ, PLY,\n"
           "                          OFF, VTK, Medit, Gmsh): vertices moved, topology\n"
           "                          kept; OUT by its extension: .mesh/.meshb[.gz], .vtu,\n"
           "                          and for surfaces .stl, .obj, .ply, .off, .vtk\n"
           "  --field FILE            a .sol on the template's vertices (the result's,\n"
           "                          with --inverse): scalars kept, vectors mapped by the\n"
           "                          deformation gradient F, symmetric tensors T (Medit\n"
           "                          type 3) to F T F^T; OUT a .sol/.solb\n"
           "  --strict                refuse points outside the mesh (exit 2, naming the\n"
           "                          first one's CSV line, the header counted, or its\n"
           "                          0-based .npy row) instead of extrapolating them\n"
           "  --outside MODE          --points outside the mesh: extrapolate (the\n"
           "                          default: the nearest element's affine map), flag\n"
           "                          (NaN coordinates, inside 0), skip (left out of OUT;\n"
           "                          the summary line says how many)\n"
           "  --normalize             --field: vectors scaled to unit length (directions)\n"
           "  -o, --output FILE       the output ('-': standard output, --points only)\n"
           "  -q, --quiet             no summary line on stderr\n"
           "  -h, --help              this help\n"
           "\n");
    remote_help_connection(stdout);
    printf("\n%s", cli_exit_codes_help);
}

enum { W_RESULT, W_JOB, W_INVERSE, W_STRICT, W_NORMALIZE, W_POINTS, W_MESH, W_FIELD, W_OUTPUT,
       W_QUIET, W_OUTSIDE };

typedef struct warp_args {
    const char *result, *job, *points, *mesh, *field, *out, *outside;
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
    case W_OUTSIDE: slot = &a->outside; break;
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
    else if (a->outside && sm_job_warp_outside_from_name(a->outside) < 0)
        snprintf(msg, cap, "--outside: expected %s, got '%.40s'", SM_JOB_WARP_OUTSIDE_NAMES,
                 a->outside);
    else if (a->outside && sm_job_warp_outside_from_name(a->outside) && !a->points)
        snprintf(msg, cap, "--outside %s is for --points (a mesh's vertices outside are "
                 "extrapolated, or refused with --strict)", a->outside);
    else if (a->outside && sm_job_warp_outside_from_name(a->outside) && a->strict)
        snprintf(msg, cap, "give --strict or --outside %s, not both", a->outside);
    else if (strcmp(a->out, "-") == 0 && !a->points)
        snprintf(msg, cap, "-o -: standard output is for --points only");
    else if (a->job && remote_check_id(a->job, msg, cap) != 0)
        return -1;
    else
        return 0;
    return -1;
}

/* ------------------------------------------------------------ the map */

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

/* The exit code of a failed warp (job/sm_job_warp.h), its message
 * printed. */
static int failed(const sm_job_warp_report *rep, const sm_error *err)
{
    fprintf(stderr, "shapematch warp: %s\n", err->msg);
    if (rep->stage == SM_JOB_WARP_FORMAT)
        return CLI_EXIT_USAGE;
    if (err->code == SM_ERR_NOMEM && rep->stage != SM_JOB_WARP_INPUT)
        return CLI_EXIT_NUMERIC;
    return rep->stage == SM_JOB_WARP_OUTPUT ? CLI_EXIT_OUTPUT : CLI_EXIT_INPUT;
}

static int warp_points(const warp_args *a, sm_job_map *map, const sm_job_warp_request *rq)
{
    char *text = NULL, *answer = NULL;
    size_t len = 0, n = 0;
    sm_error err;
    sm_error_clear(&err);
    sm_job_warp_report rep;
    int rc;
    if (warp_read_file(a->points, WARP_POINTS_MAX_BYTES, &text, &len, &err) != SM_OK) {
        fprintf(stderr, "shapematch warp: %s%s%s\n", err.code == SM_ERR_IO ? "" : a->points,
                err.code == SM_ERR_IO ? "" : ": ", err.msg);
        return CLI_EXIT_INPUT;
    }
    sm_job_points_format in = sm_job_points_format_of(a->points);
    sm_job_points_format out = strcmp(a->out, "-") == 0 ? SM_JOB_POINTS_CSV
                                                         : sm_job_points_format_of(a->out);
    if (sm_job_warp_points_bytes(map, in, text, len, out, rq, &answer, &n, &rep, &err) != SM_OK) {
        rc = failed(&rep, &err);
        goto done;
    }
    rc = CLI_EXIT_OUTPUT;
    if (strcmp(a->out, "-") == 0) {
        if (fwrite(answer, 1, n, stdout) != n || fflush(stdout) != 0) {
            fprintf(stderr, "shapematch warp: cannot write to standard output\n");
            goto done;
        }
    } else if (sm_atomic_write_file(a->out, answer, n, 0, &err) != SM_OK) {
        fprintf(stderr, "shapematch warp: %s\n", err.msg);
        goto done;
    }
    if (!a->quiet)
        fprintf(stderr, "shapematch warp: %lld points %s, %lld outside the %s (%s)\n",
                (long long)rep.n, rep.direction == SM_WARP_FORWARD ? "forward" : "back",
                (long long)rep.noutside,
                rep.direction == SM_WARP_FORWARD ? "template" : "deformed mesh",
                rq->outside == SM_JOB_OUTSIDE_FLAG   ? "flagged: NaN"
                : rq->outside == SM_JOB_OUTSIDE_SKIP ? "skipped: not in the output"
                                                     : "extrapolated");
    rc = 0;
done:
    free(text);
    free(answer);
    return rc;
}

static int warp_mesh(const warp_args *a, sm_job_map *map, const sm_job_warp_request *rq)
{
    sm_error err;
    sm_error_clear(&err);
    sm_job_warp_report rep;
    if (sm_job_warp_mesh_file(map, a->mesh, a->out, rq, NULL, &rep, &err) != SM_OK)
        return failed(&rep, &err);
    if (!a->quiet)
        fprintf(stderr, "shapematch warp: %s -> %s: %ld vertices, %lld outside (extrapolated)\n",
                a->mesh, a->out, (long)rep.n, (long long)rep.noutside);
    return 0;
}

static int warp_field(const warp_args *a, sm_job_map *map, const sm_job_warp_request *rq)
{
    sm_error err;
    sm_error_clear(&err);
    sm_job_warp_report rep;
    if (sm_job_warp_field_file(map, a->field, a->out, rq, NULL, &rep, &err) != SM_OK)
        return failed(&rep, &err);
    int dim = sm_job_map_dim(map);
    if (!a->quiet)
        fprintf(stderr, "shapematch warp: %s field on %ld vertices carried %s\n",
                rep.ncomp == 1 ? "scalar" : rep.ncomp == dim ? "vector" : "symmetric tensor",
                (long)rep.n, rep.direction == SM_WARP_FORWARD ? "forward" : "back");
    return 0;
}

static int warp_run(const warp_args *a, const char *dir)
{
    sm_warp_direction d = a->inverse ? SM_WARP_INVERSE : SM_WARP_FORWARD;
    if (a->mesh && !sm_job_warp_output_known(a->out)) { /* before reading anything */
        fprintf(stderr, "shapematch warp: %s: the output format is chosen by its extension: "
                "%s\n", a->out, SM_SURFACE_WRITE_FORMATS);
        return CLI_EXIT_USAGE;
    }
    sm_job_map *map = NULL;
    sm_error err;
    sm_error_clear(&err);
    if (sm_job_map_open(dir, a->field ? 0u : 1u << d, &map, &err) != SM_OK) {
        fprintf(stderr, "shapematch warp: %s\n", err.msg);
        return err.code == SM_ERR_NOMEM ? CLI_EXIT_NUMERIC : CLI_EXIT_INPUT;
    }
    int outside = a->outside ? sm_job_warp_outside_from_name(a->outside) : 0;
    sm_job_warp_request rq = {.direction = d, .strict = a->strict, .normalize = a->normalize,
                              .outside = (sm_job_warp_outside)outside, .name = a->points};
    int rc = a->points ? warp_points(a, map, &rq)
             : a->mesh ? warp_mesh(a, map, &rq)
                       : warp_field(a, map, &rq);
    sm_job_map_free(map);
    return rc;
}

int cmd_warp(int argc, char **argv)
{
    static const cli_flag flags[] = {
        {"--result", 1, W_RESULT},       {"--job", 1, W_JOB},         {"--inverse", 0, W_INVERSE},
        {"--strict", 0, W_STRICT},       {"--normalize", 0, W_NORMALIZE}, {"--points", 1, W_POINTS},
        {"--mesh", 1, W_MESH},           {"--field", 1, W_FIELD},     {"--output", 1, W_OUTPUT},
        {"-o", 1, W_OUTPUT},             {"--quiet", 0, W_QUIET},     {"-q", 0, W_QUIET},
        {"--outside", 1, W_OUTSIDE},
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
