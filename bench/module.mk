# Benchmarks: every rule of `make bench` is here.  Figures, not verdicts;
# docs/performance.md has today's and says how to read them.
#
#   make bench            all of them, in this order: bench/run.sh (the
#                         examples, the paper's size end to end, auto
#                         against each solver (bench/solvers.sh), the
#                         surface distance, the readers and writers, the
#                         daemon under wrk, the cluster), the soak, the
#                         scaling benchmark, the large background; the
#                         label map to a distance (bench/image_sdf.sh); the
#                         populations (bench/batch.sh)
#   make bench-soak       bench/soak.sh alone (SOAK_SECONDS, default 600)
#   make bench-scale      bench/scale.sh alone (SCALE_SIZES, SCALE_SOLVERS)
#   make bench-bigfield   bench/bigfield.sh alone (BIGFIELD_TETS, default 5M)
#   make bench-batch      bench/batch.sh alone (populations: batch against
#                         separate runs, the model's build time)
#   make bench-image      bench/image_sdf.sh alone (label map to distance,
#                         against ITK's Maurer filter and scipy's EDT)
#
# The C benchmarks are built in the release variant only (figures from a
# sanitized build mean nothing), each one C file linked against the core.
BENCH_PROGS := match_bench field_bench sdf_bench io_bench bg_bench read_bench write_bench warp_bench solver_bench
BENCH_SRCS := $(BENCH_PROGS:%=bench/%.c)

$(foreach b,$(BENCH_PROGS),$(eval build/release/$(b): build/release/obj/bench/$(b).o build/release/libshapematch.a))
# write_bench also times the core's own number formatting (sm_number.h)
build/release/obj/bench/write_bench.o: release_CFLAGS += -I core
# solver_bench drives the elastic operator (core/sm_elasticity.h) directly
build/release/obj/bench/solver_bench.o: release_CFLAGS += -I core
$(addprefix build/release/,$(BENCH_PROGS)):
	@mkdir -p $(dir $@)
	$(call show,LD,$@)$(CC) -o $@ $^ $(CORE_LIBS)
RELEASE_ONLY_TARGETS += $(BENCH_PROGS)

# ITK's Maurer distance map beside ours (bench/image_sdf.sh): a C++ program
# built here only, for the benchmark, against Debian's ITK (not a
# dependency of the project: bench-deps installs it for `make bench`)
BENCH_DEB_PACKAGES := libinsighttoolkit5-dev g++
ITK_INCLUDE := /usr/include/ITK-5.2
build/release/itk_maurer: bench/itk_maurer.cxx
	@mkdir -p $(dir $@)
	$(call show,CXX,$@)g++ -O2 -std=c++17 -I $(ITK_INCLUDE) $< -o $@ -lITKIONRRD-5.2 \
	  -lITKIOImageBase-5.2 -lITKCommon-5.2 -litksys-5.2 -litkvnl_algo-5.2 -litkvnl-5.2

.PHONY: bench-deps
bench-deps:
	@missing="$(call missing_debs,$(BENCH_DEB_PACKAGES))"; \
	if [ -n "$$missing" ]; then \
	  echo "bench-deps: installing $$missing"; \
	  apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends $$missing; \
	fi

# each: the prerequisite check, the release build, then the script(s)
.PHONY: bench bench-soak bench-scale bench-bigfield bench-batch bench-image
bench: check-deps bench-deps
	$(MAKE) -j$$(nproc) release build/release/itk_maurer
	bench/run.sh
	bench/image_sdf.sh
	bench/batch.sh
	bench/soak.sh
	bench/scale.sh
	bench/bigfield.sh

bench-image: check-deps bench-deps
	$(MAKE) -j$$(nproc) release build/release/itk_maurer
	bench/image_sdf.sh

bench-soak bench-scale bench-bigfield bench-batch: bench-%: check-deps
	$(MAKE) -j$$(nproc) release
	bench/$*.sh
