# libsmproto: the wire contract shared by daemon, workers and client
# (params JSON, events NDJSON, result summary, binary mesh payload, the
# wire vocabulary).  Depends on libshapematch, never on proto/job (the job
# runner, libsmjob.a, stands on it); users link libsmproto.a before
# libshapematch.a, plus $(PROTO_LIBS) and -lz.
PROTO_SRCS := proto/sm_payload.c proto/sm_proto_events.c proto/sm_proto_json.c \
  proto/sm_points_csv.c proto/sm_proto_params.c proto/sm_proto_text.c proto/sm_proto_vocab.c
define proto_rules
build/$(1)/libsmproto.a: $$(PROTO_SRCS:%.c=build/$(1)/obj/%.o)
	@mkdir -p $$(dir $$@)
	$$(call show,AR,$$@,$(1))rm -f $$@ && ar rcs $$@ $$^
endef
$(foreach v,$(VARIANTS),$(eval $(call proto_rules,$(v))))
ALL_TARGETS += libsmproto.a

include proto/job/module.mk
