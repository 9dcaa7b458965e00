/* Progress display (see progress.h). */
#include "progress.h"

#include <math.h>
#include <stdarg.h>
#include <string.h>
#include <unistd.h>

/* A redraw costs a write(2) on the terminal: at most ~10 a second is
 * plenty for a human and keeps fast runs from being terminal-bound. */
#define TTY_REDRAW_SECONDS 0.1

void progress_init(progress_display *d, FILE *out, int quiet)
{
    d->out = out;
    d->mode = quiet ? PROGRESS_QUIET : isatty(fileno(out)) ? PROGRESS_TTY : PROGRESS_LINES;
    d->last_draw = 0.0;
    d->line_open = 0;
    d->last_printed = -1;
    d->have_last = 0;
    d->max_iter = 0;
    d->tol_l2 = 0.0;
    d->have_first = 0;
    d->done = 0;
}

void progress_set_goal(progress_display *d, int max_iter, double tol_l2)
{
    d->max_iter = max_iter > 0 ? max_iter : 0;
    d->tol_l2 = tol_l2 > 0 ? tol_l2 : 0.0;
}

/* Fraction of the goal reached in [0, 1], -1 without a goal; *eta gets
 * the estimated seconds left (-1 unknown). */
static double progress_fraction(const progress_display *d, const sm_progress *p, double *eta)
{
    double f = -1.0;
    if (d->done && (d->max_iter > 0 || d->tol_l2 > 0)) {
        *eta = 0.0; /* whatever the stop reason, the run is over */
        return 1.0;
    }
    if (d->max_iter > 0)
        f = (double)p->iteration / d->max_iter;
    if (d->tol_l2 > 0 && d->have_first && d->first_l2 > d->tol_l2 && p->boundary_l2 > 0) {
        double g = log(d->first_l2 / p->boundary_l2) / log(d->first_l2 / d->tol_l2);
        if (g > f)
            f = g;
    }
    if (f > 1.0)
        f = 1.0;
    if (f < 0.0 && f != -1.0)
        f = 0.0;
    *eta = -1.0;
    double spent = p->elapsed - (d->have_first ? d->first_elapsed : 0.0);
    if (f > 0.0 && spent > 0)
        *eta = spent * (1.0 - f) / f; /* the rate so far, toward the goal */
    return f;
}

/* "[#####.....]  42%  12.3 it/s  ETA 31s  " or "12.3 it/s  " without a goal */
static void format_bar(const progress_display *d, const sm_progress *p, char *buf, size_t cap)
{
    double eta, f = progress_fraction(d, p, &eta);
    double spent = p->elapsed - d->first_elapsed;
    int its = p->iteration - d->first_iter;
    char rate[32] = "";
    if (spent > 0 && its > 0)
        snprintf(rate, sizeof rate, "%.1f it/s  ", its / spent);
    if (f < 0) {
        snprintf(buf, cap, "%s", rate);
        return;
    }
    char bar[24];
    int width = 20, full = (int)(f * width + 0.5);
    for (int i = 0; i < width; i++)
        bar[i] = i < full ? '#' : '.';
    bar[width] = '\0';
    char left[32] = "";
    if (eta >= 0)
        snprintf(left, sizeof left, "ETA %.0fs  ", eta);
    snprintf(buf, cap, "[%s] %3.0f%%  %s%s", bar, 100 * f, rate, left);
}

/* One-line description of a progress state. */
static void progress_format(char *buf, size_t cap, const sm_progress *p)
{
    /* the unit-free figure and its length first; the L2 norm (which
     * scales with the unit) is in history.csv and summary.json */
    snprintf(buf, cap, "iter %d  rms %.3e  relative %.2e  J %.6e  step %.3e  qmin %.3f  %.1fs",
             p->iteration, p->boundary_rms, p->boundary_relative, p->J, p->step, p->min_quality,
             p->elapsed);
}

static void draw(progress_display *d, const sm_progress *p)
{
    char line[256];
    progress_format(line, sizeof line, p);
    if (d->mode == PROGRESS_TTY) {
        char bar[96];
        format_bar(d, p, bar, sizeof bar);
        /* carriage return, the line, then erase what a longer previous
         * line left to the right */
        fprintf(d->out, "\r%s%s\033[K", bar, line);
        d->line_open = 1;
        d->last_draw = p->elapsed;
    } else {
        fprintf(d->out, "%s\n", line);
    }
    fflush(d->out);
    d->last_printed = p->iteration;
}

void progress_update(progress_display *d, const sm_progress *p)
{
    d->last = *p;
    d->have_last = 1;
    if (!d->have_first) {
        d->have_first = 1;
        d->first_iter = p->iteration;
        d->first_elapsed = p->elapsed;
        d->first_l2 = p->boundary_l2;
    }
    switch (d->mode) {
    case PROGRESS_QUIET:
        break;
    case PROGRESS_TTY:
        if (d->last_printed < 0 || p->elapsed - d->last_draw >= TTY_REDRAW_SECONDS)
            draw(d, p);
        break;
    case PROGRESS_LINES:
        if (p->iteration % PROGRESS_LINE_EVERY == 0 && p->iteration != d->last_printed)
            draw(d, p);
        break;
    }
}

void progress_finish(progress_display *d)
{
    if (d->mode == PROGRESS_QUIET || !d->have_last)
        return;
    d->done = 1;
    if (d->mode == PROGRESS_TTY || d->last.iteration != d->last_printed)
        draw(d, &d->last);
    if (d->line_open) {
        fputc('\n', d->out);
        d->line_open = 0;
        fflush(d->out);
    }
}

void progress_message(progress_display *d, const char *fmt, ...)
{
    if (d->line_open) {
        fputc('\n', d->out);
        d->line_open = 0;
    }
    va_list ap;
    va_start(ap, fmt);
    vfprintf(d->out, fmt, ap);
    va_end(ap);
    fputc('\n', d->out);
    fflush(d->out);
}
