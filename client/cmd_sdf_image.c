/* `shapematch sdf --image`: the signed distance to a label's boundary in
 * a segmentation (NIfTI, NRRD, MetaImage; sm_image.h), on a generated
 * background graded toward it — the target a matching run needs.
 *   shapematch sdf --image F [--label N] [--level L] [--image-space S] -o DIR
 * -o OUT.nii[.gz], .nrrd or .mha writes the distance on the image's own
 * grid instead (sm_job_image_grid_distance).
 * The label summary (voxels, components, world box) and its warnings go
 * to stderr.  The image, its selection and the background are
 * sm_job_image.h's, the job runner's own (run --target-image).  Background: the generated graded one (sm_background.c), not
 * the image grid: the grid cropped to a sphere of radius 20 voxels (box
 * padded by 10 %) has ~100k voxels, 600k tetrahedra, where the graded
 * background has the same cell size at the boundary with a fraction of
 * the vertices (measured in the report of this change and docs/formats.md). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "args.h"
#include "cli.h"
#include "shapematch/sm_clock.h"
#include "shapematch/sm_image.h"
#include "shapematch/sm_io.h"
#include "shapematch/sm_path.h"
#include "shapematch/sm_sdf.h"
#include "job/sm_job_image.h"

typedef struct image_options {
    const char *image, *out, *edt_out, *space;
    sm_image_select sel;
    double size, padding, smooth;
} image_options;

static int usage_error(const char *msg)
{
    fprintf(stderr, "shapematch sdf: %s\n(see 'shapematch sdf --help')\n", msg);
    return CLI_EXIT_USAGE;
}

static int parse(int argc, char **argv, image_options *o, int *done)
{
    char msg[ARGS_MSG_LEN];
    *done = 1;
    for (int i = 1; i < argc; i++) {
        char flag[64];
        const char *inline_value;
        if (args_split_flag(argv[i], flag, sizeof flag, &inline_value) != 0)
            snprintf(flag, sizeof flag, "?");
        const char **target = strcmp(flag, "--image") == 0          ? &o->image
                              : strcmp(flag, "-o") == 0             ? &o->out
                              : strcmp(flag, "--edt-out") == 0      ? &o->edt_out
                              : strcmp(flag, "--image-space") == 0  ? &o->space
                                                                    : NULL;
        int real = strcmp(flag, "--background-size") == 0 ||
                   strcmp(flag, "--background-padding") == 0 || strcmp(flag, "--level") == 0 ||
                   strcmp(flag, "--smooth") == 0;
        int label = strcmp(flag, "--label") == 0;
        if (!target && !real && !label) {
            snprintf(msg, sizeof msg, "unknown option '%.80s' with --image", argv[i]);
            return usage_error(msg);
        }
        const char *value;
        if (args_take_value(argc, argv, &i, flag, inline_value, 1, &value, msg, sizeof msg) != 0)
            return usage_error(msg);
        if (target) {
            *target = value;
        } else if (label) {
            long v;
            if (args_parse_int(flag, value, -2147483647L - 1, 4294967295L, &v, msg, sizeof msg) != 0)
                return usage_error(msg);
            o->sel.has_label = v != 0; /* 0: every nonzero voxel, as params label */
            o->sel.label = v;
        } else {
            double *dst = strcmp(flag, "--level") == 0    ? &o->sel.level
                          : strcmp(flag, "--smooth") == 0 ? &o->smooth
                          : strcmp(flag, "--background-size") == 0 ? &o->size : &o->padding;
            if (args_parse_real(flag, value, dst, msg, sizeof msg) != 0)
                return usage_error(msg);
            if (dst != &o->sel.level && !(*dst >= 0))
                return usage_error("expected a number >= 0");
        }
    }
    if (!o->image || !o->out)
        return usage_error("--image and -o are required");
    if (o->edt_out && sm_image_write_format(o->out))
        return usage_error("--edt-out goes with -o DIR (-o an image holds the accurate distance "
                           "on the image's grid)");
    if (o->space && strcmp(o->space, "lps") != 0 && strcmp(o->space, "ras") != 0)
        return usage_error("--image-space is lps or ras");
    *done = 0;
    return CLI_EXIT_OK;
}

