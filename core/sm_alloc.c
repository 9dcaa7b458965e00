#include "sm_alloc.h"

#include <stdint.h>
#include <stdlib.h>
#include <sys/mman.h>

void *sm__alloc_huge(size_t bytes)
{
    if (bytes < SM_HUGE_PAGE_BYTES)
        return malloc(bytes ? bytes : 1);
    void *p;
    if (posix_memalign(&p, SM_HUGE_PAGE_BYTES, bytes) != 0)
        return malloc(bytes); /* an allocator refusing the alignment */
#ifdef MADV_HUGEPAGE
    /* A hint: refused (no THP, an old kernel), the pages are normal. */
    (void)madvise(p, bytes / SM_HUGE_PAGE_BYTES * SM_HUGE_PAGE_BYTES, MADV_HUGEPAGE);
#endif
    return p;
}

void *sm__alloc_huge_buffer(size_t bytes, size_t *cap)
{
    size_t whole = (bytes + SM_HUGE_PAGE_BYTES - 1) / SM_HUGE_PAGE_BYTES * SM_HUGE_PAGE_BYTES;
    *cap = bytes >= SM_HUGE_BUFFER_MIN && whole >= bytes ? whole : bytes;
    void *p = sm__alloc_huge(*cap);
    if (!p)
        *cap = 0;
    return p;
}
