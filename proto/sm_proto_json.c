#include "sm_proto_json.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sm_json.h"
#include "sm_proto_text.h"
#include "sm_proto_events.h"

void smp_path_join(char buf[SMP_PATH_MAX], const char *parent,
                   const char *key)
{
    /* Keys come from hostile input: keep messages printable and short. */
    char shown[64];
    sm_text_printable_copy(shown, sizeof shown, key, NULL);
    snprintf(buf, SMP_PATH_MAX, "%s.%s", parent, shown);
}

void smp_path_index(char buf[SMP_PATH_MAX], const char *parent, size_t index)
{
    snprintf(buf, SMP_PATH_MAX, "%s[%zu]", parent, index);
}

const char *smp_type_name(const json_t *v)
{
    switch (json_typeof(v)) {
    case JSON_OBJECT: return "object";
    case JSON_ARRAY: return "array";
    case JSON_STRING: return "string";
    case JSON_INTEGER: return "integer";
    case JSON_REAL: return "number";
    case JSON_TRUE: return "true";
    case JSON_FALSE: return "false";
    case JSON_NULL: return "null";
    }
    return "unknown";
}

sm_status smp_get_number(const json_t *v, const char *path, int allow_null,
                         double *out, sm_error *err)
{
    if (allow_null && json_is_null(v)) {
        *out = NAN;
        return SM_OK;
    }
    if (!json_is_number(v))
        return sm_error_set(err, SM_ERR_INVALID, "%s: must be a number%s (got %s)",
                            path, allow_null ? " or null" : "", smp_type_name(v));
    double x = json_number_value(v);
    /* jansson never produces a non-finite real, but an integer beyond
     * 2^53 loses precision silently: that is fine for a double field. */
    if (!isfinite(x))
        return sm_error_set(err, SM_ERR_INVALID, "%s: must be a finite number", path);
    *out = x;
    return SM_OK;
}

sm_status smp_get_integer(const json_t *v, const char *path, long long min,
                          long long max, long long *out, sm_error *err)
{
    long long value;
    if (json_is_integer(v)) {
        value = json_integer_value(v);
    } else if (json_is_real(v)) {
        double x = json_real_value(v);
        char got[SM_NUMBER_TEXT_LEN];
        if (x != floor(x))
            return sm_error_set(err, SM_ERR_INVALID, "%s: must be an integer (got %s)", path,
                                sm_number_text(got, x));
        /* Range test in double first so the conversion below is defined. */
        if (x < (double)min || x > (double)max)
            return sm_error_set(err, SM_ERR_INVALID,
                                "%s: must be an integer in [%lld, %lld] (got %s)", path,
                                min, max, sm_number_text(got, x));
        value = (long long)x;
    } else {
        return sm_error_set(err, SM_ERR_INVALID, "%s: must be an integer (got %s)", path,
                            smp_type_name(v));
    }
    if (value < min || value > max)
        return sm_error_set(err, SM_ERR_INVALID,
                            "%s: must be an integer in [%lld, %lld] (got %lld)", path,
                            min, max, value);
    *out = value;
    return SM_OK;
}

sm_status smp_load(const char *text, size_t len, size_t max_len,
                   const char *what, json_t **out, sm_error *err)
{
    *out = NULL;
    if (!text)
        return sm_error_set(err, SM_ERR_FORMAT, "%s: no document", what);
    if (len > max_len)
        return sm_error_set(err, SM_ERR_FORMAT,
                            "%s: document is %zu bytes, larger than the limit of %zu bytes",
                            what, len, max_len);
    json_error_t jerr;
    json_t *root = json_loadb(text, len, JSON_REJECT_DUPLICATES | JSON_DECODE_ANY, &jerr);
    if (!root)
        return sm_error_set(err, SM_ERR_FORMAT,
                            "%s: invalid JSON at line %d, column %d (byte %d): %s", what,
                            jerr.line, jerr.column, jerr.position, jerr.text);
    *out = root;
    return SM_OK;
}

json_t *smp_real_or_null(double x)
{
    return isfinite(x) ? json_real(x) : json_null();
}

int smp_set(json_t *obj, const char *key, json_t *value)
{
    if (!value)
        return -1;
    return json_object_set_new(obj, key, value);
}

/* ------------------------------------------------------------ serializer */

/* jansson prints every real with 17 significant digits (0.3 comes out as
 * 0.29999999999999999); this writer prints the shortest text that reads
 * back to the same double, so documents stay exact and readable. */

typedef struct outbuf {
    char *data;
    size_t len, cap;
    int failed;
} outbuf;

static void out_bytes(outbuf *b, const char *s, size_t n)
{
    if (b->failed)
        return;
    if (b->len + n + 1 > b->cap) {
        size_t cap = b->cap ? b->cap : 256;
        while (b->len + n + 1 > cap)
            cap *= 2;
        char *grown = realloc(b->data, cap);
        if (!grown) {
            b->failed = 1;
            return;
        }
        b->data = grown;
        b->cap = cap;
    }
    memcpy(b->data + b->len, s, n);
    b->len += n;
    b->data[b->len] = '\0';
}

static void out_str(outbuf *b, const char *s) { out_bytes(b, s, strlen(s)); }

/* Shortest "%.{15,16,17}g" text that reads back to x, with ".0" added to
 * integral values; "null" when not finite. */