static void summary(const image_options *o, const sm_job_image_info *im)
{
    const sm_label_stats *s = &im->stats;
    fprintf(stderr, "image %s: %s, %lld x %lld x %lld %s, spacing %g x %g x %g\n", o->image,
            im->format, (long long)im->dims[0], (long long)im->dims[1], (long long)im->dims[2],
            sm_voxel_type_name(im->type), im->spacing[0], im->spacing[1], im->spacing[2]);
    char what[64];
    if (o->sel.has_label)
        snprintf(what, sizeof what, "label %lld", (long long)o->sel.label);
    else if (im->type == SM_VOXEL_F32 || im->type == SM_VOXEL_F64)
        snprintf(what, sizeof what, "values >= %g", o->sel.level);
    else
        snprintf(what, sizeof what, "every nonzero voxel");
    fprintf(stderr, "  %s: %lld voxels, %lld component(s)", what, (long long)s->voxels,
            (long long)s->components);
    if (s->voxels)
        fprintf(stderr, ", world box (%s) [%g, %g] x [%g, %g] x [%g, %g]",
                o->space && strcmp(o->space, "ras") == 0 ? "RAS" : "LPS", s->lo[0], s->hi[0],
                s->lo[1], s->hi[1], s->lo[2], s->hi[2]);
    fputc('\n', stderr);
    if (s->touches_border)
        fprintf(stderr, "warning: label-touches-border: the label reaches the image's border; "
                        "it is closed there (the shape may be cut)\n");
    if (s->components > 1)
        fprintf(stderr, "warning: label-components: the label has %lld separate components\n",
                (long long)s->components);
}

/* The crop's voxel-centre signed EDT as NRRD (float32, the image's frame). */
static int write_edt(const image_options *o, const sm_image_target *t)
{
    int64_t n[3];
    double m[12];
    const float *dist;
    float *d;
    sm_error err;
    sm_error_clear(&err);
    sm_image_target_grid(t, n, m, &dist);
    (void)dist; /* the crop's geometry; the file holds the voxel-centre EDT */
    if (sm_image_target_voxel_edt(t, &d, &err) != SM_OK) {
        fprintf(stderr, "shapematch sdf: %s\n", err.msg);
        return CLI_EXIT_INPUT;
    }
    FILE *f = fopen(o->edt_out, "wb");
    if (!f) {
        perror(o->edt_out);
        free(d);
        return CLI_EXIT_OUTPUT;
    }
    int ras = o->space && strcmp(o->space, "ras") == 0;
    fprintf(f, "NRRD0004\ntype: float\ndimension: 3\nspace: %s\nsizes: %lld %lld %lld\n"
               "space directions: (%.17g,%.17g,%.17g) (%.17g,%.17g,%.17g) (%.17g,%.17g,%.17g)\n"
               "space origin: (%.17g,%.17g,%.17g)\nendian: little\nencoding: raw\n\n",
            ras ? "right-anterior-superior" : "left-posterior-superior", (long long)n[0],
            (long long)n[1], (long long)n[2], m[0], m[4], m[8], m[1], m[5], m[9], m[2], m[6],
            m[10], m[3], m[7], m[11]);
    size_t count = (size_t)(n[0] * n[1] * n[2]);
    int ok = fwrite(d, sizeof *d, count, f) == count;
    free(d);
    ok = fclose(f) == 0 && ok;
    if (!ok) {
        fprintf(stderr, "shapematch sdf: %s: write error\n", o->edt_out);
        return CLI_EXIT_OUTPUT;
    }
    return CLI_EXIT_OK;
}

/* The graded background around the label's surface (sm_job_image.h:
 * the one `run --target-image` builds, without a template), its
 * distance. */
