/* Label-map images (sm_image.h): the EDT against brute force on random
 * masks of anisotropic grids (unsigned and signed), the nearest-site
 * transform against brute force, the selection and its
 * summary (voxels, 26-connected components, border, world box) against
 * hand counts, NIfTI's qform against its sform for the same rotation, the
 * three readers agreeing on one array in memory, the components against
 * a flood fill, the level-set surface's distance against an exact
 * sphere, the grid's distance against the exact distance to the surface
 * and to the sphere; a 2D label's contour against the exact area of its
 * pixel square. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "shapematch/sm_image.h"
#include "shapematch/sm_sdf.h"
#include "sm_edt.h"
#include "sm_image_march.h"

#include <omp.h>

static uint64_t rng = 88172645463325252ull;
static double rnd(void)
{
    rng ^= rng << 13;
    rng ^= rng >> 7;
    rng ^= rng << 17;
    return (double)(rng >> 11) / 9007199254740992.0;
}

/* brute force: distance from v to the nearest voxel with cls */
static double brute(const int64_t *n, const double *h, const uint8_t *m, int64_t v, int cls)
{
    double best = INFINITY;
    int64_t vi = v % n[0], vj = (v / n[0]) % n[1], vk = v / (n[0] * n[1]);
    for (int64_t w = 0; w < n[0] * n[1] * n[2]; w++) {
        if ((m[w] != 0) != cls)
            continue;
        double dx = (double)(w % n[0] - vi) * h[0], dy = (double)((w / n[0]) % n[1] - vj) * h[1],
               dz = (double)(w / (n[0] * n[1]) - vk) * h[2];
        best = fmin(best, sqrt(dx * dx + dy * dy + dz * dz));
    }
    return best;
}

/* The oracle of the grid tests: the world points of the crop's voxel
 * centres (grid cn, map cm: sm_image_target_grid's), their exact distance
 * to t's surface over every triangle (its hierarchy) and their winding
 * number.  The caller frees the three arrays. */
static void grid_exact(sm_image_target *t, const int64_t cn[3], const double cm[12], double **pts,
                       double **u, double **wn)
{
    int64_t ct = cn[0] * cn[1] * cn[2];
    *pts = malloc((size_t)ct * 3 * sizeof **pts);
    *u = malloc((size_t)ct * sizeof **u);
    *wn = malloc((size_t)ct * sizeof **wn);
    assert_true(*pts && *u && *wn);
    for (int64_t w = 0; w < ct; w++)
        sm__grid_world(cm, (double)(w % cn[0]), (double)((w / cn[0]) % cn[1]),
                       (double)(w / (cn[0] * cn[1])), *pts + 3 * w);
    sm_sdf_distance(sm_image_target_sdf(t), ct, *pts, *u, NULL);
    sm_sdf_winding(sm_image_target_sdf(t), ct, *pts, *wn);
}

static void test_edt_brute_force(void **state)
{
    (void)state;
    for (int trial = 0; trial < 12; trial++) {
        int64_t n[3] = {3 + (int64_t)(rnd() * 14), 1 + (int64_t)(rnd() * 12), 2 + (int64_t)(rnd() * 9)};
        double h[3] = {0.3 + rnd() * 2, 0.3 + rnd() * 2, 0.3 + rnd() * 2};
        int64_t total = n[0] * n[1] * n[2];
        uint8_t *m = malloc((size_t)total);
        float *d = malloc((size_t)total * sizeof *d), *s = malloc((size_t)total * sizeof *s);
        double density = trial % 3 == 0 ? 0.03 : trial % 3 == 1 ? 0.3 : 0.8;
        for (int64_t v = 0; v < total; v++)
            m[v] = rnd() < density;
        assert_int_equal(sm_edt(n, h, m, d, NULL), SM_OK);
        assert_int_equal(sm_edt_signed(n, h, m, s, NULL), SM_OK);
        for (int64_t v = 0; v < total; v++) {
            double to_in = brute(n, h, m, v, 1), to_out = brute(n, h, m, v, 0);
            if (isinf(to_in))
                assert_true(isinf(d[v]));
            else
                assert_true(fabs(d[v] - to_in) <= 1e-5 * (1 + to_in));
            double want = m[v] ? -to_out : to_in;
            if (isinf(want))
                assert_true(isinf(s[v]) && (s[v] < 0) == (want < 0));
            else
                assert_true(fabs(s[v] - want) <= 1e-5 * (1 + fabs(want)));
        }
        free(m);
        free(d);
        free(s);
    }
}

/* The nearest-site transform (sm_edt.h) against brute force: on random
 * anisotropic grids with sparse and dense sites, every voxel's site is
 * one of the nearest (ties either way). */
