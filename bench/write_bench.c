/* write_bench: the time to write the ASCII result files of a run, as
 * shapematch run writes them at its end, without the run before it.
 *
 *   write_bench TEMPLATE DIR [REPS]
 *
 * Reads the template mesh TEMPLATE (e.g. examples/3d/template.mesh),
 * moves its vertices by a smooth displacement (so that, as after a real
 * run, every coordinate needs 16 or 17 digits), then writes into DIR
 * what the job runner writes from it: result.mesh (sm_mesh_write_coords),
 * result.vtu (sm_vtu_write, with the displacement and a distance) and
 * displacement.sol (sm_sol_write), each REPS times (default 9), and
 * prints the best wall and CPU time of each and of the three (on a shared
 * machine the wall time also counts waiting for a core), the size and a
 * checksum of each file (a faster writer must write the same bytes), and
 * the cost of one number on the numbers of these files, as snprintf
 * formats it ("%.17g", "%ld": what the writers called before) and as the
 * core's own formatting does (sm__double_to_decimal, sm__int_to_decimal:
 * what they call now). */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "bench_util.h"
#include "shapematch/sm_clock.h"
#include "shapematch/sm_io.h"
#include "shapematch/sm_mesh.h"
#include "io/sm_number.h"

/* FNV-1a of a whole file and its size; 0 if it cannot be read. */
static uint64_t file_hash(const char *path, long *size)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return 0;
    uint64_t h = BENCH_FNV_START;
    unsigned char buf[1 << 16];
    size_t n;
    *size = 0;
    while ((n = fread(buf, 1, sizeof buf, f)) > 0) {
        h = bench_fnv(h, buf, n);
        *size += (long)n;
    }
    fclose(f);
    return h;
}

/* What the job runner writes from: the moved vertices, their
 * displacement and a distance at each (a sphere's, as a stand-in). */
typedef struct result {
    const sm_mesh *mesh;
    double *coords, *displacement, *distance;
    sm_sol *sol;
} result;

static int make_result(const sm_mesh *m, result *r)
{
    size_t n = (size_t)m->nverts * (size_t)m->dim;
    sm_error err;
    r->mesh = m;
    r->coords = malloc(n * sizeof(double));
    r->displacement = malloc(n * sizeof(double));
    r->distance = malloc(((size_t)m->nverts + 1) * sizeof(double));
    if (!r->coords || !r->displacement || !r->distance ||
        sm_sol_alloc(&r->sol, m->dim, m->nverts, m->dim, &err) != SM_OK)
        return -1;
    for (int32_t v = 0; v < m->nverts; v++) {
        const double *x = m->coords + (size_t)v * (size_t)m->dim;
        double r2 = 0;
        for (int c = 0; c < m->dim; c++) {
            size_t i = (size_t)v * (size_t)m->dim + (size_t)c;
            double u = 0.02 * sin(7.0 * x[c] + 1.3 * c) * cos(5.0 * x[(c + 1) % m->dim]);
            r->coords[i] = x[c] + u;
            /* as sm_job_write_selected computes it */
            r->displacement[i] = r->coords[i] - x[c];
            r2 += (r->coords[i] - 0.5) * (r->coords[i] - 0.5);
        }
        r->distance[v] = sqrt(r2) - 0.3;
    }
    memcpy(r->sol->values, r->displacement, n * sizeof(double));
    return 0;
}

static void free_result(result *r)
{
    free(r->coords);
    free(r->displacement);
    free(r->distance);
    sm_sol_free(r->sol);
}

enum { FILES = 3 };
static const char *const file_name[FILES] = {"result.mesh", "result.vtu", "displacement.sol"};

static sm_status write_file(int f, const char *path, const result *r, sm_error *err)
{
    if (f == 0)
        return sm_mesh_write_coords(path, r->mesh, r->coords, err);
    if (f == 1)
        return sm_vtu_write(path, r->mesh, r->coords, r->displacement, r->distance, err);
    return sm_sol_write(path, r->sol, err);
}

