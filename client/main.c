/* shapematch: command-line client.  Dispatches to a subcommand
 * (`shapematch COMMAND [options]`); each command parses its own options.
 * `run` works locally; the other commands talk to a shapematchd daemon
 * over HTTP (remote.h).  Exit codes: see cli.h (and `shapematch --help`). */
#include <stdio.h>
#include <string.h>

#include "cli.h"

/* Each code's line(s), shared by the help pages (run and sdf list their
 * own codes only). */
#define EXIT_0 "  0  finished and converged (summary.json \"converged\": true)\n"
#define EXIT_1 "  1  usage error (unknown option, missing or malformed argument)\n"
#define EXIT_2 "  2  bad input file (unreadable, malformed, dimension or size mismatch)\n"
#define EXIT_3 "  3  numerical failure (factorization failed, no valid step at the start)\n"
#define EXIT_4 "  4  cannot write the outputs\n"
#define EXIT_5 "  5  cancelled (Ctrl-C / SIGTERM); outputs of the state reached are written\n"
#define EXIT_5_DAEMON "     daemon commands: the job was cancelled (dismissed) on the daemon\n"
#define EXIT_6_9                                                                          \
    "  6  cannot connect to the daemon, or the connection was lost\n"                     \
    "  7  the daemon refused the request (HTTP 4xx, its detail is printed): 401 no or\n"  \
    "     wrong token, 404 unknown job or no results yet, 422 invalid job\n"              \
    "  8  the job failed on the daemon (the reason is printed)\n"                         \
    "  9  daemon error (HTTP 5xx) or a response the client cannot understand\n"
#define EXIT_10                                                                           \
    "  10 run, watch, submit --wait: finished but not converged (quality_blocked, the\n"  \
    "     result->target RMS ends above half the background's element size, or the\n"    \
    "     target is not covered: a side's p99 above twice it, or a handle or piece the\n" \
    "     template cannot have; warning target-not-reached); every output is written\n"  \
    "     (a daemon's job is successful with \"converged\": false)\n"

/* From the top of the source tree; tests/cli/help.sh runs the local ones
 * as written, docs/man/man.sh makes them the pages' EXAMPLES. */
static const char cli_examples_help[] =
    "Examples:\n"
    "  # the bundled 2D case: a disk matched onto a star, the results in out-2d/\n"
    "  shapematch run --template examples/2d/template.mesh \\\n"
    "      --target-mesh examples/2d/background.mesh.gz \\\n"
    "      --target-sol examples/2d/background.sol.gz --clamp-ball 0.5,0.5,0.04 -o out-2d\n"
    "  # points of the template carried onto the target by that result's map\n"
    "  printf '0.5,0.3\\n0.4,0.5\\n' >points.csv\n"
    "  shapematch warp --result out-2d --points points.csv -o moved.csv\n"
    "  # the signed distance to a surface, at the vertices of a background mesh\n"
    "  shapematch sdf --surface out-2d/result.mesh --background examples/2d/background.mesh.gz \\\n"
    "      -o distance.sol\n"
    "  # the same match on a daemon, named, followed to its end, results in out-d/\n"
    "  shapematch submit --server http://127.0.0.1:8080 --name star \\\n"
    "      --template examples/2d/template.mesh \\\n"
    "      --target-mesh examples/2d/background.mesh.gz \\\n"
    "      --target-sol examples/2d/background.sol.gz --clamp-ball 0.5,0.5,0.04 \\\n"
    "      --wait -o out-d\n"
    "  shapematch list --server http://127.0.0.1:8080\n";

const char cli_exit_codes_help[] =
    "Exit codes:\n" EXIT_0 EXIT_1 EXIT_2 EXIT_3 EXIT_4 EXIT_5 EXIT_5_DAEMON EXIT_6_9 EXIT_10;
#define EXIT_10_RUN                                                                    \
    "  10 finished but not converged (quality_blocked, the result->target RMS ends\n"  \
    "     above half the background's element size, or the target is not covered: a\n"  \
    "     side's p99 above twice it, or a handle or piece the template cannot have;\n"   \
    "     warning target-not-reached); every output is written\n"
