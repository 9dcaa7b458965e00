/* Small helpers of the daemon and the worker: job ids, constant-time
 * token comparison, path building that refuses truncation, durable file
 * writes (temporary file + fsync + rename + fsync of the folder), folder
 * removal, clocks and the description of a worker's exit status.
 *
 * Nothing here keeps state; every function is safe to call from any
 * thread. */
#ifndef SMD_UTIL_H
#define SMD_UTIL_H

#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

/* Job ids are 128 random bits written as 32 lowercase hex digits. */
#define SMD_ID_LEN 32

/* Fills out with a fresh id from getrandom(2).  Returns 0, or -1 when the
 * kernel's random source failed (errno set). */
int smd_random_id(char out[SMD_ID_LEN + 1]);

/* 1 when s is exactly SMD_ID_LEN lowercase hex digits, else 0.  Every id
 * taken from a request goes through this before it is used in a path, so
 * no request can name a file outside the spool's job folders. */
int smd_id_valid(const char *s);

/* Compares a secret in time that depends only on the lengths, never on
 * where the first difference is.  1 when equal. */
int smd_secret_equal(const char *given, size_t given_len, const char *expected,
                     size_t expected_len);

/* snprintf into buf that reports truncation: returns 0, or -1 when the
 * result did not fit (buf then holds a truncated string). */
int smd_pathf(char *buf, size_t cap, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

/* Removes the daemon's folder root from a message a client reads: every
 * path under root (root itself, or root followed by '/') is replaced, in
 * place, by its last component (the file's base name), so that job
 * messages, events and problem details never show where the spool lives.
 * A path ends at white space, a quote, ':', ',', ';', ')' or ']'.  root ""
 * (or "/") leaves msg as it is. */
void smd_unroot(char *msg, const char *root);

/* snprintf that truncates silently (messages built from other messages,
 * where truncation is acceptable). */
void smd_textf(char *buf, size_t cap, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

/* Writes len bytes to path durably: path.tmp-<pid>-<n> is written,
 * fsync'ed, renamed over path, and the containing folder fsync'ed, so a
 * crash leaves either the old or the new content, never a torn file.
 * Returns 0, or -1 with errno set. */
int smd_write_file_atomic(const char *path, const void *data, size_t len);

/* fsync of a folder (makes renames and creations in it durable). */
int smd_fsync_dir(const char *dir);

/* mkdir -p with mode; existing folders are fine.  0 or -1 (errno). */
int smd_mkdirs(const char *path, mode_t mode);

/* Removes path and everything under it without following symbolic
 * links.  A missing path is not an error.  0 or -1 (errno). */
int smd_rmtree(const char *path);

/* Reads a whole file of at most max bytes into a NUL-terminated malloc'd
 * buffer.  Returns 0, or -1 with errno (EFBIG when larger than max). */
int smd_read_file(const char *path, size_t max, char **out, size_t *len);

/* FNV-1a (64 bits) over n bytes, from h (SMD_FNV_OFFSET to start): a
 * cheap fingerprint of the daemon's own files and requests, not a
 * defence against someone who writes them. */
#define SMD_FNV_OFFSET 0xcbf29ce484222325ULL
uint64_t smd_fnv1a(uint64_t h, const void *data, size_t n);
/* The same over a whole file: 0, or -1 with errno set. */
int smd_fnv1a_file(uint64_t *h, const char *path);

/* A growable text buffer: *buf (malloc'd, NULL to start) holds *len bytes
 * and a NUL in *cap bytes.  Appends n bytes of data (smd_buf_append) or
 * formatted text (smd_buf_printf), doubling the capacity as needed.  0,
 * or -1 when out of memory (the buffer is then unchanged). */
int smd_buf_append(char **buf, size_t *len, size_t *cap, const void *data, size_t n);
int smd_buf_printf(char **buf, size_t *len, size_t *cap, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
int smd_buf_vprintf(char **buf, size_t *len, size_t *cap, const char *fmt, va_list ap)
    __attribute__((format(printf, 4, 0)));

/* Describes a wait status in words, e.g. "exited with status 2",
 * "killed by signal 9 (SIGKILL)". */
void smd_describe_wait_status(int wstatus, char *buf, size_t cap);

/* The one parser of numbers taken from requests, headers and the spool's
 * text: a plain decimal integer (digits only: no sign, no space, no
 * suffix; leading zeros allowed) in [lo, hi].  Accumulates without
 * overflow whatever the length of the text.  Returns SMD_NUM_OK and sets
 * *out, SMD_NUM_MALFORMED when text is not such a number (NULL or empty
 * included), SMD_NUM_RANGE when it is one outside [lo, hi] (*out is then
 * left alone), so callers can say which. */
#define SMD_NUM_OK 0
#define SMD_NUM_MALFORMED (-1)
#define SMD_NUM_RANGE (-2)
int smd_parse_uint(const char *text, uint64_t lo, uint64_t hi, uint64_t *out);

/* The largest number a request may carry in a count, offset or event
 * sequence number: 2^53 - 1, the largest integer every JSON client
 * (JavaScript's Number included) represents exactly.  Sums of two such
 * numbers, and of one with a page limit, fit in int64_t with room. */
#define SMD_REQUEST_INT_MAX 9007199254740991LL

/* Parses a size such as "1048576", "64K", "512M", "2G" (binary units).
 * Returns 0, or -1 when malformed or out of range. */
int smd_parse_size(const char *text, uint64_t *out);

/* Parses a duration such as "30", "30s", "15m", "2h", "7d" into seconds
 * (fractions allowed: "0.5s").  Returns 0, or -1 when malformed or
 * negative. */
int smd_parse_duration(const char *text, double *out);

#endif
