/* Command-line parsing of the shapematch client (see args.h). */
#include "args.h"
#include "msg.h"
#include "job/sm_job_inputs.h"
#include "sm_proto_vocab.h"

#include <ctype.h>
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>


/* Quotes user text for a message, cut short so that a huge argument
 * cannot drown the message. */
static const char *shorten(const char *text, char *buf, size_t cap)
{
    size_t n = strlen(text);
    if (n < cap) {
        memcpy(buf, text, n + 1);
    } else {
        memcpy(buf, text, cap - 4);
        memcpy(buf + cap - 4, "...", 4);
    }
    return buf;
}

int args_parse_real(const char *flag, const char *text, double *out,
                    char *msg, size_t cap)
{
    char q[48];
    /* strtod would skip leading blanks and accept "nan"/"inf": reject
     * both explicitly so that only plain finite numbers get through */
    if (text[0] == '\0' || isspace((unsigned char)text[0]))
        return cli_fail(msg, cap, "%s: expected a number, got '%s'", flag,
                    shorten(text, q, sizeof q));
    char *end = NULL;
    errno = 0;
    double v = strtod(text, &end);
    if (end == text || *end != '\0')
        return cli_fail(msg, cap, "%s: '%s' is not a number", flag,
                    shorten(text, q, sizeof q));
    if (!isfinite(v) || (errno == ERANGE && fabs(v) > 1.0))
        return cli_fail(msg, cap, "%s: '%s' is not a finite number", flag,
                    shorten(text, q, sizeof q));
    *out = v;
    return 0;
}

int args_parse_int(const char *flag, const char *text, long lo, long hi,
                   long *out, char *msg, size_t cap)
{
    char q[48];
    if (text[0] == '\0' || isspace((unsigned char)text[0]))
        return cli_fail(msg, cap, "%s: expected an integer, got '%s'", flag,
                    shorten(text, q, sizeof q));
    char *end = NULL;
    errno = 0;
    long v = strtol(text, &end, 10);
    if (end == text || *end != '\0')
        return cli_fail(msg, cap, "%s: '%s' is not an integer", flag,
                    shorten(text, q, sizeof q));
    if (errno == ERANGE || v < lo || v > hi)
        return cli_fail(msg, cap, "%s: %s is out of range (%ld..%ld)", flag,
                    shorten(text, q, sizeof q), lo, hi);
    *out = v;
    return 0;
}

/* Splits text at commas into items of at most item_cap-1 characters;
 * calls each() on every item.  Empty items are errors. */
typedef int (*item_fn)(const char *flag, const char *item, int index,
                       void *user, char *msg, size_t cap);

static int split_commas(const char *flag, const char *text, int max,
                        int *count, item_fn each, void *user, char *msg,
                        size_t cap)
{
    char q[48];
    int n = 0;
    const char *p = text;
    for (;;) {
        const char *comma = strchr(p, ',');
        size_t len = comma ? (size_t)(comma - p) : strlen(p);
        if (len == 0)
            return cli_fail(msg, cap, "%s: empty item in '%s' (expected a comma-separated list)",
                        flag, shorten(text, q, sizeof q));
        if (n >= max)
            return cli_fail(msg, cap, "%s: too many values (at most %d)", flag, max);
        char item[64];
        if (len >= sizeof item)
            return cli_fail(msg, cap, "%s: value too long in '%s'", flag,
                        shorten(text, q, sizeof q));
        memcpy(item, p, len);
        item[len] = '\0';
        if (each(flag, item, n, user, msg, cap) != 0)
            return -1;
        n++;
        if (!comma)
            break;
        p = comma + 1;
    }
    *count = n;
    return 0;
}

static int ref_item(const char *flag, const char *item, int index,
                    void *user, char *msg, size_t cap)
{
    long v;
    if (args_parse_int(flag, item, INT32_MIN, INT32_MAX, &v, msg, cap) != 0)
        return -1;
    ((int32_t *)user)[index] = (int32_t)v;
    return 0;
}

static int real_item(const char *flag, const char *item, int index,
                     void *user, char *msg, size_t cap)
{
    return args_parse_real(flag, item, &((double *)user)[index], msg, cap);
}

/* Comma-separated integers (int32), 1..max of them. */
static int args_parse_refs(const char *flag, const char *text, int32_t *refs,
                           int max, int *count, char *msg, size_t cap)
{
    return split_commas(flag, text, max, count, ref_item, refs, msg, cap);
}

