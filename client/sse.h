/* Incremental parser of a Server-Sent Events stream (WHATWG HTML, "Server-
 * sent events", event stream interpretation), fed with whatever chunks the
 * network delivers: a line or a field may be split anywhere, lines end in
 * LF, CRLF or CR (a CRLF split between two chunks counts once), a leading
 * byte-order mark is skipped.
 *
 * Per event block it collects "event:", "data:" (several data lines are
 * joined with "\n") and "id:"; "retry:" is remembered; comments (": ...",
 * the daemon's keepalives) are counted; unknown fields are ignored.  An
 * empty line dispatches the block to the callback when it has data.
 *
 * Unlike a browser's EventSource, the event reports whether *its own*
 * block carried an id: shapematchd numbers the job's events (id = seq)
 * but sends the closing "status" event without one, and a client that
 * de-duplicates by id must not mistake it for a repeat of the previous
 * event.
 *
 * Bounded: a line longer than max_line bytes, or an event whose data grows
 * past max_line, is an error (a hostile or broken server cannot make the
 * client allocate without limit). */
#ifndef CLI_SSE_H
#define CLI_SSE_H

#include <stddef.h>

#define SSE_ID_MAX 64
#define SSE_TYPE_MAX 64

typedef struct sse_event {
    const char *type;     /* "event:" value, "message" when none was given */
    const char *id;       /* "id:" value of this block ("" when has_id is 0) */
    int has_id;
    const char *data;     /* NUL-terminated, data_len bytes */
    size_t data_len;
} sse_event;

/* Returns 0 to go on, non-zero to stop parsing (sse_feed returns -1 and
 * sets stopped). */
typedef int (*sse_event_fn)(void *user, const sse_event *ev);

typedef struct sse_parser {
    sse_event_fn on_event;
    void *user;
    size_t max_line;
    char *line;               /* current line, without its terminator */
    size_t line_len, line_cap;
    char *data;               /* data of the current block */
    size_t data_len, data_cap;
    int have_data;
    char type[SSE_TYPE_MAX + 1];
    char id[SSE_ID_MAX + 1];
    int has_id;
    int after_cr;             /* last byte was a CR: skip a following LF */
    int at_start;             /* nothing seen yet: a BOM may come */
    size_t bom_matched;       /* BOM bytes matched so far at the start */
    long retry_ms;            /* last "retry:" value, -1 none */
    unsigned long comments;   /* comment lines seen */
    unsigned long events;     /* events dispatched */
    int stopped;              /* the callback asked to stop */
    char error[128];          /* why sse_feed failed, when not stopped */
} sse_parser;

/* max_line 0 means 64 KiB. */
void sse_init(sse_parser *p, size_t max_line, sse_event_fn fn, void *user);
/* Parses n more bytes.  Returns 0, or -1: the callback stopped it
 * (p->stopped) or the stream broke a bound / memory ran out (p->error). */
int sse_feed(sse_parser *p, const char *buf, size_t n);
/* Forgets a partial line and a partial event (the connection it came on
 * ended) and expects a new stream (BOM allowed again).  Counters and
 * retry are kept. */
void sse_restart(sse_parser *p);
void sse_free(sse_parser *p);

#endif
