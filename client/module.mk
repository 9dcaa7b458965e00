# shapematch: the command-line client (local runs with `run`; submit, watch,
# fetch, status, list, cancel talk to shapematchd over HTTP with libcurl,
# which client/curl_api.c opens when one of them first needs it).
# Links libsmjob.a (the job runner of `run`) and libsmproto.a (params/events
# codecs) before libshapematch.a.
CLIENT_SRCS := $(wildcard client/*.c)
CLIENT_LIBS := $(PROTO_LIBS) $(CURL_LIBS) $(CORE_LIBS)
define client_rules
build/$(1)/shapematch: $$(CLIENT_SRCS:%.c=build/$(1)/obj/%.o) build/$(1)/libsmjob.a build/$(1)/libsmproto.a build/$(1)/libshapematch.a
	@mkdir -p $$(dir $$@)
	$$(call show,LD,$$@,$(1))$$(CC) $$($(1)_LDFLAGS) -o $$@ $$^ $$(CLIENT_LIBS)
endef
$(foreach v,$(VARIANTS),$(eval $(call client_rules,$(v))))
ALL_TARGETS += shapematch
INSTALL_PROGRAMS += shapematch
