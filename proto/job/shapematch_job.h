/* shapematch_job.h: a whole job in one call, for bindings (the Python
 * package, python/shapematch) and programs that want what `shapematch run`
 * does: the job runner (job/sm_job_runner.h: the inputs read and checked,
 * the run, the warnings, the result set and its summary) behind an opaque
 * handle and plain C types.  Exported by libshapematch_job.so (every
 * function here, nothing else), which stands on libshapematch.so:
 *
 *   cc prog.c $(pkg-config --cflags --libs shapematch) -lshapematch_job
 *
 * The parameters are a params document (proto/params.schema.json, the same
 * JSON as the daemon's jobs, e.g. {"clamp": {"kind": "elements", "refs":
 * [3]}, "max_iter": 200}), decoded by the one parameter table
 * (sm_params_table): a new parameter needs no change here.  Messages name
 * the files as given and the parameters by their JSON path
 * ("params.max_iter: must be ..."). */
#ifndef SHAPEMATCH_JOB_H
#define SHAPEMATCH_JOB_H

#include <stddef.h>
#include <stdint.h>

/* the core's headers are C only: C linkage for them too */
#ifdef __cplusplus
extern "C" {
#endif

#include "shapematch/sm_error.h"
#include "shapematch/sm_match.h"

/* A job that ran (or was refused at its start): its inputs, the state
 * reached and the result set it can write. */
typedef struct sm_run sm_run;

/* After each iteration (iteration 0: the initial state); nonzero stops the
 * run, which then ends "cancelled" with the state reached. */
typedef int (*sm_run_progress_fn)(const sm_progress *p, void *user);

/* The job's files (NULL when not given), or their contents in memory
 * (the members appended last): template_mesh, and either
 * target_mesh + target_sol, or target_surface or target_image (a label
 * map: NIfTI, NRRD, MetaImage; the params' label, level and image_space
 * select its voxels and frame, as `run --target-image`) with an optional
 * target_mesh (sm_job_inputs.h).  The *_name members (NULL: the path) are
 * what the summary's "inputs" calls them (a binding that wrote arrays to
 * temporary files names them otherwise).
 *
 * The struct only grows at its end (members appended, none moved), so a
 * program that zero-initialises it (designated initialisers, memset)
 * keeps its meaning when rebuilt against a newer header; the SONAME's
 * major version changes if a member ever moves. */
typedef struct sm_run_files {
    const char *template_mesh;
    const char *target_mesh;
    const char *target_sol;
    const char *target_surface;
    const char *template_name;
    const char *target_mesh_name;
    const char *target_sol_name;
    const char *target_surface_name;
    /* appended (image targets): excludes target_sol and target_surface */
    const char *target_image;
    const char *target_image_name;
    /* appended (inputs in memory, sm_run_mesh, sm_run_surface): each,
     * when not NULL, is that part instead of its file (give one or the
     * other), named by its *_name member in messages and in the summary
     * (NULL: "template (array)", ...).  target_sol_values holds
     * target_sol_count distances, one per target mesh vertex.  Borrowed:
     * sm_run_job copies them before it returns. */
    const struct sm_run_mesh *template_arrays;
    const struct sm_run_mesh *target_mesh_arrays;
    const double *target_sol_values;
    int32_t target_sol_count;
    const struct sm_run_surface *target_surface_arrays;
    /* appended (templates meshed by nglib, sm_job_template.h): a closed
     * surface (a path, or arrays) or a label map's label (template_label,
     * 0: every nonzero voxel), in place of template_mesh and
     * template_arrays; the params' template_size sizes the elements */
    const char *template_surface;
    const struct sm_run_surface *template_surface_arrays;
    const char *template_image;
    int64_t template_label;
} sm_run_files;

/* A mesh in memory: dim 2 or 3; nverts vertices (coords: nverts*dim
 * reals, finite); nelems triangles (2D) or tetrahedra (3D) of dim+1
 * 0-based vertex indices; element and vertex references (NULL: all 0);
 * nfacets facets of dim indices (edges in 2D, triangles in 3D; facets
 * NULL when 0) and their references (NULL: 0), as a Medit file's
 * Edges/Triangles (a clamp's references, for instance).  Checked as a
 * file's contents are: SM_ERR_FORMAT naming the part and the entry. */
typedef struct sm_run_mesh {
    int dim;
    int32_t nverts;
    const double *coords;
    int32_t nelems;
    const int32_t *elems;
    const int32_t *elem_refs;
    const int32_t *vert_refs;
    int32_t nfacets;
    const int32_t *facets;
    const int32_t *facet_refs;
} sm_run_mesh;

/* A target surface in memory (shapematch/sm_surface.h): dim 3,
 * triangles; or dim 2, segments; nfacets of dim 0-based indices into
 * nverts vertices (coords: nverts*dim finite reals). */
typedef struct sm_run_surface {
    int dim;
    int32_t nverts;
    const double *coords;
    int32_t nfacets;
    const int32_t *facets;
} sm_run_surface;

/* Reads and checks the inputs, runs the job under the runner's thread
 * policy, and keeps everything in *out (free with sm_run_free).  params_json
 * NUL-terminated; NULL or "" is refused (the clamp is required).  cancel,
 * when not NULL, is polled between iterations (another thread may set it).
 * SM_OK: the job ran; sm_run_outcome says how it ended ("finished",
 * "cancelled", or "failed": no valid step at all, sm_run_message says why).
 * Errors (*out NULL): the inputs' or parameters' (SM_ERR_FORMAT,
 * SM_ERR_INVALID), the run's (SM_ERR_NUMERIC, ...), SM_ERR_NOMEM; err->msg
 * the message. */
sm_status sm_run_job(const sm_run_files *files, const char *params_json,
                     sm_run_progress_fn progress, void *user, const volatile int *cancel,
                     sm_run **out, sm_error *err);
void sm_run_free(sm_run *r);

/* "finished", "cancelled", "failed". */
const char *sm_run_outcome(const sm_run *r);
/* What `shapematch run` would exit with: 0, 3 (failed), 5 (cancelled), 10
 * (finished, not converged). */
int sm_run_exit_code(const sm_run *r);
/* Why a run failed ("" otherwise). */
const char *sm_run_message(const sm_run *r);
/* The summary document (summary.json without "outputs"), as JSON text
 * owned by r; NULL when memory ran out. */
const char *sm_run_summary(const sm_run *r);

/* The template as read and the state reached: dim (2 or 3), nverts
 * vertices (coords nverts*dim, initial coordinates init_coords), nelems
 * elements of dim+1 vertices (0-based) and their references, the vertex
 * references.  Owned by r. */
int sm_run_dim(const sm_run *r);
int32_t sm_run_nverts(const sm_run *r);
int32_t sm_run_nelems(const sm_run *r);
const double *sm_run_coords(const sm_run *r);
const double *sm_run_init_coords(const sm_run *r);
const int32_t *sm_run_elems(const sm_run *r);
const int32_t *sm_run_elem_refs(const sm_run *r);
const int32_t *sm_run_vert_refs(const sm_run *r);
/* One row per iteration, 0 first; *n rows.  Owned by r. */
const sm_progress *sm_run_history(const sm_run *r, size_t *n);

/* Writes the result set into dir (created if missing), the same files as
 * `shapematch run --format formats` (NULL: "mesh,vtu,sol") with
 * summary.json and history.csv/.json.  SM_ERR_INVALID for a bad format
 * list, SM_ERR_IO, SM_ERR_NOMEM. */
sm_status sm_run_write(const sm_run *r, const char *dir, const char *formats, sm_error *err);

/* A batch (docs/populations.md, `shapematch batch`) in one call: the
 * template at template_path matched onto the targets of list_csv (a
 * LIST.csv text of list_len bytes, relative paths from the current
 * folder), with params_json (a params document, as sm_run_job's), then
 * the shape model (model_align "none", "rigid" or "similarity"; NULL:
 * rigid), jobs targets at a time (0: the online CPUs), into out_dir.
 * Each target runs in a forked process with one thread (the caller may
 * hold an OpenMP pool, which a forked child cannot use).
 *
 * What it does to the calling process, all of it undone before it
 * returns: the OpenMP limit and OpenBLAS's thread count are 1 while the
 * targets run (the template is set up on one thread; both are put back
 * before the model is built); stdio's buffers are flushed (fflush(NULL))
 * before each fork, so nothing buffered is written twice.  It waits for
 * its own children only, each by its pid (a pidfd where the kernel has
 * them): a child the host started keeps its exit status for the host
 * (but a host that sets SIGCHLD to SIG_IGN makes its children
 * unwaitable: the batch then fails).  No signal disposition of the host
 * is changed: the children install their SIGINT/SIGTERM handlers after
 * the fork.  SM_OK when the
 * batch ran: out_dir/summary.json says how each target ended and whether
 * the model was built.  Errors: the list's (SM_ERR_FORMAT, "line N:"),
 * the parameters' or the template's (SM_ERR_INVALID, SM_ERR_FORMAT,
 * SM_ERR_IO), writing out_dir. */
sm_status sm_run_batch(const char *template_path, const char *list_csv, size_t list_len,
                       const char *params_json, const char *model_align, int jobs,
                       const char *out_dir, sm_error *err);

/* sm_run_batch on the population's own template (`shapematch batch
 * --template-from`, job/sm_job_template_from.h): template_from "medoid"
 * or "mean" starts from template_path (rounds: mean's most, 0: default
 * 3; tolerance: mean's relative movement, 0: default 1e-3), "file" or
 * NULL is sm_run_batch's one round, named in the summaries.  The last
 * round's results and model are in out_dir as sm_run_batch's, each
 * round's batch in out_dir/rounds/K/, and out_dir/summary.json's
 * "template_from" says how the template was chosen.  Errors:
 * sm_run_batch's, and SM_ERR_INVALID for another template_from, rounds
 * or tolerance out of range; SM_ERR_IO when out_dir holds an earlier
 * batch (targets/, model/ or rounds/). */
sm_status sm_run_batch_from(const char *template_path, const char *template_from, int rounds,
                            double tolerance, const char *list_csv, size_t list_len,
                            const char *params_json, const char *model_align, int jobs,
                            const char *out_dir, sm_error *err);

/* The release the library was built as ("0.1.0": the Makefile's
 * VERSION, the one place it is written); the Python package's
 * __version__. */
const char *sm_run_version(void);
/* Warp (docs/warp.md, `shapematch warp`): points, meshes, surfaces and
 * fields carried through the map of a finished match, forward (template
 * -> target) or back (inverse nonzero): the job layer's warp use case
 * (job/sm_job_warp.h), the same as the CLI's and the daemon's.
 *
 * A map: a result folder's (result.mesh or .meshb, possibly .gz, and
 * displacement.sol or .solb), or one made of arrays: dim (2 or 3), nverts
 * template and deformed coordinates (nverts * dim each), nelems elements
 * of dim + 1 vertices (0-based); copied.  SM_ERR_IO naming what a result
 * folder holds, SM_ERR_FORMAT, SM_ERR_INVALID, SM_ERR_NOMEM. */
typedef struct sm_run_map sm_run_map;
sm_status sm_run_map_open(const char *result_dir, sm_run_map **out, sm_error *err);
sm_status sm_run_map_new(int dim, int32_t nverts, const double *template_coords,
                         const double *deformed_coords, int32_t nelems, const int32_t *elems,
                         sm_run_map **out, sm_error *err);
void sm_run_map_free(sm_run_map *m);
int sm_run_map_dim(const sm_run_map *m);
int32_t sm_run_map_nverts(const sm_run_map *m);

/* n points of dim coordinates (xyz, n * dim) into out (n * dim); inside
 * (n flags, may be NULL): 0 for a point outside the source mesh; *noutside
 * (may be NULL) their count.  outside says what becomes of those (without
 * strict): 0 mapped by the nearest element (extrapolate), 1 NaN
 * coordinates (flag), 2 left out of out, whose first *kept rows are the
 * images of the points inside, in order (skip); *kept (may be NULL) is n
 * otherwise.  SM_ERR_INVALID: dim not the map's, outside not 0 to 2, or
 * with strict the first point outside ("point I (1-based) is outside
 * ..."). */
sm_status sm_run_warp_points(sm_run_map *m, int inverse, int strict, int outside, int dim,
                             int64_t n, const double *xyz, double *out, uint8_t *inside,
                             int64_t *noutside, int64_t *kept, sm_error *err);
/* A field on the source mesh's vertices (nverts * ncomp values, in
 * place): scalars kept, vectors by the deformation gradient (normalize:
 * to unit length), symmetric tensors (xx, xy, yy[, xz, yz, zz]) as F T
 * F^T.  SM_ERR_INVALID when dim or nverts are not the map's, or ncomp
 * none of 1, dim, dim * (dim + 1) / 2. */
sm_status sm_run_warp_field(sm_run_map *m, int inverse, int normalize, int dim, int32_t nverts,
                            int ncomp, double *values, sm_error *err);
/* A file: a mesh or surface (field 0; any `shapematch warp --mesh`
 * reads) or a .sol/.solb field (field 1), written to out when not NULL
 * (the format by its name, as `shapematch warp -o`); the warped
 * coordinates or field values in *values (malloc'd: free with
 * sm_run_warp_values_free), *rows by *cols.  The statuses of
 * job/sm_job_warp.h: SM_ERR_INVALID for a rule, the reader's for the
 * input, SM_ERR_IO for the output. */
sm_status sm_run_warp_file(sm_run_map *m, int field, const char *in, const char *out,
                           int inverse, int strict, int normalize, double **values,
                           int64_t *rows, int *cols, sm_error *err);
void sm_run_warp_values_free(double *values);

#ifdef __cplusplus
}
#endif

#endif
