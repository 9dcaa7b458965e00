/* The target list of `shapematch batch --targets LIST.csv`
 * (proto/job/sm_job_batch_list.c): any input is parsed or refused with a
 * message naming its line; every accepted target has one of a surface,
 * an image, or a mesh and its distance; after sm_batch_list_finish the names are
 * non-empty, unique and made of [A-Za-z0-9._-] without a leading dot. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "job/sm_job_batch_list.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static int name_ok(const char *s)
{
    if (!s[0] || s[0] == '.')
        return 0;
    for (; *s; s++)
        if (!((*s >= 'a' && *s <= 'z') || (*s >= 'A' && *s <= 'Z') || (*s >= '0' && *s <= '9') ||
              *s == '.' || *s == '-' || *s == '_'))
            return 0;
    return 1;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    sm_error err;
    sm_error_clear(&err);
    sm_batch_list l;
    memset(&l, 0, sizeof l);
    if (sm_batch_list_parse(&l, (const char *)data, size, "base", &err) != SM_OK) {
        if (err.msg[0] == '\0' || (strncmp(err.msg, "line ", 5) != 0 &&
                                   strstr(err.msg, "empty") == NULL &&
                                   strstr(err.msg, "memory") == NULL))
            abort();
        sm_batch_list_free(&l);
        return 0;
    }
    for (size_t i = 0; i < l.n; i++) {
        const sm_batch_target *t = &l.t[i];
        if (!t->name ||
            !(t->target_surface || t->target_image || (t->target_mesh && t->target_sol)) ||
            !!t->target_surface + !!t->target_image + !!t->target_sol > 1)
            abort();
    }
    if (sm_batch_list_finish(&l, &err) != SM_OK)
        abort();
    for (size_t i = 0; i < l.n; i++) {
        if (!name_ok(l.t[i].name))
            abort();
        for (size_t j = 0; j < i; j++)
            if (strcmp(l.t[i].name, l.t[j].name) == 0)
                abort();
    }
    sm_batch_list_free(&l);
    return 0;
}
