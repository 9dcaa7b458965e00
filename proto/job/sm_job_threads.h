/* The thread policy of a job run: how many OpenMP and BLAS threads a
 * template gets.  sm_job_run_exec applies it around the run
 * (sm_job_threads_apply, then sm_job_threads_restore). */
#ifndef SM_JOB_THREADS_H
#define SM_JOB_THREADS_H

#include <stdint.h>

/* Thread policy of a run: OpenMP threads for a template of
 * `elements` elements when at most max_threads are allowed (the OpenMP
 * limit when the run starts: OMP_NUM_THREADS, which the daemon sets from
 * --worker-threads; else the cores) and idle_cores cores run no other
 * process's task right now (sm_job_idle_cores; -1: unknown).
 *   - From SM_JOB_THREADS_MIN_ELEMENTS on, max_threads: the parallel
 *     regions hold enough work to pay even on a busy machine.
 *   - From SM_JOB_THREADS_IDLE_MIN_ELEMENTS on, as many threads as cores
 *     are idle (at most max_threads): with another core free, the
 *     30k-tetrahedron 3D example runs in 0.53 s instead of 0.63 s, but
 *     with both cores busy two threads make it 1.35 s instead of 1.03
 *     (a thread the scheduler does not run makes every barrier wait for
 *     it), so a second thread is only taken where a core is free.
 *   - Below, one thread: a region holds a few microseconds of work (a
 *     778-triangle 2D run at 0.07 ms per iteration with one thread, 0.09
 *     with two even on an idle machine, 16 ms on a busy one).
 * BLAS threads: one below SM_JOB_THREADS_MIN_ELEMENTS, else as many.  A
 * factor that small (3D example: 22k unknowns) is no faster with a
 * second BLAS thread, whose spinning takes the core from the OpenMP
 * loops; and a factor of two BLAS threads differs from one's in the
 * last bits (the 3D example's boundary_rms 1.86607502976e-4 against
 * ...2826e-4), so below that size a run's result files are the same
 * whatever the thread count (the parallel loops write per-item results
 * and take their sums in a fixed order; tests/cli/threads_same.sh).
 * Above it, a comparison bit for bit (a batch against separate runs)
 * is made at the same thread count. */
#define SM_JOB_THREADS_MIN_ELEMENTS 100000
#define SM_JOB_THREADS_IDLE_MIN_ELEMENTS 20000
int sm_job_threads_for(int64_t elements, int max_threads, int idle_cores);

/* Cores this process may run on (its affinity) that no task of another
 * process is running on now: from /proc/loadavg's count of running
 * tasks, less this process's own running threads (/proc/self/task).
 * An instant's view, taken when a run starts; -1 when unknown (no
 * /proc), which the policy reads as "none free". */
int sm_job_idle_cores(void);

/* Sets the OpenMP and BLAS threads for a run on a template of `elements`
 * elements by the policy above (reading the idle cores only between the
 * two thresholds, where they decide); returns the limit before, which
 * sm_job_threads_restore puts back after the run. */
int sm_job_threads_apply(int64_t elements);
void sm_job_threads_restore(int limit);

/* A process's OpenMP limit and BLAS threads (OpenBLAS's count; -1 for a
 * BLAS without threads), as sm_job_threads_single found them. */
typedef struct sm_job_threads_saved {
    int omp, blas;
} sm_job_threads_saved;
/* One OpenMP and one BLAS thread until sm_job_threads_put_back (the
 * batch's parent, which forks: a child cannot use a pool its parent
 * started); what was set before goes into *saved. */
void sm_job_threads_single(sm_job_threads_saved *saved);
void sm_job_threads_put_back(const sm_job_threads_saved *saved);

/* BLAS threads to n (OpenBLAS's; nothing for a BLAS without threads);
 * returns the count before, or -1 when there is no count to restore.
 * The set-up beside the target's read (sm_job_inputs_read_target) takes
 * one for a template below SM_JOB_THREADS_MIN_ELEMENTS: its other
 * thread is busy, so a second BLAS thread only takes the core from it
 * and spins (3D example: the first factorization 0.85 s instead of 0.16
 * on a loaded machine), and its factor is then the same whatever the
 * cores (a factor of two BLAS threads differs in the last bits). */
int sm_job_blas_threads_set(int n);

#endif
