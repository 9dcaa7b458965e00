/* The warp use case (docs/warp.md): points, meshes, surfaces and fields
 * carried through the map of a finished match, forward (template ->
 * target) or inverse.  Written once here and called by `shapematch warp`
 * (client/cmd_warp.c), the daemon's warp route (server/api/smd_warp.c, in
 * a check child) and Python (python/shapematch/_warp.py, through
 * shapematch_job.h's sm_run_map_* and sm_run_warp_*); the arithmetic is
 * core's sm_warp.h, the points CSV proto's sm_points_csv.h.
 *
 * The map of a result folder: the deformed mesh (the first of
 * sm_job_result_mesh_files that exists) and the displacement at its
 * vertices (sm_job_result_sol_files); the template is the deformed mesh's
 * elements with coordinates result - displacement.
 *
 * One status convention: SM_ERR_INVALID for a rule (a dimension that is
 * not the map's, a strict point outside, an output format that cannot
 * hold the input, a field not on the map's vertices), the reader's status
 * for an input that cannot be read (SM_ERR_IO, SM_ERR_FORMAT, SM_ERR_NOMEM
 * with limits->hit when a bound refused it), SM_ERR_IO for an output that
 * cannot be written; report->stage says which step failed, so that the
 * CLI can map it to its exit codes and the daemon to 400/413/422/500.
 * Messages name the input as request->name says ("the body" for the
 * daemon; NULL: its path), also inside the readers' messages. */
#ifndef SM_JOB_WARP_H
#define SM_JOB_WARP_H

#include <stddef.h>
#include <stdint.h>

#include "shapematch/sm_error.h"
#include "shapematch/sm_io.h"
#include "shapematch/sm_mesh.h"
#include "shapematch/sm_warp.h"

/* A result folder's files, in the order they are looked for (NULL
 * ends each): the deformed mesh and the displacement.  The one list of
 * them (the batch's shape model reads the same meshes). */
extern const char *const sm_job_result_mesh_files[];
extern const char *const sm_job_result_sol_files[];

/* The first of dir/names[] that exists, malloc'd; NULL when none (or out
 * of memory). */
char *sm_job_result_find(const char *dir, const char *const *names);

typedef struct sm_job_map sm_job_map;

/* Reads result_dir's map and builds the location structures of
 * directions (bit 1 << SM_WARP_FORWARD, 1 << SM_WARP_INVERSE; others are
 * built when first needed).  SM_ERR_IO when a file is missing (naming
 * what a result folder holds) or unreadable, SM_ERR_FORMAT for a
 * malformed file or a displacement that does not match the mesh,
 * SM_ERR_INVALID for a mesh the warp cannot use, SM_ERR_NOMEM. */
sm_status sm_job_map_open(const char *result_dir, unsigned directions, sm_job_map **out,
                          sm_error *err);
/* The map of a template (taken: freed by sm_job_map_free, or here on
 * error) and its deformed coordinates (taken, malloc'd, nverts * dim). */
sm_status sm_job_map_new(sm_mesh *tmpl, double *deformed, unsigned directions,
                         sm_job_map **out, sm_error *err);
void sm_job_map_free(sm_job_map *map);
int sm_job_map_dim(const sm_job_map *map);
const sm_mesh *sm_job_map_template(const sm_job_map *map);
/* The warp of the map locating points in dir's source mesh (built on
 * first use); NULL with err set when it cannot be built. */
const sm_warp *sm_job_map_warp(sm_job_map *map, sm_warp_direction dir, sm_error *err);

/* What becomes of points outside the direction's source mesh (points
 * only: a mesh's vertices are always extrapolated, or refused by strict). */
typedef enum sm_job_warp_outside {
    SM_JOB_OUTSIDE_EXTRAPOLATE = 0, /* the nearest element's affine map, inside 0 */
    SM_JOB_OUTSIDE_FLAG,            /* NaN coordinates, inside 0 (JSON: null) */
    SM_JOB_OUTSIDE_SKIP             /* left out of the answer; report->noutside says how many */
} sm_job_warp_outside;

/* "extrapolate", "flag", "skip" (the CLI's --outside, the daemon's
 * outside, Python's outside=): the policy, or -1 for another name. */
int sm_job_warp_outside_from_name(const char *name);
const char *sm_job_warp_outside_name(sm_job_warp_outside outside);
/* The names for messages: "extrapolate, flag or skip". */
#define SM_JOB_WARP_OUTSIDE_NAMES "extrapolate, flag or skip"

/* What a warp is asked. */
typedef struct sm_job_warp_request {
    sm_warp_direction direction;
    int strict;              /* points and vertices: one outside is an error */
    sm_job_warp_outside outside; /* points, when not strict */
    int normalize;           /* fields: vectors scaled to unit length */
    sm_read_limits *limits;  /* bounds of the input's reader (NULL: none) */
    int64_t max_points;      /* points: at most this many (0: no bound) */
    const char *name;        /* the input in messages (NULL: its path) */
} sm_job_warp_request;

typedef enum sm_job_warp_stage {
    SM_JOB_WARP_INPUT,   /* reading the input (the reader's status) */
    SM_JOB_WARP_FORMAT,  /* the output format cannot hold the input */
    SM_JOB_WARP_MAP,     /* a rule between the input and the map */
    SM_JOB_WARP_OUTPUT   /* writing the output */
} sm_job_warp_stage;

