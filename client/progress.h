/* Progress display on a terminal stream (stderr):
 *   - a TTY gets one line updated in place ("\r"), redrawn at most ~10
 *     times a second, ended by a newline when the run finishes;
 *   - anything else (a log file, a pipe, CI) gets one plain line every
 *     PROGRESS_LINE_EVERY iterations plus the final state;
 *   - quiet prints nothing.
 * Shared by the commands that show a run's progress (run; watch later). */
#ifndef CLI_PROGRESS_H
#define CLI_PROGRESS_H

#include <stdio.h>

#include "shapematch/sm_match.h"

#define PROGRESS_LINE_EVERY 10

typedef enum progress_mode {
    PROGRESS_QUIET,
    PROGRESS_TTY,
    PROGRESS_LINES
} progress_mode;

typedef struct progress_display {
    FILE *out;
    progress_mode mode;
    double last_draw;       /* TTY: elapsed time of the last redraw */
    int line_open;          /* TTY: an unterminated line is on screen */
    int last_printed;       /* iteration of the last line shown, -1 none */
    sm_progress last;       /* latest state received */
    int have_last;
} progress_display;

/* Chooses the mode from quiet and isatty(fileno(out)). */
void progress_init(progress_display *d, FILE *out, int quiet);
void progress_update(progress_display *d, const sm_progress *p);
/* Shows the final state (if not shown yet) and ends the TTY line. */
void progress_finish(progress_display *d);
/* Prints a message line without garbling an open TTY line (shown even
 * when quiet: used for warnings). */
void progress_message(progress_display *d, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));

/* One-line description of a progress state. */
void progress_format(char *buf, size_t cap, const sm_progress *p);

#endif
