/* Which voxels of a label map are the target (sm_image.h): the mask of a
 * label, of every nonzero voxel or of a float image's level, and what
 * the summary reports of it — voxel count, 26-connected components, the
 * world box, contact with the image's border. */
#include "shapematch/sm_image.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static int is_float(sm_voxel_type t)
{
    return t == SM_VOXEL_F32 || t == SM_VOXEL_F64;
}

/* Counts 26-connected components of mask (values 1), marking visited
 * voxels 2 and turning them back to 1 at the end; an explicit stack. */
static sm_status count_components(const int64_t *n, uint8_t *mask, int64_t *components,
                                  sm_error *err)
{
    int64_t total = n[0] * n[1] * n[2], cap = 1024, top = 0, count = 0;
    int64_t *stack = malloc((size_t)cap * sizeof *stack);
    if (!stack)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the label's components");
    sm_status st = SM_OK;
    for (int64_t s = 0; s < total && st == SM_OK; s++) {
        if (mask[s] != 1)
            continue;
        count++;
        mask[s] = 2;
        stack[top++] = s;
        while (top > 0 && st == SM_OK) {
            int64_t v = stack[--top];
            int64_t i = v % n[0], j = (v / n[0]) % n[1], k = v / (n[0] * n[1]);
            for (int dk = -1; dk <= 1; dk++)
                for (int dj = -1; dj <= 1; dj++)
                    for (int di = -1; di <= 1; di++) {
                        int64_t a = i + di, b = j + dj, c = k + dk;
                        if (a < 0 || b < 0 || c < 0 || a >= n[0] || b >= n[1] || c >= n[2])
                            continue;
                        int64_t w = a + n[0] * (b + n[1] * c);
                        if (mask[w] != 1)
                            continue;
                        mask[w] = 2;
                        if (top == cap) {
                            int64_t *grown = realloc(stack, (size_t)cap * 2 * sizeof *stack);
                            if (!grown) {
                                st = sm_error_set(err, SM_ERR_NOMEM, "out of memory for the "
                                                  "label's components");
                                break;
                            }
                            stack = grown;
                            cap *= 2;
                        }
                        stack[top++] = w;
                    }
        }
    }
    free(stack);
    for (int64_t s = 0; s < total; s++)
        mask[s] = mask[s] != 0;
    *components = count;
    return st;
}

sm_status sm_image_mask(const sm_image *im, const sm_image_select *sel, uint8_t *mask,
                        sm_label_stats *stats, sm_error *err)
{
    const int64_t *n = im->dims;
    int64_t total = n[0] * n[1] * n[2];
    int flt = is_float(im->type);
#pragma omp parallel for schedule(static)
    for (int64_t v = 0; v < total; v++) {
        double x = sm_image_value(im, v);
        mask[v] = sel->has_label ? x == (double)sel->label : flt ? x >= sel->level : x != 0;
    }
    if (!stats)
        return SM_OK;
    memset(stats, 0, sizeof *stats);
    for (int c = 0; c < 3; c++) {
        stats->lo[c] = INFINITY;
        stats->hi[c] = -INFINITY;
        stats->index_lo[c] = n[c];
        stats->index_hi[c] = -1;
    }
    /* The world box of the selected voxel centres: along a row of the
     * image (j, k fixed) the world map is affine in i, so its extremes
     * over the row's selected voxels are at the row's first and last
     * selected i.  (The box of the index box's corners is wider on an
     * oblique grid: by the grid's rotation times its extent.) */
    const double *m = im->ijk_to_lps;
    for (int64_t row = 0; row < n[1] * n[2]; row++) {
        const uint8_t *line = mask + row * n[0];
        int64_t first = -1, last = -1;
        for (int64_t i = 0; i < n[0]; i++) {
            if (!line[i])
                continue;
            if (first < 0)
                first = i;
            last = i;
            stats->voxels++;
        }
        if (first < 0)
            continue;
        int64_t j = row % n[1], k = row / n[1], at[3][2] = {{first, last}, {j, j}, {k, k}};
        for (int c = 0; c < 3; c++) {
            if (at[c][0] < stats->index_lo[c])
                stats->index_lo[c] = at[c][0];
            if (at[c][1] > stats->index_hi[c])
                stats->index_hi[c] = at[c][1];
        }
        /* a 2D image's one slice is no border */
        if (first == 0 || last == n[0] - 1 || j == 0 || j == n[1] - 1 ||
            (n[2] > 1 && (k == 0 || k == n[2] - 1)))
            stats->touches_border = 1;
        for (int end = 0; end < 2; end++) {
            double ijk[3] = {(double)(end ? last : first), (double)j, (double)k};
            for (int r = 0; r < 3; r++) {
                double w = m[4 * r + 3];
                for (int c = 0; c < 3; c++)
                    w += m[4 * r + c] * ijk[c];
                stats->lo[r] = fmin(stats->lo[r], w);
                stats->hi[r] = fmax(stats->hi[r], w);
            }
        }
    }
    if (stats->voxels == 0)
        return SM_OK;
    return count_components(n, mask, &stats->components, err);
}
