/* A template meshed from a closed surface (sm_template_mesh.h): the
 * checks, a bound on the work, nglib in a child process, and what comes
 * back checked and oriented.
 *
 * Why a child: nglib (through its shim, core/mesh/sm_nglib.cc) is
 * loaded with dlopen there only, so no program links OpenCascade, MPI
 * and Python's runtime that Debian's nglib pulls; nglib keeps global
 * state (one meshing per process); and a crash or an endless loop inside
 * it on a bad surface ends the child (killed at the time bound), never
 * the caller.  The child sends the mesh back through a pipe. */
#include "shapematch/sm_template_mesh.h"

#include <dlfcn.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "mesh/sm_nglib.h"
#include "shapematch/sm_clock.h"
#include "shapematch/sm_params.h"

#define SHIM_NAME "libshapematch_nglib.so.0"

/* What the child writes first, then coords and elems. */
typedef struct reply_head {
    int32_t status, nverts, nelems;
    char msg[256];
} reply_head;

/* The shim: next to the program or library holding this code (build/
 * VARIANT/, or an installed lib/), one folder up (the test programs in
 * build/VARIANT/tests/), ../lib from a bin/, else the loader's path. */
static void *open_shim(char *why, size_t cap)
{
    Dl_info info;
    char dir[4096] = "";
    if (dladdr((void *)&sm_template_mesh_surface, &info) && info.dli_fname) {
        snprintf(dir, sizeof dir, "%s", info.dli_fname);
        char *slash = strrchr(dir, '/');
        if (slash)
            *slash = 0;
        else
            dir[0] = 0;
    }
    const char *rel[] = {"", "/..", "/../lib"};
    for (size_t i = 0; dir[0] && i < sizeof rel / sizeof rel[0]; i++) {
        char path[4200];
        snprintf(path, sizeof path, "%s%s/" SHIM_NAME, dir, rel[i]);
        if (access(path, R_OK) == 0) {
            void *h = dlopen(path, RTLD_NOW | RTLD_LOCAL);
            if (h)
                return h;
            snprintf(why, cap, "%s", dlerror());
            return NULL;
        }
    }
    void *h = dlopen(SHIM_NAME, RTLD_NOW | RTLD_LOCAL);
    if (!h)
        snprintf(why, cap, "%s", dlerror());
    return h;
}

static int write_all(int fd, const void *buf, size_t n)
{
    const char *p = buf;
    while (n > 0) {
        ssize_t w = write(fd, p, n);
        if (w < 0 && errno == EINTR)
            continue;
        if (w <= 0)
            return -1;
        p += w;
        n -= (size_t)w;
    }
    return 0;
}

/* The child: nglib's output silenced, the shim called, the mesh sent.
 * _exit, never exit: no atexit handler of the caller's (nor the leak
 * check of a sanitized build, which would report nglib's own) runs. */
