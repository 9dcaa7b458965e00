/* Submission limits of shapematchd (issue 8): per tenant, or per client
 * address when the daemon runs without tokens.
 *
 * Two limits, both answered 429 problem+json with Retry-After:
 * - --submit-rate N per --submit-window: a fixed window per key, counted
 *   when a POST /v1/jobs arrives (before its body is read, so a refused
 *   client uploads nothing); Retry-After is the rest of the window;
 * - --max-queued N: unfinished jobs (accepted, queued, running) of the
 *   key.  With tokens they are counted from the job table by owner (it
 *   survives restarts); without, the limiter remembers the ids each
 *   address submitted and asks the caller which are still unfinished.
 *
 * The table holds at most SMD_RATELIMIT_KEYS keys (bounded memory); when
 * it is full, a new key takes the room of one whose window has passed and
 * that tracks no job, else of the least recently used key tracking none,
 * else of the least recently used (its tracked jobs forgotten): a flood
 * of throw-away keys (addresses) evicts idle keys and never shuts new
 * ones out, and a refusal is always a key's own rate (issue 28).  One mutex of
 * its own, taken after the server lock when both are held (never the
 * other way round).  Cost: O(keys) per submission. */
#ifndef SMD_RATELIMIT_H
#define SMD_RATELIMIT_H

#include <stddef.h>

#include "base/smd_util.h"

#define SMD_RATELIMIT_KEYS 4096
#define SMD_RATELIMIT_KEY_MAX 80

typedef struct smd_ratelimit smd_ratelimit;

/* rate 0 = no rate limit; window in seconds (> 0).  NULL when out of
 * memory. */
smd_ratelimit *smd_ratelimit_new(unsigned rate, double window);
void smd_ratelimit_free(smd_ratelimit *rl);

/* The limit key of a client address (text, as smd_conn_address gives
 * it) into key (cap >= SMD_RATELIMIT_KEY_MAX + 1): "a:<address>", an
 * IPv6 one by its /64 ("a:2001:db8:1:2::/64": a client holds 2^64
 * addresses), an IPv4 one (or IPv4-mapped IPv6) by its network of
 * ipv4_prefix bits (8..32; 32: the address itself, else
 * "a:198.51.100.0/24"). */
void smd_ratelimit_address_key(const char *addr, unsigned ipv4_prefix, char *key, size_t cap);

/* Counts one submission of key at monotonic time now.  0 when it is
 * allowed, else the seconds until the key's window ends (>= 1). */
unsigned smd_ratelimit_take(smd_ratelimit *rl, const char *key, double now);

/* Is job id still unfinished?  Called with the caller's lock held. */
typedef int (*smd_ratelimit_live_fn)(const char *id, void *user);

/* Remembers that key submitted job id (daemons without tokens). */
void smd_ratelimit_track(smd_ratelimit *rl, const char *key, const char *id);
/* The tracked jobs of key that live() still calls unfinished; the others
 * are forgotten. */
size_t smd_ratelimit_live(smd_ratelimit *rl, const char *key, smd_ratelimit_live_fn live,
                          void *user);

#endif
