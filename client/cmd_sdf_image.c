/* `shapematch sdf --image`: the signed distance to a label's boundary in
 * a segmentation (NIfTI, NRRD, MetaImage; sm_image.h), on a generated
 * background graded toward it — the target a matching run needs.
 *   shapematch sdf --image F [--label N] [--level L] [--image-space S] -o DIR
 * The label summary (voxels, components, world box) and its warnings go
 * to stderr.  Background: the generated graded one (sm_background.c), not
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
            o->sel.has_label = 1;
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
    if (o->space && strcmp(o->space, "lps") != 0 && strcmp(o->space, "ras") != 0)
        return usage_error("--image-space is lps or ras");
    *done = 0;
    return CLI_EXIT_OK;
}

static void summary(const image_options *o, const sm_image *im, const sm_label_stats *s)
{
    const double *m = im->ijk_to_lps;
    fprintf(stderr, "image %s: %s, %lld x %lld x %lld %s, spacing %g x %g x %g\n", o->image,
            im->format, (long long)im->dims[0], (long long)im->dims[1], (long long)im->dims[2],
            sm_voxel_type_name(im->type), hypot(hypot(m[0], m[4]), m[8]),
            hypot(hypot(m[1], m[5]), m[9]), hypot(hypot(m[2], m[6]), m[10]));
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

/* The crop's signed EDT as NRRD (float32, the image's frame). */
static int write_edt(const image_options *o, const sm_image_target *t)
{
    int64_t n[3];
    double m[12];
    const float *d;
    sm_image_target_grid(t, n, m, &d);
    FILE *f = fopen(o->edt_out, "wb");
    if (!f) {
        perror(o->edt_out);
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
    ok = fclose(f) == 0 && ok;
    if (!ok) {
        fprintf(stderr, "shapematch sdf: %s: write error\n", o->edt_out);
        return CLI_EXIT_OUTPUT;
    }
    return CLI_EXIT_OK;
}

/* The graded background around the label's surface, its distance. */
static int distance(const image_options *o, const sm_image *im, sm_image_target *t)
{
    const sm_surface *s = sm_image_target_surface(t);
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int32_t v = 0; v < s->nverts; v++)
        for (int k = 0; k < 3; k++) {
            lo[k] = fmin(lo[k], s->coords[3 * v + k]);
            hi[k] = fmax(hi[k], s->coords[3 * v + k]);
        }
    double diag = hypot(hypot(hi[0] - lo[0], hi[1] - lo[1]), hi[2] - lo[2]);
    double pad = (o->padding >= 0 ? o->padding : 0.1) * diag, vol = 1;
    for (int k = 0; k < 3; k++) {
        lo[k] -= pad;
        hi[k] += pad;
        vol *= hi[k] - lo[k];
    }
    const double *m = im->ijk_to_lps;
    double hmin = fmin(hypot(hypot(m[0], m[4]), m[8]),
                       fmin(hypot(hypot(m[1], m[5]), m[9]), hypot(hypot(m[2], m[6]), m[10])));
    /* the voxel size, but no finer than a uniform grid of 250k vertices
     * over the box: a 256^3 map's 1.4M-voxel ellipsoid at 1 mm gave 1.65M
     * vertices (8.9 s of the command's 19.5 s), at 2.9 mm 0.2M */
    double size = o->size > 0 ? o->size : fmax(hmin, cbrt(vol / 250000.0));
    sm_error err;
    sm_error_clear(&err);
    sm_mesh *bg = NULL;
    sm_sol *sol = NULL;
    int64_t exact = 0;
    int rc = CLI_EXIT_INPUT;
    double t0 = sm_clock_seconds(), t1 = t0, t2 = t0;
    if (sm_background_graded_new(3, lo, hi, size, sm_image_target_sdf(t), &bg, &err) != SM_OK ||
        (t1 = sm_clock_seconds(), sm_sol_alloc(&sol, 3, bg->nverts, 1, &err)) != SM_OK ||
        sm_image_target_signed(t, bg->nverts, bg->coords, sol->values, &exact, &err) != SM_OK) {
        fprintf(stderr, "shapematch sdf: %s\n", err.msg);
    } else {
        t2 = sm_clock_seconds();
        rc = cmd_sdf_write_dir(o->out, bg, sol);
        fprintf(stderr, "distance at %d vertices of the generated background of size %g (%lld "
                        "exact, near the label's surface of %d triangles)\n"
                        "  seconds: background %.2f, distance %.2f, writing %.2f\n",
                bg->nverts, size, (long long)exact, s->nfacets, t1 - t0, t2 - t1,
                sm_clock_seconds() - t2);
    }
    sm_sol_free(sol);
    sm_mesh_free(bg);
    return rc;
}

