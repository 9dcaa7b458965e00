/* `shapematch batch`: one template matched onto many targets locally,
 * the template side built once (proto/job/sm_job_batch.h), then the
 * shape model of the results (sm_job_model.h).  Every option of `run`
 * applies to every target; what is the CLI's own is the target list,
 * the model's and the batch's options, one line per target and the exit
 * code. */
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "args.h"
#include "cli.h"
#include "fsutil.h"
#include "job/sm_job_batch.h"
#include "job/sm_job_template_from.h"

/* Set by SIGINT/SIGTERM: the batch stops (sm_batch_opts.cancel).  A
 * signal handler has no other way to reach it. */
static volatile sig_atomic_t batch_cancel;
_Static_assert(_Generic((sig_atomic_t)0, int: 1, default: 0),
               "sig_atomic_t must be int to be shared with the batch");

static void on_batch_signal(int sig)
{
    (void)sig;
    batch_cancel = 1;
}

/* As run's: the first signal asks for a clean stop, a second one ends the
 * process; no SA_RESTART, so the wait for the targets sees it at once. */
static void install_cancel_handlers(void)
{
    struct sigaction sa, old;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_batch_signal;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = SA_RESETHAND;
    if (sigaction(SIGINT, NULL, &old) != 0 || old.sa_handler != SIG_IGN)
        sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
}

