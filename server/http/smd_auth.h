/* Bearer-token authentication: a tokens file holds one token per line
 * (blank lines and lines starting with '#' are skipped, surrounding
 * whitespace is trimmed).  A request is authorized when its
 * "Authorization: Bearer <token>" matches one of them; every stored token
 * is compared, in constant time, whatever the outcome.
 *
 * Tenants: a line "TOKEN NAME" or "TOKEN NAME admin" gives the token a
 * tenant name (letters, digits, '.', '_', '-', at most SMD_TENANT_MAX):
 * its jobs belong to NAME and other tenants do not see them; "admin" sees
 * every job.  A line with the token alone (the original form) is an
 * unnamed admin: such a daemon behaves as before (every token sees every
 * job). */
#ifndef SMD_AUTH_H
#define SMD_AUTH_H

#include <stddef.h>

typedef struct smd_tokens smd_tokens;

/* Largest tokens file read, and longest token kept. */
#define SMD_TOKENS_FILE_MAX (1 << 20)
#define SMD_TOKEN_MAX 4096
#define SMD_TENANT_MAX 64

/* Who a request is: its tenant ("" for unnamed tokens and for a daemon
 * without tokens) and whether it sees every tenant's jobs. */
typedef struct smd_identity {
    char tenant[SMD_TENANT_MAX + 1];
    int admin;
} smd_identity;

/* Loads path.  Returns 0, or -1 with msg saying why (unreadable, too
 * large, no token in it, a token with inner whitespace or control
 * characters, with its line number). */
int smd_tokens_load(const char *path, smd_tokens **out, char *msg, size_t cap);
/* Same from text in memory (for tests); name is used in messages. */
int smd_tokens_parse(const char *text, size_t len, const char *name,
                     smd_tokens **out, char *msg, size_t cap);
void smd_tokens_free(smd_tokens *t);
size_t smd_tokens_count(const smd_tokens *t);

typedef enum smd_auth_result {
    SMD_AUTH_OK = 0,
    SMD_AUTH_MISSING = 1,  /* no Authorization header or not Bearer */
    SMD_AUTH_INVALID = 2   /* a bearer token that matches none */
} smd_auth_result;

/* Checks an Authorization header value (NULL when absent). */
smd_auth_result smd_tokens_check(const smd_tokens *t, const char *authorization);
/* The same, and on SMD_AUTH_OK fills who (may be NULL) from the token's
 * line. */
smd_auth_result smd_tokens_identify(const smd_tokens *t, const char *authorization,
                                    smd_identity *who);
/* Likewise for a bare token (the access_token query parameter of RFC 6750
 * section 2.3; NULL when absent). */
smd_auth_result smd_tokens_identify_token(const smd_tokens *t, const char *token,
                                          smd_identity *who);

#endif
