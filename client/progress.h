/* Progress display on a terminal stream (stderr):
 *   - a TTY gets one line updated in place ("\r"), redrawn at most ~10
 *     times a second, ended by a newline when the run finishes: with a
 *     goal (progress_set_goal) a bar toward it, the percentage, the
 *     iteration rate and an ETA, then the figures;
 *   - anything else (a log file, a pipe, CI) gets one plain line every
 *     PROGRESS_LINE_EVERY iterations plus the final state;
 *   - quiet prints nothing.
 * Shared by the commands that show a run's progress (run, watch, submit --wait). */
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
    int max_iter;           /* goal: iteration cap (0 = unknown) */
    double tol_l2;          /* goal: boundary error target (0 = none) */
    int have_first;         /* the first state seen (start of the rate) */
    int first_iter;
    double first_elapsed, first_l2;
    int done;               /* progress_finish: the bar shows 100% */
} progress_display;

/* Chooses the mode from quiet and isatty(fileno(out)). */
void progress_init(progress_display *d, FILE *out, int quiet);
/* What the bar advances toward: the boundary error tol_l2 (> 0: on a log
 * scale from the first error seen) or else the iteration cap max_iter
 * (> 0); the larger of the two fractions is shown (whichever ends the
 * run first).  Without a goal the TTY line shows the rate only. */
void progress_set_goal(progress_display *d, int max_iter, double tol_l2);
void progress_update(progress_display *d, const sm_progress *p);
/* Shows the final state (if not shown yet) and ends the TTY line. */
void progress_finish(progress_display *d);
/* 1 when d holds both sides' figures (progress events and results from
 * a daemon or library that measures them; older ones do not). */
int progress_has_distance(const sm_distance *d);
/* The headline figures of a result, by their names in summary.json:
 * "result->target RMS a (max b), target->result RMS c (max d, p99 e); L2
 * of d on the boundary f", or without the distance "boundary RMS a (max
 * b); L2 of d on the boundary f" (rms, max: boundary_rms, boundary_max). */
void progress_format_figures(char *buf, size_t cap, const sm_distance *d, double rms,
                             double max, double l2);

/* Prints a message line without garbling an open TTY line (shown even
 * when quiet: used for warnings). */
void progress_message(progress_display *d, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));

#endif
