/* Shared helpers of the file-reader fuzz targets.  Each input goes to the
 * core's readers in memory (sm_read_input.h: the same readers as
 * sm_mesh_read and the others, over the bytes instead of a file), which
 * costs no system call per input.  Inputs that start with the gzip magic
 * go through a file instead, an anonymous in-memory file (memfd) named by
 * its /proc/self/fd path: gzip is inflated for files only, so that path
 * keeps the readers' gzip detection and inflating under the fuzzer.
 * Nothing touches the disk.  The checks abort() on a broken reader
 * contract, which libFuzzer reports as a crash with the input saved. */
#ifndef FUZZ_INPUT_H
#define FUZZ_INPUT_H

#include <stddef.h>
#include <stdint.h>

#include "io/sm_reader.h"

/* Writes prefix (NULL: none) then data into a new memfd and fills path
 * ("/proc/self/fd/N").  Returns the fd (close it when done) or -1.  A
 * prefix steers a content-detecting reader to one format, so the fuzzer
 * spends its time in that format's parser. */
int fuzz_memfile(const char *prefix, const uint8_t *data, size_t size, char *path, size_t cap);

/* sm_mesh_read of in: it fails cleanly (NULL and a message) or gives a
 * mesh whose element and facet indices are in range; an accepted mesh
 * also goes through the boundary build, which trusts those checks. */
void fuzz_check_mesh(const sm_reader_input *in);

/* sm_surface_read of in: it fails cleanly or gives a surface whose
 * indices are in range and whose coordinates are finite; sm_surface_repair
 * of it then keeps the indices in range with consistent counts. */
void fuzz_check_surface(const sm_reader_input *in);

/* The whole target for a file reader: prefix then the input, in memory
 * (or as a memfd when it starts with the gzip magic), then check(in). */
int fuzz_file_target(const char *prefix, const uint8_t *data, size_t size,
                     void (*check)(const sm_reader_input *in));

#endif
