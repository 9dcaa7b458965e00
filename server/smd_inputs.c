/* Reading and checking a job's inputs (see smd_inputs.h). */
#include "smd_inputs.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sm_proto_params.h"

static int ref_listed(int32_t ref, const int32_t *refs, int n)
{
    for (int i = 0; i < n; i++)
        if (refs[i] == ref)
            return 1;
    return 0;
}

int32_t smd_clamp_mark(const sm_mesh *m, const sm_params *p, uint8_t *clamped)
{
    const int dim = m->dim, nv = dim + 1;
    memset(clamped, 0, (size_t)m->nverts);
    switch (p->clamp) {
    case SM_CLAMP_BALL: {
        double r2 = p->clamp_radius * p->clamp_radius;
        for (int32_t v = 0; v < m->nverts; v++) {
            double s = 0;
            for (int c = 0; c < dim; c++) {
                double dx = m->coords[(size_t)v * (size_t)dim + (size_t)c] - p->clamp_center[c];
                s += dx * dx;
            }
            clamped[v] = s <= r2 * (1.0 + 1e-9);
        }
        break;
    }
    case SM_CLAMP_VERTICES:
        for (int32_t v = 0; v < m->nverts; v++)
            clamped[v] = (uint8_t)ref_listed(m->vert_refs[v], p->clamp_refs, p->n_clamp_refs);
        break;
    case SM_CLAMP_ELEMENTS:
        for (int32_t e = 0; e < m->nelems; e++)
            if (ref_listed(m->elem_refs[e], p->clamp_refs, p->n_clamp_refs))
                for (int i = 0; i < nv; i++)
                    clamped[m->elems[(size_t)e * (size_t)nv + (size_t)i]] = 1;
        break;
    case SM_CLAMP_NONE:
        break;
    }
    int32_t count = 0;
    for (int32_t v = 0; v < m->nverts; v++)
        count += clamped[v];
    return count;
}

int smd_clamp_rank(const sm_mesh *m, const uint8_t *clamped)
{
    const int dim = m->dim;
    const double *x = m->coords;
    int32_t first = -1, far = -1;
    double far_d2 = 0;
    for (int32_t v = 0; v < m->nverts; v++) {
        if (!clamped[v])
            continue;
        if (first < 0) {
            first = v;
            continue;
        }
        double d2 = 0;
        for (int k = 0; k < dim; k++) {
            double d = x[(size_t)v * (size_t)dim + (size_t)k] - x[(size_t)first * (size_t)dim + (size_t)k];
            d2 += d * d;
        }
        if (d2 > far_d2) {
            far_d2 = d2;
            far = v;
        }
    }
    /* "distinct" relative to the template's size, not to rounding */
    double diam = sm_mesh_diameter(m, x);
    if (far < 0 || !(far_d2 > 1e-20 * diam * diam))
        return 0;
    if (dim == 2)
        return 1;
    double a[3], best = 0;
    for (int k = 0; k < 3; k++)
        a[k] = x[(size_t)far * 3 + (size_t)k] - x[(size_t)first * 3 + (size_t)k];
    for (int32_t v = 0; v < m->nverts; v++) {
        if (!clamped[v])
            continue;
        double b[3];
        for (int k = 0; k < 3; k++)
            b[k] = x[(size_t)v * 3 + (size_t)k] - x[(size_t)first * 3 + (size_t)k];
        double c0 = a[1] * b[2] - a[2] * b[1], c1 = a[2] * b[0] - a[0] * b[2],
               c2 = a[0] * b[1] - a[1] * b[0];
        double n2 = c0 * c0 + c1 * c1 + c2 * c2;
        if (n2 > best)
            best = n2;
    }
    return best > 1e-20 * far_d2 * far_d2 ? 2 : 1;
}

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
    if (out->params.clamp != SM_CLAMP_NONE) {
        const sm_mesh *m = out->template_mesh;
        uint8_t *clamped = malloc((size_t)m->nverts + 1);
        if (!clamped) {
            st = sm_error_set(err, SM_ERR_NOMEM, "out of memory");
            goto fail;
        }
        out->nclamped = smd_clamp_mark(m, &out->params, clamped);
        int rank = smd_clamp_rank(m, clamped);
        free(clamped);
        const char *what = out->params.clamp == SM_CLAMP_BALL ? "lies in the ball"
                           : out->params.clamp == SM_CLAMP_ELEMENTS
                               ? "belongs to an element with these references"
                               : "has one of these references";
        const char *field = out->params.clamp == SM_CLAMP_BALL ? "params.clamp" : "params.clamp.refs";
        if (out->nclamped == 0) {
            st = sm_error_set(err, SM_ERR_INVALID,
                              "%s: the clamp set is empty: no template vertex %s", field, what);
            goto fail;
        }
        if (out->nclamped == m->nverts) {
            st = sm_error_set(err, SM_ERR_INVALID,
                              "%s: every template vertex %s: nothing could move", field, what);
            goto fail;
        }
        if (rank < m->dim - 1) {
            st = sm_error_set(err, SM_ERR_INVALID,
                              "%s: the clamp holds %s %ld vert%s: rigid rotations stay free (the "
                              "elasticity system is singular); clamp at least %d %s vertices",
                              field, out->nclamped == 1 ? "only" : "collinear",
                              (long)out->nclamped, out->nclamped == 1 ? "ex" : "ices", m->dim,
                              m->dim == 2 ? "distinct" : "non-collinear");
            goto fail;
        }
    }
    return SM_OK;
fail:
    sm_mesh_free(checked);
    smd_inputs_free(out);
    return st;
}