static void test_nearest_site_brute_force(void **state)
{
    (void)state;
    for (int trial = 0; trial < 12; trial++) {
        int64_t n[3] = {1 + (int64_t)(rnd() * 40), 1 + (int64_t)(rnd() * 12), 1 + (int64_t)(rnd() * 9)};
        double h[3] = {0.3 + rnd() * 2, 0.3 + rnd() * 2, 0.3 + rnd() * 2};
        int64_t total = n[0] * n[1] * n[2], nsites = 0;
        int32_t *near = malloc((size_t)total * sizeof *near), *ijk = malloc((size_t)total * 3 * sizeof *ijk);
        double density = trial % 3 == 0 ? 0.01 : trial % 3 == 1 ? 0.1 : 0.5;
        for (int64_t v = 0; v < total; v++) {
            near[v] = -1;
            if (rnd() < density || (v == total - 1 && nsites == 0)) {
                near[v] = (int32_t)nsites;
                ijk[3 * nsites] = (int32_t)(v % n[0]);
                ijk[3 * nsites + 1] = (int32_t)((v / n[0]) % n[1]);
                ijk[3 * nsites + 2] = (int32_t)(v / (n[0] * n[1]));
                nsites++;
            }
        }
        assert_int_equal(sm__edt_nearest(n, h, ijk, nsites, near, NULL), SM_OK);
        for (int64_t v = 0; v < total; v++) {
            double p[3] = {(double)(v % n[0]), (double)((v / n[0]) % n[1]), (double)(v / (n[0] * n[1]))};
            double best = INFINITY, got;
            for (int64_t s = 0; s < nsites; s++) {
                double d2 = 0;
                for (int a = 0; a < 3; a++)
                    d2 += (p[a] - ijk[3 * s + a]) * (p[a] - ijk[3 * s + a]) * h[a] * h[a];
                best = fmin(best, d2);
            }
            assert_true(near[v] >= 0 && near[v] < nsites);
            got = 0;
            for (int a = 0; a < 3; a++)
                got += (p[a] - ijk[3 * near[v] + a]) * (p[a] - ijk[3 * near[v] + a]) * h[a] * h[a];
            assert_true(got <= best * (1 + 1e-12) + 1e-12);
        }
        free(near);
        free(ijk);
    }
}

/* A NIfTI-1 header in memory: uint8 voxels, sform or qform. */
static unsigned char *nifti(const int64_t *n, const uint8_t *vox, const double *ras, int sform,
                            const double *quat, const double *pix, size_t *size)
{
    size_t total = (size_t)(n[0] * n[1] * n[2]);
    unsigned char *b = calloc(1, 352 + total);
    int32_t hs = 348;
    memcpy(b, &hs, 4);
    int16_t dim[8] = {3, (int16_t)n[0], (int16_t)n[1], (int16_t)n[2], 1, 1, 1, 1};
    memcpy(b + 40, dim, sizeof dim);
    int16_t dt[2] = {2, 8};
    memcpy(b + 70, dt, sizeof dt);
    float pd[8] = {1, (float)pix[0], (float)pix[1], (float)pix[2], 0, 0, 0, 0};
    memcpy(b + 76, pd, sizeof pd);
    float off = 352;
    memcpy(b + 108, &off, 4);
    int16_t codes[2] = {(int16_t)(sform ? 0 : 1), (int16_t)(sform ? 1 : 0)};
    memcpy(b + 252, codes, sizeof codes);
    float q[6] = {(float)quat[0], (float)quat[1], (float)quat[2], (float)ras[3], (float)ras[7],
                  (float)ras[11]};
    memcpy(b + 256, q, sizeof q);
    for (int k = 0; k < 12; k++) {
        float v = (float)ras[k];
        memcpy(b + 280 + 4 * k, &v, 4);
    }
    memcpy(b + 344, "n+1", 4);
    memcpy(b + 352, vox, total);
    *size = 352 + total;
    return b;
}

static void test_nifti_qform_sform(void **state)
{
    (void)state;
    /* a rotation by 90 degrees about z: quaternion (b, c, d) = (0, 0, s) */
    double s = sqrt(0.5), pix[3] = {0.5, 2, 3};
    double ras[12] = {0, -2, 0, 10, 0.5, 0, 0, -20, 0, 0, 3, 30};
    double quat[3] = {0, 0, s};
    int64_t n[3] = {2, 3, 4};
    uint8_t vox[24] = {0};
    vox[5] = 1;
    size_t size;
    unsigned char *a = nifti(n, vox, ras, 1, quat, pix, &size);
    unsigned char *b = nifti(n, vox, ras, 0, quat, pix, &size);
    sm_image *ia, *ib;
    sm_error err;
    assert_int_equal(sm_image_read_memory("a.nii", a, size, NULL, &ia, &err), SM_OK);
    assert_int_equal(sm_image_read_memory("b.nii", b, size, NULL, &ib, &err), SM_OK);
    for (int k = 0; k < 12; k++) {
        /* LPS: x and y negated */
        double want = k < 8 ? -ras[k] : ras[k];
        assert_true(fabs(ia->ijk_to_lps[k] - want) < 1e-6);
        assert_true(fabs(ib->ijk_to_lps[k] - want) < 1e-6);
    }
    assert_string_equal(ia->format, "NIfTI-1");
    assert_int_equal(ia->type, SM_VOXEL_U8);
    assert_true(sm_image_value(ia, 5) == 1);
    /* truncated voxel data: the byte named */
    sm_image *ic = (sm_image *)1;
    assert_int_not_equal(sm_image_read_memory("c.nii", a, size - 3, NULL, &ic, &err), SM_OK);
    assert_null(ic);
    assert_non_null(strstr(err.msg, "c.nii: byte 352"));
    /* the voxel limit, before allocation */
    sm_image_limits lim = {.max_voxels = 10};
    assert_int_equal(sm_image_read_memory("a.nii", a, size, &lim, &ic, &err), SM_ERR_NOMEM);
    assert_int_equal(lim.hit, SM_IMAGE_LIMIT_VOXELS);
    sm_image_free(ia);
    sm_image_free(ib);
    free(a);
    free(b);
}

