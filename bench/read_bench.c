/* read_bench: the time to read one case's inputs, as match_bench's
 * "read inputs" line counts it, without the run behind it.
 *
 *   read_bench DIR [REPS]
 *
 * DIR holds template.mesh, background.mesh and background.sol (each
 * optionally .gz or binary, the same choice as match_bench).  Reads the
 * three files REPS times (default 7), each time in a fresh child process
 * as match_bench reads them once in a fresh process (a second reading in
 * the same process would reuse the pages the first one faulted in, which
 * on a virtual machine are a large part of the cost), and prints, per
 * file and for all three, the best wall time and the best CPU time (on a
 * shared machine the wall time also counts waiting for a core), the peak
 * RSS after reading, and a checksum of everything read (coordinates bit
 * for bit, indices, references, values), so that a faster reader can be
 * shown to give the same result. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "bench_util.h"
#include "shapematch/sm_clock.h"
#include "shapematch/sm_io.h"
#include "shapematch/sm_mesh.h"

static uint64_t mesh_hash(uint64_t h, const sm_mesh *m)
{
    size_t nv = (size_t)m->nverts, ne = (size_t)m->nelems, nf = (size_t)m->nfacets;
    h = bench_fnv(h, m->coords, nv * (size_t)m->dim * sizeof(double));
    h = bench_fnv(h, m->vert_refs, nv * sizeof(int32_t));
    h = bench_fnv(h, m->elems, ne * (size_t)(m->dim + 1) * sizeof(int32_t));
    h = bench_fnv(h, m->elem_refs, ne * sizeof(int32_t));
    h = bench_fnv(h, m->facets, nf * (size_t)m->dim * sizeof(int32_t));
    return bench_fnv(h, m->facet_refs, nf * sizeof(int32_t));
}

/* What one reading of the three files measured. */
typedef struct reading {
    double wall[4], cpu[4]; /* per file, then the sum */
    double rss;             /* peak RSS after reading, MiB */
    uint64_t hash;
    int ok;
} reading;

/* Reads the three files once (in the calling process). */
static void read_once(char path[3][4096], reading *out)
{
    memset(out, 0, sizeof *out);
    uint64_t h = BENCH_FNV_START;
    for (int f = 0; f < 3; f++) {
        sm_error err;
        sm_mesh *m = NULL;
        sm_sol *s = NULL;
        double t0 = sm_clock_seconds(), c0 = bench_cpu_seconds();
        sm_status st = f < 2 ? sm_mesh_read(path[f], &m, &err) : sm_sol_read(path[f], &s, &err);
        out->wall[f] = sm_clock_seconds() - t0;
        out->cpu[f] = bench_cpu_seconds() - c0;
        if (st != SM_OK) {
            fprintf(stderr, "%s\n", err.msg);
            return;
        }
        if (m)
            h = mesh_hash(h, m);
        else
            h = bench_fnv(h, s->values, (size_t)s->nverts * (size_t)s->ncomp * sizeof(double));
        sm_mesh_free(m);
        sm_sol_free(s);
        out->wall[3] += out->wall[f];
        out->cpu[3] += out->cpu[f];
    }
    out->rss = bench_peak_rss_mib();
    out->hash = h;
    out->ok = 1;
}

/* read_once in a fresh child process; 0 when it read everything. */
static int read_in_child(char path[3][4096], reading *out)
{
    int fds[2];
    if (pipe(fds) != 0) {
        perror("pipe");
        return -1;
    }
    pid_t pid = fork();
    if (pid < 0) {
        perror("fork");
        return -1;
    }
    if (pid == 0) {
        close(fds[0]);
        read_once(path, out);
        ssize_t n = write(fds[1], out, sizeof *out);
        _exit(n == (ssize_t)sizeof *out ? 0 : 1);
    }
    close(fds[1]);
    ssize_t n = read(fds[0], out, sizeof *out);
    close(fds[0]);
    int status;
    waitpid(pid, &status, 0);
    return n == (ssize_t)sizeof *out && out->ok ? 0 : -1;
}

int main(int argc, char **argv)
{
    if (argc < 2) {
        fprintf(stderr, "usage: %s DIR [REPS]\n", argv[0]);
        return 1;
    }
    int reps = argc > 2 ? atoi(argv[2]) : 7;
    if (reps < 1)
        reps = 1;
    char path[3][4096];
    static const char *const base[3] = {"template.mesh", "background.mesh", "background.sol"};
    for (int f = 0; f < 3; f++)
        if (!bench_first_existing(argv[1], base[f], path[f], sizeof path[f])) {
            fprintf(stderr, "%s: no %s\n", argv[1], base[f]);
            return 1;
        }
    double best_wall[4], best_cpu[4], rss = -1;
    uint64_t hash = 0;
    for (int rep = 0; rep < reps; rep++) {
        reading got;
        if (read_in_child(path, &got) != 0)
            return 1;
        if (rep == 0) {
            hash = got.hash;
        } else if (got.hash != hash) {
            fprintf(stderr, "reading %d gave a different result\n", rep + 1);
            return 1;
        }
        if (rep == 0 || got.rss > rss)
            rss = got.rss;
        for (int f = 0; f < 4; f++) {
            if (rep == 0 || got.wall[f] < best_wall[f])
                best_wall[f] = got.wall[f];
            if (rep == 0 || got.cpu[f] < best_cpu[f])
                best_cpu[f] = got.cpu[f];
        }
    }
    for (int f = 0; f < 3; f++)
        printf("  %-40s %7.4f s wall, %7.4f s CPU\n", path[f], best_wall[f], best_cpu[f]);
    printf("  all three (best of %d)                   %7.4f s wall, %7.4f s CPU\n", reps,
           best_wall[3], best_cpu[3]);
    printf("  peak RSS after reading %.1f MiB, checksum %016llx\n", rss,
           (unsigned long long)hash);
    printf("RESULT read wall=%.4f cpu=%.4f rss_mib=%.1f hash=%016llx\n", best_wall[3], best_cpu[3],
           rss, (unsigned long long)hash);
    return 0;
}