static int compute(const image_options *o, sm_image *im)
{
    if (o->space && strcmp(o->space, "ras") == 0)
        sm_image_flip_ras(im);
    size_t total = (size_t)(im->dims[0] * im->dims[1] * im->dims[2]);
    uint8_t *mask = malloc(total);
    if (!mask) {
        fprintf(stderr, "shapematch sdf: out of memory\n");
        return CLI_EXIT_INPUT;
    }
    sm_error err;
    sm_error_clear(&err);
    sm_label_stats stats;
    sm_image_target *t = NULL;
    int rc = CLI_EXIT_INPUT;
    if (sm_image_mask(im, &o->sel, mask, &stats, &err) != SM_OK) {
        fprintf(stderr, "shapematch sdf: %s\n", err.msg);
    } else if (summary(o, im, &stats), stats.voxels == 0) {
        fprintf(stderr, "shapematch sdf: label-empty: no voxel of %s is selected\n", o->image);
    } else {
        sm_image_target_opts to = {o->smooth, 3.0, 0};
        const double *m = im->ijk_to_lps;
        double hmin = fmin(hypot(hypot(m[0], m[4]), m[8]),
                           fmin(hypot(hypot(m[1], m[5]), m[9]), hypot(hypot(m[2], m[6]), m[10])));
        double diag = hypot(hypot(stats.hi[0] - stats.lo[0], stats.hi[1] - stats.lo[1]),
                            stats.hi[2] - stats.lo[2]);
        /* the crop covers the background's margin */
        to.pad_voxels = fmin(64, (o->padding >= 0 ? o->padding : 0.1) * diag / hmin + 1);
        double t0 = sm_clock_seconds();
        if (sm_image_target_new(im, mask, &o->sel, &to, &t, &err) != SM_OK)
            fprintf(stderr, "shapematch sdf: %s\n", err.msg);
        else if (fprintf(stderr, "  seconds: label's surface and EDT %.2f\n",
                         sm_clock_seconds() - t0) < 0)
            rc = CLI_EXIT_OUTPUT;
        else if ((rc = o->edt_out ? write_edt(o, t) : CLI_EXIT_OK) == CLI_EXIT_OK)
            rc = distance(o, im, t);
    }
    sm_image_target_free(t);
    free(mask);
    return rc;
}

int cmd_sdf_image(int argc, char **argv)
{
    image_options o = {NULL, NULL, NULL, NULL, {0, 0, 0.5}, 0, -1, 1.0};
    int done;
    int rc = parse(argc, argv, &o, &done);
    if (done)
        return rc;
    sm_image *im = NULL;
    sm_error err;
    sm_error_clear(&err);
    double t0 = sm_clock_seconds();
    if (sm_image_read(o.image, NULL, &im, &err) != SM_OK) {
        fprintf(stderr, "shapematch sdf: %s\n", err.msg);
        return CLI_EXIT_INPUT;
    }
    fprintf(stderr, "  seconds: reading %.2f\n", sm_clock_seconds() - t0);
    rc = compute(&o, im);
    sm_image_free(im);
    return rc;
}
