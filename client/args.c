/* Command-line parsing of the shapematch client (see args.h). */
#include "args.h"
#include "cli.h"
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

/* An item of a reference list that is not a number: a physical name. */
static int has_name(const char *text)
{
    for (const char *p = text; *p;) {
        size_t n = strcspn(p, ",");
        char *end;
        char item[64];
        snprintf(item, sizeof item, "%.*s", (int)(n < 63 ? n : 63), p);
        (void)strtol(item, &end, 10);
        if (n && (end == item || *end))
            return 1;
        p += n + (p[n] == ',');
    }
    return 0;
}

/* The names of m of dimension dim (any when dim < 0), for messages. */
static void list_names(const sm_mesh *m, int dim, char *out, size_t cap)
{
    size_t at = 0;
    out[0] = '\0';
    for (int32_t i = 0; i < m->nnames && at + 1 < cap; i++)
        if (dim < 0 || m->names[i].dim == dim)
            at += (size_t)snprintf(out + at, cap - at, "%s\"%s\" (%d)", at ? ", " : "",
                                   m->names[i].name, (int)m->names[i].tag);
    if (!out[0])
        snprintf(out, cap, "none");
}

/* text's items (numbers, or names of dimension dim) into refs. */
static int resolve_list(const char *flag, const char *text, const sm_mesh *m, int dim,
                        int32_t *refs, int *count, char *msg, size_t cap)
{
    int n = 0;
    for (const char *p = text; *p;) {
        size_t len = strcspn(p, ",");
        char item[64], *end;
        snprintf(item, sizeof item, "%.*s", (int)(len < 63 ? len : 63), p);
        long v = strtol(item, &end, 10);
        int found = end != item && !*end;
        for (int32_t i = 0; !found && i < m->nnames; i++)
            if ((dim < 0 || m->names[i].dim == dim) && strcmp(m->names[i].name, item) == 0) {
                v = m->names[i].tag;
                found = 1;
            }
        if (!found) {
            char names[512];
            list_names(m, dim, names, sizeof names);
            return cli_fail(msg, cap, "%s: the template has no physical group named '%s'%s "
                            "(its names%s: %s)", flag, item,
                            dim < 0 ? "" : dim == m->dim ? " of its elements" : " of its facets",
                            dim < 0 ? "" : dim == m->dim ? " of elements" : " of facets", names);
        }
        if (n >= SM_MAX_REFS || v < INT32_MIN || v > INT32_MAX)
            return cli_fail(msg, cap, "%s: too many values or out of range", flag);
        refs[n++] = (int32_t)v;
        p += len + (p[len] == ',');
    }
    *count = n;
    return 0;
}

int job_options_resolve_names(job_options *j, const sm_mesh *m, char *msg, size_t cap)
{
    sm_params *p = &j->params;
    if (j->clamp_names &&
        resolve_list(j->clamp_flag, j->clamp_names, m,
                     p->clamp == SM_CLAMP_ELEMENTS ? m->dim : -1, p->clamp_refs,
                     &p->n_clamp_refs, msg, cap) != 0)
        return -1;
    if (j->free_names && resolve_list("--free-boundary", j->free_names, m, m->dim - 1,
                                      p->free_refs, &p->n_free_refs, msg, cap) != 0)
        return -1;
    j->clamp_names = j->free_names = NULL;
    return 0;
}

int job_options_resolve_names_at(job_options *j, const char *template_path, char *msg,
                                 size_t cap)
{
    if (!j->clamp_names && !j->free_names)
        return 0;
    sm_mesh *m = NULL;
    sm_error err;
    sm_error_clear(&err);
    if (sm_mesh_read(template_path, &m, &err) != SM_OK) {
        cli_fail(msg, cap, "%s", err.msg);
        return CLI_EXIT_INPUT;
    }
    int bad = job_options_resolve_names(j, m, msg, cap);
    sm_mesh_free(m);
    return bad ? CLI_EXIT_USAGE : 0;
}

/* The job parameters' options are the rows of the parameter table
 * (sm_params_table, shapematch/sm_params.h) and of the background rows
 * (sm_background_params_table) that have a flag: the flag, the value's
 * type and range and the help come from there.  The range is checked
 * here so that the message names the flag; the core's
 * sm_params_validate runs afterwards as the last word.  The clamp's
 * four options are code of their own (below). */
static const sm_param_info *find_row(const char *flag, int *background)
{
    size_t n;
    for (int bg = 0; bg < 2; bg++) {
        const sm_param_info *rows = bg ? sm_background_params_table(&n) : sm_params_table(&n);
        for (size_t i = 0; i < n; i++)
            if (rows[i].flag && strcmp(rows[i].flag, flag) == 0) {
                *background = bg;
                return &rows[i];
            }
    }
    return NULL;
}

