# libFuzzer targets for every parser (tests/fuzz/fuzz_*.c), built with
# clang into build/fuzz/ with AddressSanitizer and UndefinedBehaviorSanitizer
# (gcc has no libFuzzer).  The core, proto, client and server sources a
# target needs (the server's: header negotiation, the bounded integer
# parser, the multipart part handling smd_parts.c, which fuzz_parts drives
# directly and fuzz_multipart through libmicrohttpd's PostProcessor) are
# compiled again with clang: its sanitizer checks things gcc's
# does not (e.g. a zero offset applied to a null pointer).
#   make fuzz                 each target for FUZZ_SECONDS (default 300),
#                             FUZZ_WORKERS processes at once (default nproc)
#   make fuzz-build           build only (make test runs each briefly)
# Seeds: tests/fuzz/seeds.sh collects them from tests/data.
# -Wno-pass-failed: at -O1 clang leaves a loop that `omp simd` asks to
# vectorise as it is (an optimisation not made, not a fault in the code).
FUZZ_CC := clang
FUZZ_DIR := build/fuzz
FUZZ_CFLAGS := -std=c11 -D_DEFAULT_SOURCE -D_GNU_SOURCE -Wall -Wextra -Werror \
  -Wno-missing-field-initializers -Wno-pass-failed -g -O1 -fno-omit-frame-pointer -fopenmp \
  -fsanitize=fuzzer-no-link,address,undefined -fno-sanitize-recover=all \
  -I core/include -I core -I proto -I client -I server -I tests/fuzz -I /usr/include/suitesparse \
  -DSM_VERSION='"$(VERSION)"' $(HYPRE_CFLAGS)
FUZZ_LDFLAGS := -fopenmp -fsanitize=fuzzer,address,undefined
FUZZ_LIB_SRCS := $(CORE_SRCS) $(PROTO_SRCS) client/sse.c tests/fuzz/fuzz_input.c \
  server/http/smd_negotiate.c server/http/smd_cors.c server/base/smd_util.c
FUZZ_LIB_SRCS += server/api/smd_parts.c tests/fuzz/fuzz_parts_check.c server/worker/smd_job_file.c \
  proto/job/sm_job_batch_list.c proto/job/sm_job_template_json.c
FUZZ_LIB_SRCS += server/api/smd_batch_request.c
FUZZ_TARGETS := $(patsubst tests/fuzz/%.c,%,$(wildcard tests/fuzz/fuzz_*.c))
FUZZ_TARGETS := $(filter-out fuzz_input fuzz_parts_check,$(FUZZ_TARGETS))
FUZZ_TARGET_SRCS := $(FUZZ_TARGETS:%=tests/fuzz/%.c)

$(FUZZ_DIR)/obj/%.o: %.c
	@mkdir -p $(dir $@)
	$(call show,CC,$<,fuzz)$(FUZZ_CC) $(FUZZ_CFLAGS) -MMD -MP -c $< -o $@

$(FUZZ_DIR)/libfuzzdeps.a: $(FUZZ_LIB_SRCS:%.c=$(FUZZ_DIR)/obj/%.o)
	$(call show,AR,$@)rm -f $@ && ar rcs $@ $^

$(FUZZ_TARGETS:%=$(FUZZ_DIR)/%): $(FUZZ_DIR)/%: $(FUZZ_DIR)/obj/tests/fuzz/%.o $(FUZZ_DIR)/libfuzzdeps.a
	$(call show,LD,$@)$(FUZZ_CC) $(FUZZ_LDFLAGS) -o $@ $^ $(PROTO_LIBS) -lcholmod $(HYPRE_LIBS) -llapack -lblas -ldeflate -lz -lm $(HTTP_LIBS)

.PHONY: fuzz fuzz-build
fuzz-build: $(FUZZ_TARGETS:%=$(FUZZ_DIR)/%)

FUZZ_SECONDS ?= 300
# processes per target (run.sh: one corpus, executions summed); one per core
FUZZ_WORKERS ?= $(shell nproc)
fuzz: check-deps
	$(MAKE) -j$$(nproc) fuzz-build
	FUZZ_WORKERS=$(FUZZ_WORKERS) tests/fuzz/run.sh $(FUZZ_SECONDS) $(FUZZ_TARGETS)
