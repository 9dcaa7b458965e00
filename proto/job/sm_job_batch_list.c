/* The target list of a batch (see sm_job_batch_list.h). */
#include "job/sm_job_batch_list.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "shapematch/sm_path.h"

/* ------------------------------------------------------------ the list */

static char *dup_or_null(const char *s)
{
    return s && *s ? strdup(s) : NULL;
}

/* The file's stem: no folder, no ".gz", no last extension. */
static char *stem_of(const char *path)
{
    const char *base = strrchr(path, '/');
    char *s = strdup(base ? base + 1 : path);
    if (!s)
        return NULL;
    size_t n = strlen(s);
    if (n > 3 && strcmp(s + n - 3, ".gz") == 0)
        s[n -= 3] = '\0';
    char *dot = strrchr(s, '.');
    if (dot && dot != s)
        *dot = '\0';
    return s;
}

sm_status sm_batch_list_add(sm_batch_list *l, const char *name, const char *surface,
                            const char *image, const char *mesh, const char *sol,
                            const char *landmarks, sm_error *err)
{
    if (l->n == l->cap) {
        size_t cap = l->cap ? 2 * l->cap : 16;
        sm_batch_target *t = realloc(l->t, cap * sizeof *t);
        if (!t)
            return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
        l->t = t;
        l->cap = cap;
    }
    sm_batch_target *t = &l->t[l->n];
    memset(t, 0, sizeof *t);
    t->name = name && *name             ? strdup(name)
              : surface && *surface ? stem_of(surface)
              : image && *image     ? stem_of(image)
                                    : stem_of(mesh ? mesh : "");
    t->target_surface = dup_or_null(surface);
    t->target_image = dup_or_null(image);
    t->target_mesh = dup_or_null(mesh);
    t->target_sol = dup_or_null(sol);
    t->landmarks = dup_or_null(landmarks);
    l->n++;
    if (!t->name || (surface && *surface && !t->target_surface) ||
        (image && *image && !t->target_image) ||
        (mesh && *mesh && !t->target_mesh) || (sol && *sol && !t->target_sol) ||
        (landmarks && *landmarks && !t->landmarks))
        return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    return SM_OK;
}

enum { COL_NAME, COL_SURFACE, COL_IMAGE, COL_MESH, COL_SOL, COL_LANDMARKS, NCOLS };
static const char *const col_names[NCOLS] = {"name",        "target_surface", "target_image",
                                              "target_mesh", "target_sol",     "landmarks"};

/* Splits line (modified) at commas into at most cap trimmed fields;
 * returns the count, or cap + 1 when there are more. */
static int split_fields(char *line, char **f, int cap)
{
    int n = 0;
    for (char *p = line;;) {
        char *comma = strchr(p, ',');
        if (comma)
            *comma = '\0';
        while (*p == ' ' || *p == '\t')
            p++;
        char *e = p + strlen(p);
        while (e > p && (e[-1] == ' ' || e[-1] == '\t' || e[-1] == '\r'))
            *--e = '\0';
        if (n == cap)
            return cap + 1;
        f[n++] = p;
        if (!comma)
            return n;
        p = comma + 1;
    }
}

/* path relative to base (a new string). */
static char *resolve(const char *base, const char *path)
{
    if (!path || !*path)
        return NULL;
    if (!base || !*base || path[0] == '/')
        return strdup(path);
    return sm_path_join(base, path);
}

static sm_status parse_header(char *line, int *col, int *ncol, size_t lineno, sm_error *err)
{
    char *f[NCOLS + 1];
    int n = split_fields(line, f, NCOLS);
    if (n > NCOLS)
        return sm_error_set(err, SM_ERR_FORMAT, "line %zu: more than %d columns", lineno, NCOLS);
    for (int c = 0; c < NCOLS; c++)
        col[c] = -1;
    for (int i = 0; i < n; i++) {
        int c = 0;
        while (c < NCOLS && strcmp(f[i], col_names[c]) != 0)
            c++;
        if (c == NCOLS)
            return sm_error_set(err, SM_ERR_FORMAT,
                                "line %zu: unknown column '%.64s' (name, target_surface, "
                                "target_image, target_mesh, target_sol, landmarks)", lineno, f[i]);
        if (col[c] >= 0)
            return sm_error_set(err, SM_ERR_FORMAT, "line %zu: column %s given twice", lineno,
                                col_names[c]);
        col[c] = i;
    }
    if (col[COL_SURFACE] < 0 && col[COL_IMAGE] < 0 && col[COL_MESH] < 0)
        return sm_error_set(err, SM_ERR_FORMAT,
                            "line %zu: the header names none of target_surface, target_image, "
                            "target_mesh", lineno);
    *ncol = n;
    return SM_OK;
}

