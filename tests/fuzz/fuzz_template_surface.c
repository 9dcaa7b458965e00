/* The template-surface path before meshing (sm_template_mesh.h): an OFF
 * surface (prefix "OFF\n": compact, so the fuzzer reaches closed ones)
 * read, repaired as a template surface is (sm_job_template.c), then
 * sm_template_surface_check.  Contract: the check fails cleanly (a
 * message) or accepts a surface with a positive finite volume whose
 * every edge is on two facets.  nglib itself is not called here: each
 * meshing forks a child and takes from a tenth of a second to seconds,
 * far too slow for a fuzzer; the checks are what stand before it. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>

#include "fuzz_input.h"
#include "io/sm_read_input.h"
#include "shapematch/sm_template_mesh.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* Every edge of s on exactly two facets (3D), every vertex used on two
 * segments (2D), by brute force: the accepted surfaces are small. */
static int closed_brute(const sm_surface *s)
{
    int d = s->dim;
    if (s->nfacets > 400)
        return 1;
    for (int32_t f = 0; f < s->nfacets; f++)
        for (int k = 0; k < d; k++) {
            int32_t a = s->facets[d * f + k], b = d == 3 ? s->facets[d * f + (k + 1) % 3] : -1;
            int uses = 0;
            for (int32_t g = 0; g < s->nfacets; g++)
                for (int j = 0; j < d; j++) {
                    int32_t x = s->facets[d * g + j];
                    int32_t y = d == 3 ? s->facets[d * g + (j + 1) % 3] : -1;
                    if (d == 2 ? x == a : ((x == a && y == b) || (x == b && y == a)))
                        uses++;
                }
            if (uses != 2)
                return 0;
        }
    return 1;
}

static void check(const sm_reader_input *in)
{
    sm_error err;
    sm_error_clear(&err);
    sm_surface *s = NULL;
    if (sm__surface_read_input(in, NULL, &s, &err) != SM_OK)
        return;
    sm_surface_health h;
    double volume = -1;
    if (sm_surface_repair(s, &h, &err) == SM_OK) {
        sm_status st = sm_template_surface_check(s, &volume, &err);
        if (st == SM_OK && (!(volume > 0) || !isfinite(volume) || !closed_brute(s)))
            abort();
        if (st != SM_OK && err.msg[0] == '\0')
            abort();
    }
    sm_surface_free(s);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    return fuzz_file_target("OFF\n", data, size, check);
}
