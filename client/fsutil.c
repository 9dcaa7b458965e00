/* File-system helpers of the client (see fsutil.h). */
#include "fsutil.h"
#include "msg.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "shapematch/sm_atomic.h"


char *fs_join(const char *dir, const char *name)
{
    size_t a = strlen(dir), b = strlen(name);
    int slash = a > 0 && dir[a - 1] != '/';
    char *s = malloc(a + (size_t)slash + b + 1);
    if (!s)
        return NULL;
    memcpy(s, dir, a);
    if (slash)
        s[a] = '/';
    memcpy(s + a + (size_t)slash, name, b + 1);
    return s;
}

static int mkdir_one(const char *path, char *msg, size_t cap)
{
    if (mkdir(path, 0777) == 0)
        return 0;
    int e = errno;
    struct stat st;
    if (e == EEXIST && stat(path, &st) == 0) {
        if (S_ISDIR(st.st_mode))
            return 0;
        return cli_fail(msg, cap, "cannot create directory '%s': a file of that name exists", path);
    }
    return cli_fail(msg, cap, "cannot create directory '%s': %s", path, strerror(e));
}

int fs_mkdir_p(const char *path, char *msg, size_t cap)
{
    char *buf = strdup(path);
    if (!buf)
        return cli_fail(msg, cap, "out of memory");
    size_t n = strlen(buf);
    while (n > 1 && buf[n - 1] == '/')
        buf[--n] = '\0';
    int rc = 0;
    /* create each prefix ending before a '/', then the whole path */
    for (size_t i = 1; i < n && rc == 0; i++)
        if (buf[i] == '/' && buf[i - 1] != '/') {
            buf[i] = '\0';
            rc = mkdir_one(buf, msg, cap);
            buf[i] = '/';
        }
    if (rc == 0)
        rc = mkdir_one(buf, msg, cap);
    free(buf);
    return rc;
}

int fs_check_writable(const char *dir, char *msg, size_t cap)
{
    char *probe = fs_join(dir, "write-probe");
    if (!probe)
        return cli_fail(msg, cap, "out of memory");
    sm_atomic a;
    sm_error err;
    int rc = 0;
    if (sm_atomic_open(&a, probe, &err) != SM_OK) {
        rc = cli_fail(msg, cap, "%s", err.msg);
    } else {
        if (fputs("probe\n", a.f) == EOF || fflush(a.f) != 0)
            rc = cli_fail(msg, cap, "cannot write in '%s': %s", dir, strerror(errno));
        sm_atomic_abort(&a);
    }
    free(probe);
    return rc;
}
