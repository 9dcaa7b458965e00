/* Bearer tokens (see smd_auth.h). */
#include "smd_auth.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "smd_util.h"

struct smd_tokens {
    size_t count;
    char **token;
    size_t *len;
};

void smd_tokens_free(smd_tokens *t)
{
    if (!t)
        return;
    for (size_t i = 0; i < t->count; i++) {
        /* do not leave secrets in freed memory */
        explicit_bzero(t->token[i], t->len[i]);
        free(t->token[i]);
    }
    free(t->token);
    free(t->len);
    free(t);
}

size_t smd_tokens_count(const smd_tokens *t)
{
    return t ? t->count : 0;
}

static int is_space(char c)
{
    return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\v' || c == '\f';
}

int smd_tokens_parse(const char *text, size_t len, const char *name,
                     smd_tokens **out, char *msg, size_t cap)
{
    *out = NULL;
    smd_tokens *t = calloc(1, sizeof *t);
    if (!t) {
        snprintf(msg, cap, "%s: out of memory", name);
        return -1;
    }
    size_t pos = 0, alloc = 0;
    long line = 0;
    while (pos < len) {
        line++;
        size_t start = pos;
        while (pos < len && text[pos] != '\n')
            pos++;
        size_t end = pos;
        if (pos < len)
            pos++; /* the newline */
        while (start < end && is_space(text[start]))
            start++;
        while (end > start && is_space(text[end - 1]))
            end--;
        if (start == end || text[start] == '#')
            continue;
        for (size_t i = start; i < end; i++) {
            unsigned char c = (unsigned char)text[i];
            if (c <= 0x20 || c == 0x7f) {
                snprintf(msg, cap, "%s:%ld: a token must not contain whitespace or control characters",
                         name, line);
                smd_tokens_free(t);
                return -1;
            }
        }
        if (end - start > SMD_TOKEN_MAX) {
            snprintf(msg, cap, "%s:%ld: token longer than %d bytes", name, line, SMD_TOKEN_MAX);
            smd_tokens_free(t);
            return -1;
        }
        if (t->count == alloc) {
            size_t n = alloc ? 2 * alloc : 8;
            char **tok = realloc(t->token, n * sizeof *tok);
            if (tok)
                t->token = tok;
            size_t *lens = tok ? realloc(t->len, n * sizeof *lens) : NULL;
            if (!tok || !lens) {
                snprintf(msg, cap, "%s: out of memory", name);
                smd_tokens_free(t);
                return -1;
            }
            t->len = lens;
            alloc = n;
        }
        char *copy = strndup(text + start, end - start);
        if (!copy) {
            snprintf(msg, cap, "%s: out of memory", name);
            smd_tokens_free(t);
            return -1;
        }
        t->token[t->count] = copy;
        t->len[t->count] = end - start;
        t->count++;
    }
    if (t->count == 0) {
        snprintf(msg, cap, "%s: no token in the file", name);
        smd_tokens_free(t);
        return -1;
    }
    *out = t;
    return 0;
}

int smd_tokens_load(const char *path, smd_tokens **out, char *msg, size_t cap)
{
    char *text;
    size_t len;
    *out = NULL;
    if (smd_read_file(path, SMD_TOKENS_FILE_MAX, &text, &len) != 0) {
        snprintf(msg, cap, "%s: %s", path,
                 errno == EFBIG ? "larger than 1 MiB" : strerror(errno));
        return -1;
    }
    int rc = smd_tokens_parse(text, len, path, out, msg, cap);
    explicit_bzero(text, len);
    free(text);
    return rc;
}

smd_auth_result smd_tokens_check(const smd_tokens *t, const char *authorization)
{
    if (!authorization)
        return SMD_AUTH_MISSING;
    while (*authorization == ' ')
        authorization++;
    if (strncasecmp(authorization, "Bearer", 6) != 0 || authorization[6] != ' ')
        return SMD_AUTH_MISSING;
    const char *given = authorization + 7;
    while (*given == ' ')
        given++;
    size_t given_len = strlen(given);
    while (given_len > 0 && given[given_len - 1] == ' ')
        given_len--;
    int match = 0;
    for (size_t i = 0; i < t->count; i++)
        match |= smd_secret_equal(given, given_len, t->token[i], t->len[i]);
    return match ? SMD_AUTH_OK : SMD_AUTH_INVALID;
}

smd_auth_result smd_tokens_check_token(const smd_tokens *t, const char *token)
{
    if (!token || !*token)
        return SMD_AUTH_MISSING;
    size_t len = strlen(token);
    int match = 0;
    for (size_t i = 0; i < t->count; i++)
        match |= smd_secret_equal(token, len, t->token[i], t->len[i]);
    return match ? SMD_AUTH_OK : SMD_AUTH_INVALID;
}
