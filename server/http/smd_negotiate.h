/* Content negotiation (smd_negotiate.c): the Accept and Accept-Encoding
 * headers (RFC 9110 12.5).  Pure functions of the header text. */
#ifndef SMD_NEGOTIATE_H
#define SMD_NEGOTIATE_H

/* Picks among offered media types (first = default) the one the Accept
 * header prefers (q-values, type/ and star wildcards).  Returns the
 * index, 0 when accept is NULL or empty, -1 when none is acceptable. */
int smd_accept_choose(const char *accept, const char *const *offered, int n);
/* 1 when the Accept-Encoding header value allows gzip. */
int smd_accepts_gzip(const char *accept_encoding);

#endif
