/* Progress display (see progress.h). */
#include "progress.h"

#include <stdarg.h>
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
}

void progress_format(char *buf, size_t cap, const sm_progress *p)
{
    snprintf(buf, cap, "iter %d  J %.6e  boundary %.3e  step %.3e  qmin %.3f  %.1fs",
             p->iteration, p->J, p->boundary_l2, p->step, p->min_quality, p->elapsed);
}

static void draw(progress_display *d, const sm_progress *p)
{
    char line[256];
    progress_format(line, sizeof line, p);
    if (d->mode == PROGRESS_TTY) {
        /* carriage return, the line, then erase what a longer previous
         * line left to the right */
        fprintf(d->out, "\r%s\033[K", line);
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
