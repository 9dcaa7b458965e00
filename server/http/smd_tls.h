/* TLS for the HTTP front (libmicrohttpd with GnuTLS): the certificate
 * chain and key come from PEM files (--tls-cert, --tls-key), TLS 1.2 and
 * 1.3 only, and SIGHUP reloads them without a restart: every handshake
 * asks for the current pair (a certificate callback), so a reload takes
 * effect on the next connection and open ones keep theirs.
 *
 * libmicrohttpd's certificate callback takes no user pointer, so the
 * current pair lives in this module (one TLS configuration per process:
 * the daemon's).  Pairs replaced by a reload are kept until
 * smd_tls_shutdown (a handshake in flight may still use one); each reload
 * costs one pair of memory, bounded by the number of SIGHUPs. */
#ifndef SMD_TLS_H
#define SMD_TLS_H

#include <stddef.h>

/* The GnuTLS priority string: TLS 1.2 and 1.3, GnuTLS's NORMAL ciphers. */
#define SMD_TLS_PRIORITIES "NORMAL:-VERS-ALL:+VERS-TLS1.3:+VERS-TLS1.2"

/* Loads cert_file (PEM chain, leaf first) and key_file (PEM key) as the
 * current pair; 0, or -1 with msg saying which file and why.  On failure
 * the pair in use (if any) stays. */
int smd_tls_load(const char *cert_file, const char *key_file, char *msg, size_t cap);

/* The value for MHD_OPTION_HTTPS_CERT_CALLBACK (a
 * gnutls_certificate_retrieve_function2 *). */
void *smd_tls_callback(void);

/* Frees every pair loaded (after the HTTP daemon stopped). */
void smd_tls_shutdown(void);

#endif
