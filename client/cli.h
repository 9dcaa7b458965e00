/* Shared declarations of the shapematch command-line client: exit codes
 * and the subcommand entry points dispatched by main.c.
 *
 * Exit codes (also printed by `shapematch --help`; scripts rely on them,
 * so they never change meaning):
 *   0  the run finished normally: converged (step tolerance or boundary
 *      tolerance reached) or stopped at the iteration cap
 *   1  usage error (unknown option, missing or malformed argument, ...)
 *   2  bad input file (cannot read, parse error, dimension mismatch,
 *      sizes that do not agree)
 *   3  numerical failure (factorization failed, no valid step at the
 *      start, out of memory during the run)
 *   4  cannot write the outputs
 *   5  cancelled (SIGINT/SIGTERM); the outputs of the state reached are
 *      still written
 */
#ifndef CLI_H
#define CLI_H

enum cli_exit_code {
    CLI_EXIT_OK = 0,
    CLI_EXIT_USAGE = 1,
    CLI_EXIT_INPUT = 2,
    CLI_EXIT_NUMERIC = 3,
    CLI_EXIT_OUTPUT = 4,
    CLI_EXIT_CANCELLED = 5
};

#ifndef SM_VERSION
#define SM_VERSION "unknown"
#endif

/* The text block describing the exit codes, shared by the help pages. */
extern const char cli_exit_codes_help[];

/* A subcommand: argv[0] is the command name, options follow.  Returns
 * the process exit code. */
typedef int (*cli_command_fn)(int argc, char **argv);

int cmd_run(int argc, char **argv);
/* Writes the help page of `shapematch run` to stdout. */
void cmd_run_help(void);

#endif