static sm_status parse_row(sm_batch_list *l, char *line, const int *col, int ncol,
                           const char *base, size_t lineno, sm_error *err)
{
    char *f[NCOLS + 1];
    int n = split_fields(line, f, NCOLS);
    if (n != ncol)
        return sm_error_set(err, SM_ERR_FORMAT, "line %zu: %d field%s, the header has %d",
                            lineno, n, n == 1 ? "" : "s", ncol);
    const char *v[NCOLS];
    for (int c = 0; c < NCOLS; c++)
        v[c] = col[c] >= 0 && *f[col[c]] ? f[col[c]] : NULL;
    if (!v[COL_SURFACE] && !v[COL_IMAGE] && !(v[COL_MESH] && v[COL_SOL]))
        return sm_error_set(err, SM_ERR_FORMAT,
                            "line %zu: a target needs target_surface, target_image, or "
                            "target_mesh and target_sol", lineno);
    if (!!v[COL_SURFACE] + !!v[COL_IMAGE] + !!v[COL_SOL] > 1)
        return sm_error_set(err, SM_ERR_FORMAT,
                            "line %zu: target_surface, target_image and target_sol exclude "
                            "each other", lineno);
    char *p[NCOLS] = {NULL};
    sm_status st = SM_OK;
    for (int c = COL_SURFACE; c < NCOLS; c++)
        if (v[c] && !(p[c] = resolve(base, v[c])))
            st = sm_error_set(err, SM_ERR_NOMEM, "out of memory");
    if (st == SM_OK)
        st = sm_batch_list_add(l, v[COL_NAME], p[COL_SURFACE], p[COL_IMAGE], p[COL_MESH],
                               p[COL_SOL], p[COL_LANDMARKS], err);
    for (int c = 0; c < NCOLS; c++)
        free(p[c]);
    return st;
}

sm_status sm_batch_list_parse(sm_batch_list *l, const char *text, size_t len,
                              const char *base_dir, sm_error *err)
{
    int col[NCOLS], ncol = 0, have_header = 0;
    size_t lineno = 0;
    for (size_t at = 0; at < len;) {
        const char *nl = memchr(text + at, '\n', len - at);
        size_t n = nl ? (size_t)(nl - (text + at)) : len - at;
        lineno++;
        if (memchr(text + at, '\0', n))
            return sm_error_set(err, SM_ERR_FORMAT, "line %zu: NUL byte", lineno);
        if (n > 16384)
            return sm_error_set(err, SM_ERR_FORMAT, "line %zu: longer than 16384 bytes", lineno);
        char *line = malloc(n + 1);
        if (!line)
            return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
        memcpy(line, text + at, n);
        line[n] = '\0';
        at += n + (nl ? 1 : 0);
        const char *s = line + strspn(line, " \t\r");
        sm_status st = SM_OK;
        if (*s && *s != '#') {
            if (!have_header)
                st = parse_header(line, col, &ncol, lineno, err), have_header = 1;
            else
                st = parse_row(l, line, col, ncol, base_dir, lineno, err);
        }
        free(line);
        if (st != SM_OK)
            return st;
    }
    if (!have_header)
        return sm_error_set(err, SM_ERR_FORMAT, "the list is empty (no header line)");
    return SM_OK;
}

sm_status sm_batch_list_finish(sm_batch_list *l, sm_error *err)
{
    for (size_t i = 0; i < l->n; i++) {
        char *s = l->t[i].name;
        for (char *p = s; *p; p++)
            if (!((*p >= 'a' && *p <= 'z') || (*p >= 'A' && *p <= 'Z') ||
                  (*p >= '0' && *p <= '9') || *p == '.' || *p == '-' || *p == '_') ||
                (p == s && *p == '.'))
                *p = '_';
        if (!*s) {
            free(s);
            if (!(l->t[i].name = strdup("target")))
                return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
        }
        for (int k = 2;; k++) {
            size_t j = 0;
            while (j < i && strcmp(l->t[j].name, l->t[i].name) != 0)
                j++;
            if (j == i)
                break;
            size_t n = strlen(l->t[i].name) + 24;
            char *u = malloc(n);
            if (!u)
                return sm_error_set(err, SM_ERR_NOMEM, "out of memory");
            /* from the original stem each time: x, x-2, x-3 */
            char *dash = k > 2 ? strrchr(l->t[i].name, '-') : NULL;
            if (dash)
                *dash = '\0';
            snprintf(u, n, "%s-%d", l->t[i].name, k);
            free(l->t[i].name);
            l->t[i].name = u;
        }
    }
    return SM_OK;
}

void sm_batch_list_free(sm_batch_list *l)
{
    for (size_t i = 0; l && i < l->n; i++) {
        free(l->t[i].name);
        free(l->t[i].target_surface);
        free(l->t[i].target_image);
        free(l->t[i].target_mesh);
        free(l->t[i].target_sol);
        free(l->t[i].landmarks);
    }
    if (l) {
        free(l->t);
        memset(l, 0, sizeof *l);
    }
}
