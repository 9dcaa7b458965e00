/* Paths and folders (see sm_path.h). */
#include "shapematch/sm_path.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

char *sm_path_join(const char *dir, const char *name)
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

/* One folder; an existing folder is fine, an existing file is not. */
static sm_status mkdir_one(const char *path, sm_error *err)
{
    if (mkdir(path, 0777) == 0)
        return SM_OK;
    int e = errno;
    struct stat st;
    if (e == EEXIST && stat(path, &st) == 0) {
        if (S_ISDIR(st.st_mode))
            return SM_OK;
        return sm_error_set(err, SM_ERR_IO,
                            "cannot create directory '%s': a file of that name exists", path);
    }
    return sm_error_set(err, SM_ERR_IO, "cannot create directory '%s': %s", path, strerror(e));
}

sm_status sm_mkdir_p(const char *path, sm_error *err)
{
    char *buf = strdup(path);
    if (!buf)
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    size_t n = strlen(buf);
    while (n > 1 && buf[n - 1] == '/')
        buf[--n] = '\0';
    sm_status st = SM_OK;
    /* create each prefix ending before a '/', then the whole path */
    for (size_t i = 1; i < n && st == SM_OK; i++)
        if (buf[i] == '/' && buf[i - 1] != '/') {
            buf[i] = '\0';
            st = mkdir_one(buf, err);
            buf[i] = '/';
        }
    if (st == SM_OK)
        st = mkdir_one(buf, err);
    free(buf);
    return st;
}