static void child_main(int fd, const sm_surface *s, double h, int optsteps)
{
    int null = open("/dev/null", O_WRONLY);
    if (null >= 0) {
        dup2(null, STDOUT_FILENO);
        dup2(null, STDERR_FILENO);
    }
    reply_head head = {.status = 1};
    sm_nglib_out out = {0};
    char why[120] = "";
    void *shim = open_shim(why, sizeof why);
    if (!shim) {
        snprintf(head.msg, sizeof head.msg,
                 "cannot load the meshing library " SHIM_NAME " (Netgen's nglib, Debian "
                 "libnglib-6.2): %.119s",
                 why);
        write_all(fd, &head, sizeof head);
        _exit(0);
    }
    int rc;
    if (s->dim == 3) {
        sm_nglib_volume_fn fn = (sm_nglib_volume_fn)(uintptr_t)dlsym(shim, "sm_nglib_volume");
        rc = fn ? fn(s->coords, s->nverts, s->facets, s->nfacets, h, optsteps, &out) : 1;
    } else {
        sm_nglib_planar_fn fn = (sm_nglib_planar_fn)(uintptr_t)dlsym(shim, "sm_nglib_planar");
        const char *tmp = getenv("TMPDIR");
        char scratch[4096];
        snprintf(scratch, sizeof scratch, "%s/sm-template-XXXXXX.in2d", tmp && *tmp ? tmp : "/tmp");
        int sfd = mkstemps(scratch, 5);
        if (sfd < 0) {
            snprintf(head.msg, sizeof head.msg, "cannot create a scratch file for nglib: %s",
                     strerror(errno));
            write_all(fd, &head, sizeof head);
            _exit(0);
        }
        close(sfd);
        rc = fn ? fn(s->coords, s->nverts, s->facets, s->nfacets, h, optsteps, scratch, &out) : 1;
        unlink(scratch);
    }
    head.status = rc;
    head.nverts = rc == 0 ? out.nverts : 0;
    head.nelems = rc == 0 ? out.nelems : 0;
    snprintf(head.msg, sizeof head.msg, "%s", rc == 0 ? "" : out.msg[0] ? out.msg : "nglib failed");
    if (write_all(fd, &head, sizeof head) == 0 && rc == 0 &&
        write_all(fd, out.coords, sizeof(double) * (size_t)s->dim * (size_t)out.nverts) == 0)
        write_all(fd, out.elems, sizeof(int32_t) * (size_t)(s->dim + 1) * (size_t)out.nelems);
    _exit(0);
}

/* Reads n bytes by the deadline: 0, or -1 at EOF / error, -2 past it. */
static int read_by(int fd, void *buf, size_t n, double deadline)
{
    char *p = buf;
    while (n > 0) {
        double left = deadline - sm_clock_seconds();
        if (left <= 0)
            return -2;
        struct pollfd pfd = {.fd = fd, .events = POLLIN};
        int r = poll(&pfd, 1, left > 1e6 ? 1000000000 : (int)(left * 1000) + 1);
        if (r < 0 && errno == EINTR)
            continue;
        if (r < 0)
            return -1;
        if (r == 0)
            continue;
        ssize_t got = read(fd, p, n);
        if (got < 0 && errno == EINTR)
            continue;
        if (got <= 0)
            return -1;
        p += got;
        n -= (size_t)got;
    }
    return 0;
}

/* One nglib run in a child; *coords and *elems malloc'ed on success. */
static sm_status run_child(const sm_surface *s, double h, int optsteps, double max_seconds,
                           int64_t max_elements, int32_t *nv, int32_t *ne, double **coords,
                           int32_t **elems, sm_error *err)
{
    int fds[2];
    if (pipe(fds) != 0)
        return sm_error_set(err, SM_ERR_IO, "cannot create a pipe for the mesher: %s",
                            strerror(errno));
    fflush(NULL);
    pid_t pid = fork();
    if (pid < 0) {
        close(fds[0]);
        close(fds[1]);
        return sm_error_set(err, SM_ERR_IO, "cannot start the mesher's process: %s",
                            strerror(errno));
    }
    if (pid == 0) {
        close(fds[0]);
        child_main(fds[1], s, h, optsteps);
    }
    close(fds[1]);
    double deadline = sm_clock_seconds() + max_seconds;
    reply_head head;
    sm_status st = SM_OK;
    *coords = NULL;
    *elems = NULL;
    int r = read_by(fds[0], &head, sizeof head, deadline);
    if (r == 0) {
        head.msg[sizeof head.msg - 1] = 0;
        if (head.status != 0)
            st = sm_error_set(err, SM_ERR_INVALID, "%s", head.msg);
        else if (head.nverts <= 0 || head.nelems <= 0 || head.nelems > max_elements ||
                 head.nverts > 4 * max_elements + 64)
            st = sm_error_set(err, SM_ERR_INVALID,
                              "nglib returned %d vertices and %d elements (bound %lld)",
                              (int)head.nverts, (int)head.nelems, (long long)max_elements);
        else {
            size_t cb = sizeof(double) * (size_t)s->dim * (size_t)head.nverts;
            size_t eb = sizeof(int32_t) * (size_t)(s->dim + 1) * (size_t)head.nelems;
            *coords = malloc(cb);
            *elems = malloc(eb);
            if (!*coords || !*elems)
                st = sm_error_set(err, SM_ERR_NOMEM, "out of memory receiving the mesh");
            else if ((r = read_by(fds[0], *coords, cb, deadline)) == 0)
                r = read_by(fds[0], *elems, eb, deadline);
        }
    }
    if (r == -2) {
        kill(pid, SIGKILL);
        st = sm_error_set(err, SM_ERR_INVALID,
                          "nglib did not finish within %g s (the meshing's time bound): give a "
                          "larger template size or a simpler surface",
                          max_seconds);
    }
    close(fds[0]);
    int wst = 0;
    pid_t w;
    while ((w = waitpid(pid, &wst, 0)) < 0 && errno == EINTR)
        ;
    if (st == SM_OK && r == -1)
        st = w == pid && WIFSIGNALED(wst)
                 ? sm_error_set(err, SM_ERR_INVALID,
                                "nglib crashed on this surface (its process ended by signal %d)",
                                WTERMSIG(wst))
                 : sm_error_set(err, SM_ERR_INVALID, "nglib's process ended without a mesh");
    if (st != SM_OK) {
        free(*coords);
        free(*elems);
        *coords = NULL;
        *elems = NULL;
        return st;
    }
    *nv = head.nverts;
    *ne = head.nelems;
    return SM_OK;
}

