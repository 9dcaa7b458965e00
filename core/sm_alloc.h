/* Large arrays written right after they are allocated (internal, not
 * part of the public API): the records a reader parses, an inflated
 * file.
 *
 * Their first write costs one page fault per 4 KiB page, and on a
 * virtual machine a fault costs more than the writing (measured on the
 * project's machine: 12 us a fault, 36 ms to first write 12 MB; 1.2 ms
 * with huge pages).  sm__alloc_huge therefore aligns an allocation that
 * covers a huge page to one and advises its whole huge pages to be
 * backed by huge pages (one fault per 2 MiB, where transparent huge pages
 * are enabled for madvise'd memory, as by default).  A tail shorter than
 * a huge page gets one too when it fills three quarters of it (so at
 * most 512 KiB resident beyond what is written); otherwise it, and an
 * array of 64 KiB to 2 MiB, has its pages mapped in one system call
 * rather than one fault each (half the cost).  The memory is the
 * allocator's: freed with free(), resizable with realloc (which may move
 * it off the huge pages).
 *
 * sm__alloc_large is the other kind: blocks that go back to the system
 * when freed (sm__free_large), for scratch and buffers; the arrays of
 * sm__alloc_huge are kept by their owners (sm_mesh, sm_sol), which free
 * them with free(). */
#ifndef SM_ALLOC_H
#define SM_ALLOC_H

#include <stddef.h>

/* The usual x86-64 and arm64 huge page. */
#define SM_HUGE_PAGE_BYTES ((size_t)2 << 20)

/* malloc(bytes) (bytes 0: one byte), huge-page backed as said above when
 * bytes >= SM_HUGE_PAGE_BYTES.  NULL when out of memory. */
void *sm__alloc_huge(size_t bytes);

/* For an array about to be overwritten whole: its pages inside
 * [p, p + bytes) are given back (MADV_DONTNEED), so the writes fault in
 * new zeroed pages instead of copying old ones (the pages a forked
 * process shares copy-on-write with its parent), in huge pages where
 * transparent huge pages are enabled for madvise'd memory.  The contents
 * are undefined until written.  A hint: without it, the writes copy. */
void sm__discard(void *p, size_t bytes);

/* Memory mapped directly from SM_HUGE_PAGE_BYTES on, aligned to a huge
 * page and advised as huge pages (fewer TLB misses, far fewer page
 * faults when first written), and unmapped when freed, so that scratch
 * arrays and buffers held for a while (the target field's construction,
 * an inflated file) go back to the system at once instead of staying in
 * the allocator's heap or raising its threshold for mapping blocks, which
 * would keep later blocks of that size in the heap; smaller blocks from
 * the allocator, aligned to the 128-byte pair of cache lines the hardware
 * fetches together.  Under AddressSanitizer everything goes through the
 * allocator, which checks the bounds.  NULL when out of memory.  Free
 * with sm__free_large(p, bytes), bytes as allocated. */
void *sm__alloc_large(size_t bytes);
void sm__free_large(void *p, size_t bytes);

#endif
