# libshapematch: the numerical core (no network, no JSON).
CORE_SRCS := $(wildcard core/*.c)
define core_rules
build/$(1)/libshapematch.a: $$(CORE_SRCS:%.c=build/$(1)/obj/%.o)
	@mkdir -p $$(dir $$@)
	rm -f $$@ && ar rcs $$@ $$^
endef
$(foreach v,$(VARIANTS),$(eval $(call core_rules,$(v))))
ALL_TARGETS += libshapematch.a
