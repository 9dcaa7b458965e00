/* A batch's warm starts (see sm_job_batch_warm.h). */
#include "job/sm_job_batch_warm.h"

#include <dirent.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "shapematch/sm_atomic.h"
#include "shapematch/sm_clamp.h"
#include "shapematch/sm_clock.h"
#include "shapematch/sm_path.h"

#define RECORD_MAGIC "SMWARM1"
#define RECORD_SUFFIX ".start"

/* A record's head; the displacement (nverts*dim doubles) follows.  Read
 * only by the batch's own processes, on this machine. */
typedef struct record_head {
    char magic[8];
    int32_t dim, nverts;
    double linear[3][3];      /* the alignment's linear part (template -> target) */
} record_head;

/* inv of the dim x dim matrix a; 0 when it is singular. */
static int invert(int dim, const double a[3][3], double inv[3][3])
{
    memset(inv, 0, 9 * sizeof inv[0][0]);
    if (dim == 2) {
        double det = a[0][0] * a[1][1] - a[0][1] * a[1][0];
        if (!(fabs(det) > 0))
            return 0;
        inv[0][0] = a[1][1] / det, inv[0][1] = -a[0][1] / det;
        inv[1][0] = -a[1][0] / det, inv[1][1] = a[0][0] / det;
        return 1;
    }
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) /* cofactor (j, i) */
            inv[i][j] = a[(j + 1) % 3][(i + 1) % 3] * a[(j + 2) % 3][(i + 2) % 3] -
                        a[(j + 1) % 3][(i + 2) % 3] * a[(j + 2) % 3][(i + 1) % 3];
    double det = a[0][0] * inv[0][0] + a[0][1] * inv[1][0] + a[0][2] * inv[2][0];
    if (!(fabs(det) > 0))
        return 0;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            inv[i][j] /= det;
    return 1;
}

static void linear_part(const sm_job_alignment *a, int dim, double l[3][3])
{
    memset(l, 0, 9 * sizeof l[0][0]);
    for (int i = 0; i < dim; i++)
        for (int j = 0; j < dim; j++)
            l[i][j] = a && a->done ? a->result.transform.a[i][j] : (double)(i == j);
}

/* The vertices of m's loaded boundary (facets whose reference is not in
 * free_refs), once each; their count. */
static int64_t loaded_vertices(const sm_mesh *m, const sm_params *p, int32_t *out)
{
    uint8_t *seen = calloc((size_t)m->nverts + 1, 1);
    int64_t n = 0;
    for (int32_t f = 0; seen && f < m->nbfacets; f++) {
        int free_facet = 0;
        for (int k = 0; k < p->n_free_refs; k++)
            free_facet |= m->bfacet_refs[f] == p->free_refs[k];
        for (int k = 0; !free_facet && k < m->dim; k++) {
            int32_t v = m->bfacets[(size_t)f * (size_t)m->dim + (size_t)k];
            if (!seen[v]) {
                seen[v] = 1;
                out[n++] = v;
            }
        }
    }
    free(seen);
    return n;
}

/* The RMS of the target's distance d at the loaded boundary's vertices
 * moved by disp (NULL: not moved): the run's own boundary error, one
 * side, at a few milliseconds for the 3D example (the two-sided measure
 * of sm_coverage_measure costs seconds there). */
static double boundary_rms_at(const sm_mesh *m, const sm_field *target, const int32_t *verts,
                              int64_t n, const double *disp, double *xs, double *d)
{
    const int dim = m->dim;
    for (int64_t i = 0; i < n; i++)
        for (int c = 0; c < dim; c++) {
            size_t k = (size_t)verts[i] * (size_t)dim + (size_t)c;
            xs[(size_t)i * (size_t)dim + (size_t)c] = m->coords[k] + (disp ? disp[k] : 0.0);
        }
    sm_field_eval_points(target, n, xs, NULL, d);
    double s = 0;
    for (int64_t i = 0; i < n; i++)
        s += d[i] * d[i];
    return n > 0 && isfinite(s) ? sqrt(s / (double)n) : INFINITY;
}

