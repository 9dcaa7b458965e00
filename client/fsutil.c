/* File-system helpers of the client (see fsutil.h). */
#include "fsutil.h"
#include "msg.h"

#include <errno.h>
#include <fcntl.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>


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

/* The directory part of path ("." when there is none). */
static char *dir_of(const char *path)
{
    const char *slash = strrchr(path, '/');
    if (!slash)
        return strdup(".");
    if (slash == path)
        return strdup("/");
    return strndup(path, (size_t)(slash - path));
}

static char *temp_name(const char *path, const char *fmt_prefix, int suffix)
{
    const char *slash = strrchr(path, '/');
    const char *base = slash ? slash + 1 : path;
    size_t dlen = (size_t)(base - path);
    char tag[64];
    snprintf(tag, sizeof tag, fmt_prefix, (long)getpid());
    size_t need = dlen + strlen(tag) + strlen(base) + 16;
    char *s = malloc(need);
    if (!s)
        return NULL;
    if (suffix) /* "<dir>/.<name>.tmp-<pid>" */
        snprintf(s, need, "%.*s.%s%s", (int)dlen, path, base, tag);
    else        /* "<dir>/.tmp-<pid>-<name>" */
        snprintf(s, need, "%.*s%s%s", (int)dlen, path, tag, base);
    return s;
}

char *fs_temp_name(const char *path)
{
    return temp_name(path, ".tmp-%ld-", 0);
}

static void sync_dir_of(const char *path)
{
    /* best effort: makes the rename itself durable */
    char *dir = dir_of(path);
    if (!dir)
        return;
    int fd = open(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (fd >= 0) {
        (void)fsync(fd);
        close(fd);
    }
    free(dir);
}

int fs_commit_file(const char *tmp, const char *path, char *msg, size_t cap)
{
    int fd = open(tmp, O_RDONLY | O_CLOEXEC);
    if (fd < 0)
        return cli_fail(msg, cap, "cannot open '%s': %s", tmp, strerror(errno));
    /* EINVAL: the file system does not support syncing; not an error */
    if (fsync(fd) != 0 && errno != EINVAL) {
        int e = errno;
        close(fd);
        unlink(tmp);
        return cli_fail(msg, cap, "cannot write '%s': %s", path, strerror(e));
    }
    close(fd);
    if (rename(tmp, path) != 0) {
        int e = errno;
        unlink(tmp);
        return cli_fail(msg, cap, "cannot rename '%s' to '%s': %s", tmp, path, strerror(e));
    }
    sync_dir_of(path);
    return 0;
}

int fs_atomic_open(fs_atomic *a, const char *path, char *msg, size_t cap)
{
    memset(a, 0, sizeof *a);
    a->final_path = strdup(path);
    a->tmp_path = temp_name(path, ".tmp-%ld", 1);
    if (!a->final_path || !a->tmp_path) {
        fs_atomic_abort(a);
        return cli_fail(msg, cap, "out of memory");
    }
    int fd = open(a->tmp_path, O_WRONLY | O_CREAT | O_TRUNC | O_NOFOLLOW | O_CLOEXEC, 0666);
    if (fd < 0) {
        int e = errno;
        cli_fail(msg, cap, "cannot create '%s': %s", a->tmp_path, strerror(e));
        free(a->tmp_path);
        a->tmp_path = NULL;
        fs_atomic_abort(a);
        return -1;
    }
    a->f = fdopen(fd, "w");
    if (!a->f) {
        int e = errno;
        close(fd);
        fs_atomic_abort(a);
        return cli_fail(msg, cap, "cannot open '%s': %s", path, strerror(e));
    }
    return 0;
}

static void release(fs_atomic *a)
{
    free(a->tmp_path);
    free(a->final_path);
    memset(a, 0, sizeof *a);
}

void fs_atomic_abort(fs_atomic *a)
{
    if (a->f)
        fclose(a->f);
    if (a->tmp_path)
        unlink(a->tmp_path);
    release(a);
}

int fs_atomic_commit(fs_atomic *a, char *msg, size_t cap)
{
    int bad = fflush(a->f) != 0 || ferror(a->f);
    int e = errno;
    if (!bad && fsync(fileno(a->f)) != 0 && errno != EINVAL) {
        bad = 1;
        e = errno;
    }
    if (fclose(a->f) != 0 && !bad) {
        bad = 1;
        e = errno;
    }
    a->f = NULL;
    if (bad) {
        cli_fail(msg, cap, "cannot write '%s': %s", a->final_path, strerror(e ? e : EIO));
        fs_atomic_abort(a);
        return -1;
    }
    if (rename(a->tmp_path, a->final_path) != 0) {
        e = errno;
        cli_fail(msg, cap, "cannot rename '%s' to '%s': %s", a->tmp_path, a->final_path,
             strerror(e));
        fs_atomic_abort(a);
        return -1;
    }
    sync_dir_of(a->final_path);
    release(a);
    return 0;
}

int fs_check_writable(const char *dir, char *msg, size_t cap)
{
    char *probe = fs_join(dir, "write-probe");
    if (!probe)
        return cli_fail(msg, cap, "out of memory");
    fs_atomic a;
    int rc = fs_atomic_open(&a, probe, msg, cap);
    if (rc == 0) {
        if (fputs("probe\n", a.f) == EOF || fflush(a.f) != 0)
            rc = cli_fail(msg, cap, "cannot write in '%s': %s", dir, strerror(errno));
        fs_atomic_abort(&a);
    }
    free(probe);
    return rc;
}
