/* libcurl, loaded when a command first talks to a daemon.
 *
 * libcurl and the ~30 libraries it pulls in (TLS, Kerberos, LDAP, SSH,
 * HTTP/2, ...) cost about 20 ms at every start of the process when they
 * are linked: mapped and relocated before main, on this VM at 13 µs a
 * page fault.  The local commands (run, sdf, check) never use them, so
 * the client opens libcurl.so.4 with dlopen in curl_api_load, which
 * http_global_init calls, and calls it through the table below.  The
 * prototypes are libcurl's own (__typeof__ of its declarations). */
#ifndef CLI_CURL_API_H
#define CLI_CURL_API_H

#include <stddef.h>

#include <curl/curl.h>

/* The functions the client uses, X(name) for curl_<name>. */
#define CURL_API_FUNCTIONS(X)                                                                      \
    X(global_init)                                                                                 \
    X(global_cleanup)                                                                              \
    X(easy_init)                                                                                   \
    X(easy_cleanup)                                                                                \
    X(easy_reset)                                                                                  \
    X(easy_setopt)                                                                                 \
    X(easy_getinfo)                                                                                \
    X(easy_perform)                                                                                \
    X(easy_strerror)                                                                               \
    X(free)                                                                                        \
    X(url)                                                                                         \
    X(url_set)                                                                                     \
    X(url_get)                                                                                     \
    X(url_cleanup)                                                                                 \
    X(url_strerror)                                                                                \
    X(slist_append)                                                                                \
    X(slist_free_all)                                                                              \
    X(mime_init)                                                                                   \
    X(mime_free)                                                                                   \
    X(mime_addpart)                                                                                \
    X(mime_name)                                                                                   \
    X(mime_filename)                                                                               \
    X(mime_type)                                                                                   \
    X(mime_data)                                                                                   \
    X(mime_data_cb)

typedef struct curl_api_table {
#define CURL_API_MEMBER(name) __typeof__(curl_##name) *name;
    CURL_API_FUNCTIONS(CURL_API_MEMBER)
#undef CURL_API_MEMBER
} curl_api_table;

/* Filled by curl_api_load; read only after it succeeded. */
extern curl_api_table curl_api;

/* Opens libcurl.so.4 and resolves the table, once per process (later
 * calls return the first outcome).  Returns 0, or -1 with a message. */
int curl_api_load(char *msg, size_t cap);

#endif
