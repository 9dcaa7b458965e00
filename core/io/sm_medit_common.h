/* Medit helpers shared by the mesh and solution readers (internal, not
 * part of the public API): the libMeshb keyword codes and binary layout,
 * format detection, the binary header and keyword framing, and the check
 * of a record count before anything is allocated for it. */
#ifndef SM_MEDIT_COMMON_H
#define SM_MEDIT_COMMON_H

#include <stdint.h>

#include "shapematch/sm_error.h"
#include "io/sm_reader.h"

/* libMeshb keyword codes. */
enum {
    SM_KW_VERSION = 1, SM_KW_DIMENSION = 3, SM_KW_VERTICES = 4, SM_KW_EDGES = 5,
    SM_KW_TRIANGLES = 6, SM_KW_QUADRILATERALS = 7, SM_KW_TETRAHEDRA = 8,
    SM_KW_PRISMS = 9, SM_KW_HEXAHEDRA = 10, SM_KW_CORNERS = 13, SM_KW_RIDGES = 14,
    SM_KW_REQUIRED_VERTICES = 15, SM_KW_REQUIRED_EDGES = 16,
    SM_KW_REQUIRED_TRIANGLES = 17, SM_KW_NORMAL_AT_VERTICES = 20,
    SM_KW_PYRAMIDS = 49, SM_KW_END = 54, SM_KW_TANGENTS = 59, SM_KW_NORMALS = 60,
    SM_KW_TANGENT_AT_VERTICES = 61, SM_KW_SOL_AT_VERTICES = 62
};

/* Binary layout by file version: v1 float32 reals, int32 ints, int32
 * positions; v2 float64 reals; v3 also int64 positions; v4 also int64
 * integers (counts and record fields; the Dimension value and the
 * solution type table stay int32). */
typedef struct sm_meshb_layout {
    int version, int_size, real_size, pos_size;
} sm_meshb_layout;

/* Peeks at the first bytes: binary when they are the 32-bit code 1 in
 * either byte order.  An empty file is an error. */
sm_status sm__medit_detect(sm_reader *r, int *binary, sm_error *err);
/* Reads the code and version words, sets r->swap and the layout. */
sm_status sm__meshb_read_header(sm_reader *r, sm_meshb_layout *lay, sm_error *err);
/* Reads a keyword code and the position of the next keyword (0 when
 * there is none) and checks that position points forward and inside
 * the file.  At a clean end of file, *code = -1. */
sm_status sm__meshb_read_keyword(sm_reader *r, const sm_meshb_layout *lay,
                                int32_t *code, int64_t *next, sm_error *err);
/* After a block was read: the next keyword must start where it ends. */
sm_status sm__meshb_check_block_end(sm_reader *r, const char *section, int64_t next,
                                   sm_error *err);
/* Validates a record count before any allocation: not negative, not above
 * SM_MAX_ENTITIES, and not more records than the bytes left in the file
 * can hold (min_record_bytes each). */
sm_status sm__medit_check_count(sm_reader *r, int binary, const char *section, int64_t n,
                               uint64_t min_record_bytes, uint64_t where, sm_error *err);

#endif