/* nglib's arrays as a mesh: indices checked, unused vertices dropped,
 * elements oriented positively, the boundary as the file's facets. */
static sm_status assemble(int dim, int32_t nv, int32_t ne, const double *coords,
                          const int32_t *elems, sm_mesh **out, sm_error *err)
{
    int k = dim + 1;
    int32_t *map = malloc((size_t)nv * sizeof *map);
    if (!map)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory assembling the mesh");
    for (int32_t v = 0; v < nv; v++)
        map[v] = -1;
    for (size_t i = 0; i < (size_t)ne * (size_t)k; i++) {
        if (elems[i] < 0 || elems[i] >= nv) {
            free(map);
            return sm_error_set(err, SM_ERR_INVALID, "nglib returned a vertex index out of range");
        }
        map[elems[i]] = 0;
    }
    int32_t used = 0;
    for (int32_t v = 0; v < nv; v++)
        if (map[v] == 0)
            map[v] = used++;
    sm_mesh *m = NULL, *b = NULL;
    sm_status st = sm_mesh_alloc(&m, dim, used, ne, 0, err);
    if (st != SM_OK) {
        free(map);
        return st;
    }
    for (int32_t v = 0; v < nv; v++)
        if (map[v] >= 0)
            memcpy(m->coords + (size_t)dim * map[v], coords + (size_t)dim * v, sizeof(double) * dim);
    for (int32_t e = 0; e < ne; e++) {
        int32_t *t = m->elems + (size_t)k * e;
        for (int j = 0; j < k; j++)
            t[j] = map[elems[(size_t)k * e + j]];
        m->elem_refs[e] = 1;
        if (sm_elem_volume(m, m->coords, e) < 0) {
            int32_t x = t[0];
            t[0] = t[1];
            t[1] = x;
        }
    }
    free(map);
    if ((st = sm_mesh_build_boundary(m, err)) != SM_OK ||
        (st = sm_mesh_check_manifold(m, err)) != SM_OK) {
        sm_error_prefix(err, "the mesh nglib made");
        sm_mesh_free(m);
        return st;
    }
    if ((st = sm_mesh_alloc(&b, dim, m->nverts, m->nelems, m->nbfacets, err)) != SM_OK) {
        sm_mesh_free(m);
        return st;
    }
    memcpy(b->coords, m->coords, sizeof(double) * (size_t)dim * (size_t)m->nverts);
    memcpy(b->elems, m->elems, sizeof(int32_t) * (size_t)k * (size_t)m->nelems);
    memcpy(b->elem_refs, m->elem_refs, sizeof(int32_t) * (size_t)m->nelems);
    memcpy(b->facets, m->bfacets, sizeof(int32_t) * (size_t)dim * (size_t)m->nbfacets);
    for (int32_t f = 0; f < m->nbfacets; f++)
        b->facet_refs[f] = 1;
    sm_mesh_free(m);
    *out = b;
    return SM_OK;
}

