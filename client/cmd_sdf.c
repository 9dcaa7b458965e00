/* `shapematch sdf`: the signed distance to a target surface, sampled at
 * the vertices of a background mesh — the target a matching run needs.
 *   shapematch sdf --surface S --background B -o OUT.sol
 *   shapematch sdf --surface S -o DIR   (DIR/background.mesh + .sol)
 * The surface is read by content (STL, OBJ, Medit, Gmsh), repaired
 * (orientation made consistent and outward) and its health report goes
 * to stderr.  Distances are exact (sm_sdf.h), negative inside. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "args.h"
#include "cli.h"
#include "shapematch/sm_image.h"
#include "shapematch/sm_io.h"
#include "shapematch/sm_path.h"
#include "shapematch/sm_sdf.h"
#include "shapematch/sm_surface.h"

typedef struct sdf_options {
    const char *surface, *background, *out;
    double size, padding; /* size 0: from the surface's box */
} sdf_options;

void cmd_sdf_help(void)
{
    printf("Usage: shapematch sdf --surface S --background B -o OUT.sol|OUT.vtu\n"
           "       shapematch sdf --surface S -o DIR|OUT.vtu [--background-size H]\n"
           "                      [--background-padding P]\n"
           "       shapematch sdf --image F -o DIR|OUT.nii.gz [--label N] [--level L]\n"
           "                      [--image-space lps|ras] [--smooth S] [--edt-out E.nrrd]\n"
           "                      [--background-size H] [--background-padding P]\n"
           "\n"
           "Signed distance to a surface (negative inside) at the vertices of a background\n"
           "mesh: B when given (written to OUT.sol/.solb, .gz by extension), else a\n"
           "generated one written with its distance to DIR/background.mesh and\n"
           "DIR/background.sol.\n"
           "\n"
           "  --surface FILE          target surface: STL, OBJ, PLY, OFF, PLY2, VTK\n"
           "                          .vtk/.vtu/.vtp, Medit or Gmsh .msh, optionally .gz\n"
           "  --background FILE       background mesh (Medit, Gmsh .msh or VTK .vtk/.vtu)\n"
           "  -o PATH                 OUT.sol with --background, else a directory; or\n"
           "                          OUT.vtu (either way): the background and its\n"
           "                          distance in one file for ParaView\n"
           "  --background-size H     generated background: cell size near the surface\n"
           "                          (default: the surface's mean edge length); cells\n"
           "                          double away from it (graded, non-conforming)\n"
           "  --background-padding P  generated background: margin around the surface\n"
           "                          box, as a fraction of its diagonal (default 0.1)\n"
           "\n"
           "  --image FILE            target label map: %s; its boundary's signed\n"
           "                          distance on a generated background (-o DIR), or\n"
           "                          on the image's own grid with its geometry (-o\n"
           "                          OUT.nii, .nii.gz, .nrrd or .mha: float32)\n"
           "  --label N               the label's voxels (default: every nonzero voxel)\n"
           "  --level L               float images: voxels of value >= L (default 0.5)\n"
           "  --image-space S         frame of the template's coordinates: lps (default;\n"
           "                          ITK, Slicer) or ras (NIfTI's world)\n"
           "  --smooth S              Gaussian smoothing of the label's mask before its\n"
           "                          boundary is taken, in voxels (default 1; 0: none)\n"
           "  --edt-out FILE          also write the plain voxel-centre signed EDT of the\n"
           "                          crop around the label (NRRD; -o OUT.nii.gz gives\n"
           "                          the accurate distance)\n"
           "\n"
           "The surface health report (holes, non-manifold edges, facets reoriented,\n"
           "duplicate and degenerate facets, components, bounding box) goes to stderr.\n"
           "\n%s",
           SM_IMAGE_FORMATS, cli_exit_codes_sdf_help);
}

static int has_suffix(const char *s, const char *suffix)
{
    size_t n = strlen(s), k = strlen(suffix);
    return n >= k && strcmp(s + n - k, suffix) == 0;
}

static int usage_error(const char *msg)
{
    fprintf(stderr, "shapematch sdf: %s\n(see 'shapematch sdf --help')\n", msg);
    return CLI_EXIT_USAGE;
}