static int distance(const image_options *o, sm_image_target *t, sm_job_image_info *info)
{
    sm_error err;
    sm_error_clear(&err);
    sm_mesh *bg = NULL;
    sm_sol *sol = NULL;
    double size = 0;
    int rc = CLI_EXIT_INPUT;
    double t0 = sm_clock_seconds(), t1 = t0, t2 = t0;
    if (sm_job_image_background(t, info, NULL, o->size, o->padding, &bg, &size, &err) != SM_OK ||
        (t1 = sm_clock_seconds(), sm_job_image_distance(t, bg, &sol, info, &err)) != SM_OK) {
        fprintf(stderr, "shapematch sdf: %s\n", err.msg);
    } else {
        t2 = sm_clock_seconds();
        rc = cmd_sdf_write_dir(o->out, bg, sol);
        fprintf(stderr, "distance at %d vertices of the generated background of size %g (%lld "
                        "exact, near the label's surface of %d triangles)\n"
                        "  seconds: background %.2f, distance %.2f, writing %.2f\n",
                bg->nverts, size, (long long)info->exact_vertices, info->surface_triangles,
                t1 - t0, t2 - t1, sm_clock_seconds() - t2);
    }
    sm_sol_free(sol);
    sm_mesh_free(bg);
    return rc;
}

/* -o OUT.nii.gz (or .nii, .nrrd, .mha): the accurate signed distance
 * at every voxel centre of the image, with the image's geometry. */
static int grid_distance(const image_options *o, sm_image_space space)
{
    sm_error err;
    sm_error_clear(&err);
    sm_job_image_info info;
    sm_image *d = NULL;
    double t0 = sm_clock_seconds();
    if (sm_job_image_grid_distance(o->image, NULL, &o->sel, space, o->smooth, &d, &info, &err) !=
        SM_OK) {
        if (info.stats.voxels > 0 || strstr(err.msg, "label-empty"))
            summary(o, &info);
        fprintf(stderr, "shapematch sdf: %s\n", err.msg);
        return CLI_EXIT_INPUT;
    }
    summary(o, &info);
    double t1 = sm_clock_seconds();
    int rc = CLI_EXIT_OK;
    if (sm_image_write(o->out, d, &err) != SM_OK) {
        fprintf(stderr, "shapematch sdf: %s\n", err.msg);
        rc = CLI_EXIT_OUTPUT;
    } else {
        fprintf(stderr, "distance at the %lld voxel centres of the image (exact next to the "
                        "label's surface of %d triangles) written to %s\n"
                        "  seconds: distance %.2f, writing %.2f\n",
                (long long)(d->dims[0] * d->dims[1] * d->dims[2]), info.surface_triangles,
                o->out, t1 - t0, sm_clock_seconds() - t1);
    }
    sm_image_free(d);
    return rc;
}

int cmd_sdf_image(int argc, char **argv)
{
    image_options o = {NULL, NULL, NULL, NULL, {0, 0, 0.5}, 0, -1, 1.0};
    int done;
    int rc = parse(argc, argv, &o, &done);
    if (done)
        return rc;
    sm_error err;
    sm_error_clear(&err);
    sm_job_image_info info;
    sm_image_target *t = NULL;
    sm_image_space space =
        o.space && strcmp(o.space, "ras") == 0 ? SM_IMAGE_SPACE_RAS : SM_IMAGE_SPACE_LPS;
    if (sm_image_write_format(o.out))
        return grid_distance(&o, space);
    if (sm_job_image_target(o.image, NULL, &o.sel, space, o.smooth, o.padding, &t, &info, &err) !=
        SM_OK) {
        if (info.stats.voxels > 0 || strstr(err.msg, "label-empty"))
            summary(&o, &info);
        fprintf(stderr, "shapematch sdf: %s\n", err.msg);
        return CLI_EXIT_INPUT;
    }
    summary(&o, &info);
    fprintf(stderr, "  seconds: reading, label's surface and distance grid %.2f\n", info.seconds);
    rc = o.edt_out ? write_edt(&o, t) : CLI_EXIT_OK;
    if (rc == CLI_EXIT_OK)
        rc = distance(&o, t, &info);
    sm_image_target_free(t);
    return rc;
}
