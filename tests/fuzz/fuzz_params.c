/* The job parameters document (the `params` part of POST /v1/jobs and
 * `shapematch run --params`).  The first byte picks the dimension the
 * decoder is told (0 = not known yet, 2, 3) or, fourth choice, a 2D
 * template with physical names ("core" of elements, "cut" of facets,
 * "tip" a point) that the document's names are resolved against
 * (sm_job_params_from_json_for); the rest is the document.
 * An accepted document must survive an encode/decode round trip
 * unchanged, which checks the encoder on every value the decoder lets
 * through; both read the parameter table (sm_params_table and the
 * background rows), so this is the table's round trip too. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "sm_proto_params.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* The named template, made once (a triangle: only its names matter). */
static const sm_mesh *named_template(void)
{
    static sm_mesh *m;
    static sm_mesh_name names[3] = {{2, 1, "core"}, {1, 3, "cut"}, {0, 9, "tip"}};
    sm_error err;
    if (!m) {
        if (sm_mesh_alloc(&m, 2, 3, 1, 0, &err) != SM_OK)
            abort();
        m->nnames = 3;
        m->names = names; /* never freed: it lives as long as the fuzzer */
    }
    return m;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1)
        return 0;
    static const int dims[4] = {0, 2, 3, 2};
    int named = data[0] % 4 == 3;
    int dim = dims[data[0] % 4];
    const char *text = (const char *)data + 1;
    size_t len = size - 1;

    sm_params p;
    sm_background_params bg;
    sm_error err;
    sm_error_clear(&err);
    sm_status st = named ? sm_job_params_from_json_for(text, len, named_template(), &p, &bg, &err)
                         : sm_job_params_from_json(text, len, dim, &p, &bg, &err);
    if (st != SM_OK) {
        if (err.msg[0] == '\0')
            abort();
        return 0;
    }
    char *again = sm_job_params_to_json(&p, &bg, dim);
    if (!again)
        abort(); /* the decoder accepted something the encoder cannot write */
    sm_params q;
    sm_background_params qbg;
    if (sm_job_params_from_json(again, strlen(again), dim, &q, &qbg, &err) != SM_OK)
        abort();
    char *third = sm_job_params_to_json(&q, &qbg, dim);
    if (!third || strcmp(again, third) != 0)
        abort(); /* encode(decode(x)) is not a fixed point */
    free(again);
    free(third);
    return 0;
}