static int parse(int argc, char **argv, sdf_options *o, int *done)
{
    char msg[ARGS_MSG_LEN];
    *done = 1;
    for (int i = 1; i < argc; i++) {
        char flag[64];
        const char *eq = strchr(argv[i], '=');
        size_t len = eq && argv[i][0] == '-' ? (size_t)(eq - argv[i]) : strlen(argv[i]);
        snprintf(flag, sizeof flag, "%.*s", (int)(len < 63 ? len : 63), argv[i]);
        if (strcmp(flag, "-h") == 0 || strcmp(flag, "--help") == 0) {
            cmd_sdf_help();
            return CLI_EXIT_OK;
        }
        const char **target = strcmp(flag, "--surface") == 0      ? &o->surface
                              : strcmp(flag, "--background") == 0 ? &o->background
                              : strcmp(flag, "-o") == 0           ? &o->out
                                                                  : NULL;
        int real = strcmp(flag, "--background-size") == 0 || strcmp(flag, "--background-padding") == 0;
        if (!target && !real) {
            snprintf(msg, sizeof msg, "unknown option '%.80s'", argv[i]);
            return usage_error(msg);
        }
        const char *value;
        if (args_take_value(argc, argv, &i, flag, eq && argv[i][0] == '-' ? eq + 1 : NULL, 1,
                            &value, msg, sizeof msg) != 0)
            return usage_error(msg);
        if (target) {
            *target = value;
            continue;
        }
        double *dst = strcmp(flag, "--background-size") == 0 ? &o->size : &o->padding;
        if (args_parse_real(flag, value, dst, msg, sizeof msg) != 0 || !(*dst >= 0))
            return usage_error(msg[0] ? msg : "expected a number >= 0");
    }
    if (!o->surface || !o->out)
        return usage_error("--surface and -o are required");
    static const char *const files[] = {".sol", ".solb", ".gz", ".mesh", ".meshb", ".msh",
                                        ".vtk", ".vtp"};
    for (size_t k = 0; !o->background && k < sizeof files / sizeof files[0]; k++)
        if (has_suffix(o->out, files[k]))
            return usage_error("without --background, -o names a directory (for "
                               "background.mesh and background.sol) or a .vtu file, not a "
                               "mesh or solution file");
    if (o->background && (o->size > 0 || o->padding >= 0))
        return usage_error("--background-size and --background-padding are for a generated "
                           "background (without --background)");
    *done = 0;
    return CLI_EXIT_OK;
}

static void print_health(const char *path, const sm_surface *s, const sm_surface_health *h)
{
    fprintf(stderr,
            "surface %s: %d vertices, %d %s, %lld component(s), %lld open\n"
            "  open edges (holes) %lld, non-manifold edges %lld, reoriented %lld "
            "(%lld within a piece, %lld piece(s) turned over), duplicate %lld, degenerate %lld\n"
            "  bounding box [%g, %g] x [%g, %g]",
            path, s->nverts, s->nfacets, s->dim == 3 ? "triangles" : "segments",
            (long long)h->components, (long long)h->open_components, (long long)h->open_edges,
            (long long)h->nonmanifold_edges, (long long)h->reoriented,
            (long long)h->reoriented_within, (long long)h->pieces_turned,
            (long long)h->duplicates, (long long)h->degenerate, h->lo[0], h->hi[0], h->lo[1],
            h->hi[1]);
    if (s->dim == 3)
        fprintf(stderr, " x [%g, %g]", h->lo[2], h->hi[2]);
    fputc('\n', stderr);
}

/* The generated background around the surface's box, graded toward the
 * surface; default size: the surface's mean edge length, not below a
 * quarter of the size of a uniform grid of 250k vertices. */
static int make_background(const sdf_options *o, const sm_surface *s, const sm_sdf *d,
                           const sm_surface_health *h, sm_mesh **bg)
{
    int dim = s->dim;
    double lo[3], hi[3], diag = 0;
    for (int k = 0; k < dim; k++)
        diag += (h->hi[k] - h->lo[k]) * (h->hi[k] - h->lo[k]);
    diag = sqrt(diag);
    double pad = (o->padding >= 0 ? o->padding : 0.1) * diag;
    for (int k = 0; k < dim; k++) {
        lo[k] = h->lo[k] - pad;
        hi[k] = h->hi[k] + pad;
    }
    double vol = 1;
    for (int k = 0; k < dim; k++)
        vol *= hi[k] - lo[k];
    double size = o->size > 0 ? o->size : fmax(sm_surface_mean_edge(s), pow(vol / 250000.0, 1.0 / dim) / 4);
    sm_error err;
    sm_error_clear(&err);
    if (sm_background_graded_new(dim, lo, hi, size, d, bg, &err) != SM_OK) {
        fprintf(stderr, "shapematch sdf: %s\n", err.msg);
        return CLI_EXIT_USAGE;
    }
    return CLI_EXIT_OK;
}

