/* Shared helpers of the file-reader fuzz targets: the core's readers take a
 * path (they detect format and gzip by content and report errors with the
 * path), so each input is handed over as an anonymous in-memory file
 * (memfd) named by its /proc/self/fd path.  Nothing touches the disk.
 * The checks abort() on a broken reader contract, which libFuzzer reports
 * as a crash with the input saved. */
#ifndef FUZZ_INPUT_H
#define FUZZ_INPUT_H

#include <stddef.h>
#include <stdint.h>

/* Writes prefix (NULL: none) then data into a new memfd and fills path
 * ("/proc/self/fd/N").  Returns the fd (close it when done) or -1.  A
 * prefix steers a content-detecting reader to one format, so the fuzzer
 * spends its time in that format's parser. */
int fuzz_memfile(const char *prefix, const uint8_t *data, size_t size, char *path, size_t cap);

/* sm_mesh_read of path: it fails cleanly (NULL and a message) or gives a
 * mesh whose element and facet indices are in range; an accepted mesh
 * also goes through the boundary build, which trusts those checks. */
void fuzz_check_mesh(const char *path);

/* sm_surface_read of path: it fails cleanly or gives a surface whose
 * indices are in range and whose coordinates are finite. */
void fuzz_check_surface(const char *path);

/* The whole target for a file reader: the input (after prefix) as a
 * memory file, then check(path). */
int fuzz_file_target(const char *prefix, const uint8_t *data, size_t size,
                     void (*check)(const char *path));

#endif