/* Comma-separated reals, 1..max of them, all finite. */
static int args_parse_reals(const char *flag, const char *text, double *vals,
                            int max, int *count, char *msg, size_t cap)
{
    return split_commas(flag, text, max, count, real_item, vals, msg, cap);
}

/* ---- job options ---- */

/* The scalar parameters, table-driven: flag, field, type and the range
 * accepted (checked here so that the message names the flag; the core's
 * sm_params_validate runs afterwards as the last word). */
typedef struct scalar_option {
    const char *flag;
    size_t offset;       /* into sm_params */
    int is_int;
    double lo, hi;
    int lo_open, hi_open;
    const char *meta;
    const char *help;
} scalar_option;

static const scalar_option scalar_options[] = {
    {"--alpha", offsetof(sm_params, alpha), 0, 0.0, INFINITY, 0, 1, "A",
     "0th-order term alpha*int u.v of the unclamped problem (only with --no-clamp; "
     "0: from the scale, E/diameter^2)"},
    {"--young", offsetof(sm_params, young), 0, 0.0, INFINITY, 1, 1, "E",
     "Young's modulus of the elastic model"},
    {"--poisson", offsetof(sm_params, poisson), 0, -1.0, 0.5, 1, 1, "NU",
     "Poisson ratio of the elastic model"},
    {"--max-iter", offsetof(sm_params, max_iter), 1, 1.0, 1e9, 0, 0, "N",
     "stop after N iterations"},
    {"--tol-step", offsetof(sm_params, tol_step), 0, 0.0, 1.0, 1, 1, "EPS",
     "stop when the step falls below EPS times the template diameter"},
    {"--tol-boundary", offsetof(sm_params, tol_boundary), 0, 0.0, INFINITY, 0, 1, "TOL",
     "stop when the boundary error ||d||_L2 is <= TOL (0: off; absolute, unit-dependent)"},
    {"--tol-boundary-rel", offsetof(sm_params, tol_boundary_rel), 0, 0.0, INFINITY, 0, 1, "R",
     "stop when the RMS boundary error is <= R times the template diameter (0: off; unit-free)"},
    {"--tol-stall", offsetof(sm_params, tol_stall), 0, 0.0, 1.0, 0, 1, "F",
     "stop (stalled) when the best boundary error improved by < F over the stall window (0: off)"},
    {"--stall-window", offsetof(sm_params, stall_window), 1, 1.0, 100000, 0, 0, "K",
     "iterations of the stall rule's window"},
    {"--min-quality", offsetof(sm_params, min_quality), 0, 0.0, 1.0, 0, 1, "Q",
     "element quality floor for an accepted step, in [0,1)"},
    {"--save-every", offsetof(sm_params, save_every), 1, 0.0, INT_MAX, 0, 0, "K",
     "also write OUTDIR/iter-NNNNN.mesh every K iterations (0: never)"},
    {"--step-initial", offsetof(sm_params, step_initial), 0, 0.0, 1.0, 1, 0, "S",
     "first step length, as a fraction of the template diameter"},
    {"--step-max", offsetof(sm_params, step_max), 0, 0.0, 1.0, 1, 0, "S",
     "largest step length, as a fraction of the template diameter"},
    {"--refactor-every", offsetof(sm_params, refactor_every), 1, 1.0, INT_MAX, 0, 0, "K",
     "refactorize the elasticity matrix every K iterations"},
};
#define N_SCALAR_OPTIONS (sizeof scalar_options / sizeof scalar_options[0])

static const scalar_option *find_scalar(const char *flag)
{
    for (size_t i = 0; i < N_SCALAR_OPTIONS; i++)
        if (strcmp(scalar_options[i].flag, flag) == 0)
            return &scalar_options[i];
    return NULL;
}

static void describe_range(const scalar_option *o, char *buf, size_t cap)
{
    if (isinf(o->hi) || (o->is_int && o->hi >= INT_MAX))
        snprintf(buf, cap, "%s %g", o->lo_open ? ">" : ">=", o->lo);
    else if (o->is_int)
        snprintf(buf, cap, "in [%ld, %ld]", (long)o->lo, (long)o->hi);
    else
        snprintf(buf, cap, "in %c%g, %g%c", o->lo_open ? '(' : '[', o->lo,
                 o->hi, o->hi_open ? ')' : ']');
}

