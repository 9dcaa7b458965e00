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

/* The 26-connected components of the mask, by runs: each row's runs of
 * selected voxels, joined (union-find) with the overlapping or diagonally
 * touching runs of the rows before it among its 8 neighbouring rows (j
 * and k within one); the components are the roots left. */
static int64_t run_root(int64_t *parent, int64_t r)
{
    while (parent[r] != r) {
        parent[r] = parent[parent[r]];
        r = parent[r];
    }
    return r;
}

static sm_status count_components(const int64_t *n, const uint8_t *mask, int64_t *components,
                                  sm_error *err)
{
    int64_t rows = n[1] * n[2], nruns = 0, cap = 1024;
    int64_t *first = malloc((size_t)(rows + 1) * sizeof *first);
    int64_t *run = malloc((size_t)cap * 2 * sizeof *run), *parent = NULL;
    if (!first || !run)
        goto nomem;
    for (int64_t r = 0; r < rows; r++) {
        const uint8_t *line = mask + r * n[0];
        first[r] = nruns;
        const uint8_t *at = memchr(line, 1, (size_t)n[0]);
        for (int64_t i = at ? at - line : n[0]; i < n[0];) {
            if (!line[i]) {
                i++;
                continue;
            }
            int64_t e = i;
            while (e + 1 < n[0] && line[e + 1])
                e++;
            if (nruns == cap) {
                int64_t *grown = realloc(run, (size_t)cap * 4 * sizeof *run);
                if (!grown)
                    goto nomem;
                run = grown;
                cap *= 2;
            }
            run[2 * nruns] = i;
            run[2 * nruns + 1] = e;
            nruns++;
            i = e + 1;
        }
    }
    first[rows] = nruns;
    parent = malloc((size_t)(nruns > 0 ? nruns : 1) * sizeof *parent);
    if (!parent)
        goto nomem;
    for (int64_t q = 0; q < nruns; q++)
        parent[q] = q;
    static const int before[4][2] = {{-1, -1}, {0, -1}, {1, -1}, {-1, 0}}; /* (dj, dk) */
    for (int64_t r = 0; r < rows; r++) {
        int64_t j = r % n[1], k = r / n[1];
        for (int b = 0; b < 4; b++) {
            int64_t jj = j + before[b][0], kk = k + before[b][1];
            if (jj < 0 || jj >= n[1] || kk < 0)
                continue;
            int64_t o = jj + n[1] * kk, p = first[o];
            for (int64_t q = first[r]; q < first[r + 1]; q++) {
                while (p < first[o + 1] && run[2 * p + 1] < run[2 * q] - 1)
                    p++; /* ends before q's reach */
                for (int64_t x = p; x < first[o + 1] && run[2 * x] <= run[2 * q + 1] + 1; x++) {
                    int64_t ra = run_root(parent, q), rb = run_root(parent, x);
                    if (ra != rb)
                        parent[ra > rb ? ra : rb] = ra < rb ? ra : rb;
                }
            }
        }
    }
    int64_t count = 0;
    for (int64_t q = 0; q < nruns; q++)
        count += run_root(parent, q) == q;
    *components = count;
    free(first);
    free(run);
    free(parent);
    return SM_OK;
nomem:
    free(first);
    free(run);
    free(parent);
    return sm_error_set(err, SM_ERR_NOMEM, "out of memory for the label's components");
}

sm_status sm_image_mask(const sm_image *im, const sm_image_select *sel, uint8_t *mask,
                        sm_label_stats *stats, sm_error *err)
{
    const int64_t *n = im->dims;
    int64_t total = n[0] * n[1] * n[2];
    int flt = is_float(im->type);
    if (im->type == SM_VOXEL_U8) {
        /* a byte has 256 values: the same test on each, once */
        uint8_t pick[256];
        for (int b = 0; b < 256; b++) {
            double x = im->slope * b + im->inter;
            pick[b] = sel->has_label ? x == (double)sel->label : x != 0;
        }
        const uint8_t *bytes = im->voxels;
#pragma omp parallel for schedule(static)
        for (int64_t v = 0; v < total; v++)
            mask[v] = pick[bytes[v]];
    } else {
#pragma omp parallel for schedule(static)
        for (int64_t v = 0; v < total; v++) {
            double x = sm_image_value(im, v);
            mask[v] = sel->has_label ? x == (double)sel->label : flt ? x >= sel->level : x != 0;
        }
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
        const uint8_t *at1 = memchr(line, 1, (size_t)n[0]); /* most rows have none */
        if (!at1)
            continue;
        int64_t first = at1 - line, last = n[0] - 1;
        while (!line[last])
            last--;
        for (int64_t i = first; i <= last; i++)
            stats->voxels += line[i]; /* 0 or 1 */
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
