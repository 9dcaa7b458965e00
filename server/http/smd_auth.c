/* Bearer tokens (see smd_auth.h). */
#include "http/smd_auth.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "base/smd_util.h"

struct smd_tokens {
    size_t count;
    char **token;
    size_t *len;
    smd_identity *who;
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
    free(t->who);
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

static int tenant_char(unsigned char c)
{
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
           c == '.' || c == '_' || c == '-';
}

/* One trimmed line [start, end): "TOKEN [NAME [admin]]".  *tok_end: end
 * of the token; who: its tenant.  -1 with msg on a malformed line. */
static int split_line(const char *text, size_t start, size_t end, size_t *tok_end,
                      smd_identity *who, const char *file, long line, char *msg, size_t cap)
{
    size_t word[3][2] = {{0, 0}, {0, 0}, {0, 0}}, nwords = 0, i = start;
    while (i < end) {
        if (nwords == 3) {
            snprintf(msg, cap, "%s:%ld: expected TOKEN [NAME [admin]], found more words", file, line);
            return -1;
        }
        word[nwords][0] = i;
        while (i < end && text[i] != ' ' && text[i] != '\t') {
            unsigned char c = (unsigned char)text[i];
            if (c < 0x20 || c == 0x7f) {
                snprintf(msg, cap, "%s:%ld: a token must not contain whitespace or control characters",
                         file, line);
                return -1;
            }
            i++;
        }
        word[nwords++][1] = i;
        while (i < end && (text[i] == ' ' || text[i] == '\t'))
            i++;
    }
    *tok_end = word[0][1];
    memset(who, 0, sizeof *who);
    who->admin = nwords == 1; /* the original form: sees everything */
    if (nwords >= 2) {
        size_t n = word[1][1] - word[1][0];
        for (size_t k = word[1][0]; k < word[1][1]; k++)
            if (!tenant_char((unsigned char)text[k]))
                n = 0;
        if (n == 0 || n > SMD_TENANT_MAX) {
            snprintf(msg, cap, "%s:%ld: a tenant name is 1 to %d letters, digits, '.', '_' or '-'",
                     file, line, SMD_TENANT_MAX);
            return -1;
        }
        memcpy(who->tenant, text + word[1][0], n);
    }
    if (nwords == 3) {
        if (word[2][1] - word[2][0] != 5 || strncmp(text + word[2][0], "admin", 5) != 0) {
            snprintf(msg, cap, "%s:%ld: the third word must be 'admin'", file, line);
            return -1;
        }
        who->admin = 1;
    }
    return 0;
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
        smd_identity who;
        size_t tok_end;
        if (split_line(text, start, end, &tok_end, &who, name, line, msg, cap) != 0) {
            smd_tokens_free(t);
            return -1;
        }
        end = tok_end;
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
            if (lens)
                t->len = lens;
            smd_identity *ids = lens ? realloc(t->who, n * sizeof *ids) : NULL;
            if (!tok || !lens || !ids) {
                snprintf(msg, cap, "%s: out of memory", name);
                smd_tokens_free(t);
                return -1;
            }
            t->who = ids;
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
        t->who[t->count] = who;
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
    return smd_tokens_identify(t, authorization, NULL);
}

/* Every token is compared (constant time whichever matches); the first
 * match names the tenant. */
static smd_auth_result identify_given(const smd_tokens *t, const char *given, size_t given_len,
                                      smd_identity *who)
{
    int match = 0;
    size_t which = 0;
    for (size_t i = 0; i < t->count; i++) {
        int eq = smd_secret_equal(given, given_len, t->token[i], t->len[i]);
        which = eq && !match ? i : which;
        match |= eq;
    }
    if (match && who)
        *who = t->who[which];
    return match ? SMD_AUTH_OK : SMD_AUTH_INVALID;
}

smd_auth_result smd_tokens_identify(const smd_tokens *t, const char *authorization,
                                    smd_identity *who)
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
    return identify_given(t, given, given_len, who);
}

smd_auth_result smd_tokens_identify_token(const smd_tokens *t, const char *token,
                                          smd_identity *who)
{
    if (!token || !*token)
        return SMD_AUTH_MISSING;
    return identify_given(t, token, strlen(token), who);
}
