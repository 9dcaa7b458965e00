/* The parameters of a matching run (sm_match_run): clamp set, material,
 * stopping rules and step control, with their defaults and range checks.
 * A header of its own because the wire codecs (proto), the CLI's option
 * parser and the core all speak it, while only the core runs the descent. */
#ifndef SM_PARAMS_H
#define SM_PARAMS_H

#include <stddef.h>
#include <stdint.h>

#include "sm_error.h"

#define SM_MAX_REFS 64

typedef enum sm_clamp_kind {
    SM_CLAMP_BALL = 0,     /* vertices inside a disk/ball */
    SM_CLAMP_ELEMENTS = 1, /* vertices of elements with given references */
    SM_CLAMP_VERTICES = 2, /* vertices with given references */
    SM_CLAMP_NONE = 3,     /* no clamp: 0th-order term alpha int u.v */
    SM_CLAMP_AUTO = 4      /* the default: a ball at the template's deepest
                            * point (sm_clamp_default_ball), chosen when
                            * the template is read */
} sm_clamp_kind;

/* "ball", "elements", "vertices", "none" (the params' clamp.kind); NULL
 * for a value outside the enum. */
const char *sm_clamp_kind_name(sm_clamp_kind kind);
/* 0 and *out set for a known name, -1 otherwise (NULL included). */
int sm_clamp_kind_from_name(const char *name, sm_clamp_kind *out);

/* How the elastic system is solved (params "solver").  AUTO: in 3D the
 * solver a cost model predicts faster for the template, once CHOLMOD's
 * analysis has given its factor's size, and CHOLMOD only when that factor
 * fits the memory limit (the elastic operator decides, core/sm_elasticity.h,
 * docs/solvers.md); CHOLMOD in 2D. */
typedef enum sm_solver_kind {
    SM_SOLVER_AUTO = 0,
    SM_SOLVER_CHOLMOD = 1,
    SM_SOLVER_AMG = 2
} sm_solver_kind;

/* "auto", "cholmod", "amg"; NULL for a value out of range. */
const char *sm_solver_kind_name(sm_solver_kind kind);
/* 0 and *out set for a known name, -1 otherwise. */
int sm_solver_kind_from_name(const char *name, sm_solver_kind *out);
/* The solver AUTO means when only the size is known: kind itself if not
 * AUTO; CHOLMOD in 2D (2D templates of any size this project meets factor
 * fast); in 3D AMG from SM_SOLVER_AMG_MIN_TETS tetrahedra on.  The 3D rule
 * is the fallback of the cost model (when CHOLMOD's analysis cannot run,
 * out of memory); the model decides otherwise.  On the uniform Gmsh
 * templates of bench/solvers.sh the two are about even at 100k (within
 * 10%), so the fallback errs by little either side. */
sm_solver_kind sm_solver_resolve(sm_solver_kind kind, int dim, int64_t nelems);
#define SM_SOLVER_AMG_MIN_TETS 100000

/* Pre-alignment before the descent (params "align"; sm_align.h has the
 * method): none keeps the paper's assumption that the shapes are given
 * aligned, and the run exactly as without the parameter. */
typedef enum sm_align_mode {
    SM_ALIGN_NONE = 0,       /* no alignment */
    SM_ALIGN_RIGID = 1,      /* rotation + translation */
    SM_ALIGN_SIMILARITY = 2, /* + one uniform scale */
    SM_ALIGN_AFFINE = 3      /* full matrix (det > 0, conditioning guarded) */
} sm_align_mode;

/* "none", "rigid", "similarity", "affine"; NULL out of range. */
const char *sm_align_mode_name(sm_align_mode mode);
/* 0 and *out for a known name, -1 otherwise. */
int sm_align_mode_from_name(const char *name, sm_align_mode *out);

/* The frame of the template's coordinates for a label-map target
 * (params "image_space", sm_image.h): LPS (ITK, Slicer, NRRD's
 * left-posterior-superior) or RAS (NIfTI's world, FreeSurfer). */
typedef enum sm_image_space {
    SM_IMAGE_SPACE_LPS = 0,
    SM_IMAGE_SPACE_RAS = 1
} sm_image_space;

/* "lps", "ras"; NULL out of range. */
const char *sm_image_space_name(sm_image_space space);

/* Defaults and bounds of every member: the parameter table below
 * (sm_params_table, core/sm_params.c), not these comments. */
typedef struct sm_params {
    sm_clamp_kind clamp;
    double clamp_center[3];
    double clamp_radius;
    int32_t clamp_refs[SM_MAX_REFS];
    int n_clamp_refs;
    double alpha;            /* 0th-order coefficient (clamp none); 0 = from
                              * the scale, young / diameter^2 */

    /* boundary facet references excluded from the load ("bref") */
    int32_t free_refs[SM_MAX_REFS];
    int n_free_refs;

    double young;            /* Young's modulus */
    double poisson;          /* Poisson ratio */

    int max_iter;            /* iteration cap */
    double tol_step;         /* stop when step < tol_step*diameter */
    double tol_boundary;     /* stop when ||d||_L2(boundary) <= this; 0=off.
                              * Absolute: scales like L^1.5 (2D) or L^2 (3D)
                              * with the template's size L */
    double tol_boundary_rel; /* stop when the RMS boundary error
                              * ||d||_L2 / sqrt(|dOmega|) <= this times the
                              * template's diameter: the same number works in
                              * any unit; 0 = off */
    double tol_stall;        /* stall rule: stop when the best ||d||_L2 so far
                              * improved by less than this fraction over the
                              * last stall_window iterations; 0 = off
                              * (the default's measures: sm_params.c) */
    int stall_window;        /* K of the stall rule */
    double coverage_weight;  /* weight of the target-side term T in
                              * E = J + weight * T (sm_match.h); 0 = the
                              * paper's J alone */
    double min_quality;      /* quality floor for accepted steps */
    int save_every;          /* snapshot callback period (0 = never) */
    double step_initial;     /* first step as a fraction of the diameter */
    double step_max;         /* largest step as a fraction of the diameter */
    int refactor_every;      /* refactorize the elastic operator on the current
                              * mesh every k iterations (1 = every iteration,
                              * as in the paper) */
    int warm_start;          /* batches: start a target from the nearest
                              * finished target's map (sm_job_batch.h);
                              * 0 = from the template */
    sm_solver_kind solver;   /* elastic solver */
    int live_every;          /* the daemon's live mesh (mesh/latest): published
                              * every k iterations, and at least every 0.5 s
                              * of a run; 0 = by time only */
    sm_align_mode align;     /* pre-alignment (the job runner applies it) */
    /* a label-map target (the job runner reads it; ignored otherwise) */
    int label;               /* the label's value; 0: every nonzero voxel */
    double level;            /* float images without a label: voxels >= level */
    sm_image_space image_space; /* the template's frame */
    double smooth;           /* the mask's Gaussian, in voxels (0: none) */
} sm_params;

