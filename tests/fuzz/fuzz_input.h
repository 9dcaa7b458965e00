/* Shared helper of the file-reader fuzz targets: the core's readers take a
 * path (they detect format and gzip by content and report errors with the
 * path), so each input is handed over as an anonymous in-memory file
 * (memfd) named by its /proc/self/fd path.  Nothing touches the disk. */
#ifndef FUZZ_INPUT_H
#define FUZZ_INPUT_H

#include <stddef.h>
#include <stdint.h>

/* Writes data into a new memfd and fills path ("/proc/self/fd/N").
 * Returns the fd (close it when done) or -1. */
int fuzz_memfile(const uint8_t *data, size_t size, char *path, size_t cap);

#endif