/* Sets row f of the struct at base from the option's text. */
static int apply_row(void *base, const sm_param_info *f, const char *value, char *msg,
                     size_t cap)
{
    char range[80];
    char *at = (char *)base + f->offset;
    sm_param_describe_range(f, range, sizeof range);
    switch (f->type) {
    case SM_PARAM_INT: {
        long v;
        if (args_parse_int(f->flag, value, LONG_MIN, LONG_MAX, &v, msg, cap) != 0)
            return -1;
        if (!sm_param_in_range(f, (double)v))
            return cli_fail(msg, cap, "%s: %ld is out of range (must be %s)", f->flag, v, range);
        *(int *)at = (int)v;
        return 0;
    }
    case SM_PARAM_REAL: {
        double v;
        if (args_parse_real(f->flag, value, &v, msg, cap) != 0)
            return -1;
        if (!sm_param_in_range(f, v))
            return cli_fail(msg, cap, "%s: %s is out of range (must be %s)", f->flag, value,
                            range);
        *(double *)at = v;
        return 0;
    }
    case SM_PARAM_REFS:
        return args_parse_refs(f->flag, value, (int32_t *)at, (int)f->max,
                               (int *)((char *)base + f->count_offset), msg, cap);
    case SM_PARAM_SOLVER:
    case SM_PARAM_ALIGN:
    case SM_PARAM_SPACE: {
        int k = sm_param_value_from_name(f, value);
        char names[96];
        sm_param_names_text(f, names, sizeof names);
        if (k < 0)
            return cli_fail(msg, cap, "%s: '%s' is not %s", f->flag, value, names);
        sm_param_set_value(f, base, k);
        return 0;
    }
    case SM_PARAM_CLAMP:
        break;
    }
    return cli_fail(msg, cap, "unknown option '%s'", f->flag);
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
    int background;
    return find_row(flag, &background) ? 1 : -1;
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
        char got[SM_NUMBER_TEXT_LEN];
        if (!(v[n - 1] > 0))
            return cli_fail(msg, cap, "%s: the radius must be > 0, got %s", flag,
                            sm_number_text(got, v[n - 1]));
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
        j->clamp_names = NULL;
        if (has_name(value))
            j->clamp_names = value; /* resolved once the template is read */
        else if (args_parse_refs(flag, value, p->clamp_refs, SM_MAX_REFS,
                                 &p->n_clamp_refs, msg, cap) != 0)
            return -1;
        p->clamp = strcmp(flag, "--clamp-elements") == 0 ? SM_CLAMP_ELEMENTS
                                                        : SM_CLAMP_VERTICES;
        return 0;
    }
    if (strcmp(flag, "--free-boundary") == 0 && value && has_name(value)) {
        j->free_names = value;
        return 0;
    }
    int background;
    const sm_param_info *f = find_row(flag, &background);
    if (!f)
        return cli_fail(msg, cap, "unknown option '%s'", flag);
    if (apply_row(background ? (void *)&j->background : (void *)p, f, value, msg, cap) != 0)
        return -1;
    if (f->in_clamp) /* --alpha: only with --no-clamp, checked at the end */
        j->alpha_given = 1;
    return 0;
}