#define SMP_DOUBLE_LEN 40
static void smp_format_double(char buf[SMP_DOUBLE_LEN], double x)
{
    if (!isfinite(x)) {
        snprintf(buf, SMP_DOUBLE_LEN, "null");
        return;
    }
    for (int digits = 15; digits <= 17; digits++) {
        snprintf(buf, SMP_DOUBLE_LEN, "%.*g", digits, x);
        if (strtod(buf, NULL) == x)
            break;
    }
    /* keep it a real for readers that distinguish (1 -> 1.0) */
    if (!strpbrk(buf, ".eEn"))
        strncat(buf, ".0", SMP_DOUBLE_LEN - strlen(buf) - 1);
}

static void out_string(outbuf *b, const char *s, size_t n)
{
    out_bytes(b, "\"", 1);
    size_t run = 0;
    for (size_t i = 0; i < n; i++) {
        unsigned char c = (unsigned char)s[i];
        const char *esc = NULL;
        char hex[8];
        switch (c) {
        case '"': esc = "\\\""; break;
        case '\\': esc = "\\\\"; break;
        case '\n': esc = "\\n"; break;
        case '\r': esc = "\\r"; break;
        case '\t': esc = "\\t"; break;
        case '\b': esc = "\\b"; break;
        case '\f': esc = "\\f"; break;
        default:
            if (c < 0x20) {
                snprintf(hex, sizeof hex, "\\u%04x", c);
                esc = hex;
            }
        }
        if (esc) {
            out_bytes(b, s + run, i - run);
            out_str(b, esc);
            run = i + 1;
        }
    }
    out_bytes(b, s + run, n - run);
    out_bytes(b, "\"", 1);
}

static void out_newline(outbuf *b, int indent, int depth)
{
    if (!indent)
        return;
    out_bytes(b, "\n", 1);
    for (int i = 0; i < indent * depth; i++)
        out_bytes(b, " ", 1);
}

static void out_value(outbuf *b, const json_t *v, int indent, int depth)
{
    char num[SMP_DOUBLE_LEN];
    if (depth > 64) { /* documents built here are shallow; refuse cycles */
        b->failed = 1;
        return;
    }
    switch (json_typeof(v)) {
    case JSON_OBJECT: {
        const char *key;
        json_t *member;
        int first = 1;
        out_bytes(b, "{", 1);
        json_object_foreach((json_t *)v, key, member) {
            if (!first)
                out_bytes(b, ",", 1);
            first = 0;
            out_newline(b, indent, depth + 1);
            out_string(b, key, strlen(key));
            out_str(b, indent ? ": " : ":");
            out_value(b, member, indent, depth + 1);
        }
        if (!first)
            out_newline(b, indent, depth);
        out_bytes(b, "}", 1);
        break;
    }
    case JSON_ARRAY: {
        size_t i;
        json_t *item;
        out_bytes(b, "[", 1);
        json_array_foreach((json_t *)v, i, item) {
            if (i)
                out_str(b, indent ? ", " : ",");
            out_value(b, item, indent, depth + 1);
        }
        out_bytes(b, "]", 1);
        break;
    }
    case JSON_STRING:
        out_string(b, json_string_value(v), json_string_length(v));
        break;
    case JSON_INTEGER:
        snprintf(num, sizeof num, "%" JSON_INTEGER_FORMAT, json_integer_value(v));
        out_str(b, num);
        break;
    case JSON_REAL:
        smp_format_double(num, json_real_value(v));
        out_str(b, num);
        break;
    case JSON_TRUE:
        out_str(b, "true");
        break;
    case JSON_FALSE:
        out_str(b, "false");
        break;
    case JSON_NULL:
        out_str(b, "null");
        break;
    }
}

char *sm_json_dumps(const json_t *value, int indent)
{
    outbuf b = {0};
    if (!value || indent < 0 || indent > 8)
        return NULL;
    out_value(&b, value, indent, 0);
    if (!b.failed && !b.data)
        b.failed = 1;
    if (b.failed) {
        free(b.data);
        return NULL;
    }
    return b.data;
}

/* Length of the valid UTF-8 sequence at s (1..4), or 0 if invalid
 * (overlong forms, surrogates and values above U+10FFFF included). */
static int utf8_sequence(const unsigned char *s)
{
    unsigned c = s[0];
    if (c < 0x80)
        return 1;
    int n;
    unsigned cp;
    if (c >= 0xc2 && c <= 0xdf) {
        n = 2;
        cp = c & 0x1f;
    } else if (c >= 0xe0 && c <= 0xef) {
        n = 3;
        cp = c & 0x0f;
    } else if (c >= 0xf0 && c <= 0xf4) {
        n = 4;
        cp = c & 0x07;
    } else {
        return 0;
    }
    for (int i = 1; i < n; i++) {
        if ((s[i] & 0xc0) != 0x80)
            return 0;
        cp = (cp << 6) | (s[i] & 0x3f);
    }
    if ((n == 3 && cp < 0x800) || (n == 4 && (cp < 0x10000 || cp > 0x10ffff)) ||
        (cp >= 0xd800 && cp <= 0xdfff))
        return 0;
    return n;
}

json_t *sm_json_string_lossy(const char *s)
{
    if (!s)
        return NULL;
    size_t len = strlen(s);
    char *buf = malloc(3 * len + 1); /* each invalid byte: 3 bytes of U+FFFD */
    if (!buf)
        return NULL;
    size_t k = 0;
    for (const unsigned char *p = (const unsigned char *)s; *p;) {
        int n = utf8_sequence(p);
        if (n == 0) {
            memcpy(buf + k, "\xef\xbf\xbd", 3);
            k += 3;
            p++;
        } else {
            memcpy(buf + k, p, (size_t)n);
            k += (size_t)n;
            p += n;
        }
    }
    json_t *v = json_stringn(buf, k);
    free(buf);
    return v;
}
