/* Helpers shared by the daemon and the worker (see smd_util.h). */
#include "base/smd_util.h"

#include <errno.h>
#include <fcntl.h>
#include <ftw.h>
#include <limits.h>
#include <math.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/random.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "shapematch/sm_atomic.h"

int smd_random_id(char out[SMD_ID_LEN + 1])
{
    unsigned char bytes[SMD_ID_LEN / 2];
    size_t got = 0;
    while (got < sizeof bytes) {
        ssize_t n = getrandom(bytes + got, sizeof bytes - got, 0);
        if (n < 0) {
            if (errno == EINTR)
                continue;
            return -1;
        }
        got += (size_t)n;
    }
    static const char hex[] = "0123456789abcdef";
    for (size_t i = 0; i < sizeof bytes; i++) {
        out[2 * i] = hex[bytes[i] >> 4];
        out[2 * i + 1] = hex[bytes[i] & 15];
    }
    out[SMD_ID_LEN] = '\0';
    return 0;
}

int smd_id_valid(const char *s)
{
    if (!s)
        return 0;
    for (int i = 0; i < SMD_ID_LEN; i++) {
        char c = s[i];
        if (!((c >= '0' && c <= '9') || (c >= 'a' && c <= 'f')))
            return 0;
    }
    return s[SMD_ID_LEN] == '\0';
}

int smd_secret_equal(const char *given, size_t given_len, const char *expected,
                     size_t expected_len)
{
    /* Every byte of expected is compared (against 0 past the end of
     * given), and the length difference is folded into the same
     * accumulator, so the time depends only on expected_len. */
    volatile unsigned char diff = (unsigned char)(given_len != expected_len);
    for (size_t i = 0; i < expected_len; i++) {
        unsigned char g = i < given_len ? (unsigned char)given[i] : 0;
        diff |= (unsigned char)(g ^ (unsigned char)expected[i]);
    }
    return diff == 0;
}

int smd_pathf(char *buf, size_t cap, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(buf, cap, fmt, ap);
    va_end(ap);
    if (n < 0 || (size_t)n >= cap) {
        errno = ENAMETOOLONG;
        return -1;
    }
    return 0;
}

void smd_textf(char *buf, size_t cap, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, cap, fmt, ap);
    va_end(ap);
}

int smd_fsync_dir(const char *dir)
{
    int fd = open(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (fd < 0)
        return -1;
    int rc = fsync(fd);
    int saved = errno;
    close(fd);
    errno = saved;
    return rc;
}

int smd_write_file_atomic(const char *path, const void *data, size_t len)
{
    /* core's one atomic write; errno is left as the failing call set it */
    return sm_atomic_write_file(path, data, len, SM_ATOMIC_FSYNC, NULL) == SM_OK ? 0 : -1;
}

int smd_mkdirs(const char *path, mode_t mode)
{
    char buf[PATH_MAX];
    if (smd_pathf(buf, sizeof buf, "%s", path) != 0)
        return -1;
    for (char *p = buf + 1; *p; p++) {
        if (*p != '/')
            continue;
        *p = '\0';
        if (mkdir(buf, mode) != 0 && errno != EEXIST)
            return -1;
        *p = '/';
    }
    if (mkdir(buf, mode) != 0 && errno != EEXIST)
        return -1;
    struct stat st;
    if (stat(buf, &st) != 0)
        return -1;
    if (!S_ISDIR(st.st_mode)) {
        errno = ENOTDIR;
        return -1;
    }
    return 0;
}

static int remove_entry(const char *path, const struct stat *st, int type, struct FTW *ftw)
{
    (void)st;
    (void)ftw;
    int rc = (type == FTW_DP) ? rmdir(path) : unlink(path);
    if (rc != 0 && errno != ENOENT)
        return -1;
    return 0;
}

int smd_rmtree(const char *path)
{
    struct stat st;
    if (lstat(path, &st) != 0)
        return errno == ENOENT ? 0 : -1;
    if (!S_ISDIR(st.st_mode))
        return unlink(path);
    return nftw(path, remove_entry, 16, FTW_DEPTH | FTW_PHYS | FTW_MOUNT);
}

int smd_read_file(const char *path, size_t max, char **out, size_t *len)
{
    *out = NULL;
    if (len)
        *len = 0;
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0)
        return -1;
    struct stat st;
    if (fstat(fd, &st) != 0) {
        int saved = errno;
        close(fd);
        errno = saved;
        return -1;
    }
    if (!S_ISREG(st.st_mode) || (uint64_t)st.st_size > (uint64_t)max) {
        close(fd);
        errno = S_ISREG(st.st_mode) ? EFBIG : EINVAL;
        return -1;
    }
    size_t size = (size_t)st.st_size;
    char *buf = malloc(size + 1);
    if (!buf) {
        close(fd);
        errno = ENOMEM;
        return -1;
    }
    size_t got = 0;
    while (got < size) {
        ssize_t n = read(fd, buf + got, size - got);
        if (n < 0 && errno == EINTR)
            continue;
        if (n <= 0)
            break; /* shrank while reading: return what is there */
        got += (size_t)n;
    }
    close(fd);
    buf[got] = '\0';
    *out = buf;
    if (len)
        *len = got;
    return 0;
}

