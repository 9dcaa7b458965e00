# shapematch: the command-line client (local runs; daemon commands later).
CLIENT_SRCS := $(wildcard client/*.c)
define client_rules
build/$(1)/shapematch: $$(CLIENT_SRCS:%.c=build/$(1)/obj/%.o) build/$(1)/libshapematch.a
	@mkdir -p $$(dir $$@)
	$$(CC) $$($(1)_LDFLAGS) -o $$@ $$^ $$(CORE_LIBS)
endef
$(foreach v,$(VARIANTS),$(eval $(call client_rules,$(v))))
ALL_TARGETS += shapematch
INSTALL_PROGRAMS += shapematch