static int apply_scalar(sm_params *p, const scalar_option *o,
                        const char *value, char *msg, size_t cap)
{
    char range[64];
    describe_range(o, range, sizeof range);
    if (o->is_int) {
        long v;
        if (args_parse_int(o->flag, value, LONG_MIN, LONG_MAX, &v, msg, cap) != 0)
            return -1;
        if (v < (long)o->lo || v > (long)o->hi)
            return cli_fail(msg, cap, "%s: %ld is out of range (must be %s)",
                        o->flag, v, range);
        *(int *)((char *)p + o->offset) = (int)v;
        return 0;
    }
    double v;
    if (args_parse_real(o->flag, value, &v, msg, cap) != 0)
        return -1;
    int below = o->lo_open ? !(v > o->lo) : !(v >= o->lo);
    int above = o->hi_open ? !(v < o->hi) : !(v <= o->hi);
    if (below || above)
        return cli_fail(msg, cap, "%s: %s is out of range (must be %s)", o->flag,
                    value, range);
    *(double *)((char *)p + o->offset) = v;
    return 0;
}

static const char *const clamp_flags[] = {
    "--clamp-ball", "--clamp-elements", "--clamp-vertices", "--no-clamp",
};

int args_split_flag(const char *arg, char *flag, size_t cap, const char **inline_value)
{
    const char *eq = arg[0] == '-' && arg[1] == '-' ? strchr(arg, '=') : NULL;
    size_t flen = eq ? (size_t)(eq - arg) : strlen(arg);
    *inline_value = eq ? eq + 1 : NULL;
    if (flen >= cap)
        return -1;
    memcpy(flag, arg, flen);
    flag[flen] = '\0';
    return 0;
}

int args_take_value(int argc, char **argv, int *i, const char *flag, const char *inline_value,
                    int takes_value, const char **value, char *msg, size_t cap)
{
    *value = NULL;
    if (!takes_value)
        return inline_value ? cli_fail(msg, cap, "%s does not take a value", flag) : 0;
    if (inline_value) {
        *value = inline_value;
        return 0;
    }
    if (*i + 1 >= argc || (argv[*i + 1][0] == '-' && argv[*i + 1][1] == '-'))
        return cli_fail(msg, cap, "%s requires a value", flag);
    *value = argv[++*i];
    return 0;
}


void job_options_init(job_options *j)
{
    memset(j, 0, sizeof *j);
    sm_params_default(&j->params);
}

int job_option_lookup(const char *flag)
{
    if (strcmp(flag, "--no-clamp") == 0)
        return 0;
    for (size_t i = 0; i < 3; i++)
        if (strcmp(flag, clamp_flags[i]) == 0)
            return 1;
    if (strcmp(flag, "--free-boundary") == 0 || strcmp(flag, "--solver") == 0 ||
        strcmp(flag, "--background-size") == 0 || strcmp(flag, "--background-padding") == 0)
        return 1;
    return find_scalar(flag) ? 1 : -1;
}

/* --background-size H (> 0) / --background-padding P (in (0, 100]): the
 * decoder's ranges of params background_size, background_padding. */
static int apply_background(job_options *j, const char *flag, const char *value, char *msg,
                            size_t cap)
{
    int size = strcmp(flag, "--background-size") == 0;
    double *dst = size ? &j->background.size : &j->background.padding;
    double max = size ? INFINITY : SM_BACKGROUND_PADDING_MAX;
    if (args_parse_real(flag, value, dst, msg, cap) != 0)
        return -1;
    if (!(*dst > 0) || !(*dst <= max))
        return size ? cli_fail(msg, cap, "%s: expected a number > 0", flag)
                    : cli_fail(msg, cap, "%s: expected a number > 0 and <= %g", flag, max);
    return 0;
}

int job_options_check_background(const job_options *j, const char *target_surface,
                                 const char *target_mesh, char *msg, size_t cap)
{
    sm_job_files files = {.target_surface = target_surface, .target_mesh = target_mesh,
                          .background_size = j->background.size,
                          .background_padding = j->background.padding};
    sm_error err;
    sm_error_clear(&err);
    if (sm_job_files_check_background(&files, SM_JOB_NAME_PATHS, &err) != SM_OK)
        return cli_fail(msg, cap, "%s", err.msg);
    return 0;
}

