/* JSON-lines logger (see smd_log.h). */
#include "base/smd_log.h"

#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "sm_proto_events.h"
#include "sm_proto_text.h"

static const char *const level_names[] = {"debug", "info", "warn", "error"};

int smd_log_level_from_name(const char *name)
{
    for (int i = 0; i < 4; i++)
        if (name && strcmp(name, level_names[i]) == 0)
            return i;
    return -1;
}

const char *smd_log_level_name(smd_log_level level)
{
    return (level >= SMD_LOG_DEBUG && level <= SMD_LOG_ERROR) ? level_names[level] : "?";
}

int smd_log_enabled(const smd_logger *log, smd_log_level level)
{
    return log && level >= log->level;
}

void smd_log(const smd_logger *log, smd_log_level level, const char *event,
             json_t *fields)
{
    if (!smd_log_enabled(log, level)) {
        json_decref(fields);
        return;
    }
    char ts[SM_RFC3339_LEN];
    if (sm_time_format_rfc3339(sm_time_now(), ts) != 0)
        strcpy(ts, "1970-01-01T00:00:00.000Z");
    json_t *line = json_object();
    if (!line) {
        json_decref(fields);
        return;
    }
    json_object_set_new(line, "ts", json_string(ts));
    json_object_set_new(line, "level", json_string(smd_log_level_name(level)));
    json_object_set_new(line, "event", json_string(event));
    if (fields) {
        const char *key;
        json_t *value;
        json_object_foreach(fields, key, value) {
            if (strcmp(key, "ts") && strcmp(key, "level") && strcmp(key, "event"))
                json_object_set(line, key, value);
        }
        json_decref(fields);
    }
    char *text = json_dumps(line, JSON_COMPACT | JSON_PRESERVE_ORDER | JSON_ENSURE_ASCII | JSON_REAL_PRECISION(6));
    json_decref(line);
    if (!text)
        return;
    size_t len = strlen(text);
    text[len] = '\n'; /* json_dumps' NUL becomes the newline */
    const char *p = text;
    size_t left = len + 1;
    while (left > 0) {
        ssize_t n = write(log->fd, p, left);
        if (n < 0 && errno == EINTR)
            continue;
        if (n <= 0)
            break; /* nowhere to report a failing log */
        p += n;
        left -= (size_t)n;
    }
    free(text);
}

void smd_logf(const smd_logger *log, smd_log_level level, const char *event,
              const char *fmt, ...)
{
    if (!smd_log_enabled(log, level))
        return;
    char msg[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    /* messages may quote file names or client input: keep the line
     * valid JSON whatever bytes they hold */
    sm_text_make_printable(msg, NULL);
    smd_log(log, level, event, json_pack("{s:s}", "msg", msg));
}