/* A record read whole (its head checked against the run's mesh); NULL
 * when unreadable or of another mesh. */
static double *read_record(const char *path, const sm_mesh *m, record_head *h)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    size_t n = (size_t)m->nverts * (size_t)m->dim;
    double *d = NULL;
    if (fread(h, sizeof *h, 1, f) == 1 && memcmp(h->magic, RECORD_MAGIC, 8) == 0 &&
        h->dim == m->dim && h->nverts == m->nverts && (d = malloc((n ? n : 1) * sizeof *d)) &&
        fread(d, sizeof *d, n, f) != n) {
        free(d);
        d = NULL;
    }
    fclose(f);
    return d;
}

/* The candidate of record d (head h) carried to this run: L_j L_i^-1 d
 * per vertex, 0 on the clamp set; 0 when i's alignment is singular. */
static int carry(const record_head *h, const double lj[3][3], const uint8_t *clamped,
                 const sm_mesh *m, const double *d, double *out)
{
    double li_inv[3][3], c[3][3] = {{0}};
    const int dim = m->dim;
    if (!invert(dim, h->linear, li_inv))
        return 0;
    for (int i = 0; i < dim; i++)
        for (int j = 0; j < dim; j++)
            for (int k = 0; k < dim; k++)
                c[i][j] += lj[i][k] * li_inv[k][j];
    for (int32_t v = 0; v < m->nverts; v++) {
        const double *dv = d + (size_t)v * (size_t)dim;
        double *ov = out + (size_t)v * (size_t)dim;
        for (int i = 0; i < dim; i++) {
            double s = 0;
            for (int k = 0; k < dim; k++)
                s += c[i][k] * dv[k];
            ov[i] = clamped[v] ? 0.0 : s;
        }
    }
    return 1;
}

static int is_record(const char *name, const char *own)
{
    size_t n = strlen(name), k = strlen(RECORD_SUFFIX), o = strlen(own);
    if (name[0] == '.' || n <= k || strcmp(name + n - k, RECORD_SUFFIX) != 0)
        return 0;
    return !(n - k == o && strncmp(name, own, o) == 0);
}

int sm_job_warm_choose(const sm_mesh *m, const sm_params *params, const sm_field *target,
                       const sm_job_alignment *a, double *start, void *user)
{
    sm_job_warm *w = user;
    double t0 = sm_clock_seconds();
    w->source[0] = '\0';
    w->candidates = 0;
    w->score_template = w->score_start = NAN;
    DIR *dir = opendir(w->dir);
    if (!dir)
        return 0;
    const size_t n = (size_t)m->nverts * (size_t)m->dim;
    double *cand = malloc((n ? n : 1) * sizeof *cand);
    double *coords = malloc((n ? n : 1) * sizeof *coords);
    uint8_t *clamped = calloc((size_t)m->nverts + 1, 1);
    int32_t *verts = malloc(((size_t)m->nverts + 1) * sizeof *verts);
    double *xs = malloc(((size_t)n + 1) * sizeof *xs), *d = malloc(((size_t)m->nverts + 1) * sizeof *d);
    int ok = cand && coords && clamped && verts && xs && d;
    int64_t nb = ok ? loaded_vertices(m, params, verts) : 0;
    double lj[3][3];
    linear_part(a, m->dim, lj);
    /* the run's floor: min_quality, or the template's own worst if lower */
    double q_template = sm_mesh_min_quality(m, m->coords, NULL);
    double floor_q = q_template < params->min_quality ? q_template : params->min_quality;
    double best = INFINITY;
    if (ok) {
        sm_clamp_mark(m, params, clamped);
        best = w->score_template = boundary_rms_at(m, target, verts, nb, NULL, xs, d);
    }
    struct dirent *de;
    while (ok && (de = readdir(dir)) != NULL) {
        if (!is_record(de->d_name, w->name))
            continue;
        char *path = sm_path_join(w->dir, de->d_name);
        record_head h;
        double *d = path ? read_record(path, m, &h) : NULL;
        free(path);
        if (d && carry(&h, lj, clamped, m, d, cand)) {
            for (size_t i = 0; i < n; i++)
                coords[i] = m->coords[i] + cand[i];
            double q = sm_mesh_min_quality(m, coords, NULL);
            double score =
                q > 0 && q >= floor_q ? boundary_rms_at(m, target, verts, nb, cand, xs, d) : INFINITY;
            w->candidates++;
            if (score < best) {
                best = score;
                memcpy(start, cand, n * sizeof *start);
                size_t len = strlen(de->d_name) - strlen(RECORD_SUFFIX);
                snprintf(w->source, sizeof w->source, "%.*s", (int)len, de->d_name);
            }
        }
        free(d);
    }
    closedir(dir);
    free(cand), free(coords), free(clamped), free(verts), free(xs), free(d);
    w->score_start = w->source[0] ? best : w->score_template;
    w->seconds = sm_clock_seconds() - t0;
    return w->source[0] != '\0';
}