static int set_clamp(job_options *j, const char *flag, char *msg, size_t cap)
{
    if (j->clamp_flag) {
        if (strcmp(j->clamp_flag, flag) == 0)
            return cli_fail(msg, cap, "%s given twice: give exactly one clamp option", flag);
        return cli_fail(msg, cap,
                    "%s and %s both given: give exactly one of --clamp-ball, "
                    "--clamp-elements, --clamp-vertices, --no-clamp",
                    j->clamp_flag, flag);
    }
    for (size_t i = 0; i < 4; i++)
        if (strcmp(flag, clamp_flags[i]) == 0)
            j->clamp_flag = clamp_flags[i]; /* static storage */
    return 0;
}

int job_option_apply(job_options *j, const char *flag, const char *value,
                     char *msg, size_t cap)
{
    sm_params *p = &j->params;
    if (strcmp(flag, "--no-clamp") == 0) {
        if (set_clamp(j, flag, msg, cap) != 0)
            return -1;
        p->clamp = SM_CLAMP_NONE;
        return 0;
    }
    if (strcmp(flag, "--clamp-ball") == 0) {
        if (set_clamp(j, flag, msg, cap) != 0)
            return -1;
        double v[4];
        int n = 0;
        if (args_parse_reals(flag, value, v, 4, &n, msg, cap) != 0)
            return -1;
        if (n != 3 && n != 4)
            return cli_fail(msg, cap,
                        "%s: expected x,y,r (2D) or x,y,z,r (3D), got %d value%s",
                        flag, n, n == 1 ? "" : "s");
        if (!(v[n - 1] > 0))
            return cli_fail(msg, cap, "%s: the radius must be > 0, got %g", flag, v[n - 1]);
        p->clamp = SM_CLAMP_BALL;
        p->clamp_center[0] = v[0];
        p->clamp_center[1] = v[1];
        p->clamp_center[2] = n == 4 ? v[2] : 0.0;
        p->clamp_radius = v[n - 1];
        j->clamp_ball_dim = n - 1;
        return 0;
    }
    if (strcmp(flag, "--clamp-elements") == 0 || strcmp(flag, "--clamp-vertices") == 0) {
        if (set_clamp(j, flag, msg, cap) != 0)
            return -1;
        if (args_parse_refs(flag, value, p->clamp_refs, SM_MAX_REFS,
                            &p->n_clamp_refs, msg, cap) != 0)
            return -1;
        p->clamp = strcmp(flag, "--clamp-elements") == 0 ? SM_CLAMP_ELEMENTS
                                                        : SM_CLAMP_VERTICES;
        return 0;
    }
    if (strcmp(flag, "--free-boundary") == 0)
        return args_parse_refs(flag, value, p->free_refs, SM_MAX_REFS,
                               &p->n_free_refs, msg, cap);
    if (strcmp(flag, "--background-size") == 0 || strcmp(flag, "--background-padding") == 0)
        return apply_background(j, flag, value, msg, cap);
    if (strcmp(flag, "--solver") == 0)
        return sm_solver_kind_from_name(value, &p->solver) == 0
                   ? 0
                   : cli_fail(msg, cap, "--solver: '%s' is not auto, cholmod or amg", value);
    const scalar_option *o = find_scalar(flag);
    if (!o)
        return cli_fail(msg, cap, "unknown option '%s'", flag);
    if (apply_scalar(p, o, value, msg, cap) != 0)
        return -1;
    if (strcmp(flag, "--alpha") == 0)
        j->alpha_given = 1;
    return 0;
}

int job_options_finish(job_options *j, char *msg, size_t cap)
{
    if (!j->clamp_flag)
        return cli_fail(msg, cap,
                    "missing clamp option: give exactly one of --clamp-ball, "
                    "--clamp-elements, --clamp-vertices, --no-clamp");
    if (j->alpha_given && j->params.clamp != SM_CLAMP_NONE)
        return cli_fail(msg, cap, "--alpha is only valid with --no-clamp (got %s)",
                    j->clamp_flag);
    if (j->params.step_initial > j->params.step_max)
        return cli_fail(msg, cap, "--step-initial (%g) must not exceed --step-max (%g)",
                    j->params.step_initial, j->params.step_max);
    return 0;
}

int job_options_check_dim(const job_options *j, int dim, char *msg,
                          size_t cap)
{
    if (j->params.clamp == SM_CLAMP_BALL && j->clamp_ball_dim != dim)
        return cli_fail(msg, cap,
                    "--clamp-ball: the template is %dD, so give %s (got %d coordinates)",
                    dim, dim == 2 ? "x,y,r" : "x,y,z,r", j->clamp_ball_dim);
    return 0;
}

