/* Structured logs: one JSON object per line on a file descriptor
 * (stderr for the daemon), e.g.
 *   {"ts":"2024-05-01T12:00:00.123Z","level":"info","event":"request",
 *    "method":"GET","path":"/v1/jobs","status":200,"ms":0.21}
 * Each line goes out in a single write(2), so lines from several threads
 * never interleave. */
#ifndef SMD_LOG_H
#define SMD_LOG_H

#include <jansson.h>

typedef enum smd_log_level {
    SMD_LOG_DEBUG = 0,
    SMD_LOG_INFO = 1,
    SMD_LOG_WARN = 2,
    SMD_LOG_ERROR = 3
} smd_log_level;

typedef struct smd_logger {
    int fd;              /* where lines go */
    smd_log_level level; /* lines below it are dropped */
} smd_logger;

/* "debug", "info", "warn", "error" -> level; -1 when unknown. */
int smd_log_level_from_name(const char *name);
const char *smd_log_level_name(smd_log_level level);

/* 1 when a line of this level would be written (to skip building it). */
int smd_log_enabled(const smd_logger *log, smd_log_level level);

/* Writes {"ts","level","event", ...fields}.  fields (may be NULL) is an
 * object whose members are appended; its reference is stolen. */
void smd_log(const smd_logger *log, smd_log_level level, const char *event,
             json_t *fields);

/* Convenience: {"ts","level","event","msg": formatted text}. */
void smd_logf(const smd_logger *log, smd_log_level level, const char *event,
              const char *fmt, ...) __attribute__((format(printf, 4, 5)));

#endif
