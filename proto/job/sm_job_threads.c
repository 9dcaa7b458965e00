/* The thread policy of a run (see sm_job_threads.h): how many threads a
 * template is worth, and how many cores are idle right now (/proc). */
#include "job/sm_job_threads.h"

#include <dirent.h>
#include <dlfcn.h>
#include <omp.h>
#include <sched.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

int sm_job_threads_for(int64_t elements, int max_threads, int idle_cores)
{
    if (max_threads < 1)
        return 1;
    if (elements >= SM_JOB_THREADS_MIN_ELEMENTS)
        return max_threads;
    if (elements >= SM_JOB_THREADS_IDLE_MIN_ELEMENTS && idle_cores >= 2)
        return idle_cores < max_threads ? idle_cores : max_threads;
    return 1;
}

/* Threads of this process in state R (running or runnable). */
static int own_running_threads(void)
{
    DIR *d = opendir("/proc/self/task");
    if (!d)
        return -1;
    int n = 0;
    struct dirent *de;
    while ((de = readdir(d)) != NULL) {
        if (de->d_name[0] == '.')
            continue;
        char path[64], buf[256];
        snprintf(path, sizeof path, "/proc/self/task/%.20s/stat", de->d_name);
        FILE *f = fopen(path, "r");
        if (!f)
            continue; /* the thread ended meanwhile */
        size_t len = fread(buf, 1, sizeof buf - 1, f);
        fclose(f);
        buf[len] = '\0';
        /* "pid (comm) S ...": the state follows the last ')' */
        const char *close = strrchr(buf, ')');
        n += close && close[1] == ' ' && close[2] == 'R';
    }
    closedir(d);
    return n;
}

/* Other runnable tasks: the kernel's count of runnable tasks minus this
 * process's.  The two are read at different moments, and this process's
 * own threads (a parallel region's workers, BLAS threads going to sleep)
 * change state in between: one counted runnable by the kernel and asleep
 * a moment later looks like another process.  Its threads are counted
 * before and after, the larger taken, and the least of a few samples 1 ms
 * apart kept: a passing kernel worker does not take a core from the run
 * (it did in 6 of 10 runs of examples/3d on the idle machine). */
static int other_running(void)
{
    int least = -1;
    for (int sample = 0; sample < 5; sample++) {
        if (sample > 0)
            nanosleep(&(struct timespec){.tv_nsec = 1000000}, NULL);
        int before = own_running_threads();
        FILE *f = fopen("/proc/loadavg", "r");
        if (!f)
            return -1;
        double l1, l5, l15;
        int running = -1, total;
        int ok = fscanf(f, "%lf %lf %lf %d/%d", &l1, &l5, &l15, &running, &total) == 5;
        fclose(f);
        int after = own_running_threads();
        if (!ok || before < 0 || after < 0)
            return -1;
        int others = running - (before > after ? before : after); /* the reading thread counts itself */
        if (others < 0)
            others = 0;
        if (least < 0 || others < least)
            least = others;
        if (least == 0)
            break;
    }
    return least;
}

int sm_job_idle_cores(void)
{
    cpu_set_t set;
    if (sched_getaffinity(0, sizeof set, &set) != 0)
        return -1;
    int cores = CPU_COUNT(&set);
    int others = other_running();
    if (others < 0)
        return -1;
    return cores > others ? cores - others : 0;
}

/* OpenMP and BLAS threads to n.  The BLAS CHOLMOD calls is whichever
 * libblas.so.3 the system selects: OpenBLAS is told through its
 * openblas_set_num_threads when it is the one loaded (found at run time,
 * so nothing links against OpenBLAS itself); a BLAS without threads
 * needs nothing. */
static void set_threads(int n, int blas)
{
    omp_set_num_threads(n);
    void (*blas_threads)(int) = (void (*)(int))dlsym(RTLD_DEFAULT, "openblas_set_num_threads");
    if (blas_threads)
        blas_threads(blas);
}

int sm_job_threads_apply(int64_t elements)
{
    int limit = omp_get_max_threads();
    /* the idle cores matter only between the two thresholds: no /proc
     * reads for the small jobs, most of a daemon's */
    int idle = elements >= SM_JOB_THREADS_IDLE_MIN_ELEMENTS && elements < SM_JOB_THREADS_MIN_ELEMENTS
                   ? sm_job_idle_cores()
                   : -1;
    int n = sm_job_threads_for(elements, limit, idle);
    set_threads(n, elements < SM_JOB_THREADS_MIN_ELEMENTS ? 1 : n);
    return limit;
}

void sm_job_threads_restore(int limit)
{
    set_threads(limit, limit);
}

void sm_job_threads_single(sm_job_threads_saved *saved)
{
    int (*blas_get)(void) = (int (*)(void))dlsym(RTLD_DEFAULT, "openblas_get_num_threads");
    saved->omp = omp_get_max_threads();
    saved->blas = blas_get ? blas_get() : -1;
    set_threads(1, 1);
}

int sm_job_blas_threads_set(int n)
{
    int (*blas_get)(void) = (int (*)(void))dlsym(RTLD_DEFAULT, "openblas_get_num_threads");
    void (*blas_set)(int) = (void (*)(int))dlsym(RTLD_DEFAULT, "openblas_set_num_threads");
    if (!blas_get || !blas_set)
        return -1;
    int before = blas_get();
    blas_set(n);
    return before;
}

void sm_job_threads_put_back(const sm_job_threads_saved *saved)
{
    omp_set_num_threads(saved->omp);
    void (*blas_set)(int) = (void (*)(int))dlsym(RTLD_DEFAULT, "openblas_set_num_threads");
    if (blas_set && saved->blas > 0)
        blas_set(saved->blas);
}