/* The same array as NRRD and MetaImage text headers: same map, voxels. */
static void test_text_formats(void **state)
{
    (void)state;
    static const char nrrd[] = "NRRD0004\ntype: short\ndimension: 3\nspace: RAS\nsizes: 2 2 1\n"
                       "space directions: (0,1.5,0) (-2,0,0) (0,0,3)\nendian: big\n"
                       "encoding: raw\nspace origin: (1,2,3)\n\n\x00\x01\x00\x02\xff\xff\x00\x00";
    static const char mha[] = "ObjectType = Image\nNDims = 3\nDimSize = 2 2 1\nElementType = MET_SHORT\n"
                      "ElementSpacing = 1.5 2 3\nTransformMatrix = 0 -1 0 1 0 0 0 0 1\n"
                      "Offset = -1 -2 3\nElementDataFile = LOCAL\n\x01\x00\x02\x00\xff\xff\x00\x00";
    sm_image *a, *b;
    sm_error err;
    assert_int_equal(sm_image_read_memory("a.nrrd", nrrd, sizeof nrrd - 1, NULL, &a, &err), SM_OK);
    assert_int_equal(sm_image_read_memory("b.mha", mha, sizeof mha - 1, NULL, &b, &err), SM_OK);
    for (int k = 0; k < 12; k++)
        assert_true(a->ijk_to_lps[k] == b->ijk_to_lps[k]);
    for (int v = 0; v < 4; v++)
        assert_true(sm_image_value(a, v) == sm_image_value(b, v));
    assert_true(sm_image_value(a, 2) == -1);
    sm_image_free(a);
    sm_image_free(b);
}

static void test_mask_stats(void **state)
{
    (void)state;
    int64_t n[3] = {6, 5, 4};
    sm_image im = {.dims = {6, 5, 4}, .type = SM_VOXEL_S16, .slope = 1, .inter = 0};
    double map[12] = {2, 0, 0, 1, 0, 1, 0, 0, 0, 0, 1, 0};
    memcpy(im.ijk_to_lps, map, sizeof map);
    int16_t v[120] = {0};
    v[1 + 6 * (1 + 5 * 1)] = 3;
    v[2 + 6 * (2 + 5 * 2)] = 3; /* diagonal neighbour: one component */
    v[4 + 6 * (3 + 5 * 1)] = 3; /* apart: a second */
    v[5] = 5;                   /* another label, on the border */
    im.voxels = v;
    uint8_t m[120];
    sm_label_stats st;
    sm_image_select sel = {1, 3, 0.5};
    assert_int_equal(sm_image_mask(&im, &sel, m, &st, NULL), SM_OK);
    assert_int_equal(st.voxels, 3);
    assert_int_equal(st.components, 2);
    assert_int_equal(st.touches_border, 0);
    assert_true(st.lo[0] == 3 && st.hi[0] == 9 && st.lo[1] == 1 && st.hi[1] == 3);
    sel.has_label = 0;
    assert_int_equal(sm_image_mask(&im, &sel, m, &st, NULL), SM_OK);
    assert_int_equal(st.voxels, 4);
    assert_int_equal(st.components, 3);
    assert_int_equal(st.touches_border, 1);
    (void)n;
}

/* A ball of radius 8 voxels (spacing 1): the level-set surface's signed
 * distance near it within 0.25 of |x - c| - 8, far better than the
 * voxel-centre EDT's half voxel. */
static void test_target_sphere(void **state)
{
    (void)state;
    int64_t n = 24;
    sm_image im = {.dims = {n, n, n}, .type = SM_VOXEL_U8, .slope = 1, .inter = 0};
    double map[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};
    memcpy(im.ijk_to_lps, map, sizeof map);
    uint8_t *v = calloc((size_t)(n * n * n), 1), *m = malloc((size_t)(n * n * n));
    double c[3] = {11.3, 11.7, 12.1};
    for (int64_t k = 0; k < n; k++)
        for (int64_t j = 0; j < n; j++)
            for (int64_t i = 0; i < n; i++)
                v[i + n * (j + n * k)] = hypot(hypot(i - c[0], j - c[1]), k - c[2]) <= 8;
    im.voxels = v;
    sm_image_select sel = {0, 0, 0.5};
    assert_int_equal(sm_image_mask(&im, &sel, m, NULL, NULL), SM_OK);
    sm_image_target_opts o = {1.0, 3.0, 0};
    sm_image_target *t;
    sm_error err;
    assert_int_equal(sm_image_target_new(&im, m, &sel, &o, &t, &err), SM_OK);
    double pts[3 * 200], d[200], worst = 0;
    for (int p = 0; p < 200; p++) {
        double dir[3] = {rnd() - 0.5, rnd() - 0.5, rnd() - 0.5}, len = hypot(hypot(dir[0], dir[1]), dir[2]);
        double r = 8 + (rnd() - 0.5) * 4;
        for (int k = 0; k < 3; k++)
            pts[3 * p + k] = c[k] + dir[k] / len * r;
    }
    int64_t exact;
    assert_int_equal(sm_image_target_signed(t, 200, pts, d, &exact, &err), SM_OK);
    for (int p = 0; p < 200; p++) {
        double want = hypot(hypot(pts[3 * p] - c[0], pts[3 * p + 1] - c[1]), pts[3 * p + 2] - c[2]) - 8;
        worst = fmax(worst, fabs(d[p] - want));
    }
    print_message("# sphere r 8: worst error %.3f voxels at %lld exact points\n", worst,
                  (long long)exact);
    assert_true(worst < 0.4);
    assert_int_equal(exact, 200);
    sm_image_target_free(t);
    free(v);
    free(m);
}

