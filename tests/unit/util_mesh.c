#include "util_mesh.h"

#include <math.h>
#include <stdlib.h>

sm_mesh *util_box_mesh(int dim, int n, const double *lo, const double *hi, unsigned shuffle)
{
    int np = n + 1;
    int32_t nverts = dim == 2 ? np * np : np * np * np;
    int32_t nelems = dim == 2 ? 2 * n * n : 6 * n * n * n;
    sm_mesh *m = NULL;
    if (sm_mesh_alloc(&m, dim, nverts, nelems, 0, NULL) != SM_OK)
        return NULL;
    for (int32_t v = 0; v < nverts; v++) {
        int idx[3] = {v % np, (v / np) % np, v / (np * np)};
        for (int c = 0; c < dim; c++)
            m->coords[v * dim + c] = lo[c] + (hi[c] - lo[c]) * idx[c] / n;
    }
    int32_t e = 0;
    if (dim == 2) {
        for (int j = 0; j < n; j++)
            for (int i = 0; i < n; i++) {
                int32_t a = j * np + i, b = a + 1, c = a + np + 1, d = a + np;
                int32_t t[2][3] = {{a, b, c}, {a, c, d}};
                for (int s = 0; s < 2; s++, e++)
                    for (int q = 0; q < 3; q++)
                        m->elems[e * 3 + q] = t[s][q];
            }
    } else {
        static const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2},
                                        {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
        for (int k = 0; k < n; k++)
            for (int j = 0; j < n; j++)
                for (int i = 0; i < n; i++)
                    for (int p = 0; p < 6; p++, e++) {
                        int cur[3] = {i, j, k};
                        m->elems[e * 4] = (k * np + j) * np + i;
                        for (int s = 0; s < 3; s++) {
                            cur[perms[p][s]]++;
                            m->elems[e * 4 + s + 1] = (cur[2] * np + cur[1]) * np + cur[0];
                        }
                    }
    }
    if (shuffle) {
        unsigned state = shuffle;
        int nv = dim + 1;
        for (int32_t f = 0; f < nelems; f++)
            for (int q = nv - 1; q > 0; q--) {
                state = state * 1103515245u + 12345u;
                int r = (int)((state >> 16) % (unsigned)(q + 1));
                int32_t t = m->elems[f * nv + q];
                m->elems[f * nv + q] = m->elems[f * nv + r];
                m->elems[f * nv + r] = t;
            }
    }
    return m;
}

sm_mesh *util_disk_mesh(const double *center, double radius, int rings)
{
    int32_t nverts = 1 + 3 * rings * (rings + 1);
    int32_t nelems = 6 * rings * rings;
    sm_mesh *m = NULL;
    if (sm_mesh_alloc(&m, 2, nverts, nelems, 6 * rings, NULL) != SM_OK)
        return NULL;
    m->coords[0] = center[0];
    m->coords[1] = center[1];
    for (int k = 1; k <= rings; k++) {
        int32_t first = 1 + 3 * k * (k - 1);
        for (int j = 0; j < 6 * k; j++) {
            double a = 2.0 * M_PI * j / (6 * k), r = radius * k / rings;
            m->coords[2 * (first + j)] = center[0] + r * cos(a);
            m->coords[2 * (first + j) + 1] = center[1] + r * sin(a);
        }
    }
    /* between ring k-1 (6(k-1) vertices) and ring k (6k), merge by angle */
    int32_t e = 0;
    for (int k = 1; k <= rings; k++) {
        int32_t in0 = k == 1 ? 0 : 1 + 3 * (k - 1) * (k - 2), out0 = 1 + 3 * k * (k - 1);
        int nin = k == 1 ? 1 : 6 * (k - 1), nout = 6 * k;
        int i = 0, o = 0;
        while (i < nin || o < nout) {
            /* advance on the ring whose next vertex has the smaller angle */
            double ai = k == 1 ? 1e9 : (double)(i + 1) / nin, ao = (double)(o + 1) / nout;
            int32_t vi = in0 + (k == 1 ? 0 : i % nin), vo = out0 + o % nout;
            if (o < nout && (ao <= ai || i >= nin || k == 1)) {
                m->elems[3 * e] = vi;
                m->elems[3 * e + 1] = vo;
                m->elems[3 * e + 2] = out0 + (o + 1) % nout;
                o++;
            } else {
                m->elems[3 * e] = vi;
                m->elems[3 * e + 1] = vo;
                m->elems[3 * e + 2] = in0 + (i + 1) % nin;
                i++;
            }
            e++;
            if (k == 1 && o == nout)
                break;
        }
    }
    m->nelems = e;
    int32_t out0 = 1 + 3 * rings * (rings - 1);
    for (int j = 0; j < 6 * rings; j++) {
        m->facets[2 * j] = out0 + j;
        m->facets[2 * j + 1] = out0 + (j + 1) % (6 * rings);
        m->facet_refs[j] = 1;
    }
    for (int32_t t = 0; t < e; t++)
        m->elem_refs[t] = 1;
    return m;
}
