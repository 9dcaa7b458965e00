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
# The daemon soak (bench/soak.sh, SOAK_SECONDS, default 600): mixed load
# while RSS, descriptors and threads are sampled; part of `make bench`.
.PHONY: bench-soak
bench-soak: build/release/shapematchd build/release/shapematch-worker
	bench/soak.sh
bench: bench-soak