const char cli_exit_codes_run_help[] =
    "Exit codes:\n" EXIT_0 EXIT_1 EXIT_2 EXIT_3 EXIT_4 EXIT_5 EXIT_10_RUN;
const char cli_exit_codes_sdf_help[] =
    "Exit codes:\n  0  the distance is written\n" EXIT_1 EXIT_2 EXIT_4;

typedef struct command {
    const char *name;
    cli_command_fn run;
    void (*help)(void);
    const char *summary;
} command;

static const command commands[] = {
    {"run", cmd_run, cmd_run_help, "run a matching job locally (no daemon)"},
    {"batch", cmd_batch, cmd_batch_help,
     "one template onto many targets locally, then their shape model"},
    {"sdf", cmd_sdf, cmd_sdf_help, "signed distance to a surface (STL, OBJ, ...) on a mesh"},
    {"submit", cmd_submit, cmd_submit_help,
     "send a job to the daemon (--wait: and follow it, fetch its results)"},
    {"watch", cmd_watch, cmd_watch_help, "follow a job's progress to its end"},
    {"fetch", cmd_fetch, cmd_fetch_help, "download a finished job's results"},
    {"status", cmd_status, cmd_status_help, "show a job's state"},
    {"list", cmd_list, cmd_list_help, "list the daemon's jobs"},
    {"cancel", cmd_cancel, cmd_cancel_help, "cancel a job (or delete a finished one)"},
    {"warp", cmd_warp, cmd_warp_help,
     "carry points, a mesh or a field through a result's map (forward or inverse)"},
};
#define N_COMMANDS (sizeof commands / sizeof commands[0])

static const command *find_command(const char *name)
{
    for (size_t i = 0; i < N_COMMANDS; i++)
        if (strcmp(commands[i].name, name) == 0)
            return &commands[i];
    return NULL;
}

static void usage(FILE *out)
{
    fprintf(out,
            "Usage: shapematch COMMAND [OPTIONS]\n"
            "       shapematch --help | --version\n"
            "\n"
            "Elastic shape matching: deforms a template mesh onto a target shape given by\n"
            "its signed distance function (de Buhan, Dapogny, Frey, Nardoni 2016).\n"
            "\n"
            "Commands:\n");
    for (size_t i = 0; i < N_COMMANDS; i++)
        fprintf(out, "  %-10s %s\n", commands[i].name, commands[i].summary);
    fprintf(out,
            "  %-10s %s\n"
            "\n"
            "Run 'shapematch COMMAND --help' for the options of a command.\n"
            "\n"
            "The daemon commands reach shapematchd at --server URL (default: the\n"
            "environment variable SHAPEMATCH_SERVER, else http://127.0.0.1:8080) and send\n"
            "--token T (default: SHAPEMATCH_TOKEN) as 'Authorization: Bearer T'.\n"
            "\n%s\n%s",
            "help", "show this help, or a command's help ('shapematch help run')",
            cli_exit_codes_help, cli_examples_help);
}

int main(int argc, char **argv)
{
    if (argc < 2) {
        usage(stderr);
        return CLI_EXIT_USAGE;
    }
    const char *name = argv[1];
    if (strcmp(name, "--help") == 0 || strcmp(name, "-h") == 0 || strcmp(name, "help") == 0) {
        if (argc > 2 && strcmp(name, "help") == 0) {
            const command *c = find_command(argv[2]);
            if (!c) {
                fprintf(stderr, "shapematch: unknown command '%s'\n", argv[2]);
                return CLI_EXIT_USAGE;
            }
            c->help();
            return CLI_EXIT_OK;
        }
        usage(stdout);
        return CLI_EXIT_OK;
    }
    if (strcmp(name, "--version") == 0 || strcmp(name, "-V") == 0 ||
        strcmp(name, "version") == 0) {
        printf("shapematch %s\n", SM_VERSION);
        return CLI_EXIT_OK;
    }
    const command *c = find_command(name);
    if (!c) {
        fprintf(stderr, "shapematch: %s '%s'\nTry 'shapematch --help' for more information.\n",
                name[0] == '-' ? "unknown option" : "unknown command", name);
        return CLI_EXIT_USAGE;
    }
    /* the command sees argv[0] = its own name */
    return c->run(argc - 1, argv + 1);
}