/* ns_NAME(values, n, reps, &bytes): ns per number of FORMAT(buf, value)
 * (which returns the length written) over the n values, best of reps
 * passes; one function per formatting, so that the timed loop calls it
 * directly as the writers do. */
#define NS_PER_NUMBER(name, type, bufsize, format)                                                  \
    static double ns_##name(const type *v, size_t n, int reps, size_t *bytes)                       \
    {                                                                                              \
        char buf[bufsize];                                                                         \
        double best = -1;                                                                          \
        for (int rep = 0; rep < reps; rep++) {                                                     \
            size_t total = 0;                                                                      \
            double t0 = bench_cpu_seconds();                                                       \
            for (size_t i = 0; i < n; i++)                                                         \
                total += (size_t)(format);                                                         \
            double t = bench_cpu_seconds() - t0;                                                   \
            if (best < 0 || t < best)                                                              \
                best = t;                                                                          \
            *bytes = total;                                                                        \
        }                                                                                          \
        return best * 1e9 / (double)n;                                                             \
    }
/* what the writers called before, and what they call now */
NS_PER_NUMBER(snprintf_doubles, double, 32, snprintf(buf, sizeof buf, "%.17g", v[i]))
NS_PER_NUMBER(snprintf_ints, long, 32, snprintf(buf, sizeof buf, "%ld", v[i]))
NS_PER_NUMBER(core_doubles, double, SM_DECIMAL_MAX, sm__double_to_decimal(v[i], buf))
NS_PER_NUMBER(core_ints, long, SM_DECIMAL_MAX, sm__int_to_decimal(v[i], buf))

/* The doubles and the integers of the three files, as the writers print
 * them (vertex indices from 1 in Medit, from 0 in VTK, references). */
static int numbers_of(const result *r, double **xs, size_t *nx, long **ks, size_t *nk)
{
    const sm_mesh *m = r->mesh;
    size_t nv = (size_t)m->nverts, nd = nv * (size_t)m->dim;
    size_t ne = (size_t)m->nelems * (size_t)(m->dim + 1), nf = (size_t)m->nfacets * (size_t)m->dim;
    *nx = 4 * nd + nv;
    *nk = 2 * (ne + nf) + 2 * (nv + (size_t)m->nelems + (size_t)m->nfacets);
    *xs = malloc(*nx * sizeof **xs);
    *ks = malloc(*nk * sizeof **ks);
    if (!*xs || !*ks)
        return -1;
    size_t a = 0, b = 0;
    for (int pass = 0; pass < 2; pass++)
        for (size_t i = 0; i < nd; i++)
            (*xs)[a++] = r->coords[i];
    for (size_t i = 0; i < nd; i++)
        (*xs)[a++] = r->displacement[i];
    for (size_t i = 0; i < nd; i++)
        (*xs)[a++] = r->sol->values[i];
    for (size_t i = 0; i < nv; i++)
        (*xs)[a++] = r->distance[i];
    for (int base = 0; base < 2; base++) {
        for (size_t i = 0; i < ne; i++)
            (*ks)[b++] = (long)m->elems[i] + (base == 0);
        for (size_t i = 0; i < nf; i++)
            (*ks)[b++] = (long)m->facets[i] + (base == 0);
        for (size_t i = 0; i < (size_t)m->nelems; i++)
            (*ks)[b++] = m->elem_refs[i];
        for (size_t i = 0; i < (size_t)m->nfacets; i++)
            (*ks)[b++] = m->facet_refs[i];
    }
    for (size_t i = 0; i < nv; i++)
        (*ks)[b++] = m->vert_refs[i];
    for (size_t i = 0; i < nv; i++) /* offsets, about as long */
        (*ks)[b++] = (long)(i + 1) * (m->dim + 1);
    return 0;
}

