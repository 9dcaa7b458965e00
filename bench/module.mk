# Benchmarks (release only: figures from a sanitized build mean nothing).
build/release/match_bench: build/release/obj/bench/match_bench.o build/release/libshapematch.a
	@mkdir -p $(dir $@)
	$(CC) -o $@ $^ $(CORE_LIBS)
release: build/release/match_bench
all: build/release/match_bench
build/release/field_bench: build/release/obj/bench/field_bench.o build/release/libshapematch.a
	@mkdir -p $(dir $@)
	$(CC) -o $@ $^ $(CORE_LIBS)
release: build/release/field_bench
all: build/release/field_bench
build/release/sdf_bench: build/release/obj/bench/sdf_bench.o build/release/libshapematch.a
	@mkdir -p $(dir $@)
	$(CC) -o $@ $^ $(CORE_LIBS)
release: build/release/sdf_bench
all: build/release/sdf_bench
# Scaling benchmark (bench/scale.sh, sizes from SCALE_SIZES): part of
# `make bench`, or alone with `make bench-scale`.
.PHONY: bench-scale
bench-scale: deps
	$(MAKE) -j$$(nproc) release
	bench/scale.sh
bench: bench-scale