void smd_describe_wait_status(int wstatus, char *buf, size_t cap)
{
    if (WIFEXITED(wstatus)) {
        snprintf(buf, cap, "exited with status %d", WEXITSTATUS(wstatus));
    } else if (WIFSIGNALED(wstatus)) {
        int sig = WTERMSIG(wstatus);
        const char *abbrev = sigabbrev_np(sig);
        snprintf(buf, cap, "killed by signal %d (SIG%s)%s", sig, abbrev ? abbrev : "?",
                 WCOREDUMP(wstatus) ? ", core dumped" : "");
    } else {
        snprintf(buf, cap, "stopped with wait status 0x%x", (unsigned)wstatus);
    }
}

static int buf_reserve(char **buf, size_t *cap, size_t need)
{
    if (need <= *cap)
        return 0;
    size_t ncap = *cap ? *cap : 4096;
    while (ncap < need) {
        if (ncap > SIZE_MAX / 2)
            return -1;
        ncap *= 2;
    }
    char *b = realloc(*buf, ncap);
    if (!b)
        return -1;
    *buf = b;
    *cap = ncap;
    return 0;
}

int smd_buf_append(char **buf, size_t *len, size_t *cap, const void *data, size_t n)
{
    if (n > SIZE_MAX - *len - 1 || buf_reserve(buf, cap, *len + n + 1) != 0)
        return -1;
    memcpy(*buf + *len, data, n);
    *len += n;
    (*buf)[*len] = '\0';
    return 0;
}

int smd_buf_vprintf(char **buf, size_t *len, size_t *cap, const char *fmt, va_list ap)
{
    va_list again;
    va_copy(again, ap);
    int n = vsnprintf(NULL, 0, fmt, ap);
    int rc = -1;
    if (n >= 0 && buf_reserve(buf, cap, *len + (size_t)n + 1) == 0) {
        vsnprintf(*buf + *len, *cap - *len, fmt, again);
        *len += (size_t)n;
        rc = 0;
    }
    va_end(again);
    return rc;
}

int smd_buf_printf(char **buf, size_t *len, size_t *cap, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    int rc = smd_buf_vprintf(buf, len, cap, fmt, ap);
    va_end(ap);
    return rc;
}

int smd_parse_uint(const char *text, uint64_t lo, uint64_t hi, uint64_t *out)
{
    if (!text || !*text)
        return SMD_NUM_MALFORMED;
    uint64_t v = 0;
    int over = 0;
    for (const char *c = text; *c; c++) {
        if (*c < '0' || *c > '9')
            return SMD_NUM_MALFORMED;
        unsigned d = (unsigned)(*c - '0');
        /* v * 10 + d > hi, written so that nothing overflows */
        if (over || d > hi || v > (hi - d) / 10)
            over = 1;
        else
            v = v * 10 + d;
    }
    if (over || v < lo)
        return SMD_NUM_RANGE;
    *out = v;
    return SMD_NUM_OK;
}

