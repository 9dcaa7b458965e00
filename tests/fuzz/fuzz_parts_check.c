#include "fuzz_parts_check.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "sm_proto_params.h"
#include "base/smd_util.h"

static char upload_dir[64];

static void remove_upload_dir(void)
{
    smd_rmtree(upload_dir);
}

const char *fuzz_parts_upload_dir(const char *tag)
{
    struct stat st;
    int shm = stat("/dev/shm", &st) == 0 && S_ISDIR(st.st_mode) && access("/dev/shm", W_OK) == 0;
    if (snprintf(upload_dir, sizeof upload_dir, "%s/fuzz-%s-XXXXXX", shm ? "/dev/shm" : "/tmp",
                 tag) >= (int)sizeof upload_dir ||
        !mkdtemp(upload_dir))
        abort();
    atexit(remove_upload_dir);
    return upload_dir;
}

void fuzz_parts_finish(smd_parts *p)
{
    smd_parts_close(p);
    if (!p->err_status && smd_parts_check(p) == 0)
        smd_parts_name_files(p);
}

void fuzz_parts_check(const smd_parts *p)
{
    static const unsigned allowed[] = {0, 400, 413, 422, 500, 507};
    int known = 0;
    for (size_t i = 0; i < sizeof allowed / sizeof allowed[0]; i++)
        known |= p->err_status == allowed[i];
    if (!known || (p->err_status && (!p->err_type || !p->err_detail[0])))
        abort();
    if (p->params_len > SM_PARAMS_JSON_MAX_BYTES || p->fd >= 0)
        abort();
    if (p->err_status)
        return;
    /* one template: a mesh, or a closed surface or a label map to mesh */
    if (p->seen[SM_PART_TEMPLATE] + p->seen[SM_PART_TEMPLATE_SURFACE] +
                p->seen[SM_PART_TEMPLATE_IMAGE] != 1 ||
        !p->seen[SM_PART_PARAMS] ||
        smd_parts_hash(p) == 0)
        abort();
    if (p->seen[SM_PART_TEMPLATE_LANDMARKS] != p->seen[SM_PART_TARGET_LANDMARKS])
        abort(); /* the landmark parts come both or not at all */
    char why[96];
    if (p->seen[SM_PART_NAME] && (p->name_len != strlen(p->name) ||
                                  sm_job_name_check(p->name, p->name_len, why, sizeof why) != 0))
        abort(); /* an accepted name is one: 1-200 bytes of UTF-8, no control character */
    struct stat st;
    for (int i = 0; i < SM_PART_PARAMS; i++)
        if (p->seen[i] && stat(p->path[i], &st) != 0)
            abort(); /* an accepted file part is on disk under its final name */
}
