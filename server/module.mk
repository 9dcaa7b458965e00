# shapematchd (the HTTP job daemon) and shapematch-worker (one job per
# process).  The daemon's parts are built into libsmserver.a, which the two
# programs and the server unit tests (tests/unit/test_server_*.c) link.
# One list per folder, in layer order (server/README.md): includes name
# their folder ("jobs/smd_jobs.h") from -I server, and only store/pg/
# sees libpq's header.
SERVER_BASE_SRCS := $(addprefix server/base/,smd_body.c smd_config.c smd_log.c smd_metrics.c smd_util.c)
SERVER_HTTP_SRCS := $(addprefix server/http/,smd_http.c smd_reply.c smd_negotiate.c smd_cors.c \
    smd_auth.c smd_tls.c smd_conns.c smd_ratelimit.c)
SERVER_API_SRCS := $(addprefix server/api/,smd_route_table.c smd_routes.c smd_results.c smd_warp.c smd_live.c \
    smd_app.c smd_ogc.c smd_upload.c smd_parts.c smd_stream.c smd_inputs.c smd_batches.c smd_batch_request.c \
    smd_batch_events.c)
SERVER_JOBS_SRCS := $(addprefix server/jobs/,smd_jobs.c smd_usecases.c smd_pool.c smd_check.c smd_follow.c smd_spool_backend.c)
SERVER_SPOOL_SRCS := $(addprefix server/store/spool/,smd_job.c smd_store.c smd_store_summary.c smd_fifo.c)
SERVER_PG_SRCS := $(addprefix server/store/pg/,smd_pg_conn.c smd_pg_queue.c smd_pg_blob.c \
    smd_pg_node.c smd_pg_mirror.c smd_pg_work.c smd_pg_outbox.c smd_pg_backend.c)
# job.json: written by the upload's check, read by the worker
SERVER_WORKER_SRCS := server/worker/smd_job_file.c
SERVER_LIB_SRCS := $(SERVER_BASE_SRCS) $(SERVER_HTTP_SRCS) $(SERVER_API_SRCS) $(SERVER_JOBS_SRCS) \
    $(SERVER_SPOOL_SRCS) $(SERVER_PG_SRCS) $(SERVER_WORKER_SRCS)
SERVER_MAIN_SRCS := server/shapematchd.c server/worker/shapematch_worker.c
SERVER_TEST_NAMES := $(patsubst tests/unit/%.c,%,$(wildcard tests/unit/test_server_*.c))
SERVER_TEST_UTIL_SRCS := $(wildcard tests/unit/util_*.c)
# the OpenAPI document and the params schema are served by the daemon
SERVER_EMBEDDED := proto/params.schema.json proto/events.schema.json $(wildcard proto/openapi.yaml)
SERVER_LIBS := $(HTTP_LIBS) $(PROTO_LIBS) $(CORE_LIBS) -lpq -lpthread
PG_CFLAGS := -I /usr/include/postgresql

define server_rules
$$(SERVER_LIB_SRCS:%.c=build/$(1)/obj/%.o) $$(SERVER_MAIN_SRCS:%.c=build/$(1)/obj/%.o): $(1)_CFLAGS += -I server
# the PostgreSQL backend's folder and its test see libpq's header
$$(SERVER_PG_SRCS:%.c=build/$(1)/obj/%.o): $(1)_CFLAGS += $$(PG_CFLAGS)
build/$(1)/obj/tests/unit/test_server_pg.o: $(1)_CFLAGS += $$(PG_CFLAGS)
build/$(1)/gen/server/smd_embedded.c: server/embed.sh $$(SERVER_EMBEDDED)
	@mkdir -p $$(dir $$@)
	$$(call show,GEN,$$@,$(1))server/embed.sh $$@ smd_params_schema proto/params.schema.json smd_openapi_yaml proto/openapi.yaml \
	    smd_events_schema proto/events.schema.json

build/$(1)/obj/gen/server/smd_embedded.o: build/$(1)/gen/server/smd_embedded.c
	@mkdir -p $$(dir $$@)
	$$(call show,CC,$$<,$(1))$$(CC) $$($(1)_CFLAGS) -c $$< -o $$@

build/$(1)/libsmserver.a: $$(SERVER_LIB_SRCS:%.c=build/$(1)/obj/%.o) build/$(1)/obj/gen/server/smd_embedded.o $$(call WEB_APP_OBJ,$(1))
	@mkdir -p $$(dir $$@)
	$$(call show,AR,$$@,$(1))rm -f $$@ && ar rcs $$@ $$^

build/$(1)/shapematchd: build/$(1)/obj/server/shapematchd.o build/$(1)/libsmserver.a build/$(1)/libsmjob.a build/$(1)/libsmproto.a build/$(1)/libshapematch.a
	@mkdir -p $$(dir $$@)
	$$(call show,LD,$$@,$(1))$$(CC) $$($(1)_LDFLAGS) -o $$@ $$^ $$(SERVER_LIBS)

# the worker takes only the spool and input helpers from libsmserver.a: no HTTP
build/$(1)/shapematch-worker: build/$(1)/obj/server/worker/shapematch_worker.o build/$(1)/libsmserver.a build/$(1)/libsmjob.a build/$(1)/libsmproto.a build/$(1)/libshapematch.a
	@mkdir -p $$(dir $$@)
	$$(call show,LD,$$@,$(1))$$(CC) $$($(1)_LDFLAGS) -o $$@ $$^ $$(PROTO_LIBS) $$(CORE_LIBS)

# server unit tests see the server headers and also link libsmserver.a
# (explicit rules win over the generic pattern of tests/module.mk)
build/$(1)/obj/tests/unit/test_server_%.o: $(1)_CFLAGS += -I server
$$(SERVER_TEST_NAMES:%=build/$(1)/tests/%): build/$(1)/tests/%: build/$(1)/obj/tests/unit/%.o $$(SERVER_TEST_UTIL_SRCS:%.c=build/$(1)/obj/%.o) build/$(1)/libsmserver.a build/$(1)/libsmjob.a build/$(1)/libsmproto.a build/$(1)/libshapematch.a
	@mkdir -p $$(dir $$@)
	$$(call show,LD,$$@,$(1))$$(CC) $$($(1)_LDFLAGS) -o $$@ $$^ $$(SERVER_LIBS) -lcmocka
endef
$(foreach v,$(VARIANTS),$(eval $(call server_rules,$(v))))
ALL_TARGETS += shapematchd shapematch-worker
INSTALL_PROGRAMS += shapematchd shapematch-worker
