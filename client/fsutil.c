/* File-system helpers of the client (see fsutil.h). */
#include "fsutil.h"
#include "msg.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "shapematch/sm_atomic.h"
#include "shapematch/sm_path.h"

int fs_output_dir(const char *dir, char *msg, size_t cap)
{
    sm_error err;
    if (sm_mkdir_p(dir, &err) != SM_OK)
        return cli_fail(msg, cap, "%s", err.msg);
    return fs_check_writable(dir, msg, cap);
}

int fs_check_writable(const char *dir, char *msg, size_t cap)
{
    char *probe = sm_path_join(dir, "write-probe");
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