/* The distance on the image's grid (the far field, and `sdf --image -o
 * OUT.nii`) of a smoothed sphere of radius 10 mm on a rotated grid of
 * 1 x 1.25 x 1.5 mm: against the exact distance to the level-set surface
 * (the hierarchy, over every triangle) never below it, equal to it (to
 * float rounding) at every voxel within the smallest spacing of the
 * surface, within a quarter of the largest spacing of it within 3
 * voxels (0.35 mm measured), signs the winding number's; against the
 * exact sphere, near the surface at most half the
 * voxel-centre EDT's RMS error and over the whole grid no worse than its
 * largest. */
static void test_grid_distance_exact(void **state)
{
    (void)state;
    int64_t n[3] = {34, 29, 25};
    double h[3] = {1, 1.25, 1.5}, co = cos(0.5), si = sin(0.5);
    sm_image im = {.dims = {n[0], n[1], n[2]}, .type = SM_VOXEL_U8, .slope = 1, .inter = 0};
    double map[12] = {co * h[0], -si * h[1], 0, 3, si * h[0], co * h[1], 0, -2, 0, 0, h[2], 5};
    memcpy(im.ijk_to_lps, map, sizeof map);
    int64_t total = n[0] * n[1] * n[2];
    uint8_t *v = malloc((size_t)total), *m = malloc((size_t)total);
    double c[3] = {3 + co * 16.3 - si * 1.25 * 14.2, -2 + si * 16.3 + co * 1.25 * 14.2, 5 + 1.5 * 12.1};
    for (int64_t w = 0; w < total; w++) {
        double ijk[3] = {(double)(w % n[0]), (double)((w / n[0]) % n[1]), (double)(w / (n[0] * n[1]))};
        double x[3];
        for (int r = 0; r < 3; r++)
            x[r] = map[4 * r] * ijk[0] + map[4 * r + 1] * ijk[1] + map[4 * r + 2] * ijk[2] + map[4 * r + 3];
        v[w] = hypot(hypot(x[0] - c[0], x[1] - c[1]), x[2] - c[2]) <= 10;
    }
    im.voxels = v;
    sm_image_select sel = {0, 0, 0.5};
    assert_int_equal(sm_image_mask(&im, &sel, m, NULL, NULL), SM_OK);
    sm_image_target_opts o = {1.0, 3.0, 0, 1, 1};
    sm_image_target *t;
    sm_error err;
    assert_int_equal(sm_image_target_new(&im, m, &sel, &o, &t, &err), SM_OK);
    int64_t cn[3];
    double cm[12];
    const float *d;
    float *edt;
    sm_image_target_grid(t, cn, cm, &d);
    assert_int_equal(sm_image_target_voxel_edt(t, &edt, &err), SM_OK);
    int64_t ct = cn[0] * cn[1] * cn[2];
    double *pts, *u, *wn;
    grid_exact(t, cn, cm, &pts, &u, &wn);
    int64_t below = 0, site = 0, site_off = 0, band = 0, signs = 0, near = 0;
    double band_worst = 0, se = 0, se_edt = 0, worst = 0, worst_edt = 0;
    for (int64_t w = 0; w < ct; w++) {
        double a = fabs(d[w]), tol = 2.5e-7 * (1 + u[w]);
        below += a < u[w] - tol;
        if (u[w] < 1.0) { /* every voxel this near is a site: exact */
            site++;
            site_off += fabs(a - u[w]) > tol;
        }
        if (u[w] <= 3 * 1.5) {
            band++;
            band_worst = fmax(band_worst, a - u[w]);
        }
        if (u[w] > 1e-6)
            signs += (d[w] < 0) != (wn[w] > 0.5);
        double *p = pts + 3 * w, exact = hypot(hypot(p[0] - c[0], p[1] - c[1]), p[2] - c[2]) - 10;
        worst = fmax(worst, fabs(d[w] - exact));
        worst_edt = fmax(worst_edt, fabs(edt[w] - exact));
        if (fabs(exact) <= 2 * 1.5) {
            near++;
            se += (d[w] - exact) * (d[w] - exact);
            se_edt += (edt[w] - exact) * (edt[w] - exact);
        }
    }
    double rms = sqrt(se / (double)near), rms_edt = sqrt(se_edt / (double)near);
    print_message("# grid distance, sphere r 10 on %lld voxels: %lld below the exact surface "
                  "distance, %lld of %lld within a voxel not exact, worst excess within 3 voxels "
                  "%.3f (%lld voxels), %lld signs against the winding number; against the sphere: "
                  "rms %.3f near (voxel-centre EDT %.3f), max %.3f (EDT %.3f)\n",
                  (long long)ct, (long long)below, (long long)site_off, (long long)site, band_worst,
                  (long long)band, (long long)signs, rms, rms_edt, worst, worst_edt);
    assert_int_equal(below, 0);
    assert_true(site > 500);
    assert_int_equal(site_off, 0);
    assert_true(band_worst <= 0.25 * 1.5);
    assert_int_equal(signs, 0);
    assert_true(rms <= 0.5 * rms_edt);
    assert_true(worst <= worst_edt);
    free(pts);
    free(u);
    free(wn);
    free(edt);
    sm_image_target_free(t);
    free(v);
    free(m);
}

