/* The target list of a batch (sm_job_batch.h): targets given one by one
 * or as a LIST.csv, and their unique folder names.  Only the core's path
 * helpers below it, so the fuzz target links it alone. */
#ifndef SM_JOB_BATCH_LIST_H
#define SM_JOB_BATCH_LIST_H

#include <stddef.h>

#include "shapematch/sm_error.h"

/* One target.  Paths owned (malloc'd); name unique in its list. */
typedef struct sm_batch_target {
    char *name;
    char *target_surface, *target_mesh, *target_sol;
    char *target_image;     /* a label-map image (sm_job_image.h), or NULL */
    char *landmarks;        /* this target's landmark CSV, or NULL */
} sm_batch_target;

typedef struct sm_batch_list {
    sm_batch_target *t;
    size_t n, cap;
} sm_batch_list;

/* Adds a target (paths copied, NULL or "" for none; name NULL: the stem
 * of the surface, image or mesh file).  Names are made unique at
 * sm_batch_list_finish. */
sm_status sm_batch_list_add(sm_batch_list *l, const char *name, const char *surface,
                            const char *image, const char *mesh, const char *sol,
                            const char *landmarks, sm_error *err);

/* Parses a target list (text, len bytes; need not be NUL-terminated).
 * Format: a header line naming the columns, comma-separated, among
 * name, target_surface, target_image, target_mesh, target_sol, landmarks
 * (each at most once; target_surface, target_image or target_mesh
 * required); then one target per line with as many fields.  Blank lines and lines starting with '#' are
 * skipped; fields are trimmed of spaces and tabs; no quoting (a path with
 * a comma cannot be listed).  A row needs target_surface, target_image
 * (its distance on target_mesh when given, as `run`), or target_mesh with
 * target_sol; target_sol excludes the other two, and they each other.  Relative paths are
 * taken relative to base_dir (NULL: as they are).  Errors:
 * SM_ERR_FORMAT "LINE N: ..." (N from 1), the list left with the rows
 * before. */
sm_status sm_batch_list_parse(sm_batch_list *l, const char *text, size_t len,
                              const char *base_dir, sm_error *err);
/* Makes the names unique and usable as folder names: characters other
 * than letters, digits, '.', '-', '_' become '_', a leading '.' too;
 * the second "x" becomes "x-2", and so on. */
sm_status sm_batch_list_finish(sm_batch_list *l, sm_error *err);
void sm_batch_list_free(sm_batch_list *l);

#endif