static char *file_of(const sm_job_warm *w, const char *suffix)
{
    size_t len = strlen(w->name) + strlen(suffix) + 1;
    char *leaf = malloc(len), *path = NULL;
    if (leaf) {
        snprintf(leaf, len, "%s%s", w->name, suffix);
        path = sm_path_join(w->dir, leaf);
        free(leaf);
    }
    return path;
}

sm_status sm_job_warm_record(const sm_job_warm *w, const sm_job_inputs *in,
                             const sm_job_run *run, sm_error *err)
{
    const sm_mesh *m = run->alignment.done ? run->alignment.template_mesh : in->template_mesh;
    const size_t n = (size_t)m->nverts * (size_t)m->dim;
    size_t len = sizeof(record_head) + n * sizeof(double);
    char *buf = calloc(1, len);
    char *path = file_of(w, RECORD_SUFFIX), *used = file_of(w, ".used");
    sm_status st = SM_OK;
    if (!buf || !path || !used) {
        st = sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    } else {
        record_head h = {.dim = m->dim, .nverts = m->nverts};
        memcpy(h.magic, RECORD_MAGIC, 8);
        linear_part(&run->alignment, m->dim, h.linear);
        memcpy(buf, &h, sizeof h);
        double *d = (double *)(void *)(buf + sizeof h);
        for (size_t i = 0; i < n; i++)
            d[i] = run->coords[i] - m->coords[i];
        char text[512];
        int k = snprintf(text, sizeof text, "%s\n%d %.17g %.17g %.17g\n", w->source,
                         w->candidates, w->score_template, w->score_start, w->seconds);
        /* the choice first: the record is what the next targets read */
        st = sm_atomic_write_file(used, text, (size_t)k, 0, err);
        if (st == SM_OK)
            st = sm_atomic_write_file(path, buf, len, 0, err);
    }
    free(buf), free(path), free(used);
    return st;
}

int sm_job_warm_read_used(const char *dir, const char *name, sm_job_warm *w)
{
    sm_job_warm tmp = {.dir = dir, .name = name};
    char *path = file_of(&tmp, ".used");
    FILE *f = path ? fopen(path, "r") : NULL;
    free(path);
    w->source[0] = '\0';
    w->candidates = 0;
    w->score_template = w->score_start = w->seconds = NAN;
    if (!f)
        return 0;
    int ok = fgets(w->source, sizeof w->source, f) != NULL &&
             fscanf(f, "%d %lf %lf %lf", &w->candidates, &w->score_template, &w->score_start,
                    &w->seconds) == 4;
    fclose(f);
    w->source[strcspn(w->source, "\n")] = '\0';
    return ok;
}

void sm_job_warm_clear(const char *dir)
{
    DIR *d = opendir(dir);
    if (!d)
        return;
    struct dirent *de;
    while ((de = readdir(d)) != NULL) {
        if (strcmp(de->d_name, ".") == 0 || strcmp(de->d_name, "..") == 0)
            continue;
        char *path = sm_path_join(dir, de->d_name);
        if (path)
            unlink(path);
        free(path);
    }
    closedir(d);
    rmdir(dir);
}
