/* Error reporting for libshapematch: every fallible function returns an
 * sm_status and, when given a non-NULL sm_error, fills a human-readable
 * message.  No function in core/ calls exit() or abort(). */
#ifndef SM_ERROR_H
#define SM_ERROR_H

#include <stddef.h>

typedef enum sm_status {
    SM_OK = 0,
    SM_ERR_IO = 1,        /* cannot open/read/write a file */
    SM_ERR_FORMAT = 2,    /* malformed input file */
    SM_ERR_INVALID = 3,   /* inconsistent inputs or parameters */
    SM_ERR_NOMEM = 4,     /* allocation failed or size limit exceeded */
    SM_ERR_NUMERIC = 5    /* factorization failed, mesh inverted, ... */
    /* no "cancelled" status: a cancelled descent is a normal end
     * (SM_OK, stop reason SM_STOP_CANCELLED) and keeps its result */
} sm_status;

#define SM_ERROR_MSG_LEN 512

typedef struct sm_error {
    sm_status code;
    char msg[SM_ERROR_MSG_LEN];
} sm_error;

/* Sets err (if non-NULL) and returns code, so callers can write
 * `return sm_error_set(err, SM_ERR_FORMAT, "...", ...);`. */
sm_status sm_error_set(sm_error *err, sm_status code, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

/* Prefixes the existing message with "prefix: " (e.g. a file name). */
void sm_error_prefix(sm_error *err, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));

void sm_error_clear(sm_error *err);

/* A number for a message: the shortest text that reads back as x ("0.7",
 * not %.17g's "0.69999999999999996"), whole numbers in full ("1000000000",
 * not "1e+09"), "inf", "-inf", "nan".  Fills buf and returns it, so that it
 * can be an argument: sm_error_set(err, ..., "got %s", sm_number_text(b, x)). */
#define SM_NUMBER_TEXT_LEN 32
const char *sm_number_text(char buf[SM_NUMBER_TEXT_LEN], double x);

/* Short stable name of a status, e.g. "format". */
const char *sm_status_name(sm_status code);

#endif
