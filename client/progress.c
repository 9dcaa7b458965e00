/* Progress display (see progress.h). */
#include "progress.h"

#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
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

/* The terminal's width in columns: the stream's own (TIOCGWINSZ), else
 * $COLUMNS, else 80. */
static int terminal_columns(FILE *out)
{
    struct winsize ws;
    if (ioctl(fileno(out), TIOCGWINSZ, &ws) == 0 && ws.ws_col > 0)
        return ws.ws_col;
    const char *env = getenv("COLUMNS");
    char *end;
    long n = env ? strtol(env, &end, 10) : 0;
    if (env && *end == '\0' && n > 0 && n < 10000)
        return (int)n;
    return 80;
}

/* One field of the line: its text and how much it matters (0 first).  A
 * terminal line shows the fields that fit by that order, in line order. */
#define SEG_LEN 48
#define MAX_SEGS 16
typedef struct segment {
    char text[SEG_LEN];
    int rank;
} segment;

typedef struct segments {
    segment s[MAX_SEGS];
    int n;
} segments;

static void seg_add(segments *l, int rank, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
static void seg_add(segments *l, int rank, const char *fmt, ...)
{
    if (l->n == MAX_SEGS)
        return;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(l->s[l->n].text, SEG_LEN, fmt, ap);
    va_end(ap);
    l->s[l->n++].rank = rank;
}

int progress_has_distance(const sm_distance *d)
{
    return d->method != SM_DISTANCE_NONE && isfinite(d->result_to_target.rms) &&
           isfinite(d->target_to_result.rms);
}

void progress_format_figures(char *buf, size_t cap, const sm_distance *d, double rms,
                             double max, double l2)
{
    if (progress_has_distance(d)) {
        char p99[48] = "";
        if (isfinite(d->target_to_result.p99))
            snprintf(p99, sizeof p99, ", p99 %.3e", d->target_to_result.p99);
        snprintf(buf, cap,
                 "result->target RMS %.3e (max %.3e), target->result RMS %.3e (max %.3e%s); "
                 "L2 of d on the boundary %.3e",
                 d->result_to_target.rms, d->result_to_target.max, d->target_to_result.rms,
                 d->target_to_result.max, p99, l2);
    } else {
        snprintf(buf, cap, "boundary RMS %.3e (max %.3e); L2 of d on the boundary %.3e", rms,
                 max, l2);
    }
}

/* The fields of a state.  The figures are named as in the progress event
 * and summary.json: the two-sided distance's RMS and max (result->target,
 * target->result; lengths in the meshes' unit), or without it the RMS and
 * max of d on the boundary; the L2 norm is named L2 and, when
 * --tol-boundary is the goal, shown beside it (that is what the rule
 * compares).  tty: short forms, r->t and t->r. */
static void state_segments(const progress_display *d, const sm_progress *p, int tty,
                           segments *l)
{
    const sm_distance *dist = &p->distance;
    int two_sided = progress_has_distance(dist);
    seg_add(l, 0, "iter %d", p->iteration);
    if (two_sided) {
        seg_add(l, 0, tty ? "r->t rms %.2e" : "result->target rms %.3e",
                dist->result_to_target.rms);
        seg_add(l, 2, tty ? "max %.2e" : "max %.3e", dist->result_to_target.max);
        seg_add(l, 0, tty ? "t->r rms %.2e" : "target->result rms %.3e",
                dist->target_to_result.rms);
        seg_add(l, 2, tty ? "max %.2e" : "max %.3e", dist->target_to_result.max);
        if (!tty && isfinite(dist->target_to_result.p99))
            seg_add(l, 3, "p99 %.3e", dist->target_to_result.p99);
    } else {
        seg_add(l, 0, tty ? "rms %.2e" : "rms %.3e", p->boundary_rms);
        seg_add(l, 2, tty ? "max %.2e" : "max %.3e", p->boundary_max);
    }
    if (!tty)
        seg_add(l, 6, "relative %.2e", p->boundary_relative);
    if (d->tol_l2 > 0)
        seg_add(l, two_sided ? 2 : 1, "L2 %.2e (tol %.1e)", p->boundary_l2, d->tol_l2);
    else
        seg_add(l, 6, tty ? "L2 %.2e" : "L2 %.3e", p->boundary_l2);
    seg_add(l, 5, tty ? "J %.4e" : "J %.6e", p->J);
    seg_add(l, 5, "step %.2e", p->step);
    seg_add(l, 3, "qmin %.3f", p->min_quality);
    seg_add(l, 4, "%.1fs", p->elapsed);
}

/* Length of the fields of rank <= keep joined by two spaces. */
static int joined_length(const segments *l, int keep)
{
    int len = 0, any = 0;
    for (int i = 0; i < l->n; i++)
        if (l->s[i].rank <= keep) {
            len += (any ? 2 : 0) + (int)strlen(l->s[i].text);
            any = 1;
        }
    return len;
}

/* Joins with two spaces the fields of the largest rank that keeps the
 * line within width (every field when width <= 0; at least rank 0, cut
 * at width if even that is too long). */
static void join_fitting(const segments *l, int width, char *buf, size_t cap)
{
    int keep = 0;
    for (int i = 0; i < l->n; i++)
        if (l->s[i].rank > keep)
            keep = l->s[i].rank;
    while (width > 0 && keep > 0 && joined_length(l, keep) > width)
        keep--;
    size_t k = 0;
    buf[0] = '\0';
    for (int i = 0; i < l->n && k < cap; i++)
        if (l->s[i].rank <= keep)
            k += (size_t)snprintf(buf + k, cap - k, "%s%s", k ? "  " : "", l->s[i].text);
    if (width > 0 && strlen(buf) > (size_t)width)
        buf[width] = '\0';
}

/* The terminal line: "[#####.....]  42%  iter 12  rms ...  ETA 31s ..."
 * cut to the terminal's width (the last column left free: some
 * terminals wrap when it is written). */
static void format_tty(const progress_display *d, const sm_progress *p, char *buf, size_t cap)
{
    segments l = {.n = 0};
    int width = terminal_columns(d->out) - 1;
    double eta, f = progress_fraction(d, p, &eta);
    if (f >= 0) {
        char bar[24];
        int bar_width = width >= 120 ? 20 : 10, full = (int)(f * bar_width + 0.5);
        for (int i = 0; i < bar_width; i++)
            bar[i] = i < full ? '#' : '.';
        bar[bar_width] = '\0';
        seg_add(&l, 0, "[%s] %3.0f%%", bar, 100 * f);
    }
    segments fig = {.n = 0};
    state_segments(d, p, 1, &fig);
    for (int i = 0; i < fig.n && l.n < MAX_SEGS; i++)
        l.s[l.n++] = fig.s[i];
    double spent = p->elapsed - d->first_elapsed;
    int its = p->iteration - d->first_iter;
    if (f >= 0 && eta >= 0)
        seg_add(&l, 1, "ETA %.0fs", eta);
    if (spent > 0 && its > 0)
        seg_add(&l, 4, "%.1f it/s", its / spent);
    join_fitting(&l, width, buf, cap);
}

static void draw(progress_display *d, const sm_progress *p)
{
    char line[512];
    if (d->mode == PROGRESS_TTY) {
        format_tty(d, p, line, sizeof line);
        /* carriage return, the line, then erase what a longer previous
         * line left to the right */
        fprintf(d->out, "\r%s\033[K", line);
        d->line_open = 1;
        d->last_draw = p->elapsed;
    } else {
        segments l = {.n = 0};
        state_segments(d, p, 0, &l);
        join_fitting(&l, 0, line, sizeof line);
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
