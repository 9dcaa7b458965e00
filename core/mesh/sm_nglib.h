/* The C face of the Netgen shim (sm_nglib.cc), core-private.
 *
 * The shim is its own shared object, libshapematch_nglib.so.0, linked
 * against Debian's nglib (LGPL-2.1, dynamically linked) and opened with
 * dlopen by sm_template_mesh.c in a child process only: the library and
 * every program keep no link to nglib (which pulls OpenCascade, MPI and
 * Python's runtime), and a crash or a loop inside nglib ends a child,
 * not the caller.
 *
 * Both entries mesh the inside of a closed, outward boundary given as
 * 0-based arrays: triangles in 3D (remeshed by nglib's STL geometry at
 * size h, then the volume) and segments in 2D (a polygon geometry,
 * nglib's 2D mesher at size h).  optsteps: nglib's optimisation steps.
 * On success they return 0 and fill out (malloc'ed coords and elems,
 * 0-based, the caller frees them); else non-zero with out->msg naming
 * the step that failed.  Not thread-safe (nglib has global state): one
 * call per process. */
#ifndef SM_NGLIB_H
#define SM_NGLIB_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sm_nglib_out {
    int32_t nverts, nelems;
    double *coords;  /* nverts * dim */
    int32_t *elems;  /* nelems * (dim + 1) */
    char msg[256];
} sm_nglib_out;

typedef int (*sm_nglib_volume_fn)(const double *coords, int32_t nverts, const int32_t *tris,
                                  int32_t ntris, double h, int optsteps, sm_nglib_out *out);
typedef int (*sm_nglib_planar_fn)(const double *coords, int32_t nverts, const int32_t *segs,
                                  int32_t nsegs, double h, int optsteps, const char *scratch,
                                  sm_nglib_out *out);

/* The names dlsym looks up. */
int sm_nglib_volume(const double *coords, int32_t nverts, const int32_t *tris, int32_t ntris,
                    double h, int optsteps, sm_nglib_out *out);
/* scratch: a file path the shim may write (nglib reads 2D geometries
 * from a file only: a .in2d of the polygon); it is removed after. */
int sm_nglib_planar(const double *coords, int32_t nverts, const int32_t *segs, int32_t nsegs,
                    double h, int optsteps, const char *scratch, sm_nglib_out *out);

#ifdef __cplusplus
}
#endif

#endif
