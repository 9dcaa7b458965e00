/* A small streaming JSON writer (objects, arrays, strings, numbers) for
 * the client's summary.json and NDJSON events.  Strings are escaped per
 * RFC 8259; bytes that are not valid UTF-8 (file names may contain any
 * byte) become U+FFFD so the output always parses.  Non-finite numbers
 * are written as null.  Pretty mode puts each object member on its own
 * line and keeps arrays (of scalars, in our files) on one line.  Write
 * errors are left to ferror() on the stream. */
#ifndef CLI_JSONW_H
#define CLI_JSONW_H

#include <stdint.h>
#include <stdio.h>

#define JSONW_MAX_DEPTH 16

typedef struct jsonw {
    FILE *f;
    int pretty;                   /* indent with 2 spaces, one item a line */
    int depth;
    int count[JSONW_MAX_DEPTH];   /* items written at each level */
    int inline_level[JSONW_MAX_DEPTH]; /* level printed on one line */
} jsonw;

void jsonw_init(jsonw *w, FILE *f, int pretty);

/* key is the member name inside an object, NULL inside an array or at
 * the top level. */
void jsonw_object_begin(jsonw *w, const char *key);
void jsonw_object_end(jsonw *w);
void jsonw_array_begin(jsonw *w, const char *key);
void jsonw_array_end(jsonw *w);
void jsonw_string(jsonw *w, const char *key, const char *value); /* NULL: null */
void jsonw_number(jsonw *w, const char *key, double value);
void jsonw_int(jsonw *w, const char *key, long long value);
void jsonw_bool(jsonw *w, const char *key, int value);
void jsonw_null(jsonw *w, const char *key);

#define JSON_NUMBER_LEN 32
/* Shortest decimal form of a finite v that reads back exactly (buf has
 * JSON_NUMBER_LEN bytes); returns buf.  Also used for CSV output. */
const char *json_format_number(char *buf, double v);

/* The escaped string, quotes included. */
void json_write_string(FILE *f, const char *s);

#endif
