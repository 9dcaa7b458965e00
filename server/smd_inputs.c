/* Reading and checking a job's inputs (see smd_inputs.h). */
#include "smd_inputs.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sm_clamp.h"
#include "sm_proto_params.h"

void smd_inputs_free(smd_inputs *in)
{
    if (!in)
        return;
    sm_field_free(in->field);
    sm_sol_free(in->distance);
    sm_mesh_free(in->background);
    sm_mesh_free(in->template_mesh);
    in->field = NULL;
    in->distance = NULL;
    in->background = NULL;
    in->template_mesh = NULL;
}

/* "PART: message" with every occurrence of path replaced by PART. */
static sm_status part_error(sm_error *err, const char *part, const char *path)
{
    char msg[SM_ERROR_MSG_LEN];
    size_t k = 0, plen = path ? strlen(path) : 0;
    const char *src = err->msg;
    while (*src && k + 1 < sizeof msg) {
        if (plen && strncmp(src, path, plen) == 0) {
            size_t n = strlen(part);
            if (k + n >= sizeof msg)
                break;
            memcpy(msg + k, part, n);
            k += n;
            src += plen;
        } else {
            msg[k++] = *src++;
        }
    }
    msg[k] = '\0';
    size_t n = strlen(part);
    if (strncmp(msg, part, n) == 0 && msg[n] == ':') {
        /* the readers say "FILE:LINE: what": make it "PART: line LINE: what" */
        const char *p = msg + n + 1;
        const char *digits = p;
        while (*p >= '0' && *p <= '9')
            p++;
        if (p > digits && *p == ':')
            return sm_error_set(err, err->code, "%s: line %.*s:%s", part, (int)(p - digits), digits, p + 1);
        /* already "PART: what" */
        return sm_error_set(err, err->code, "%s", msg);
    }
    return sm_error_set(err, err->code, "%s: %s", part, msg);
}

sm_status smd_inputs_load(const char *template_path, const char *target_mesh_path,
                          const char *target_sol_path, const char *params_text,
                          size_t params_len, smd_inputs *out, sm_error *err)
{
    memset(out, 0, sizeof *out);
    sm_status st;
    sm_mesh *checked = NULL;
    /* cheap syntax check first: no mesh parsing for a garbled params */
    if ((st = sm_params_from_json(params_text, params_len, 0, &out->params, err)) != SM_OK)
        return st;
    if ((st = sm_mesh_read(template_path, &out->template_mesh, err)) != SM_OK) {
        part_error(err, "template", template_path);
        goto fail;
    }
    if ((st = sm_mesh_read(target_mesh_path, &out->background, err)) != SM_OK) {
        part_error(err, "target_mesh", target_mesh_path);
        goto fail;
    }
    out->dim = out->template_mesh->dim;
    if (out->background->dim != out->dim) {
        st = sm_error_set(err, SM_ERR_INVALID,
                          "dimension mismatch: the template is %dD but the target mesh is %dD",
                          out->dim, out->background->dim);
        goto fail;
    }
    if ((st = sm_sol_read(target_sol_path, &out->distance, err)) != SM_OK) {
        part_error(err, "target_sol", target_sol_path);
        goto fail;
    }
    if (out->distance->ncomp != 1) {
        st = sm_error_set(err, SM_ERR_INVALID,
                          "target_sol: a scalar signed distance is expected, got a field of %d "
                          "components",
                          out->distance->ncomp);
        goto fail;
    }
    if (out->distance->nverts != out->background->nverts) {
        st = sm_error_set(err, SM_ERR_INVALID,
                          "target_sol: has %ld values but the target mesh has %ld vertices",
                          (long)out->distance->nverts, (long)out->background->nverts);
        goto fail;
    }
    for (int32_t v = 0; v < out->distance->nverts; v++)
        if (!isfinite(out->distance->values[v])) {
            st = sm_error_set(err, SM_ERR_INVALID, "target_sol: value %ld is not finite",
                              (long)v + 1);
            goto fail;
        }
    /* topology checks on a copy: building the boundary reorients
     * elements, and the outputs keep the input's connectivity as is */
    if ((st = sm_mesh_clone(out->template_mesh, &checked, err)) != SM_OK ||
        (st = sm_mesh_build_boundary(checked, err)) != SM_OK) {
        part_error(err, "template", template_path);
        goto fail;
    }
    sm_mesh_free(checked);
    checked = NULL;
    if ((st = sm_field_new(out->background, out->distance->values, &out->field, err)) != SM_OK) {
        part_error(err, "target_mesh", target_mesh_path);
        goto fail;
    }
    if ((st = sm_params_from_json(params_text, params_len, out->dim, &out->params, err)) != SM_OK)
        goto fail;
    if ((st = sm_clamp_check(out->template_mesh, &out->params, &out->nclamped, err)) != SM_OK) {
        sm_error_prefix(err, "%s", out->params.clamp == SM_CLAMP_BALL ? "params.clamp" : "params.clamp.refs");
        goto fail;
    }
    return SM_OK;
fail:
    sm_mesh_free(checked);
    smd_inputs_free(out);
    return st;
}
