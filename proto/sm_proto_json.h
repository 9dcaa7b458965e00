/* Internal helpers shared by the proto sources (not installed, not part of the
 * contract): strict typed reads of jansson values with messages that name
 * the JSON path of the offending member. */
#ifndef SM_PROTO_JSON_H
#define SM_PROTO_JSON_H

#include <stddef.h>
#include <stdint.h>

#include <jansson.h>

#include "shapematch/sm_error.h"

/* Longest path kept in messages; deeper paths are cut (still readable). */
#define SMP_PATH_MAX 160

/* Writes "parent.key" into buf, with the key made printable (control and
 * non-ASCII bytes shown as '?', long keys cut with "..."). */
void smp_path_join(char buf[SMP_PATH_MAX], const char *parent,
                   const char *key);
/* "parent[index]". */
void smp_path_index(char buf[SMP_PATH_MAX], const char *parent, size_t index);

/* JSON type name for messages: "object", "array", "string", "integer",
 * "number", "true", "false", "null". */
const char *smp_type_name(const json_t *v);

/* Number (integer or real) into *out.  allow_null: null reads as NaN. */
sm_status smp_get_number(const json_t *v, const char *path, int allow_null,
                         double *out, sm_error *err);
/* Integer in [min, max]; a real with no fractional part counts as an
 * integer (as in JSON Schema). */
sm_status smp_get_integer(const json_t *v, const char *path, long long min,
                          long long max, long long *out, sm_error *err);

/* Parses len bytes of text (no NUL needed) with duplicate keys rejected;
 * messages start with what ("params", "event", ...) and give line, column
 * and byte offset of a syntax error. */
sm_status smp_load(const char *text, size_t len, size_t max_len,
                   const char *what, json_t **out, sm_error *err);

/* Real value for a double: json_real, or json_null when not finite
 * (JSON cannot carry NaN or infinities). */
json_t *smp_real_or_null(double x);


/* json_object_set_new that reports failure (and releases value). */
int smp_set(json_t *obj, const char *key, json_t *value);

#endif