static int cmp_edge(const void *a, const void *b)
{
    const int64_t *x = a, *y = b;
    return *x < *y ? -1 : *x > *y;
}

static int cmp_point(const void *a, const void *b)
{
    const double *x = a, *y = b;
    for (int k = 0; k < 3; k++)
        if (x[k] != y[k])
            return x[k] < y[k] ? -1 : 1;
    return 0;
}

/* The marching on one thread and on three (cells in 2 and 6 chunks,
 * joined): the same surface, vertex for vertex and triangle for triangle
 * with the same cells; closed and oriented (every directed edge once, its
 * reverse once), no vertex twice (a chunk's copy of a shared vertex left
 * unjoined would be); two blobs on an oblique grid, one of them thin in
 * z so that chunks start and end at many slices. */
static void test_march_chunks_joined(void **state)
{
    (void)state;
    int64_t n[3] = {21, 17, 40}, total = n[0] * n[1] * n[2];
    float *f = malloc((size_t)total * sizeof *f);
    for (int64_t w = 0; w < total; w++) {
        double x = (double)(w % n[0]), y = (double)((w / n[0]) % n[1]), z = (double)(w / (n[0] * n[1]));
        double a = exp(-((x - 9.3) * (x - 9.3) + (y - 8.1) * (y - 8.1)) / 20 - (z - 12.2) * (z - 12.2) / 40);
        double b = exp(-((x - 11.7) * (x - 11.7) + (y - 7.6) * (y - 7.6)) / 12 - (z - 29.5) * (z - 29.5) / 6);
        f[w] = (float)(a + b);
    }
    int64_t lo[3] = {0, 0, 0}, hi[3] = {n[0] - 1, n[1] - 1, n[2] - 1};
    double map[12] = {0.9, -0.3, 0.1, 2, 0.3, 1.1, 0, -1, 0, 0.2, 1.4, 5};
    sm_surface *s[2];
    int64_t *tcell[2], nt[2];
    sm_error err;
    for (int run = 0; run < 2; run++) {
        int threads = omp_get_max_threads();
        omp_set_num_threads(run ? 3 : 1);
        mt_builder b = {.f = f, .n = {n[0], n[1], n[2]}, .lo = lo, .hi = hi, .level = 0.5, .map = map};
        assert_int_equal(sm__image_march(&b, &s[run], &err), SM_OK);
        omp_set_num_threads(threads);
        assert_null(b.coords);
        tcell[run] = b.tcell;
        nt[run] = b.nt;
    }
    assert_int_equal(s[0]->nverts, s[1]->nverts);
    assert_int_equal(s[0]->nfacets, s[1]->nfacets);
    assert_int_equal(nt[0], s[0]->nfacets);
    assert_memory_equal(s[0]->coords, s[1]->coords, (size_t)s[0]->nverts * 3 * sizeof(double));
    assert_memory_equal(s[0]->facets, s[1]->facets, (size_t)s[0]->nfacets * 3 * sizeof(int32_t));
    assert_memory_equal(tcell[0], tcell[1], (size_t)nt[0] * sizeof(int64_t));
    int64_t m = s[0]->nfacets, nv = s[0]->nverts;
    int64_t *edges = malloc((size_t)m * 3 * sizeof *edges);
    for (int64_t t = 0; t < m; t++) {
        assert_true(t == 0 || tcell[0][t] >= tcell[0][t - 1]);
        for (int e = 0; e < 3; e++)
            edges[3 * t + e] = (int64_t)s[0]->facets[3 * t + e] * nv + s[0]->facets[3 * t + (e + 1) % 3];
    }
    qsort(edges, (size_t)(3 * m), sizeof *edges, cmp_edge);
    int64_t unpaired = 0;
    for (int64_t e = 0; e < 3 * m; e++) {
        int64_t rev = edges[e] % nv * nv + edges[e] / nv;
        unpaired += (e > 0 && edges[e] == edges[e - 1]) ||
                    !bsearch(&rev, edges, (size_t)(3 * m), sizeof *edges, cmp_edge);
    }
    double *pts = malloc((size_t)nv * 3 * sizeof *pts);
    memcpy(pts, s[0]->coords, (size_t)nv * 3 * sizeof *pts);
    qsort(pts, (size_t)nv, 3 * sizeof *pts, cmp_point);
    int64_t twice = 0;
    for (int64_t v = 1; v < nv; v++)
        twice += cmp_point(pts + 3 * v, pts + 3 * (v - 1)) == 0;
    print_message("# march in chunks: %lld vertices, %lld triangles, %lld edges unpaired, %lld "
                  "vertices twice\n", (long long)nv, (long long)m, (long long)unpaired,
                  (long long)twice);
    assert_true(m > 1000);
    assert_int_equal(unpaired, 0);
    assert_int_equal(twice, 0);
    for (int run = 0; run < 2; run++) {
        sm_surface_free(s[run]);
        free(tcell[run]);
    }
    free(edges);
    free(pts);
    free(f);
}

