#include "shapematch/sm_error.h"

#include <stdarg.h>
#include <stdio.h>
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
