/* What the benchmarks share: process CPU time, peak RSS, the example
 * files' lookup and a byte hash.  Header-only (each benchmark is one C
 * file linked against the core library, bench/module.mk). */
#ifndef SM_BENCH_UTIL_H
#define SM_BENCH_UTIL_H

#include <stdint.h>
#include <stdio.h>
#include <time.h>
#include <unistd.h>

/* CPU seconds of the process, all threads: on a shared machine the wall
 * time also counts waiting for a core, this does not. */
static inline double bench_cpu_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* The process's peak resident set so far (VmHWM), MiB; -1 if unknown.
 * Read after each phase, it says which phase set the peak. */
static inline double bench_peak_rss_mib(void)
{
    FILE *f = fopen("/proc/self/status", "r");
    char line[256];
    double kb = -1;
    while (f && fgets(line, sizeof line, f))
        if (sscanf(line, "VmHWM: %lf", &kb) == 1)
            break;
    if (f)
        fclose(f);
    return kb < 0 ? -1 : kb / 1024.0;
}

/* The first of base, base.gz, baseb, baseb.gz that can be read in dir
 * (written into buf), or NULL. */
static inline const char *bench_first_existing(const char *dir, const char *base, char *buf,
                                               size_t n)
{
    static const char *const suffix[] = {"", ".gz", "b", "b.gz"};
    for (int i = 0; i < 4; i++) {
        snprintf(buf, n, "%s/%s%s", dir, base, suffix[i]);
        if (access(buf, R_OK) == 0)
            return buf;
    }
    return NULL;
}

/* FNV-1a over n bytes, continuing from h (start: BENCH_FNV_START). */
#define BENCH_FNV_START 0xcbf29ce484222325u
static inline uint64_t bench_fnv(uint64_t h, const void *p, size_t n)
{
    const unsigned char *b = p;
    for (size_t i = 0; i < n; i++)
        h = (h ^ b[i]) * 0x100000001b3u;
    return h;
}

#endif
