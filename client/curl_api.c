/* libcurl loaded on first use (see curl_api.h). */
#include "curl_api.h"
#include "msg.h"

#include <dlfcn.h>
#include <stdio.h>

#define CURL_SONAME "libcurl.so.4"

curl_api_table curl_api;

int curl_api_load(char *msg, size_t cap)
{
    static int state; /* 0 not tried, 1 loaded, -1 failed */
    static char failure[256];
    if (state == 0) {
        void *lib = dlopen(CURL_SONAME, RTLD_NOW | RTLD_LOCAL);
        if (!lib) {
            snprintf(failure, sizeof failure, "cannot load libcurl: %s", dlerror());
            state = -1;
        } else {
            state = 1;
            /* void * to a function pointer: what dlsym is for (POSIX) */
#define CURL_API_RESOLVE(name)                                                                     \
    if (state == 1 && !(*(void **)&curl_api.name = dlsym(lib, "curl_" #name))) {                   \
        snprintf(failure, sizeof failure, "cannot load libcurl: %s has no curl_%s",              \
                 CURL_SONAME, #name);                                                             \
        state = -1;                                                                                \
    }
            CURL_API_FUNCTIONS(CURL_API_RESOLVE)
#undef CURL_API_RESOLVE
        }
    }
    return state == 1 ? 0 : cli_fail(msg, cap, "%s", failure);
}
