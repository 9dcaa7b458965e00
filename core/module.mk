# libshapematch: the numerical core (no network, no JSON).  Sources by
# folder, listed (a new file is added here on purpose):
#   core/      the model (mesh, surface, parameters, clamp, errors, memory),
#              the target field, the surface distance, elasticity, the
#              functional and the descent, the pre-alignment
#   core/io/   every file format and the streams under them (sm_io.c and
#              sm_io_surface.c dispatch by content)
# Core files include their own folder's private headers by path from core/
# ("sm_alloc.h", "io/sm_reader.h"); programs see core/include only.
CORE_BASE_SRCS := core/sm_alloc.c core/sm_atomic.c core/sm_clamp.c core/sm_clock.c \
  core/sm_error.c core/sm_facets.c core/sm_mesh.c core/sm_morton.c core/sm_params.c core/sm_path.c \
  core/sm_surface.c core/sm_topology.c
CORE_FIELD_SRCS := core/sm_field.c core/sm_field_adjacency.c core/sm_field_grid.c \
  core/sm_field_locate.c core/sm_field_nearest.c
CORE_SDF_SRCS := core/sm_background.c core/sm_bvh.c core/sm_sdf.c core/sm_surface_repair.c \
  core/sm_surface_orient.c core/sm_winding.c
CORE_SOLVE_SRCS := core/sm_elasticity.c core/sm_elasticity_pattern.c core/sm_element.c \
  core/sm_solver_amg.c core/sm_shape.c core/sm_match.c
CORE_ALIGN_SRCS := core/sm_align.c core/sm_align_landmarks.c core/sm_align_linalg.c
CORE_IO_SRCS := core/io/sm_io.c core/io/sm_io_surface.c \
  core/io/sm_io_medit.c core/io/sm_io_medit_write.c core/io/sm_medit_common.c \
  core/io/sm_io_msh.c core/io/sm_io_sol.c core/io/sm_io_stl.c core/io/sm_io_obj.c \
  core/io/sm_io_vtu.c \
  core/io/sm_reader.c core/io/sm_writer.c core/io/sm_stream.c core/io/sm_inflate.c \
  core/io/sm_number.c
CORE_SRCS := $(CORE_BASE_SRCS) $(CORE_FIELD_SRCS) $(CORE_SDF_SRCS) $(CORE_SOLVE_SRCS) \
  $(CORE_ALIGN_SRCS) $(CORE_IO_SRCS)
define core_rules
build/$(1)/obj/core/%.o: $(1)_CFLAGS += -I core
build/$(1)/libshapematch.a: $$(CORE_SRCS:%.c=build/$(1)/obj/%.o)
	@mkdir -p $$(dir $$@)
	rm -f $$@ && ar rcs $$@ $$^
endef
$(foreach v,$(VARIANTS),$(eval $(call core_rules,$(v))))
ALL_TARGETS += libshapematch.a