sm_status sm_template_mesh_surface(const sm_surface *s, const sm_template_mesh_opts *o,
                                   sm_mesh **out, sm_template_mesh_info *info,
                                   sm_error *err)
{
    *out = NULL;
    sm_template_mesh_info inf;
    memset(&inf, 0, sizeof inf);
    double t0 = sm_clock_seconds();
    sm_status st = sm_template_surface_check(s, &inf.surface_volume, err);
    if (st != SM_OK)
        return st;
    sm_params defaults;
    sm_params_default(&defaults);
    double h = o && o->size > 0 ? o->size : sm_surface_mean_edge(s);
    int64_t max_el = o && o->max_elements > 0 ? o->max_elements : SM_TEMPLATE_MAX_ELEMENTS_DEFAULT;
    double max_s = o && o->max_seconds > 0 ? o->max_seconds : SM_TEMPLATE_MAX_SECONDS_DEFAULT;
    double floor_q = o && o->min_quality > 0 ? o->min_quality : defaults.min_quality;
    if (!(h > 0) || !isfinite(h))
        return sm_error_set(err, SM_ERR_INVALID, "the element size must be > 0 (got %g)", h);
    /* the bound: the volume over a regular simplex of edge h (nglib's
     * elements are on average larger: an upper estimate) */
    double cell = s->dim == 3 ? h * h * h / (6.0 * sqrt(2.0)) : h * h * sqrt(3.0) / 4.0;
    double est = inf.surface_volume / cell;
    inf.estimated_elements = est > 9e18 ? INT64_MAX : (int64_t)ceil(est);
    if (!(est <= (double)max_el))
        return sm_error_set(err, SM_ERR_INVALID,
                            "the element size %g would make about %.3g elements (the %s "
                            "enclosed over a regular %s of that edge), over the bound of %lld: "
                            "give a larger template size",
                            h, est, s->dim == 3 ? "volume" : "area",
                            s->dim == 3 ? "tetrahedron" : "triangle", (long long)max_el);
    /* nglib's own optimisation first; below the floor, again with more
     * steps; below it still, refused (the descent's steps could not
     * keep such an element above the floor) */
    const int steps[2] = {3, 10};
    for (int pass = 0; pass < 2; pass++) {
        int32_t nv = 0, ne = 0;
        double *coords = NULL;
        int32_t *elems = NULL;
        double left = max_s - (sm_clock_seconds() - t0);
        if (left <= 0)
            return sm_error_set(err, SM_ERR_INVALID,
                                "meshing did not finish within %g s (the meshing's time bound)",
                                max_s);
        st = run_child(s, h, steps[pass], left, max_el, &nv, &ne, &coords, &elems, err);
        if (st != SM_OK)
            return st;
        sm_mesh *m = NULL;
        st = assemble(s->dim, nv, ne, coords, elems, &m, err);
        free(coords);
        free(elems);
        if (st != SM_OK)
            return st;
        sm_quality_stats q;
        sm_mesh_quality(m, m->coords, &q);
        inf.passes = pass + 1;
        inf.min_quality = q.min;
        inf.mean_quality = q.mean;
        if (q.min >= floor_q && q.ninverted == 0) {
            inf.size = h;
            inf.nverts = m->nverts;
            inf.nelems = m->nelems;
            for (int32_t e = 0; e < m->nelems; e++)
                inf.mesh_volume += sm_elem_volume(m, m->coords, e);
            inf.seconds = sm_clock_seconds() - t0;
            if (info)
                *info = inf;
            *out = m;
            return SM_OK;
        }
        sm_mesh_free(m);
    }
    return sm_error_set(err, SM_ERR_INVALID,
                        "slivers: the meshed template's worst element quality is %.3g, below "
                        "the quality floor %g, after nglib's optimisation with %d steps: give "
                        "another template size or a smoother surface",
                        inf.min_quality, floor_q, steps[1]);
}
