/* The landmark CSV reader (sm_landmarks_parse, core/sm_align_landmarks.c)
 * on untrusted bytes, in 3D and in 2D.  Contract: SM_OK with 1 to
 * SM_LANDMARKS_MAX rows of finite numbers, or an error with a message and
 * *pts NULL; never a crash or a leak.  Each accepted set goes on to the
 * Kabsch/Umeyama start against itself (its checks of degenerate and
 * non-finite sets). */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>

#include "shapematch/sm_align.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    for (int dim = 2; dim <= 3; dim++) {
        double *pts = NULL;
        int32_t n = -1;
        sm_error err;
        sm_status st = sm_landmarks_parse((const char *)data, size, dim, &pts, &n, &err);
        if (st != SM_OK) {
            if (pts || n != 0 || err.msg[0] == '\0')
                abort();
            continue;
        }
        if (!pts || n < 1 || n > SM_LANDMARKS_MAX)
            abort();
        for (int64_t i = 0; i < (int64_t)n * dim; i++)
            if (!isfinite(pts[i]))
                abort();
        sm_transform t;
        if (sm_align_landmarks(dim, n, pts, pts, SM_ALIGN_SIMILARITY, &t, &err) == SM_OK)
            for (int i = 0; i < dim; i++) /* a set onto itself: the identity */
                if (!(fabs(t.a[i][i] - 1) < 1e-6))
                    abort();
        free(pts);
    }
    return 0;
}