void cmd_batch_help(void)
{
    printf("Usage: shapematch batch --template T.mesh TARGETS CLAMP [PARAMETERS]\n"
           "                        [--template-from medoid|mean [--rounds K]]\n"
           "                        [--model-align none|rigid|similarity] [--no-model]\n"
           "                        [--jobs N] [--format LIST] [--quiet] -o DIR\n"
           "       shapematch batch --server URL [--token T] --template T.mesh TARGETS\n"
           "                        CLAMP [PARAMETERS] [--template-from medoid|mean\n"
           "                        [--rounds K]] [--model-align MODE] -o DIR\n"
           "\n"
           "Matches one template onto many targets, setting the template up once (its\n"
           "topology, clamp set, elastic operator and factorization are shared by every\n"
           "target), and builds the statistical shape model of the results: mean shape,\n"
           "principal modes, scores, compactness, generalization and specificity.\n"
           "Each target's result set (the files of 'shapematch run') goes to\n"
           "DIR/targets/NAME/ (NAME: the target file's stem, made unique), the model to\n"
           "DIR/model/, the batch's summary to DIR/summary.json.  A target that fails\n"
           "is reported and left out of the model.\n"
           "\n"
           "Targets (any number of each, mixed):\n"
           "  --target-surface FILE...\n"
           "                          target surfaces (as in run): several files after\n"
           "                          one option (a shell glob, *.stl), or the option\n"
           "                          repeated\n"
           "  --target-image FILE...  label-map images (as in run: NIfTI, NRRD, MetaImage;\n"
           "                          --label, --level, --image-space apply to each)\n"
           "  --target-mesh B --target-sol D\n"
           "                          a target given as a distance on a mesh (in pairs)\n"
           "  --targets LIST.csv      a list: header of columns among name,\n"
           "                          target_surface, target_image, target_mesh,\n"
           "                          target_sol, landmarks,\n"
           "                          then one target per line (paths relative to the\n"
           "                          list's folder; '#' lines skipped)\n"
           "  --template-landmarks T.csv\n"
           "                          the template's landmarks, for the targets' own in\n"
           "                          LIST.csv (with --align)\n"
           "\n"
           "The population's own template (each round a whole batch in DIR/rounds/K/;\n"
           "the last round's targets and model moved to DIR/targets and DIR/model, its\n"
           "template to DIR/template.mesh; the summaries' \"template_from\" says how):\n"
           "  --template-from FILE    FILE is the template (as --template), named so in the\n"
           "                          summaries; one round\n"
           "  --template-from medoid  round 1 on --template; round 2 on the result mesh of\n"
           "                          the medoid: the target whose matched shape has the\n"
           "                          smallest sum of two-sided RMS boundary distances to\n"
           "                          the others (pairs aligned as --model-align); 2 rounds\n"
           "  --template-from mean    round 1 on --template, then each round on the\n"
           "                          previous round's model mean (model/mean.mesh, the\n"
           "                          template's mesh in the first target's frame), until\n"
           "                          the mean moves less than the tolerance or K rounds\n"
           "  --rounds K              mean: at most K rounds (2 to %d, default %d)\n"
           "  --template-tolerance T  mean: stop when the two-sided RMS distance between\n"
           "                          consecutive means, over their size (bounding-box\n"
           "                          diagonal), is below T (default %g)\n"
           "                          A mean with an inverted element stops the rounds on\n"
           "                          the last valid template.  Cost: each round is a\n"
           "                          whole batch (medoid 2x; mean up to Kx), plus the\n"
           "                          medoid's N(N-1)/2 boundary distances\n"
           "\n"
           "Batch and model:\n"
           "  --jobs N                targets run side by side, each in its own process\n"
           "                          (default: the online CPUs; at most the targets and\n"
           "                          the cores, each with cores/N threads)\n"
           "  --model-align MODE      Procrustes alignment of the results before the\n"
           "                          model: none, rigid (default) or similarity\n"
           "  --model-modes K         mode files written (mode_K.sol; default 20)\n"
           "  --no-model              the targets only\n"
           "  --model-from DIR        no matching: build DIR/model again from the targets\n"
           "                          of an earlier batch's DIR (e.g. another alignment)\n"
           "  -o, --output DIR        output folder (created if missing)\n"
           "  -q, --quiet             no line per target\n"
           "\n"
           "Every option of 'shapematch run' (clamp, parameters, --align, --format,\n"
           "--background-size, ...) applies to every target; see 'shapematch run\n"
           "--help'.  docs/populations.md describes the files.\n"
           "\n"
           "With --server URL (and --token, as for 'shapematch submit'), the daemon runs\n"
           "the batch: each target is submitted as a job, the jobs are grouped into a\n"
           "batch (POST /v1/batches, --model-align), followed with a line whenever its\n"
           "progress changes, then each target's results (--format, as for 'shapematch\n"
           "fetch') and the model's files are fetched into DIR/targets/NAME/ and\n"
           "DIR/model/, the batch's last document into DIR/batch.json.  With\n"
           "--template-from, each round is a daemon batch into DIR/rounds/K/ (its\n"
           "request naming the round and the batch before), the next template chosen\n"
           "here as for a local batch; DIR/batch.json and DIR/model/summary.json get\n"
           "\"template_from\".  --jobs, --no-model, --model-modes, --model-from and\n"
           "per-target landmarks are local.\n"
           "\n"
           "Ctrl-C stops the batch: no new target starts, the running ones stop after\n"
           "their current iteration and write the state reached (status \"cancelled\"),\n"
           "no model is built; a second Ctrl-C ends it at once.\n"
           "\n"
           "Exit: 0 every target finished and the model was built; 2 the template or an\n"
           "option is wrong (nothing run); 4 an output cannot be written; 5 cancelled;\n"
           "11 some targets failed or the model could not be built (DIR/summary.json).\n",
           SM_TEMPLATE_ROUNDS_MAX, SM_TEMPLATE_ROUNDS_DEFAULT, SM_TEMPLATE_TOLERANCE_DEFAULT);
}

typedef struct batch_args {
    sm_batch_list list;
    const char *outdir, *template_path, *template_landmarks, *model_align, *model_from;
    const char *template_from; /* --template-from: medoid, mean or a FILE */
    int rounds;                /* --rounds (0: not given) */
    double tolerance;          /* --template-tolerance (0: not given) */
    sm_template_from from;     /* what --template-from names */
    int jobs, model_modes, no_model, quiet;
    const char *pending_mesh;  /* a --target-mesh waiting for its --target-sol */
    char **rest;               /* the options passed to run's parser */
    int nrest;
} batch_args;

static int fail(const char *fmt, const char *a)
{
    fprintf(stderr, "shapematch batch: ");
    fprintf(stderr, fmt, a);
    fprintf(stderr, "\nTry 'shapematch batch --help' for more information.\n");
    return CLI_EXIT_USAGE;
}

