/* io_bench: parse rates of the mesh readers.
 *
 *   io_bench DIR [N]
 *
 * Writes one tetrahedral mesh of an N^3 grid of cubes (6 tetrahedra
 * each, default N = 64: 275k vertices, 1.57M tetrahedra, coordinates
 * perturbed so that they print with all 17 digits) into DIR as .mesh,
 * .meshb and .mesh.gz, then reads each back (best of 3) and prints the
 * rate in MB/s of file bytes (wall and CPU time) and of tetrahedra, and
 * checks that every
 * form reads back to the same mesh (the figures of a wrong reader would
 * mean nothing).  Goal (issue 13): .meshb >= 200 MB/s. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

#include "bench_util.h"
#include "shapematch/sm_clock.h"
#include "shapematch/sm_io.h"
#include "shapematch/sm_mesh.h"

/* Kuhn's split of the unit cube into 6 tetrahedra around the diagonal
 * 0-7 (corner bits: x = 1, y = 2, z = 4). */
static const int kuhn[6][4] = {{0, 1, 3, 7}, {0, 3, 2, 7}, {0, 2, 6, 7},
                               {0, 6, 4, 7}, {0, 4, 5, 7}, {0, 5, 1, 7}};

static sm_mesh *grid_mesh(int n, sm_error *err)
{
    int32_t nv1 = n + 1, nverts = nv1 * nv1 * nv1, nelems = 6 * n * n * n;
    sm_mesh *m = NULL;
    if (sm_mesh_alloc(&m, 3, nverts, nelems, 0, err) != SM_OK)
        return NULL;
    unsigned s = 12345;
    for (int32_t v = 0; v < nverts; v++) {
        int32_t ijk[3] = {v % nv1, (v / nv1) % nv1, v / (nv1 * nv1)};
        for (int c = 0; c < 3; c++) {
            s = s * 1103515245u + 12345u;
            double jitter = ((s >> 8) & 0xffff) / 65536.0 - 0.5;
            double interior = ijk[c] > 0 && ijk[c] < n;
            m->coords[3 * v + c] = (ijk[c] + 0.2 * interior * jitter) / n;
        }
        m->vert_refs[v] = 0;
    }
    int32_t e = 0;
    for (int32_t k = 0; k < n; k++)
        for (int32_t j = 0; j < n; j++)
            for (int32_t i = 0; i < n; i++)
                for (int t = 0; t < 6; t++, e++) {
                    for (int q = 0; q < 4; q++) {
                        int b = kuhn[t][q];
                        m->elems[4 * e + q] = (i + (b & 1)) + nv1 * ((j + (b >> 1 & 1)) + nv1 * (k + (b >> 2 & 1)));
                    }
                    m->elem_refs[e] = 1 + t % 2;
                }
    return m;
}

static int same_mesh(const sm_mesh *a, const sm_mesh *b)
{
    return a->dim == b->dim && a->nverts == b->nverts && a->nelems == b->nelems &&
           memcmp(a->coords, b->coords, sizeof(double) * 3 * (size_t)a->nverts) == 0 &&
           memcmp(a->elems, b->elems, sizeof(int32_t) * 4 * (size_t)a->nelems) == 0 &&
           memcmp(a->elem_refs, b->elem_refs, sizeof(int32_t) * (size_t)a->nelems) == 0;
}

/* Best of 3 reads of path (wall, and CPU in *cpu); -1 on a read error or
 * a different mesh. */
static double time_read(const char *path, const sm_mesh *ref, double *cpu)
{
    double best = -1;
    *cpu = -1;
    for (int rep = 0; rep < 3; rep++) {
        sm_error err;
        sm_mesh *m = NULL;
        double t0 = sm_clock_seconds(), c0 = bench_cpu_seconds();
        sm_status st = sm_mesh_read(path, &m, &err);
        double t = sm_clock_seconds() - t0, c = bench_cpu_seconds() - c0;
        if (st != SM_OK) {
            fprintf(stderr, "%s\n", err.msg);
            return -1;
        }
        int same = same_mesh(m, ref);
        sm_mesh_free(m);
        if (!same) {
            fprintf(stderr, "%s: reads back to a different mesh\n", path);
            return -1;
        }
        if (best < 0 || t < best)
            best = t;
        if (*cpu < 0 || c < *cpu)
            *cpu = c;
    }
    return best;
}

int main(int argc, char **argv)
{
    if (argc < 2) {
        fprintf(stderr, "usage: %s DIR [N]\n", argv[0]);
        return 1;
    }
    int n = argc > 2 ? atoi(argv[2]) : 64;
    if (n < 1 || n > 200) {
        fprintf(stderr, "N must be in [1, 200]\n");
        return 1;
    }
    sm_error err;
    sm_mesh *m = grid_mesh(n, &err);
    if (!m) {
        fprintf(stderr, "%s\n", err.msg);
        return 1;
    }
    printf("mesh: %d vertices, %d tetrahedra\n", m->nverts, m->nelems);
    static const char *const ext[] = {"mesh", "meshb", "mesh.gz"};
    int rc = 0;
    for (int f = 0; f < 3; f++) {
        char path[4096];
        snprintf(path, sizeof path, "%s/io-bench-%d.%s", argv[1], n, ext[f]);
        double t0 = sm_clock_seconds();
        if (sm_mesh_write(path, m, &err) != SM_OK) {
            fprintf(stderr, "%s\n", err.msg);
            rc = 1;
            break;
        }
        double tw = sm_clock_seconds() - t0;
        struct stat st;
        double mb = stat(path, &st) == 0 ? (double)st.st_size / 1e6 : 0;
        double cpu;
        double tr = time_read(path, m, &cpu);
        if (tr < 0) {
            rc = 1;
            break;
        }
        printf("  %-8s %8.1f MB  write %6.3f s  read %6.3f s = %7.1f MB/s, %6.2f M tetrahedra/s"
               " (CPU %6.3f s = %7.1f MB/s)\n",
               ext[f], mb, tw, tr, mb / tr, m->nelems / tr / 1e6, cpu, mb / cpu);
        printf("RESULT io format=%s mb=%.1f read_s=%.4f mb_per_s=%.1f cpu_mb_per_s=%.1f\n", ext[f], mb,
               tr, mb / tr, mb / cpu);
        remove(path);
    }
    sm_mesh_free(m);
    return rc;
}
