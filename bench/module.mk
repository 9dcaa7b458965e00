# Benchmarks (release only: figures from a sanitized build mean nothing).
# Each is one C file linked against the core library.
BENCH_PROGS := match_bench field_bench sdf_bench io_bench bg_bench read_bench write_bench

$(foreach b,$(BENCH_PROGS),$(eval build/release/$(b): build/release/obj/bench/$(b).o build/release/libshapematch.a))
# write_bench also times the core's own number formatting (sm_number.h)
build/release/obj/bench/write_bench.o: release_CFLAGS += -I core
$(addprefix build/release/,$(BENCH_PROGS)):
	@mkdir -p $(dir $@)
	$(CC) -o $@ $^ $(CORE_LIBS)
release: $(addprefix build/release/,$(BENCH_PROGS))
all: $(addprefix build/release/,$(BENCH_PROGS))
# The daemon soak (bench/soak.sh, SOAK_SECONDS, default 600): mixed load
# while RSS, descriptors and threads are sampled; part of `make bench`.
.PHONY: bench-soak
bench-soak: build/release/shapematchd build/release/shapematch-worker
	bench/soak.sh
bench: bench-soak
# Scaling benchmark (bench/scale.sh, sizes from SCALE_SIZES): part of
# `make bench`, or alone with `make bench-scale`.
.PHONY: bench-scale
bench-scale: deps
	$(MAKE) -j$$(nproc) release
	bench/scale.sh
bench: bench-scale
# The target field on a large background (bench/bigfield.sh,
# BIGFIELD_TETS, default 5M): build time and memory; part of `make
# bench`, or alone with `make bench-bigfield`.
.PHONY: bench-bigfield
bench-bigfield: deps
	$(MAKE) -j$$(nproc) release
	bench/bigfield.sh
bench: bench-bigfield