/* Fills p with the defaults of the parameter table (below); clamp AUTO
 * (the default ball, chosen on the template by sm_match_new or the job
 * layer). */
void sm_params_default(sm_params *p);
/* Checks every parameter against the table's bounds, then the rules that
 * join several fields (the clamp kind's members, step_initial <=
 * step_max); the message names the offending parameter by its params
 * name ("max_iter: must be in [1, 1000000000] (got 0)"). */
sm_status sm_params_validate(const sm_params *p, int dim, sm_error *err);

/* ---- The parameter table ----
 *
 * One row per job parameter: its params (JSON) name, type, bounds,
 * default, CLI flag and a one-line help.  The core's checks and defaults
 * (above), the params codec (proto/sm_proto_params.c), the CLI's options
 * and --help (client/args.c) and the documentation's parameter table are
 * all read from it; tests/unit/test_proto_params.c checks
 * proto/params.schema.json against it and tests/unit/test_params.c walks
 * every bound through the three.  Plain data: no JSON here. */
typedef enum sm_param_type {
    SM_PARAM_REAL = 0,   /* double; finite */
    SM_PARAM_INT = 1,    /* int */
    SM_PARAM_SOLVER = 2, /* sm_solver_kind, written by name (sm_solver_kind_name) */
    SM_PARAM_REFS = 3,   /* int32_t list at offset, its int count at count_offset;
                          * min/max bound the count */
    SM_PARAM_CLAMP = 4,  /* the clamp set: its kind and members are code of their
                          * own (the clamp options, decode_clamp, the checks) */
    SM_PARAM_ALIGN = 5,  /* sm_align_mode, written by name (sm_align_mode_name) */
    SM_PARAM_SPACE = 6   /* sm_image_space, written by name (sm_image_space_name) */
} sm_param_type;

typedef struct sm_param_info {
    const char *name;      /* params member, e.g. "max_iter" */
    sm_param_type type;
    size_t offset;         /* of the value in its struct (sm_params here) */
    size_t count_offset;   /* SM_PARAM_REFS: of the count */
    /* Bounds of the value (of the count for REFS): -INFINITY / INFINITY
     * when there is none; *_open: the bound itself is outside.  An
     * infinite bound is always open, so that in range means finite. */
    double min, max;
    int min_open, max_open;
    double def;            /* default (REAL, INT; SOLVER: the enum value) */
    const char *def_text;  /* the default in words where a number would
                            * mislead ("from the meshes"), else NULL */
    int in_clamp;          /* 1: a member of the params' clamp object,
                            * with kind "none" only (alpha) */
    const char *flag;      /* option of `shapematch run`/`submit`, or NULL */
    const char *meta;      /* its value's name in --help ("N") */
    const char *help;      /* one sentence, no default (printers add it) */
    const char *group;     /* the section of a form or a page that shows it:
                            * "inputs", "clamp", "stop" or "advanced" (the
                            * web app folds that one), from params.schema.json's
                            * x-group; NULL reads as "advanced" */
} sm_param_info;

/* The table, in the order of the params document; *count rows. */
const sm_param_info *sm_params_table(size_t *count);
/* The row of params member name, or NULL. */
const sm_param_info *sm_params_lookup(const char *name);
/* 1 when x lies within f's bounds (0 for NaN and infinities). */
int sm_param_in_range(const sm_param_info *f, double x);
/* f's bounds for people: "> 0", ">= 0", "in (-1, 0.5)", "in [1, 100000]"
 * (an INT bound at INT_MAX counts as none).  Returns snprintf's count. */
int sm_param_describe_range(const sm_param_info *f, char *buf, size_t cap);

/* The rows whose values are names (SM_PARAM_SOLVER, SM_PARAM_ALIGN,
 * SM_PARAM_SPACE): 1
 * for them.  Their value k (an enum from f->min to f->max) by name (NULL
 * out of range), a name's value (-1 when unknown), and the value of the
 * row in a struct (base: the sm_params), so that readers and writers of
 * the table need no case per enum. */
int sm_param_is_named(const sm_param_info *f);
const char *sm_param_value_name(const sm_param_info *f, int k);
int sm_param_value_from_name(const sm_param_info *f, const char *name);
int sm_param_get_value(const sm_param_info *f, const void *base);
void sm_param_set_value(const sm_param_info *f, void *base, int k);
/* "a, b or c": the names of a named row, for messages. */
void sm_param_names_text(const sm_param_info *f, char *buf, size_t cap);

#endif