/* The grid's distance on random labels (unions of balls less smaller
 * ones: several pieces, cavities, thin walls; sharp and smoothed; a
 * straight and an oblique anisotropic grid) against the exact distance
 * to the surface over every triangle (the hierarchy): never below it,
 * equal within the smallest spacing, at most a quarter of the largest
 * spacing above it within 3 voxels, and every sign the winding
 * number's (each voxel's sign is its nearest site's). */
static void test_grid_distance_random(void **state)
{
    (void)state;
    for (int trial = 0; trial < 4; trial++) {
        int64_t n[3] = {26, 22, 18};
        double h[3] = {1, 1.2, 0.9}, co = trial & 1 ? cos(0.4) : 1, si = trial & 1 ? sin(0.4) : 0;
        double map[12] = {co * h[0], 0, -si * h[2], 1, 0, h[1], 0, -2, si * h[0], 0, co * h[2], 3};
        sm_image im = {.dims = {n[0], n[1], n[2]}, .type = SM_VOXEL_U8, .slope = 1, .inter = 0};
        memcpy(im.ijk_to_lps, map, sizeof map);
        int64_t total = n[0] * n[1] * n[2];
        uint8_t *v = calloc((size_t)total, 1), *m = malloc((size_t)total);
        for (int ball = 0; ball < 10; ball++) {
            double c[3] = {3 + rnd() * 20, 3 + rnd() * 16, 3 + rnd() * 12}, r = 1.5 + rnd() * 4;
            int hole = ball >= 6;
            for (int64_t w = 0; w < total; w++) {
                double x = (double)(w % n[0]) - c[0], y = (double)((w / n[0]) % n[1]) - c[1],
                       z = (double)(w / (n[0] * n[1])) - c[2];
                if (x * x + y * y + z * z <= (hole ? r * r / 4 : r * r))
                    v[w] = !hole;
            }
        }
        im.voxels = v;
        sm_image_select sel = {0, 0, 0.5};
        assert_int_equal(sm_image_mask(&im, &sel, m, NULL, NULL), SM_OK);
        sm_image_target_opts o = {trial < 2 ? 0.0 : 1.0, 3.0, 0, 1, 1};
        sm_image_target *t;
        sm_error err;
        assert_int_equal(sm_image_target_new(&im, m, &sel, &o, &t, &err), SM_OK);
        int64_t cn[3];
        double cm[12];
        const float *d;
        sm_image_target_grid(t, cn, cm, &d);
        int64_t ct = cn[0] * cn[1] * cn[2];
        double *pts, *u, *wn;
        grid_exact(t, cn, cm, &pts, &u, &wn);
        int64_t below = 0, off = 0, near = 0, signs = 0;
        double excess = 0;
        for (int64_t w = 0; w < ct; w++) {
            double a = fabs(d[w]), tol = 2.5e-7 * (1 + u[w]);
            below += a < u[w] - tol;
            if (u[w] < 0.9) {
                near++;
                off += fabs(a - u[w]) > tol;
            }
            if (u[w] <= 3 * 1.2)
                excess = fmax(excess, a - u[w]);
            if (u[w] > 1e-6)
                signs += (d[w] < 0) != (wn[w] > 0.5);
        }
        print_message("# random label %d (%s, %s): %lld voxels, %lld below the exact distance, "
                      "%lld of %lld within a voxel not exact, worst excess within 3 voxels %.3f, "
                      "%lld signs against the winding number\n", trial,
                      trial < 2 ? "sharp" : "smoothed", trial & 1 ? "oblique" : "straight",
                      (long long)ct, (long long)below, (long long)off, (long long)near, excess,
                      (long long)signs);
        assert_int_equal(below, 0);
        assert_true(near > 300);
        assert_int_equal(off, 0);
        assert_true(excess <= 0.25 * 1.2);
        assert_int_equal(signs, 0);
        free(pts);
        free(u);
        free(wn);
        sm_image_target_free(t);
        free(v);
        free(m);
    }
}