int cmd_sdf_write_dir(const char *dir, const sm_mesh *bg, const sm_sol *sol)
{
    sm_error err;
    sm_error_clear(&err);
    if (sm_mkdir_p(dir, &err) != SM_OK) {
        fprintf(stderr, "shapematch sdf: %s\n", err.msg);
        return CLI_EXIT_OUTPUT;
    }
    char *pm = sm_path_join(dir, "background.mesh");
    char *ps = sm_path_join(dir, "background.sol");
    sm_status st = pm && ps ? sm_mesh_write(pm, bg, &err) : SM_ERR_NOMEM;
    if (st == SM_OK)
        st = sm_sol_write(ps, sol, &err);
    free(pm);
    free(ps);
    if (st == SM_OK)
        return CLI_EXIT_OK;
    fprintf(stderr, "shapematch sdf: %s\n", err.msg[0] ? err.msg : "out of memory");
    return CLI_EXIT_OUTPUT;
}

static int write_outputs(const sdf_options *o, const sm_mesh *bg, const sm_sol *sol)
{
    if (!has_suffix(o->out, ".vtu") && !o->background)
        return cmd_sdf_write_dir(o->out, bg, sol);
    sm_error err;
    sm_error_clear(&err);
    if (has_suffix(o->out, ".vtu")) { /* one file for ParaView: mesh and distance */
        if (sm_vtu_write(o->out, bg, NULL, NULL, sol->values, &err) == SM_OK)
            return CLI_EXIT_OK;
    } else if (sm_sol_write(o->out, sol, &err) == SM_OK) {
        return CLI_EXIT_OK;
    }
    fprintf(stderr, "shapematch sdf: %s\n", err.msg[0] ? err.msg : "out of memory");
    return CLI_EXIT_OUTPUT;
}

static int compute(const sdf_options *o, sm_surface *s)
{
    sm_error err;
    sm_error_clear(&err);
    sm_surface_health h;
    sm_mesh *bg = NULL;
    sm_sdf *d = NULL;
    sm_sol *sol = NULL;
    int rc = CLI_EXIT_INPUT;
    if (sm_surface_repair(s, &h, &err) != SM_OK)
        goto fail;
    print_health(o->surface, s, &h);
    if (sm_sdf_new(s, &d, &err) != SM_OK)
        goto fail;
    if (o->background) {
        if (sm_mesh_read(o->background, &bg, &err) != SM_OK)
            goto fail;
        if (bg->dim != s->dim) {
            sm_error_set(&err, SM_ERR_INVALID, "%s is a %dD mesh and %s a %dD surface",
                         o->background, bg->dim, o->surface, s->dim);
            goto fail;
        }
    } else if ((rc = make_background(o, s, d, &h, &bg)) != CLI_EXIT_OK) {
        goto done;
    }
    rc = CLI_EXIT_INPUT;
    if (sm_sol_alloc(&sol, s->dim, bg->nverts, 1, &err) != SM_OK ||
        sm_sdf_signed(d, bg->nverts, bg->coords, sol->values, &err) != SM_OK)
        goto fail;
    fprintf(stderr, "distance at %d vertices of %s\n", bg->nverts,
            o->background ? o->background : "the generated background");
    rc = write_outputs(o, bg, sol);
    goto done;
fail:
    fprintf(stderr, "shapematch sdf: %s\n", err.msg);
done:
    sm_sol_free(sol);
    sm_sdf_free(d);
    sm_mesh_free(bg);
    return rc;
}

int cmd_sdf(int argc, char **argv)
{
    for (int i = 1; i < argc; i++)
        if (strcmp(argv[i], "--image") == 0 || strncmp(argv[i], "--image=", 8) == 0)
            return cmd_sdf_image(argc, argv);
    sdf_options o = {NULL, NULL, NULL, 0, -1};
    int done;
    int rc = parse(argc, argv, &o, &done);
    if (done)
        return rc;
    sm_surface *s = NULL;
    sm_error err;
    sm_error_clear(&err);
    if (sm_surface_read(o.surface, &s, &err) != SM_OK) {
        fprintf(stderr, "shapematch sdf: %s\n", err.msg);
        return CLI_EXIT_INPUT;
    }
    rc = compute(&o, s);
    sm_surface_free(s);
    return rc;
}
