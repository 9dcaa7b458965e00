/* Atomic file writes (see sm_atomic.h). */
#include "shapematch/sm_atomic.h"

#include <errno.h>
#include <fcntl.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* The folder of path ("." when it has none), malloc'd. */
static char *dir_of(const char *path)
{
    const char *slash = strrchr(path, '/');
    if (!slash)
        return strdup(".");
    size_t n = slash == path ? 1 : (size_t)(slash - path);
    char *d = malloc(n + 1);
    if (d) {
        memcpy(d, path, n);
        d[n] = '\0';
    }
    return d;
}

/* "<dir>/.tmp-<pid>-<k>-<name>", created with O_EXCL (k counts up past
 * names in use); returns the open descriptor or -1. */
static int create_temp(sm_atomic *a, const char *path, sm_error *err)
{
    const char *slash = strrchr(path, '/');
    const char *name = slash ? slash + 1 : path;
    size_t dlen = slash ? (size_t)(slash - path) + 1 : 0;
    size_t cap = dlen + strlen(name) + 64;
    memset(a, 0, sizeof *a);
    a->final_path = strdup(path);
    a->tmp_path = malloc(cap);
    if (!a->final_path || !a->tmp_path) {
        sm_atomic_abort(a);
        sm_error_set(err, SM_ERR_NOMEM, "out of memory writing '%s'", path);
        errno = ENOMEM;
        return -1;
    }
    for (int k = 0; k < 1000; k++) {
        snprintf(a->tmp_path, cap, "%.*s.tmp-%ld-%d-%s", (int)dlen, path, (long)getpid(), k, name);
        int fd = open(a->tmp_path, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
        if (fd >= 0)
            return fd;
        if (errno != EEXIST)
            break;
    }
    int saved = errno;
    free(a->tmp_path);
    a->tmp_path = NULL; /* nothing of ours to remove */
    sm_atomic_abort(a);
    sm_error_set(err, SM_ERR_IO, "cannot write '%s': %s", path, strerror(saved));
    errno = saved;
    return -1;
}

sm_status sm_atomic_open(sm_atomic *a, const char *path, sm_error *err)
{
    int fd = create_temp(a, path, err);
    if (fd < 0)
        return err ? err->code : SM_ERR_IO;
    a->f = fdopen(fd, "wb");
    if (!a->f) {
        int saved = errno;
        close(fd);
        sm_atomic_abort(a);
        errno = saved;
        return sm_error_set(err, SM_ERR_IO, "cannot write '%s': %s", path, strerror(saved));
    }
    return SM_OK;
}

sm_status sm_atomic_reserve(sm_atomic *a, const char *path, sm_error *err)
{
    int fd = create_temp(a, path, err);
    if (fd < 0)
        return err ? err->code : SM_ERR_IO;
    close(fd);
    return SM_OK;
}

static sm_status fsync_path(const char *path)
{
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0)
        return SM_ERR_IO;
    int rc = fsync(fd);
    int saved = errno;
    close(fd);
    errno = saved;
    /* EINVAL: a file system (or device) without fsync */
    return rc == 0 || errno == EINVAL ? SM_OK : SM_ERR_IO;
}

sm_status sm_fsync_dir(const char *dir, sm_error *err)
{
    int fd = open(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    int rc = fd < 0 ? -1 : fsync(fd);
    int saved = errno;
    if (fd >= 0)
        close(fd);
    errno = saved;
    if (rc != 0 && !(fd >= 0 && saved == EINVAL))
        return sm_error_set(err, SM_ERR_IO, "cannot sync the folder '%s': %s", dir, strerror(saved));
    return SM_OK;
}

sm_status sm_atomic_commit(sm_atomic *a, unsigned flags, sm_error *err)
{
    sm_status st = SM_OK;
    int saved = 0;
    if (a->f) {
        int bad = fflush(a->f) != 0 || ferror(a->f);
        saved = errno ? errno : EIO;
        if (!bad && (flags & SM_ATOMIC_FSYNC) && fsync(fileno(a->f)) != 0 && errno != EINVAL) {
            bad = 1;
            saved = errno;
        }
        if (fclose(a->f) != 0 && !bad) {
            bad = 1;
            saved = errno;
        }
        a->f = NULL;
        if (bad)
            st = SM_ERR_IO;
    } else if ((flags & SM_ATOMIC_FSYNC) && fsync_path(a->tmp_path) != SM_OK) {
        saved = errno;
        st = SM_ERR_IO;
    }
    if (st == SM_OK && rename(a->tmp_path, a->final_path) != 0) {
        saved = errno;
        st = SM_ERR_IO;
    }
    if (st != SM_OK) {
        sm_error_set(err, st, "cannot write '%s': %s", a->final_path, strerror(saved));
        sm_atomic_abort(a);
        errno = saved;
        return st;
    }
    if (flags & SM_ATOMIC_FSYNC) {
        char *dir = dir_of(a->final_path);
        st = dir ? sm_fsync_dir(dir, err) : sm_error_set(err, SM_ERR_NOMEM, "out of memory");
        saved = errno;
        free(dir);
    }
    free(a->tmp_path);
    free(a->final_path);
    memset(a, 0, sizeof *a);
    errno = saved;
    return st;
}

void sm_atomic_abort(sm_atomic *a)
{
    int saved = errno;
    if (a->f)
        fclose(a->f);
    if (a->tmp_path)
        unlink(a->tmp_path);
    free(a->tmp_path);
    free(a->final_path);
    memset(a, 0, sizeof *a);
    errno = saved;
}

sm_status sm_atomic_write_file(const char *path, const void *data, size_t len, unsigned flags,
                               sm_error *err)
{
    sm_atomic a;
    sm_status st = sm_atomic_open(&a, path, err);
    if (st != SM_OK)
        return st;
    if (len > 0 && fwrite(data, 1, len, a.f) != len) {
        int saved = errno;
        sm_atomic_abort(&a);
        errno = saved;
        return sm_error_set(err, SM_ERR_IO, "cannot write '%s': %s", path, strerror(saved));
    }
    return sm_atomic_commit(&a, flags, err);
}
