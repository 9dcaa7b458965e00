# Unit and numerical-verification tests: every tests/unit/test_*.c is one
# cmocka program linked with the job, proto and core libraries and the
# shared helpers tests/unit/util_*.c.
TEST_SRCS := $(wildcard tests/unit/test_*.c)
TEST_UTIL_SRCS := $(wildcard tests/unit/util_*.c)
TEST_NAMES := $(TEST_SRCS:tests/unit/%.c=%)
# The unit tests are white-box: they also see the core's private headers
# (sm_shape.h, sm_elasticity.h, ...); the programs see core/include only.
define test_rules
build/$(1)/obj/tests/unit/%.o: $(1)_CFLAGS += -I core
build/$(1)/tests/%: build/$(1)/obj/tests/unit/%.o $$(TEST_UTIL_SRCS:%.c=build/$(1)/obj/%.o) build/$(1)/libsmjob.a build/$(1)/libsmproto.a build/$(1)/libshapematch.a
	@mkdir -p $$(dir $$@)
	$$(call show,LD,$$@,$(1))$$(CC) $$($(1)_LDFLAGS) -o $$@ $$^ $$(PROTO_LIBS) $$(CORE_LIBS) -lcmocka
endef
$(foreach v,$(VARIANTS),$(eval $(call test_rules,$(v))))
ALL_TARGETS += $(TEST_NAMES:%=tests/%)

# test_params walks every parameter through the CLI's option parser as
# well: it also links the client's args.c (and msg.c, its messages).
define test_params_rules
build/$(1)/obj/tests/unit/test_params.o: $(1)_CFLAGS += -I client
build/$(1)/tests/test_params: build/$(1)/obj/tests/unit/test_params.o build/$(1)/obj/client/args.o build/$(1)/obj/client/msg.o build/$(1)/libsmjob.a build/$(1)/libsmproto.a build/$(1)/libshapematch.a
	@mkdir -p $$(dir $$@)
	$$(call show,LD,$$@,$(1))$$(CC) $$($(1)_LDFLAGS) -o $$@ $$^ $$(PROTO_LIBS) $$(CORE_LIBS) -lcmocka
endef
$(foreach v,$(VARIANTS),$(eval $(call test_params_rules,$(v))))

# the libFuzzer targets (clang) have their own fragment
include tests/fuzz/module.mk