int main(int argc, char **argv)
{
    if (argc < 3) {
        fprintf(stderr, "usage: %s TEMPLATE DIR [REPS]\n", argv[0]);
        return 1;
    }
    int reps = argc > 3 ? atoi(argv[3]) : 9;
    if (reps < 1)
        reps = 1;
    sm_error err;
    sm_mesh *m = NULL;
    if (sm_mesh_read(argv[1], &m, &err) != SM_OK) {
        fprintf(stderr, "%s\n", err.msg);
        return 1;
    }
    result r = {0};
    if (make_result(m, &r) != 0) {
        fprintf(stderr, "out of memory\n");
        return 1;
    }
    char path[FILES][4096];
    double best_wall[FILES + 1], best_cpu[FILES + 1];
    for (int f = 0; f < FILES; f++)
        snprintf(path[f], sizeof path[f], "%s/%s", argv[2], file_name[f]);
    for (int rep = 0; rep < reps; rep++) {
        double wall = 0, cpu = 0;
        for (int f = 0; f < FILES; f++) {
            double t0 = sm_clock_seconds(), c0 = bench_cpu_seconds();
            if (write_file(f, path[f], &r, &err) != SM_OK) {
                fprintf(stderr, "%s\n", err.msg);
                return 1;
            }
            double tw = sm_clock_seconds() - t0, tc = bench_cpu_seconds() - c0;
            if (rep == 0 || tw < best_wall[f])
                best_wall[f] = tw;
            if (rep == 0 || tc < best_cpu[f])
                best_cpu[f] = tc;
            wall += tw;
            cpu += tc;
        }
        if (rep == 0 || wall < best_wall[FILES])
            best_wall[FILES] = wall;
        if (rep == 0 || cpu < best_cpu[FILES])
            best_cpu[FILES] = cpu;
    }
    printf("writing the results of %s (%d vertices, %d elements, %d facets), best of %d:\n",
           argv[1], m->nverts, m->nelems, m->nfacets, reps);
    for (int f = 0; f < FILES; f++) {
        long size = 0;
        uint64_t h = file_hash(path[f], &size);
        printf("  %-17s %8.1f KB  %7.2f ms wall, %7.2f ms CPU  (fnv %016llx)\n", file_name[f],
               size / 1e3, 1e3 * best_wall[f], 1e3 * best_cpu[f], (unsigned long long)h);
    }
    printf("  all three                     %7.2f ms wall, %7.2f ms CPU\n", 1e3 * best_wall[FILES],
           1e3 * best_cpu[FILES]);

    double *xs;
    long *ks;
    size_t nx, nk, bx, bk;
    if (numbers_of(&r, &xs, &nx, &ks, &nk) != 0) {
        fprintf(stderr, "out of memory\n");
        return 1;
    }
    size_t cx, ck;
    double ns_x = ns_snprintf_doubles(xs, nx, reps, &bx);
    double ns_k = ns_snprintf_ints(ks, nk, reps, &bk);
    double core_x = ns_core_doubles(xs, nx, reps, &cx);
    double core_k = ns_core_ints(ks, nk, reps, &ck);
    printf("  one number of these files, %zu doubles and %zu integers (CPU, best of %d):\n", nx,
           nk, reps);
    printf("    snprintf \"%%.17g\"        %6.1f ns/double (%.1f bytes)   \"%%ld\" %5.1f ns/integer\n",
           ns_x, (double)bx / (double)nx, ns_k);
    printf("    sm__double_to_decimal %6.1f ns/double (%.1f bytes)   %5.1f ns/integer%s\n", core_x,
           (double)cx / (double)nx, core_k,
           cx == bx && ck == bk ? "" : "  (NOT THE SAME LENGTHS AS SNPRINTF)");
    printf("RESULT write mesh_ms=%.2f vtu_ms=%.2f sol_ms=%.2f total_ms=%.2f total_cpu_ms=%.2f "
           "snprintf_ns_double=%.1f snprintf_ns_int=%.1f ns_double=%.1f ns_int=%.1f\n",
           1e3 * best_wall[0], 1e3 * best_wall[1], 1e3 * best_wall[2], 1e3 * best_wall[FILES],
           1e3 * best_cpu[FILES], ns_x, ns_k, core_x, core_k);
    free(xs);
    free(ks);
    free_result(&r);
    sm_mesh_free(m);
    return 0;
}