/* Prints text starting at column indent (the caller has written up to
 * column indent-2), wrapping at spaces before column width. */
static void print_wrapped(FILE *out, const char *text, int indent, int width)
{
    fputs("  ", out);
    int col = indent, line_start = 1;
    const char *p = text;
    while (*p) {
        const char *sp = strchr(p, ' ');
        int len = sp ? (int)(sp - p) : (int)strlen(p);
        if (!line_start && col + 1 + len > width) {
            fprintf(out, "\n%*s", indent, "");
            col = indent;
            line_start = 1;
        }
        if (!line_start) {
            fputc(' ', out);
            col++;
        }
        fwrite(p, 1, (size_t)len, out);
        col += len;
        line_start = 0;
        p += len;
        while (*p == ' ')
            p++;
    }
    fputc('\n', out);
}

void job_options_help(FILE *out)
{
    sm_params d;
    sm_params_default(&d);
    fputs("Clamp (exactly one):\n"
          "  --clamp-ball X,Y[,Z],R  fix the vertices inside a disk/ball\n"
          "  --clamp-elements REFS   fix the vertices of the elements with these references\n"
          "  --clamp-vertices REFS   fix the vertices with these references\n"
          "  --no-clamp              no fixed vertex; regularize with --alpha\n"
          "\n"
          "Parameters (REFS: comma-separated integers, e.g. 1,4):\n"
          "  --free-boundary REFS    boundary facet references excluded from the load\n"
          "  --solver NAME           elastic solver: cholmod (sparse Cholesky), amg (PCG +\n"
          "                          BoomerAMG: less memory, for large 3D templates) or auto\n"
          "                          (amg from 20000 tetrahedra; default auto)\n",
          out);
    for (size_t i = 0; i < N_SCALAR_OPTIONS; i++) {
        const scalar_option *o = &scalar_options[i];
        char left[40], text[256];
        snprintf(left, sizeof left, "%s %s", o->flag, o->meta);
        if (o->is_int)
            snprintf(text, sizeof text, "%s (default %d)", o->help,
                     *(const int *)((const char *)&d + o->offset));
        else
            snprintf(text, sizeof text, "%s (default %g)", o->help,
                     *(const double *)((const char *)&d + o->offset));
        fprintf(out, "  %-22s", left);
        print_wrapped(out, text, 26, 79);
    }
}

/* ---- run ---- */

typedef enum run_flag_kind {
    RUN_FLAG_UNKNOWN,
    RUN_FLAG_TEMPLATE,
    RUN_FLAG_TARGET_MESH,
    RUN_FLAG_TARGET_SOL,
    RUN_FLAG_OUTPUT,
    RUN_FLAG_FORMAT,
    RUN_FLAG_TARGET_SURFACE,
    RUN_FLAG_QUIET,
    RUN_FLAG_JSON,
    RUN_FLAG_JOB
} run_flag_kind;

static run_flag_kind classify_run_flag(const char *flag, int *takes_value)
{
    static const struct {
        const char *name;
        run_flag_kind kind;
        int takes_value;
    } own[] = {
        {"--template", RUN_FLAG_TEMPLATE, 1},
        {"--target-mesh", RUN_FLAG_TARGET_MESH, 1},
        {"--target-sol", RUN_FLAG_TARGET_SOL, 1},
        {"--target-surface", RUN_FLAG_TARGET_SURFACE, 1},
        {"--output", RUN_FLAG_OUTPUT, 1},
        {"-o", RUN_FLAG_OUTPUT, 1},
        {"--format", RUN_FLAG_FORMAT, 1},
        {"--quiet", RUN_FLAG_QUIET, 0},
        {"-q", RUN_FLAG_QUIET, 0},
        {"--json", RUN_FLAG_JSON, 0},
    };
    for (size_t i = 0; i < sizeof own / sizeof own[0]; i++)
        if (strcmp(flag, own[i].name) == 0) {
            *takes_value = own[i].takes_value;
            return own[i].kind;
        }
    int job = job_option_lookup(flag);
    if (job >= 0) {
        *takes_value = job;
        return RUN_FLAG_JOB;
    }
    return RUN_FLAG_UNKNOWN;
}

