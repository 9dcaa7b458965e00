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
 * sm_field.c has its own mapping allocator for the field's arrays, which
 * are also returned to the system when freed; these are not, since
 * their owners (sm_mesh, sm_sol) free them with free(). */
#ifndef SM_ALLOC_H
#define SM_ALLOC_H

#include <stddef.h>

/* The usual x86-64 and arm64 huge page. */
#define SM_HUGE_PAGE_BYTES ((size_t)2 << 20)

/* malloc(bytes) (bytes 0: one byte), huge-page backed as said above when
 * bytes >= SM_HUGE_PAGE_BYTES.  NULL when out of memory. */
void *sm__alloc_huge(size_t bytes);

/* A buffer of at least bytes for a short while (an inflated file, read
 * and freed by the reader): from SM_HUGE_BUFFER_MIN bytes on, rounded up
 * to whole huge pages, all huge-page backed (the resident size may then
 * exceed what is written by less than one huge page, for a moment only).
 * *cap is the size obtained.  Free with free(). */
#define SM_HUGE_BUFFER_MIN ((size_t)256 << 10)
void *sm__alloc_huge_buffer(size_t bytes, size_t *cap);

#endif
