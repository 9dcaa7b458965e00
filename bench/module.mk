# Benchmarks (release only: figures from a sanitized build mean nothing).
# Each is one C file linked against the core library.
BENCH_PROGS := match_bench field_bench sdf_bench io_bench bg_bench

$(foreach b,$(BENCH_PROGS),$(eval build/release/$(b): build/release/obj/bench/$(b).o build/release/libshapematch.a))
$(addprefix build/release/,$(BENCH_PROGS)):
	@mkdir -p $(dir $@)
	$(CC) -o $@ $^ $(CORE_LIBS)
release: $(addprefix build/release/,$(BENCH_PROGS))
all: $(addprefix build/release/,$(BENCH_PROGS))
