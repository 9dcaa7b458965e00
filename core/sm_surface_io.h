/* Surface readers, one per format, behind sm_surface_read (internal, not
 * part of the public API).  Each takes an opened reader positioned at the
 * start of the file (sm_reader.h: bounded reads, gzip, positions in
 * messages) and fills a new surface. */
#ifndef SM_SURFACE_IO_H
#define SM_SURFACE_IO_H

#include "shapematch/sm_surface.h"
#include "sm_reader.h"

/* STL: binary when the file size is 84 + 50 n with n the count at byte
 * 80, or when it does not start like an ASCII STL ("solid" then
 * "facet"/"endsolid" in printable text); ASCII otherwise. */
int sm__stl_detect(sm_reader *r);
sm_status sm__stl_read(sm_reader *r, sm_surface **out, sm_error *err);

/* OBJ: the first word is an OBJ statement (v, vt, vn, f, o, g, s, l,
 * mtllib, usemtl) or a '#' comment. */
int sm__obj_detect(sm_reader *r);
sm_status sm__obj_read(sm_reader *r, sm_surface **out, sm_error *err);

/* Medit surfaces (sm_io_medit.c). */
sm_status sm__medit_surface_read(const sm_reader_input *in, sm_read_limits *limits,
                                 sm_surface **out, sm_error *err);

/* Merges vertices with exactly equal coordinates (STL repeats them per
 * facet); the merged vertices keep the order of their first appearance
 * and facets are renumbered. */
sm_status sm__surface_weld(sm_surface *s, sm_error *err);

#endif
