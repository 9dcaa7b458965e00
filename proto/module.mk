# libsmproto: the wire contract shared by daemon, workers and client
# (params JSON, events NDJSON, result summary, binary mesh payload, the
# wire vocabulary) and the one job runner of `shapematch run` and
# `shapematch-worker` (input checks, run, result set).  Depends on
# libshapematch; users link libsmproto.a before libshapematch.a, plus
# $(PROTO_LIBS) and -lz.
PROTO_SRCS := $(wildcard proto/*.c)
define proto_rules
build/$(1)/libsmproto.a: $$(PROTO_SRCS:%.c=build/$(1)/obj/%.o)
	@mkdir -p $$(dir $$@)
	rm -f $$@ && ar rcs $$@ $$^
endef
$(foreach v,$(VARIANTS),$(eval $(call proto_rules,$(v))))
ALL_TARGETS += libsmproto.a
