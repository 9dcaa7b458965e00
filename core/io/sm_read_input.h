/* The file readers of sm_io.h and sm_surface.h over an sm_reader_input
 * (sm_reader.h): a file, or bytes in memory read as if they were a plain
 * file (internal, not part of the public API).  The public functions
 * (sm_mesh_read_limited, sm_sol_read_limited, sm_surface_read_limited)
 * are these with a path; the fuzz targets (tests/fuzz/) hand each input
 * over in memory instead of through a file.  Same contract as the public
 * functions: *out NULL and err set on error, limits may be NULL. */
#ifndef SM_READ_INPUT_H
#define SM_READ_INPUT_H

#include "shapematch/sm_io.h"
#include "shapematch/sm_surface.h"
#include "io/sm_reader.h"

sm_status sm__mesh_read_input(const sm_reader_input *in, sm_read_limits *limits, sm_mesh **out,
                              sm_error *err);
sm_status sm__sol_read_input(const sm_reader_input *in, sm_read_limits *limits, sm_sol **out,
                             sm_error *err);
sm_status sm__surface_read_input(const sm_reader_input *in, sm_read_limits *limits,
                                 sm_surface **out, sm_error *err);

#endif
