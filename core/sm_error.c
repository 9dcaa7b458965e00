#include "shapematch/sm_error.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

sm_status sm_error_set(sm_error *err, sm_status code, const char *fmt, ...)
{
    if (err) {
        va_list ap;
        va_start(ap, fmt);
        err->code = code;
        vsnprintf(err->msg, sizeof err->msg, fmt, ap);
        va_end(ap);
    }
    return code;
}

void sm_error_prefix(sm_error *err, const char *fmt, ...)
{
    if (!err)
        return;
    char prefix[SM_ERROR_MSG_LEN];
    char old[SM_ERROR_MSG_LEN];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(prefix, sizeof prefix, fmt, ap);
    va_end(ap);
    memcpy(old, err->msg, sizeof old);
    /* Build piecewise: truncation of an over-long message is acceptable. */
    size_t n = strnlen(prefix, sizeof err->msg - 1);
    memcpy(err->msg, prefix, n);
    if (n + 2 < sizeof err->msg) {
        err->msg[n++] = ':';
        err->msg[n++] = ' ';
    }
    size_t rest = strnlen(old, sizeof old);
    if (rest > sizeof err->msg - 1 - n)
        rest = sizeof err->msg - 1 - n;
    memcpy(err->msg + n, old, rest);
    err->msg[n + rest] = '\0';
}

void sm_error_clear(sm_error *err)
{
    if (err) {
        err->code = SM_OK;
        err->msg[0] = '\0';
    }
}

const char *sm_status_name(sm_status code)
{
    switch (code) {
    case SM_OK: return "ok";
    case SM_ERR_IO: return "io";
    case SM_ERR_FORMAT: return "format";
    case SM_ERR_INVALID: return "invalid";
    case SM_ERR_NOMEM: return "nomem";
    case SM_ERR_NUMERIC: return "numeric";
    }
    return "unknown";
}

const char *sm_number_text(char buf[SM_NUMBER_TEXT_LEN], double x)
{
    if (x == floor(x) && fabs(x) < 1e15) {
        snprintf(buf, SM_NUMBER_TEXT_LEN, "%.0f", x == 0 ? 0.0 : x); /* -0 as 0 */
        return buf;
    }
    for (int digits = 1; digits <= 17; digits++) {
        snprintf(buf, SM_NUMBER_TEXT_LEN, "%.*g", digits, x);
        if (!isfinite(x) || strtod(buf, NULL) == x)
            break;
    }
    return buf;
}