int batch_read_list(sm_batch_list *l, const char *path, char *msg, size_t cap)
{
    FILE *f = fopen(path, "rb");
    if (!f) {
        snprintf(msg, cap, "cannot open the target list %s", path);
        return -1;
    }
    size_t cap_text = 1 << 16, n = 0;
    char *text = malloc(cap_text);
    for (size_t got; text && (got = fread(text + n, 1, cap_text - n, f)) > 0;) {
        n += got;
        if (n == cap_text) {
            char *t = cap_text < ((size_t)64 << 20) ? realloc(text, cap_text *= 2) : NULL;
            if (!t)
                free(text);
            text = t;
        }
    }
    fclose(f);
    if (!text) {
        snprintf(msg, cap, "the target list %s is too large", path);
        return -1;
    }
    char *dir = strdup(path), *slash = dir ? strrchr(dir, '/') : NULL;
    if (slash)
        *slash = '\0';
    sm_error err;
    sm_error_clear(&err);
    sm_status st = sm_batch_list_parse(l, text, n, slash ? dir : NULL, &err);
    free(text);
    free(dir);
    if (st != SM_OK)
        snprintf(msg, cap, "%s: %s", path, err.msg);
    return st == SM_OK ? 0 : -1;
}

static int read_list(batch_args *b, const char *path)
{
    char msg[512];
    if (batch_read_list(&b->list, path, msg, sizeof msg) == 0)
        return 0;
    if (strncmp(msg, "cannot open", 11) == 0 || strstr(msg, "too large"))
        return fail("%s", msg);
    fprintf(stderr, "shapematch batch: %s\n", msg);
    return CLI_EXIT_INPUT;
}

/* Option k of parse's with_value table, with its value v. */
static int take_option(batch_args *b, size_t k, const char *v)
{
    sm_error err;
    sm_error_clear(&err);
    switch (k) {
    case 0:
    case 12:
        return sm_batch_list_add(&b->list, NULL, k == 0 ? v : NULL, k == 12 ? v : NULL, NULL,
                                 NULL, NULL, &err) != SM_OK
                   ? fail("%s", err.msg) : 0;
    case 1:
        if (b->pending_mesh)
            return fail("--target-mesh %s has no --target-sol", b->pending_mesh);
        b->pending_mesh = v;
        return 0;
    case 2:
        if (!b->pending_mesh)
            return fail("--target-sol %s follows no --target-mesh", v);
        if (sm_batch_list_add(&b->list, NULL, NULL, NULL, b->pending_mesh, v, NULL, &err) !=
            SM_OK)
            return fail("%s", err.msg);
        b->pending_mesh = NULL;
        return 0;
    case 3: return read_list(b, v);
    case 4: b->template_path = v; return 0;
    case 5: b->template_landmarks = v; return 0;
    case 6: b->model_align = v; return 0;
    case 7:
        return (b->model_modes = atoi(v)) < 1 || b->model_modes > 100000
                   ? fail("--model-modes: '%s' is not a count from 1", v) : 0;
    case 8:
        return (b->jobs = atoi(v)) < 1 || b->jobs > 256
                   ? fail("--jobs: '%s' is not a count from 1 to 256", v) : 0;
    case 9: b->model_from = v; return 0;
    case 10:
    case 11: b->outdir = v; return 0;
    case 13: b->template_from = v; return 0;
    case 14:
    case 15: {
        char m[ARGS_MSG_LEN];
        int bad = k == 14 ? batch_parse_rounds(v, &b->rounds, m, sizeof m)
                           : batch_parse_tolerance(v, &b->tolerance, m, sizeof m);
        return bad ? fail("%s", m) : 0;
    }
    default: return fail("%s", "internal: an option without a case");
    }
}

int batch_parse_rounds(const char *v, int *rounds, char *msg, size_t cap)
{
    char *end;
    long k = strtol(v, &end, 10);
    *rounds = k >= 2 && k <= SM_TEMPLATE_ROUNDS_MAX && !*end && end != v ? (int)k : 0;
    if (!*rounds)
        snprintf(msg, cap, "--rounds: '%.32s' is not a count from 2 (the first round matches "
                 "the given template) to %d", v, SM_TEMPLATE_ROUNDS_MAX);
    return *rounds ? 0 : -1;
}

