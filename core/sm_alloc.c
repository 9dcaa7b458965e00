#include "sm_alloc.h"

#include <stdint.h>
#include <stdlib.h>
#include <sys/mman.h>
#include <unistd.h>

/* Under AddressSanitizer, sm__alloc_large leaves every block to the
 * allocator, which checks the bounds. */
#if defined(__SANITIZE_ADDRESS__)
#define SM_ALLOC_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define SM_ALLOC_ASAN 1
#endif
#endif

static size_t round_up(size_t bytes, size_t align)
{
    size_t size = (bytes + align - 1) / align * align;
    return size < bytes ? 0 : size; /* 0: overflow */
}

/* Arrays below this size are left to fault their pages in one by one as
 * they are written: a prefault costs a system call, and a small block is
 * often memory the allocator has had before. */
#define PREFAULT_MIN ((size_t)64 << 10)
/* An array's tail shorter than a huge page gets a huge page of its own
 * when it leaves at most this much of it unused. */
#define TAIL_SLACK (SM_HUGE_PAGE_BYTES / 4)

/* Maps the whole pages of [p, p + bytes) now, writable, in one system
 * call rather than one fault a page (MADV_POPULATE_WRITE, Linux 5.14; a
 * hint: refused by an older kernel, the pages fault in as before).
 * Measured on the project's machine: 2.1 instead of 4.6 ms for 1.4 MB. */
static void prefault(void *p, size_t bytes)
{
#ifdef MADV_POPULATE_WRITE
    long page = sysconf(_SC_PAGESIZE);
    if (page <= 0)
        return;
    uintptr_t mask = (uintptr_t)page - 1;
    uintptr_t start = ((uintptr_t)p + mask) & ~mask, end = ((uintptr_t)p + bytes) & ~mask;
    if (end > start)
        (void)madvise((void *)start, end - start, MADV_POPULATE_WRITE);
#else
    (void)p;
    (void)bytes;
#endif
}

void *sm__alloc_huge(size_t bytes)
{
    if (bytes < SM_HUGE_PAGE_BYTES) {
        void *p = malloc(bytes ? bytes : 1);
        if (p && bytes >= PREFAULT_MIN)
            prefault(p, bytes);
        return p;
    }
    size_t whole = bytes / SM_HUGE_PAGE_BYTES * SM_HUGE_PAGE_BYTES, tail = bytes - whole;
    size_t size = tail >= SM_HUGE_PAGE_BYTES - TAIL_SLACK ? whole + SM_HUGE_PAGE_BYTES : bytes;
    void *p;
    if (size < bytes || posix_memalign(&p, SM_HUGE_PAGE_BYTES, size) != 0)
        return malloc(bytes); /* an allocator refusing the alignment */
#ifdef MADV_HUGEPAGE
    /* A hint: refused (no THP, an old kernel), the pages are normal. */
    (void)madvise(p, size / SM_HUGE_PAGE_BYTES * SM_HUGE_PAGE_BYTES, MADV_HUGEPAGE);
#endif
    if (size == bytes && tail)
        prefault((char *)p + whole, tail);
    return p;
}

void sm__discard(void *p, size_t bytes)
{
    long page = sysconf(_SC_PAGESIZE);
    if (!p || page <= 0)
        return;
    uintptr_t mask = (uintptr_t)page - 1;
    uintptr_t start = ((uintptr_t)p + mask) & ~mask, end = ((uintptr_t)p + bytes) & ~mask;
    if (end <= start)
        return;
#ifdef MADV_HUGEPAGE
    uintptr_t hstart = (start + SM_HUGE_PAGE_BYTES - 1) / SM_HUGE_PAGE_BYTES * SM_HUGE_PAGE_BYTES;
    uintptr_t hend = end / SM_HUGE_PAGE_BYTES * SM_HUGE_PAGE_BYTES;
    if (hend > hstart)
        (void)madvise((void *)hstart, hend - hstart, MADV_HUGEPAGE);
#endif
    (void)madvise((void *)start, end - start, MADV_DONTNEED);
}

void *sm__alloc_large(size_t bytes)
{
#if !defined(SM_ALLOC_ASAN) && defined(MAP_ANONYMOUS)
    if (bytes >= SM_HUGE_PAGE_BYTES) {
        size_t size = round_up(bytes, SM_HUGE_PAGE_BYTES);
        if (!size || size + SM_HUGE_PAGE_BYTES < size)
            return NULL;
        char *p = mmap(NULL, size + SM_HUGE_PAGE_BYTES, PROT_READ | PROT_WRITE,
                       MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
        if (p == MAP_FAILED)
            return NULL;
        size_t head = (SM_HUGE_PAGE_BYTES - (uintptr_t)p % SM_HUGE_PAGE_BYTES) % SM_HUGE_PAGE_BYTES;
        if (head)
            munmap(p, head);
        munmap(p + head + size, SM_HUGE_PAGE_BYTES - head);
#ifdef MADV_HUGEPAGE
        (void)madvise(p + head, size, MADV_HUGEPAGE);
#endif
        return p + head;
    }
#endif
    size_t size = round_up(bytes ? bytes : 1, 128);
    void *p = size ? aligned_alloc(128, size) : NULL;
    /* scratch is written at once: its pages mapped in one call */
    if (p && size >= PREFAULT_MIN)
        prefault(p, size);
    return p;
}

void sm__free_large(void *p, size_t bytes)
{
    if (!p)
        return;
#if !defined(SM_ALLOC_ASAN) && defined(MAP_ANONYMOUS)
    if (bytes >= SM_HUGE_PAGE_BYTES) {
        munmap(p, round_up(bytes, SM_HUGE_PAGE_BYTES));
        return;
    }
#endif
    (void)bytes;
    free(p);
}