/* brute force: the 26-connected components by flood fill */
static int64_t flood_components(const int64_t *n, const uint8_t *mask)
{
    int64_t total = n[0] * n[1] * n[2], count = 0, top;
    uint8_t *seen = calloc((size_t)total, 1);
    int64_t *stack = malloc((size_t)total * sizeof *stack);
    for (int64_t s = 0; s < total; s++) {
        if (!mask[s] || seen[s])
            continue;
        count++;
        seen[s] = 1;
        stack[0] = s;
        top = 1;
        while (top > 0) {
            int64_t w = stack[--top], i = w % n[0], j = (w / n[0]) % n[1], k = w / (n[0] * n[1]);
            for (int64_t q = 0; q < 27; q++) {
                int64_t a = i + q % 3 - 1, b = j + (q / 3) % 3 - 1, e = k + q / 9 - 1;
                if (a < 0 || b < 0 || e < 0 || a >= n[0] || b >= n[1] || e >= n[2])
                    continue;
                int64_t x = a + n[0] * (b + n[1] * e);
                if (mask[x] && !seen[x]) {
                    seen[x] = 1;
                    stack[top++] = x;
                }
            }
        }
    }
    free(seen);
    free(stack);
    return count;
}

/* The selection's 26-connected components (by runs) against a flood
 * fill on random masks of every density. */
static void test_components_brute_force(void **state)
{
    (void)state;
    for (int trial = 0; trial < 40; trial++) {
        int64_t n[3] = {1 + (int64_t)(rnd() * 15), 1 + (int64_t)(rnd() * 12), 1 + (int64_t)(rnd() * 9)};
        int64_t total = n[0] * n[1] * n[2];
        sm_image im = {.dims = {n[0], n[1], n[2]}, .type = SM_VOXEL_U8, .slope = 1, .inter = 0};
        double map[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};
        memcpy(im.ijk_to_lps, map, sizeof map);
        uint8_t *v = malloc((size_t)total), *m = malloc((size_t)total);
        double density = (trial % 5 + 0.5) / 6;
        for (int64_t w = 0; w < total; w++)
            v[w] = rnd() < density;
        im.voxels = v;
        sm_image_select sel = {0, 0, 0.5};
        sm_label_stats st;
        assert_int_equal(sm_image_mask(&im, &sel, m, &st, NULL), SM_OK);
        int64_t want = flood_components(n, m), count = 0;
        for (int64_t w = 0; w < total; w++)
            count += m[w];
        assert_int_equal(st.voxels, count);
        assert_int_equal(st.components, want);
        free(v);
        free(m);
    }
}

/* The unsmoothed mask of a ball of radius 20 voxels: its marching-
 * tetrahedra surface has planar pieces that a graded background's grid
 * points straddle exactly (|pq| = dp + dq), where sm_sdf_signed's sign
 * propagation once carried the sign across the surface (85 wrong signs
 * of 79k); every sign now agrees with the winding number. */
static void test_binary_sphere_signs(void **state)
{
    (void)state;
    int64_t n = 52;
    sm_image im = {.dims = {n, n, n}, .type = SM_VOXEL_U8, .slope = 1, .inter = 0};
    double map[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};
    memcpy(im.ijk_to_lps, map, sizeof map);
    uint8_t *v = calloc((size_t)(n * n * n), 1), *m = malloc((size_t)(n * n * n));
    double c[3] = {25.3, 25.6, 25.9};
    for (int64_t k = 0; k < n; k++)
        for (int64_t j = 0; j < n; j++)
            for (int64_t i = 0; i < n; i++)
                v[i + n * (j + n * k)] = hypot(hypot(i - c[0], j - c[1]), k - c[2]) <= 20;
    im.voxels = v;
    sm_image_select sel = {0, 0, 0.5};
    assert_int_equal(sm_image_mask(&im, &sel, m, NULL, NULL), SM_OK);
    sm_image_target_opts o = {0, 3.0, 0, 1};
    sm_image_target *t;
    sm_error err;
    assert_int_equal(sm_image_target_new(&im, m, &sel, &o, &t, &err), SM_OK);
    double lo[3] = {1.6, 1.9, 2.2}, hi[3] = {49.0, 49.3, 49.6};
    sm_mesh *bg;
    assert_int_equal(sm_background_graded_new(3, lo, hi, 1.0, sm_image_target_sdf(t), &bg, &err),
                     SM_OK);
    double *d = malloc((size_t)bg->nverts * sizeof *d), *w = malloc((size_t)bg->nverts * sizeof *w);
    assert_int_equal(sm_image_target_signed(t, bg->nverts, bg->coords, d, NULL, &err), SM_OK);
    sm_sdf_winding(sm_image_target_sdf(t), bg->nverts, bg->coords, w);
    /* the distances near the surface (found in rings of cells around the
     * point) against the hierarchy's over every triangle */
    double *u = malloc((size_t)bg->nverts * sizeof *u);
    sm_sdf_distance(sm_image_target_sdf(t), bg->nverts, bg->coords, u, NULL);
    int64_t wrong = 0, near = 0, differ = 0;
    for (int32_t p = 0; p < bg->nverts; p++)
        if (fabs(d[p]) < 3 && d[p] != 0) { /* on the surface: no side */
            near++;
            int bad = (d[p] < 0) != (w[p] > 0.5);
            wrong += bad;
            differ += fabs(fabs(d[p]) - u[p]) > 1e-12;
        }
    print_message("# binary sphere r 20: %lld near points, %lld signs against the winding number, "
                  "%lld distances against the hierarchy's\n",
                  (long long)near, (long long)wrong, (long long)differ);
    assert_true(near > 10000);
    assert_int_equal(wrong, 0);
    assert_int_equal(differ, 0);
    free(u);
    free(d);
    free(w);
    sm_mesh_free(bg);
    sm_image_target_free(t);
    free(v);
    free(m);
}