int batch_parse_tolerance(const char *v, double *tolerance, char *msg, size_t cap)
{
    char *end;
    *tolerance = strtod(v, &end);
    if (*end || end == v || !(*tolerance > 0 && *tolerance < 1)) {
        snprintf(msg, cap, "--template-tolerance: '%.32s' is not a number in (0, 1)", v);
        return -1;
    }
    return 0;
}

int batch_resolve_template_from(const char *v, const char **template_path, int rounds,
                                double tolerance, int no_model, sm_template_from *from,
                                char *msg, size_t cap)
{
    if (!v) {
        if (rounds || tolerance) {
            snprintf(msg, cap, "--rounds and --template-tolerance go with --template-from mean");
            return -1;
        }
        return 0;
    }
    if (sm_template_from_parse(v, from) != 0) {
        if (access(v, R_OK) != 0) {
            snprintf(msg, cap, "--template-from: '%.200s' is not medoid, mean or a readable "
                     "template file", v);
            return -1;
        }
        if (*template_path) {
            snprintf(msg, cap, "--template-from %.200s is the template: no --template beside "
                     "it", v);
            return -1;
        }
        *from = SM_TEMPLATE_FROM_FILE;
        *template_path = v;
    } else if (!*template_path) {
        snprintf(msg, cap, "--template-from %s: --template T.mesh is the first round's template",
                 v);
        return -1;
    }
    if ((rounds || tolerance) && *from != SM_TEMPLATE_FROM_MEAN) {
        snprintf(msg, cap, "--rounds and --template-tolerance go with --template-from mean, "
                 "not %.200s", *from == SM_TEMPLATE_FROM_FILE ? "a file" : v);
        return -1;
    }
    if (*from != SM_TEMPLATE_FROM_FILE && no_model) {
        snprintf(msg, cap, "--template-from %s builds the model each round: no --no-model", v);
        return -1;
    }
    return 0;
}

/* --template-from, --rounds and --template-tolerance into b->from: a
 * FILE is the template itself; medoid and mean start from --template. */
static int resolve_template_from(batch_args *b)
{
    char m[ARGS_MSG_LEN];
    return batch_resolve_template_from(b->template_from, &b->template_path, b->rounds,
                                       b->tolerance, b->no_model, &b->from, m, sizeof m)
               ? fail("%s", m)
               : 0;
}

/* The batch's own options; the rest are kept for run's parser. */
static int parse(int argc, char **argv, batch_args *b)
{
    static const char *const with_value[] = {
        "--target-surface", "--target-mesh", "--target-sol", "--targets", "--template",
        "--template-landmarks", "--model-align", "--model-modes", "--jobs", "--model-from", "-o",
        "--output", "--target-image", "--template-from", "--rounds", "--template-tolerance"};
    const size_t nwith = sizeof with_value / sizeof *with_value;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (strcmp(a, "-h") == 0 || strcmp(a, "--help") == 0)
            return -1;
        if (!strcmp(a, "--no-model") || !strcmp(a, "-q") || !strcmp(a, "--quiet")) {
            *(a[2] == 'n' ? &b->no_model : &b->quiet) = 1;
            continue;
        }
        size_t k = 0;
        while (k < nwith && strcmp(a, with_value[k]) != 0)
            k++;
        if (k == nwith) {
            b->rest[b->nrest++] = argv[i];
            continue;
        }
        if (!v)
            return fail("option '%s' needs a value", a);
        i++;
        int code = take_option(b, k, v);
        if (code)
            return code;
        /* --target-surface *.stl: the shell's list, one target each (the
         * batch has no positional argument of its own) */
        while ((k == 0 || k == 12) && i + 1 < argc && argv[i + 1][0] != '-')
            if ((code = take_option(b, k, argv[++i])) != 0)
                return code;
    }
    if (b->model_from)
        return b->nrest || b->list.n || b->template_path || b->outdir
                   ? fail("%s", "--model-from takes the model's options only") : 0;
    if (b->pending_mesh)
        return fail("--target-mesh %s has no --target-sol", b->pending_mesh);
    int code = resolve_template_from(b);
    if (code)
        return code;
    if (!b->template_path)
        return fail("%s", "--template is required");
    if (!b->outdir)
        return fail("%s", "-o DIR is required");
    if (b->list.n == 0)
        return fail("%s", "no target (--target-surface, --target-image, --target-mesh/--target-sol, "
                          "--targets)");
    return 0;
}