int smd_parse_size(const char *text, uint64_t *out)
{
    char digits[24];
    size_t n = 0;
    while (text && text[n] >= '0' && text[n] <= '9')
        n++;
    if (n == 0 || n >= sizeof digits)
        return -1;
    memcpy(digits, text, n);
    digits[n] = '\0';
    uint64_t v;
    if (smd_parse_uint(digits, 0, UINT64_MAX, &v) != SMD_NUM_OK)
        return -1;
    const char *end = text + n;
    unsigned shift = 0;
    if (*end) {
        switch (*end) {
        case 'k': case 'K': shift = 10; break;
        case 'm': case 'M': shift = 20; break;
        case 'g': case 'G': shift = 30; break;
        case 't': case 'T': shift = 40; break;
        default: return -1;
        }
        end++;
        if (*end == 'i')
            end++;
        if (*end == 'B' || *end == 'b')
            end++;
        if (*end)
            return -1;
    }
    if (shift && v > (UINT64_MAX >> shift))
        return -1;
    *out = (uint64_t)v << shift;
    return 0;
}

int smd_parse_duration(const char *text, double *out)
{
    /* decimal only: strtod would also take hexadecimal ("0x10", "0x1p3") */
    if (!text || !(*text >= '0' && *text <= '9') || strpbrk(text, "xX"))
        return -1;
    errno = 0;
    char *end;
    double v = strtod(text, &end);
    if (errno != 0 || end == text || !isfinite(v) || v < 0)
        return -1;
    double unit = 1;
    if (*end) {
        switch (*end) {
        case 's': unit = 1; break;
        case 'm': unit = 60; break;
        case 'h': unit = 3600; break;
        case 'd': unit = 86400; break;
        default: return -1;
        }
        if (end[1])
            return -1;
    }
    *out = v * unit;
    return 0;
}

/* ------------------------------------------------- messages for clients */

static int path_end_char(char c)
{
    return c == '\0' || c == ' ' || c == '\t' || c == '\n' || c == '"' || c == '\'' ||
           c == ':' || c == ',' || c == ';' || c == ')' || c == ']';
}

void smd_unroot(char *msg, const char *root)
{
    size_t rlen = strlen(root);
    while (rlen > 1 && root[rlen - 1] == '/')
        rlen--; /* "SPOOL/" names the same folder as "SPOOL" */
    if (rlen == 0 || (rlen == 1 && root[0] == '/'))
        return;
    char *p = msg;
    while ((p = strstr(p, root)) != NULL) {
        /* root must be a whole leading part of a path: not inside a word,
         * and followed by '/' or the path's end */
        int starts = p == msg || path_end_char(p[-1]) || p[-1] == '(' || p[-1] == '[' ||
                     p[-1] == '=';
        if (!starts || (p[rlen] != '/' && !path_end_char(p[rlen]))) {
            p += 1;
            continue;
        }
        char *end = p + rlen;
        while (!path_end_char(*end))
            end++;
        const char *base = end;
        while (base > p + rlen && base[-1] != '/')
            base--;
        static const char spool[] = "the spool";
        const char *name = base < end ? base : spool;
        size_t nlen = base < end ? (size_t)(end - base) : sizeof spool - 1;
        /* the name is never longer than the path it replaces (the spool's
         * own name only stands for a root of at least that length) */
        if (name == spool && nlen > (size_t)(end - p)) {
            name = ".";
            nlen = 1;
        }
        memmove(p, name, nlen);
        memmove(p + nlen, end, strlen(end) + 1);
        p += nlen;
    }
}

uint64_t smd_fnv1a(uint64_t h, const void *data, size_t n)
{
    const unsigned char *p = data;
    for (size_t i = 0; i < n; i++)
        h = (h ^ p[i]) * 0x100000001b3ULL;
    return h;
}

int smd_fnv1a_file(uint64_t *h, const char *path)
{
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0)
        return -1;
    unsigned char buf[1 << 16];
    for (;;) {
        ssize_t r = read(fd, buf, sizeof buf);
        if (r < 0 && errno == EINTR)
            continue;
        if (r < 0) {
            int saved = errno;
            close(fd);
            errno = saved;
            return -1;
        }
        if (r == 0)
            break;
        *h = smd_fnv1a(*h, buf, (size_t)r);
    }
    close(fd);
    return 0;
}