/* A 2D label's contour (sm_image_contour_2d) without smoothing: the mask
 * is 1 and 0 at pixel centres, so the level 0.5 crosses every edge at its
 * middle.  The square of pixels [10, 29]^2 gives the square [9.5, 29.5]^2
 * with the two corners cut where the cells' diagonal (a,b)-(a+1,b+1)
 * meets the square's other diagonal (legs 1/2: area 1/8 each), hence the
 * area 400 - 1/4 = 399.75 in pixels, times |det| of the map.  Checked:
 * every vertex starts one segment and ends one (closed, consistently
 * oriented), the shoelace area has the inside on the left (positive)
 * for a map that keeps and one that mirrors orientation, and a label of
 * several slices or a tilted plane is refused. */
static void test_contour_2d(void **state)
{
    (void)state;
    enum { N = 40 };
    uint8_t mask[N * N];
    for (int j = 0; j < N; j++)
        for (int i = 0; i < N; i++)
            mask[j * N + i] = i >= 10 && i <= 29 && j >= 10 && j <= 29;
    const double t = 0.3, hx = 0.5, hy = 2.0;
    const double maps[2][12] = {
        {cos(t) * hx, -sin(t) * hy, 0, 3, sin(t) * hx, cos(t) * hy, 0, -1, 0, 0, 1, 0},
        {-cos(t) * hx, sin(t) * hy, 0, 3, sin(t) * hx, cos(t) * hy, 0, -1, 0, 0, 1, 0}};
    for (int k = 0; k < 2; k++) {
        sm_image im = {.dims = {N, N, 1}, .type = SM_VOXEL_U8, .slope = 1, .voxels = mask,
                       .format = "test"};
        memcpy(im.ijk_to_lps, maps[k], sizeof im.ijk_to_lps);
        sm_surface *s = NULL;
        sm_error err;
        sm_error_clear(&err);
        assert_int_equal(sm_image_contour_2d(&im, mask, 0, &s, &err), SM_OK);
        assert_int_equal(s->dim, 2);
        int *starts = calloc((size_t)s->nverts, sizeof *starts);
        int *ends = calloc((size_t)s->nverts, sizeof *ends);
        double area = 0;
        for (int32_t f = 0; f < s->nfacets; f++) {
            const double *a = s->coords + 2 * s->facets[2 * f];
            const double *b = s->coords + 2 * s->facets[2 * f + 1];
            starts[s->facets[2 * f]]++;
            ends[s->facets[2 * f + 1]]++;
            area += 0.5 * (a[0] * b[1] - a[1] * b[0]);
        }
        for (int32_t v = 0; v < s->nverts; v++) {
            assert_int_equal(starts[v], 1);
            assert_int_equal(ends[v], 1);
        }
        double det = fabs(maps[k][0] * maps[k][5] - maps[k][1] * maps[k][4]);
        print_message("# contour %d: %d segments, area %.12g (exact %.12g)\n", k, s->nfacets,
                      area, 399.75 * det);
        assert_true(fabs(area - 399.75 * det) < 1e-9 * det * 400);
        free(starts);
        free(ends);
        sm_surface_free(s);
    }
    sm_image im = {.dims = {N, N / 2, 2}, .type = SM_VOXEL_U8, .slope = 1, .voxels = mask};
    memcpy(im.ijk_to_lps, maps[0], sizeof im.ijk_to_lps);
    sm_surface *s = NULL;
    sm_error err;
    assert_int_equal(sm_image_contour_2d(&im, mask, 0, &s, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "one slice"));
    im.dims[1] = N;
    im.dims[2] = 1;
    im.ijk_to_lps[8] = 0.1; /* the plane tilted */
    assert_int_equal(sm_image_contour_2d(&im, mask, 0, &s, &err), SM_ERR_INVALID);
    assert_non_null(strstr(err.msg, "not z = constant"));
    assert_null(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_edt_brute_force), cmocka_unit_test(test_nifti_qform_sform),
        cmocka_unit_test(test_text_formats),    cmocka_unit_test(test_mask_stats),
        cmocka_unit_test(test_target_sphere),   cmocka_unit_test(test_binary_sphere_signs),
        cmocka_unit_test(test_contour_2d),      cmocka_unit_test(test_grid_distance_exact),
        cmocka_unit_test(test_components_brute_force), cmocka_unit_test(test_nearest_site_brute_force),
        cmocka_unit_test(test_march_chunks_joined), cmocka_unit_test(test_grid_distance_random),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