/* Applies one classified option of `run` (value checked by kind). */
static int apply_run_flag(run_options *o, run_flag_kind kind, const char *flag, const char *value,
                          char *msg, size_t cap)
{
    const char **path = NULL;
    switch (kind) {
    case RUN_FLAG_TEMPLATE: path = &o->template_path; break;
    case RUN_FLAG_TARGET_MESH: path = &o->target_mesh_path; break;
    case RUN_FLAG_TARGET_SOL: path = &o->target_sol_path; break;
    case RUN_FLAG_TARGET_SURFACE: path = &o->target_surface_path; break;
    case RUN_FLAG_OUTPUT: path = &o->outdir; break;
    case RUN_FLAG_FORMAT: {
        char why[ARGS_MSG_LEN];
        if (sm_result_outputs_parse(value, &o->outputs, why, sizeof why) != 0)
            return cli_fail(msg, cap, "%s: %s", flag, why);
        return 0;
    }
    case RUN_FLAG_QUIET:
        o->quiet = 1;
        return 0;
    case RUN_FLAG_JSON:
        o->json = 1;
        return 0;
    case RUN_FLAG_JOB:
        return job_option_apply(&o->job, flag, value, msg, cap);
    case RUN_FLAG_UNKNOWN:
        break;
    }
    if (!path)
        return cli_fail(msg, cap, "unknown option '%s'", flag);
    if (value[0] == '\0')
        return cli_fail(msg, cap, "%s: empty path", flag);
    *path = value;
    return 0;
}

/* What `run` needs once every option is read: the inputs (a surface
 * replaces the background and its distance), the output folder, and
 * consistent targets. */
static int finish_run_options(run_options *o, char *msg, size_t cap)
{
    static const struct {
        size_t offset;
        const char *flag;
        int surface_replaces; /* not needed with --target-surface */
    } required[] = {
        {offsetof(run_options, template_path), "--template", 0},
        {offsetof(run_options, target_mesh_path), "--target-mesh", 1},
        {offsetof(run_options, target_sol_path), "--target-sol", 1},
        {offsetof(run_options, outdir), "-o/--output", 0},
    };
    if (o->target_surface_path && o->target_sol_path)
        return cli_fail(msg, cap, "--target-surface excludes --target-sol: give one target");
    if (job_options_check_background(&o->job, o->target_surface_path, o->target_mesh_path, msg,
                                     cap) != 0)
        return -1;
    for (size_t k = 0; k < sizeof required / sizeof required[0]; k++)
        if (!*(const char *const *)((const char *)o + required[k].offset) &&
            !(o->target_surface_path && required[k].surface_replaces))
            return cli_fail(msg, cap, "missing required option %s", required[k].flag);
    return job_options_finish(&o->job, msg, cap);
}

args_result args_parse_run(int argc, char **argv, run_options *o,
                           char *msg, size_t cap)
{
    char q[48];
    memset(o, 0, sizeof *o);
    job_options_init(&o->job);
    if (sm_result_outputs_parse(RUN_DEFAULT_FORMATS, &o->outputs, msg, cap) != 0)
        return ARGS_ERROR;
    for (int i = 1; i < argc; i++) {
        const char *arg = argv[i];
        if (strcmp(arg, "-h") == 0 || strcmp(arg, "--help") == 0)
            return ARGS_HELP;
        if (arg[0] != '-' || arg[1] == '\0' || strcmp(arg, "--") == 0) {
            cli_fail(msg, cap, "unexpected argument '%s' (run takes options only)",
                 shorten(arg, q, sizeof q));
            return ARGS_ERROR;
        }
        char flag[40];
        const char *inline_value, *value = NULL;
        int takes_value = 0;
        int fits = args_split_flag(arg, flag, sizeof flag, &inline_value) == 0;
        run_flag_kind kind = fits ? classify_run_flag(flag, &takes_value) : RUN_FLAG_UNKNOWN;
        if (kind == RUN_FLAG_UNKNOWN) {
            cli_fail(msg, cap, "unknown option '%s'", fits ? flag : shorten(arg, q, sizeof q));
            return ARGS_ERROR;
        }
        if (args_take_value(argc, argv, &i, flag, inline_value, takes_value, &value, msg, cap) != 0 ||
            apply_run_flag(o, kind, flag, value, msg, cap) != 0)
            return ARGS_ERROR;
    }
    return finish_run_options(o, msg, cap) == 0 ? ARGS_OK : ARGS_ERROR;
}