static void on_target_done(size_t index, const char *name, const char *status, int exit_code,
                           double seconds, void *user)
{
    const batch_args *b = user;
    if (!b->quiet || exit_code != 0)
        fprintf(stderr, "shapematch batch: target %zu/%zu %s: %s (exit %d) in %.2f s\n",
                index + 1, b->list.n, name, status, exit_code, seconds);
}

/* How the rounds ended: why they stopped early (always), which template
 * they chose (unless quiet). */
static void report_rounds(const batch_args *b, const sm_rounds_outcome *ends)
{
    if (ends->message[0])
        fprintf(stderr, "shapematch batch: %s\n", ends->message);
    if (b->from != SM_TEMPLATE_FROM_FILE && !b->quiet)
        fprintf(stderr, "shapematch batch: template from the %s: %d round%s (%s%s%s); the last "
                "round's template in %s/template.mesh\n", sm_template_from_name(b->from),
                ends->rounds, ends->rounds == 1 ? "" : "s", ends->stop,
                ends->medoid[0] ? ": " : "", ends->medoid, b->outdir);
}

static void on_round_done(int round, const char *template_path, double movement,
                          const char *next_template, void *user)
{
    const batch_args *b = user;
    if (b->quiet)
        return;
    fprintf(stderr, "shapematch batch: round %d on %s done", round, template_path);
    if (movement == movement) /* not NAN */
        fprintf(stderr, "; the mean moved by %.3g of its size", movement);
    if (next_template)
        fprintf(stderr, "; next template %s", next_template);
    fputc('\n', stderr);
}

/* run's parser over the shared options, with the first target, so that
 * the parameters and their combinations are checked as run checks them. */
static int parse_run_options(batch_args *b, run_options *ro)
{
    char **av = calloc((size_t)b->nrest + 12, sizeof *av);
    if (!av)
        return fail("%s", "out of memory");
    int n = 0;
    const sm_batch_target *t = &b->list.t[0];
    av[n++] = "batch"; /* the command its messages name */
    for (int i = 0; i < b->nrest; i++)
        av[n++] = b->rest[i];
    av[n++] = "--template";
    av[n++] = (char *)b->template_path;
    if (t->target_surface)
        av[n++] = "--target-surface", av[n++] = t->target_surface;
    if (t->target_image)
        av[n++] = "--target-image", av[n++] = t->target_image;
    if (t->target_mesh)
        av[n++] = "--target-mesh", av[n++] = t->target_mesh;
    if (t->target_sol)
        av[n++] = "--target-sol", av[n++] = t->target_sol;
    av[n++] = "-o";
    av[n++] = (char *)b->outdir;
    char msg[ARGS_MSG_LEN];
    args_result r = args_parse_run(n, av, ro, msg, sizeof msg);
    free(av);
    if (r != ARGS_OK)
        return fail("%s", r == ARGS_HELP ? "unexpected --help" : msg);
    return 0;
}

/* --server (before a "--"): the daemon runs the batch (cmd_batch_remote.c);
 * $SHAPEMATCH_SERVER alone does not make a local batch remote. */
static int wants_server(int argc, char **argv)
{
    for (int i = 1; i < argc && strcmp(argv[i], "--") != 0; i++)
        if (strcmp(argv[i], "--server") == 0 || strncmp(argv[i], "--server=", 9) == 0)
            return 1;
    return 0;
}

