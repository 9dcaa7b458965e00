/* Command-line parsing for the shapematch client.
 *
 * The job parameters (clamp, material, stopping criteria, ...) are parsed
 * by a part shared between commands (`run` and `submit` take the same
 * ones), the command-specific options (input files, output directory,
 * display) by a per-command parser on top of it.
 *
 * Options are GNU-style: `--name value` or `--name=value`; `-o DIR`.
 * Every number must be fully parsed, finite and in range; every message
 * names the offending flag. */
#ifndef CLI_ARGS_H
#define CLI_ARGS_H

#include <stdio.h>
#include <stddef.h>

#include "shapematch/sm_match.h"
#include "sm_proto_params.h"

#define ARGS_MSG_LEN 2048

typedef enum args_result {
    ARGS_OK = 0,
    ARGS_HELP = 1,   /* -h/--help was given: print help, exit 0 */
    ARGS_ERROR = 2   /* usage error, message filled */
} args_result;

/* Job parameters plus what the command line said about them (needed for
 * the checks that involve several flags or the input dimension). */
typedef struct job_options {
    sm_params params;          /* starts from sm_params_default() */
    const char *clamp_flag;    /* clamp option given ("--clamp-ball", ...) */
    int clamp_ball_dim;        /* 2 or 3: coordinates given to --clamp-ball */
    int alpha_given;
    /* --background-size, --background-padding (0: not given): the params
     * background_size, background_padding of a generated background */
    sm_background_params background;
    /* --clamp-elements/--clamp-vertices and --free-boundary given with a
     * physical name among the numbers ("core,7"): the text, resolved
     * against the template's names by job_options_resolve_names (NULL:
     * numbers only, already in params) */
    const char *clamp_names, *free_names;
} job_options;

typedef struct run_options {
    const char *template_path;
    /* or --template-surface / --template-image (its --template-label
     * in job.background, a params row): the template meshed from them
     * (sm_job_template.h) */
    const char *template_surface_path, *template_image_path;
    const char *target_mesh_path;
    const char *target_sol_path;
    const char *target_surface_path; /* --target-surface (excludes --target-sol) */
    const char *target_image_path;   /* --target-image (excludes both) */
    const char *landmarks;   /* --landmarks TEMPLATE.csv,TARGET.csv as given */
    char landmarks_template[4096], landmarks_target[4096]; /* split at the comma */
    const char *outdir;
    unsigned outputs;   /* --format: sm_proto_vocab.h's SM_RESULT_OUT_* bits */
    int quiet;
    int json;
    job_options job;
} run_options;

/* run --format when not given (sm_result_outputs_parse syntax). */
#define RUN_DEFAULT_FORMATS "mesh,vtu,sol"

/* ---- number parsing (exported for the other commands and tests) ---- */

/* Whole text as a finite real.  Returns 0, or -1 with msg naming flag. */
int args_parse_real(const char *flag, const char *text, double *out,
                    char *msg, size_t cap);
/* Whole text as a decimal integer in [lo, hi]. */
int args_parse_int(const char *flag, const char *text, long lo, long hi,
                   long *out, char *msg, size_t cap);

/* ---- job options ---- */

/* Sets defaults (sm_params_default) and clears the bookkeeping. */
void job_options_init(job_options *j);
/* Whether flag (e.g. "--young") is a job option: -1 no, 0 yes without a
 * value (--no-clamp), 1 yes with a value. */
int job_option_lookup(const char *flag);
/* Applies a job option known to job_option_lookup (value NULL for the
 * ones without a value).  Returns 0, or -1 with msg naming the flag. */
int job_option_apply(job_options *j, const char *flag, const char *value,
                     char *msg, size_t cap);
/* Resolves the physical names of --clamp-elements (elements: dimension
 * m->dim), --clamp-vertices (any dimension) and --free-boundary (facets:
 * m->dim - 1) against m's names (Gmsh $PhysicalNames) into params' refs.
 * Returns 0 (also when no name was given), or -1 with msg listing the
 * names the template has. */
int job_options_resolve_names(job_options *j, const sm_mesh *m, char *msg, size_t cap);
/* The same for a client that has the template's path only (submit,
 * batch, batch --server): reads it when a name was given.  0, or a CLI
 * exit code (input: the template unreadable; usage: a name it lacks)
 * with msg set. */
int job_options_resolve_names_at(job_options *j, const char *template_path, char *msg,
                                 size_t cap);
/* Checks that involve several flags: exactly one clamp option, --alpha
 * only with --no-clamp, --step-initial <= --step-max. */
int job_options_finish(job_options *j, char *msg, size_t cap);
/* --background-size / --background-padding only with a generated
 * background: target_surface given, target_mesh not (the paths, NULL
 * when not given; sm_job_files_check_background's message). */
int job_options_check_background(const job_options *j, const char *target_surface,
                                 const char *target_mesh, char *msg, size_t cap);
/* Checks that involve the template dimension (--clamp-ball arity). */
int job_options_check_dim(const job_options *j, int dim, char *msg,
                          size_t cap);
/* Help text of the job options (clamp and parameters) with their
 * defaults, from the parameter table. */
void job_options_help(FILE *out);
/* The same for --background-size and --background-padding, which the
 * commands list with their inputs. */
void job_options_help_background(FILE *out);
/* The parameters as a markdown table (option, params member, default,
 * range, meaning), every row of the parameter tables: the documentation's
 * table is this text (tests/unit/test_params.c checks it; `build/release/
 * tests/test_params --markdown` prints it). */
void job_options_markdown(FILE *out);

/* ---- run ---- */

/* argv[0] is the command name ("run").  o is fully initialised. */
args_result args_parse_run(int argc, char **argv, run_options *o,
                           char *msg, size_t cap);

/* Splits an option argument: "--name=value" gives flag "--name" and
 * *inline_value "value"; any other argument is the flag itself and
 * *inline_value NULL.  Returns 0, or -1 when the flag does not fit in
 * cap bytes (no option is that long: the caller reports it unknown). */
int args_split_flag(const char *arg, char *flag, size_t cap, const char **inline_value);

/* The value of option `flag` when it takes one: the text after '=' in
 * "--flag=value" (inline_value, or NULL), else the next argument, which
 * must not itself look like an option ("--something" is taken as a
 * forgotten value; "--flag=--x" still allows one).  Advances *i past a
 * consumed argument.  An inline value given to a flag that takes none is
 * an error.  Returns 0, or -1 with the message in msg. */
int args_take_value(int argc, char **argv, int *i, const char *flag, const char *inline_value,
                    int takes_value, const char **value, char *msg, size_t cap);

#endif