int job_options_finish(job_options *j, char *msg, size_t cap)
{
    /* no clamp option: the default ball (params kind auto), chosen and
     * reported once the template is read */
    if (j->alpha_given && j->params.clamp != SM_CLAMP_NONE)
        return cli_fail(msg, cap, "--alpha is only valid with --no-clamp (got %s)",
                    j->clamp_flag ? j->clamp_flag : "the default clamp");
    char a[SM_NUMBER_TEXT_LEN], b[SM_NUMBER_TEXT_LEN];
    if (j->params.step_initial > j->params.step_max)
        return cli_fail(msg, cap, "--step-initial (%s) must not exceed --step-max (%s)",
                        sm_number_text(a, j->params.step_initial),
                        sm_number_text(b, j->params.step_max));
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

/* "  --flag META            help (default D)", wrapped. */
static void print_row_help(FILE *out, const sm_param_info *f)
{
    char left[40], dflt[64] = "", text[512];
    if (f->def_text)
        snprintf(dflt, sizeof dflt, " (default %s)", f->def_text);
    else if (f->type == SM_PARAM_REFS)
        ; /* an empty list: nothing to show */
    else if (sm_param_is_named(f))
        snprintf(dflt, sizeof dflt, " (default %s)", sm_param_value_name(f, (int)f->def));
    else
        snprintf(dflt, sizeof dflt, " (default %g)", f->def);
    snprintf(left, sizeof left, "%s %s", f->flag, f->meta);
    snprintf(text, sizeof text, "%s%s", f->help, dflt);
    fprintf(out, "  %-22s", left);
    print_wrapped(out, text, 26, 79);
}

void job_options_help(FILE *out)
{
    fputs("Clamp (exactly one):\n"
          "  --clamp-ball X,Y[,Z],R  fix the vertices inside a disk/ball\n"
          "  --clamp-elements REFS   fix the vertices of the elements with these references\n"
          "  --clamp-vertices REFS   fix the vertices with these references\n"
          "  --no-clamp              no fixed vertex; regularize with --alpha\n"
          "\n"
          "Parameters (REFS: comma-separated integers, e.g. 1,4):\n",
          out);
    /* the lists and names first, then the numbers, each in table order */
    size_t n;
    const sm_param_info *rows = sm_params_table(&n);
    for (int numbers = 0; numbers < 2; numbers++)
        for (size_t i = 0; i < n; i++)
            if (rows[i].flag &&
                (rows[i].type == SM_PARAM_REAL || rows[i].type == SM_PARAM_INT) == numbers)
                print_row_help(out, &rows[i]);
}

void job_options_help_background(FILE *out)
{
    size_t n;
    const sm_param_info *rows = sm_background_params_table(&n);
    for (size_t i = 0; i < n; i++)
        print_row_help(out, &rows[i]);
}

/* Text of a markdown table cell: '|' escaped. */
static void put_cell(FILE *out, const char *text)
{
    for (const char *c = text; *c; c++) {
        if (*c == '|')
            fputc('\\', out);
        fputc(*c, out);
    }
}

/* x as %g writes it, without the exponent's leading zero (1e-6). */
static void put_number(FILE *out, double x)
{
    char buf[40];
    snprintf(buf, sizeof buf, "%g", x);
    char *e = strstr(buf, "e-0");
    if (!e)
        e = strstr(buf, "e+0");
    if (e)
        memmove(e + 2, e + 3, strlen(e + 3) + 1);
    fputs(buf, out);
}

/* One row of job_options_markdown. */
static void markdown_row(FILE *out, const sm_param_info *f)
{
    char range[80];
    fputs("| ", out);
    if (f->type == SM_PARAM_CLAMP)
        for (size_t i = 0; i < 4; i++)
            fprintf(out, "%s`%s%s`", i ? ", " : "", clamp_flags[i],
                    i == 0 ? " X,Y[,Z],R" : i < 3 ? " REFS" : "");
    else if (f->flag)
        fprintf(out, "`%s %s`", f->flag, f->meta);
    fprintf(out, "%s| `%s%s` | ", f->flag || f->type == SM_PARAM_CLAMP ? " " : "",
            f->in_clamp ? "clamp." : "", f->name);
    if (f->def_text)
        put_cell(out, f->def_text);
    else if (sm_param_is_named(f))
        fputs(sm_param_value_name(f, (int)f->def), out);
    else if (f->type == SM_PARAM_REFS)
        fputs("none", out);
    else
        put_number(out, f->def);
    fputs(" | ", out);
    sm_param_describe_range(f, range, sizeof range);
    if (f->type == SM_PARAM_REFS)
        fprintf(out, "%g to %g references", f->min, f->max);
    else if (sm_param_is_named(f))
        for (int k = (int)f->min; k <= (int)f->max; k++)
            fprintf(out, "%s%s", k > (int)f->min ? ", " : "", sm_param_value_name(f, k));
    else if (f->type != SM_PARAM_CLAMP)
        fputs(range, out);
    fputs(f->type == SM_PARAM_CLAMP ? "| " : " | ", out);
    put_cell(out, f->help);
    fputs(" |\n", out);
}

void job_options_markdown(FILE *out)
{
    size_t n;
    fputs("| option | params | default | range | meaning |\n|---|---|---|---|---|\n", out);
    for (int bg = 0; bg < 2; bg++) {
        const sm_param_info *rows = bg ? sm_background_params_table(&n) : sm_params_table(&n);
        for (size_t i = 0; i < n; i++)
            markdown_row(out, &rows[i]);
    }
}

/* ---- run ---- */

typedef enum run_flag_kind {
    RUN_FLAG_UNKNOWN,
    RUN_FLAG_TEMPLATE,
    RUN_FLAG_TEMPLATE_SURFACE,
    RUN_FLAG_TEMPLATE_IMAGE,
    RUN_FLAG_TARGET_MESH,
    RUN_FLAG_TARGET_SOL,
    RUN_FLAG_OUTPUT,
    RUN_FLAG_FORMAT,
    RUN_FLAG_TARGET_SURFACE,
    RUN_FLAG_TARGET_IMAGE,
    RUN_FLAG_LANDMARKS,
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
        {"--template-surface", RUN_FLAG_TEMPLATE_SURFACE, 1},
        {"--template-image", RUN_FLAG_TEMPLATE_IMAGE, 1},
        {"--target-mesh", RUN_FLAG_TARGET_MESH, 1},
        {"--target-sol", RUN_FLAG_TARGET_SOL, 1},
        {"--target-surface", RUN_FLAG_TARGET_SURFACE, 1},
        {"--target-image", RUN_FLAG_TARGET_IMAGE, 1},
        {"--landmarks", RUN_FLAG_LANDMARKS, 1},
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
    case RUN_FLAG_TEMPLATE_SURFACE: path = &o->template_surface_path; break;
    case RUN_FLAG_TEMPLATE_IMAGE: path = &o->template_image_path; break;
    case RUN_FLAG_TARGET_MESH: path = &o->target_mesh_path; break;
    case RUN_FLAG_TARGET_SOL: path = &o->target_sol_path; break;
    case RUN_FLAG_TARGET_SURFACE: path = &o->target_surface_path; break;
    case RUN_FLAG_TARGET_IMAGE: path = &o->target_image_path; break;
    case RUN_FLAG_LANDMARKS: path = &o->landmarks; break;
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

/* --landmarks A,B: two files (split at the first comma; a path with a
 * comma of its own goes through a symbolic link), with an alignment. */
static int finish_landmarks(run_options *o, char *msg, size_t cap)
{
    const char *comma = strchr(o->landmarks, ',');
    size_t a = comma ? (size_t)(comma - o->landmarks) : 0;
    if (!comma || a == 0 || comma[1] == '\0')
        return cli_fail(msg, cap, "--landmarks: give TEMPLATE.csv,TARGET.csv (two files)");
    if (a >= sizeof o->landmarks_template || strlen(comma + 1) >= sizeof o->landmarks_target)
        return cli_fail(msg, cap, "--landmarks: path too long");
    memcpy(o->landmarks_template, o->landmarks, a);
    o->landmarks_template[a] = '\0';
    strcpy(o->landmarks_target, comma + 1);
    if (o->job.params.align == SM_ALIGN_NONE)
        return cli_fail(msg, cap,
                        "--landmarks needs an alignment: add --align rigid, similarity or affine");
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
        {offsetof(run_options, template_path),
         "--template (or --template-surface, or --template-image)", 0},
        {offsetof(run_options, target_mesh_path), "--target-mesh", 1},
        {offsetof(run_options, target_sol_path), "--target-sol", 1},
        {offsetof(run_options, outdir), "-o/--output", 0},
    };
    int templates = !!o->template_path + !!o->template_surface_path + !!o->template_image_path;
    if (templates > 1)
        return cli_fail(msg, cap,
                        "give one template: --template, --template-surface or --template-image");
    if (o->job.background.template_label > 0 && !o->template_image_path)
        return cli_fail(msg, cap, "--template-label is the label of --template-image");
    if (o->job.background.template_size > 0 && !o->template_surface_path && !o->template_image_path)
        return cli_fail(msg, cap,
                        "--template-size sizes a template meshed from --template-surface or "
                        "--template-image");
    if (templates == 1 && !o->template_path)
        o->template_path = o->template_surface_path ? o->template_surface_path
                                                    : o->template_image_path;
    if (o->target_surface_path && o->target_sol_path)
        return cli_fail(msg, cap, "--target-surface excludes --target-sol: give one target");
    if (o->target_image_path && (o->target_sol_path || o->target_surface_path))
        return cli_fail(msg, cap, "--target-image excludes %s: give one target",
                        o->target_sol_path ? "--target-sol" : "--target-surface");
    if (o->landmarks && finish_landmarks(o, msg, cap) != 0)
        return -1;
    /* an image, like a surface, makes its own background */
    const char *own_target = o->target_surface_path ? o->target_surface_path : o->target_image_path;
    if (job_options_check_background(&o->job, own_target, o->target_mesh_path, msg, cap) != 0)
        return -1;
    for (size_t k = 0; k < sizeof required / sizeof required[0]; k++)
        if (!*(const char *const *)((const char *)o + required[k].offset) &&
            !(own_target && required[k].surface_replaces))
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
            cli_fail(msg, cap, "unexpected argument '%s' (%s takes options only)",
                     shorten(arg, q, sizeof q), argv[0]);
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