int cmd_batch(int argc, char **argv)
{
    if (wants_server(argc, argv))
        return cmd_batch_remote(argc, argv);
    batch_args b;
    memset(&b, 0, sizeof b);
    b.rest = calloc((size_t)argc + 1, sizeof *b.rest);
    long cpus = sysconf(_SC_NPROCESSORS_ONLN);
    b.jobs = 0;
    int code = b.rest ? parse(argc, argv, &b) : CLI_EXIT_NUMERIC;
    run_options ro;
    sm_error err;
    sm_error_clear(&err);
    sm_shape_align align = SM_SHAPE_ALIGN_RIGID;
    if (code == -1) {
        cmd_batch_help();
        code = CLI_EXIT_OK;
        goto done;
    }
    if (code == 0 && b.model_align && sm_shape_align_parse(b.model_align, &align) != 0)
        code = fail("--model-align: '%s' is not none, rigid or similarity", b.model_align);
    if (code == 0 && b.model_from) {
        sm_model_opts mo = {.align = align, .max_modes = b.model_modes};
        size_t used = 0;
        if (sm_job_batch_remodel(b.model_from, &mo, &used, &err) != SM_OK ||
            sm_job_rounds_keep_template_from(b.model_from, 0, &err) != SM_OK) {
            fprintf(stderr, "shapematch batch: error: %s\n", err.msg);
            code = CLI_EXIT_INPUT;
        } else if (!b.quiet) {
            fprintf(stderr, "shapematch batch: model of %zu targets in %s/model\n", used,
                    b.model_from);
        }
        goto done;
    }
    if (code == 0 && sm_batch_list_finish(&b.list, &err) != SM_OK)
        code = fail("%s", err.msg);
    if (code == 0)
        code = parse_run_options(&b, &ro);
    if (code != 0)
        goto done;
    char msg[ARGS_MSG_LEN];
    /* physical names (--clamp-elements core): the template has them */
    if ((code = job_options_resolve_names_at(&ro.job, b.template_path, msg, sizeof msg)) != 0) {
        fprintf(stderr, "shapematch batch: %s\n", msg);
        goto done;
    }
    if (ro.landmarks) {
        code = fail("%s", "--landmarks: a batch takes --template-landmarks T.csv and each "
                          "target's landmarks from the LIST.csv column 'landmarks'");
        goto done;
    }
    if (fs_output_dir(b.outdir, msg, sizeof msg) != 0) {
        fprintf(stderr, "shapematch batch: output directory: %s\n", msg);
        code = CLI_EXIT_OUTPUT;
        goto done;
    }
    sm_batch_opts o = {
        .template_mesh = b.template_path, .template_landmarks = b.template_landmarks,
        .background_size = ro.job.background.size,
        .background_padding = ro.job.background.padding, .params = &ro.job.params,
        .outputs = ro.outputs, .jobs = b.jobs ? b.jobs : (int)(cpus > 1 ? cpus : 1),
        .build_model = !b.no_model,
        .model = {.align = align, .max_modes = b.model_modes},
        .cancel = (const volatile int *)&batch_cancel, .target_done = on_target_done,
        .user = &b};
    if ((size_t)o.jobs > b.list.n)
        o.jobs = (int)b.list.n;
    sm_batch_outcome out;
    install_cancel_handlers();
    sm_rounds_opts r = {.from = b.from, .rounds = b.rounds, .tolerance = b.tolerance,
                        .round_done = on_round_done};
    sm_rounds_outcome ends;
    sm_status st = b.template_from
                       ? sm_job_batch_rounds(&b.list, &o, &r, b.outdir, &out, &ends, &err)
                       : sm_job_batch_run(&b.list, &o, b.outdir, &out, &err);
    if (st != SM_OK) {
        fprintf(stderr, "shapematch batch: error: %s\n", err.msg);
        code = st == SM_ERR_IO ? CLI_EXIT_OUTPUT : CLI_EXIT_INPUT;
        goto done;
    }
    if (out.model_error[0])
        fprintf(stderr, "shapematch batch: model: %s\n", out.model_error);
    if (b.template_from)
        report_rounds(&b, &ends);
    if (!b.quiet || out.nfailed)
        fprintf(stderr, "shapematch batch: %zu of %zu targets matched%s in %.2f s (template "
                        "set up once in %.2f s); summary in %s/summary.json\n",
                out.nok, b.list.n, out.model_built ? ", model built" : "", out.total_seconds,
                out.template_seconds, b.outdir);
    code = out.cancelled ? CLI_EXIT_CANCELLED
           : out.nfailed || (o.build_model && !out.model_built) ? CLI_EXIT_BATCH_PARTIAL
                                                                  : CLI_EXIT_OK;
done:
    sm_batch_list_free(&b.list);
    free(b.rest);
    return code;
}