typedef enum sm_job_warp_kind {
    SM_JOB_WARP_POINTS,
    SM_JOB_WARP_VOLUME,  /* a volume mesh */
    SM_JOB_WARP_SURFACE, /* a surface (a polyline in 2D) */
    SM_JOB_WARP_FIELD
} sm_job_warp_kind;

/* What a warp did, or where it failed. */
typedef struct sm_job_warp_report {
    sm_job_warp_stage stage;      /* on error */
    sm_job_warp_kind kind;
    sm_warp_direction direction;  /* points: as a JSON body may set it */
    int64_t n;                    /* points or vertices */
    int64_t noutside;             /* of them outside the source mesh (with
                                   * skip: left out) */
    int ncomp;                    /* fields: 1, dim or dim*(dim+1)/2 */
} sm_job_warp_report;

/* The output formats by extension (every one a mesh or surface can be
 * written as): 0 when path's extension is none of them. */
int sm_job_warp_output_known(const char *path);

/* Point files: CSV (sm_points_csv.h, Slicer markups among them), a JSON
 * request (the daemon's), NumPy .npy (sm_npy_parse: float64 or float32,
 * (N, dim)). */
typedef enum sm_job_points_format {
    SM_JOB_POINTS_CSV,
    SM_JOB_POINTS_JSON,
    SM_JOB_POINTS_NPY
} sm_job_points_format;

/* The format a file's name gives: .npy (any case), else CSV. */
sm_job_points_format sm_job_points_format_of(const char *path);

/* Points as arrays (Python's): n points of dim coordinates through the
 * map, the outside policy applied: out (n * dim) holds the images, NaN
 * for flagged ones, or with skip only the kept points, in order, *kept
 * of them (n otherwise); inside (n) flags the input points.  A strict
 * point outside is the core's SM_ERR_INVALID ("point I (1-based) is
 * outside ..."). */
sm_status sm_job_warp_points(sm_job_map *map, int dim, int64_t n, const double *xyz,
                             const sm_job_warp_request *request, double *out, uint8_t *inside,
                             int64_t *kept, sm_job_warp_report *report, sm_error *err);

/* Points in any format to an answer in any format (a JSON request is
 * answered in JSON whatever out_format says): bytes of in_format (len of
 * them), the answer in *answer (malloc'd, NUL-terminated for the text
 * ones, *answer_len bytes): a CSV with its inside column, a .npy of the
 * images (N, dim) float64, or the JSON below. */
sm_status sm_job_warp_points_bytes(sm_job_map *map, sm_job_points_format in_format,
                                   const char *bytes, size_t len,
                                   sm_job_points_format out_format,
                                   const sm_job_warp_request *request, char **answer,
                                   size_t *answer_len, sm_job_warp_report *report, sm_error *err);

/* Points: len bytes of text, CSV (sm_points_csv.h) or, with json, a
 * {"points": [[x, y[, z]], ...], "direction": "forward"|"inverse",
 * "strict": bool, "outside": "extrapolate"|"flag"|"skip"} document (its
 * members over request's); the answer in *answer (malloc'd,
 * NUL-terminated, *answer_len bytes): the CSV with its inside column, or
 * {"direction", "points", "inside", "outside"[, "skipped"]} written by
 * sm_json_dumps (a flagged point null, a skipped one not in "points";
 * "inside" one flag per point given).  A malformed body is SM_ERR_FORMAT
 * (SM_ERR_NOMEM past max_points), naming its line or JSON path. */
sm_status sm_job_warp_points_text(sm_job_map *map, int json, const char *text, size_t len,
                                  const sm_job_warp_request *request, char **answer,
                                  size_t *answer_len, sm_job_warp_report *report, sm_error *err);

/* A mesh file in (a volume mesh, else a surface: sm_mesh_read_limited
 * then sm_surface_read_limited), its vertices carried; written to out
 * when not NULL (by out's extension: .mesh/.meshb[.gz] and .vtu for both,
 * .stl, .obj, .ply, .off, .vtk for surfaces; a polyline not as .stl,
 * .ply, .off); the warped coordinates in *coords (malloc'd, report->n *
 * dim) when coords is not NULL. */
sm_status sm_job_warp_mesh_file(sm_job_map *map, const char *in, const char *out,
                                const sm_job_warp_request *request, double **coords,
                                sm_job_warp_report *report, sm_error *err);

/* A field given at the vertices of the direction's source mesh (nverts *
 * ncomp values in place, ncomp 1, dim or dim*(dim+1)/2): sm_warp_field.
 * SM_ERR_INVALID when nverts or dim are not the map's. */
sm_status sm_job_warp_field(sm_job_map *map, int dim, int32_t nverts, int ncomp, double *values,
                            const sm_job_warp_request *request, sm_job_warp_report *report,
                            sm_error *err);
/* A .sol/.solb file in, carried, written to out when not NULL (by its
 * extension); the field itself in *field when not NULL (free with
 * sm_sol_free). */
sm_status sm_job_warp_field_file(sm_job_map *map, const char *in, const char *out,
                                 const sm_job_warp_request *request, sm_sol **field,
                                 sm_job_warp_report *report, sm_error *err);

#endif
