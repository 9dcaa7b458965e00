/* TLS certificates with reload (see smd_tls.h). */
#include "http/smd_tls.h"

#include <gnutls/abstract.h>
#include <gnutls/gnutls.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/smd_util.h"

#define TLS_FILE_MAX (1 << 20)
#define TLS_CHAIN_MAX 16

typedef struct tls_pair {
    gnutls_pcert_st chain[TLS_CHAIN_MAX];
    unsigned nchain;
    gnutls_privkey_t key;
    struct tls_pair *older; /* replaced pairs, kept until shutdown */
} tls_pair;

/* the process's TLS configuration (the callback has no user pointer) */
static pthread_mutex_t tls_lock = PTHREAD_MUTEX_INITIALIZER;
static tls_pair *tls_current;

static void pair_free(tls_pair *p)
{
    for (unsigned i = 0; i < p->nchain; i++)
        gnutls_pcert_deinit(&p->chain[i]);
    if (p->key)
        gnutls_privkey_deinit(p->key);
    free(p);
}

/* file's bytes as a gnutls datum (malloc'd) */
static int read_datum(const char *path, gnutls_datum_t *d, char *msg, size_t cap)
{
    char *text;
    size_t len;
    if (smd_read_file(path, TLS_FILE_MAX, &text, &len) != 0) {
        snprintf(msg, cap, "%s: cannot read it (missing, unreadable or over 1 MiB)", path);
        return -1;
    }
    d->data = (unsigned char *)text;
    d->size = (unsigned)len;
    return 0;
}

static int load_pair(const char *cert_file, const char *key_file, tls_pair *p, char *msg,
                     size_t cap)
{
    gnutls_datum_t cert = {NULL, 0}, key = {NULL, 0};
    int rc = -1, e;
    if (read_datum(cert_file, &cert, msg, cap) != 0 || read_datum(key_file, &key, msg, cap) != 0)
        goto done;
    p->nchain = TLS_CHAIN_MAX;
    if ((e = gnutls_pcert_list_import_x509_raw(p->chain, &p->nchain, &cert, GNUTLS_X509_FMT_PEM,
                                               0)) < 0) {
        p->nchain = 0;
        snprintf(msg, cap, "%s: not a PEM certificate chain (%s)", cert_file, gnutls_strerror(e));
        goto done;
    }
    if ((e = gnutls_privkey_init(&p->key)) < 0 ||
        (e = gnutls_privkey_import_x509_raw(p->key, &key, GNUTLS_X509_FMT_PEM, NULL, 0)) < 0) {
        snprintf(msg, cap, "%s: not a PEM private key (%s)", key_file, gnutls_strerror(e));
        goto done;
    }
    rc = 0;
done:
    if (key.data) {
        explicit_bzero(key.data, key.size); /* no key material in freed memory */
        free(key.data);
    }
    free(cert.data);
    return rc;
}

int smd_tls_load(const char *cert_file, const char *key_file, char *msg, size_t cap)
{
    tls_pair *p = calloc(1, sizeof *p);
    if (!p) {
        snprintf(msg, cap, "out of memory");
        return -1;
    }
    if (load_pair(cert_file, key_file, p, msg, cap) != 0) {
        pair_free(p);
        return -1;
    }
    pthread_mutex_lock(&tls_lock);
    p->older = tls_current;
    tls_current = p;
    pthread_mutex_unlock(&tls_lock);
    return 0;
}

/* gnutls_certificate_retrieve_function2: the current pair, whatever the
 * client asked for (one certificate per daemon). */
static int retrieve(gnutls_session_t session, const gnutls_datum_t *req_ca_dn, int nreqs,
                    const gnutls_pk_algorithm_t *pk_algos, int pk_algos_length,
                    gnutls_pcert_st **pcert, unsigned int *pcert_length, gnutls_privkey_t *pkey)
{
    (void)session;
    (void)req_ca_dn;
    (void)nreqs;
    (void)pk_algos;
    (void)pk_algos_length;
    pthread_mutex_lock(&tls_lock);
    tls_pair *p = tls_current;
    if (p) {
        *pcert = p->chain;
        *pcert_length = p->nchain;
        *pkey = p->key;
    }
    pthread_mutex_unlock(&tls_lock);
    return p ? 0 : -1;
}

void *smd_tls_callback(void)
{
    return (void *)&retrieve;
}

void smd_tls_shutdown(void)
{
    pthread_mutex_lock(&tls_lock);
    tls_pair *p = tls_current;
    tls_current = NULL;
    pthread_mutex_unlock(&tls_lock);
    while (p) {
        tls_pair *next = p->older;
        pair_free(p);
        p = next;
    }
}
