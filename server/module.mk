# shapematchd (the HTTP job daemon) and shapematch-worker (one job per
# process).  The daemon's parts are built into libsmserver.a, which the two
# programs and the server unit tests (tests/unit/test_server_*.c) link.
SERVER_MAIN_SRCS := server/shapematchd.c server/shapematch_worker.c
SERVER_LIB_SRCS := $(filter-out $(SERVER_MAIN_SRCS),$(wildcard server/*.c))
SERVER_TEST_NAMES := $(patsubst tests/unit/%.c,%,$(wildcard tests/unit/test_server_*.c))
SERVER_TEST_UTIL_SRCS := $(wildcard tests/unit/util_*.c)
# the OpenAPI document and the params schema are served by the daemon
SERVER_EMBEDDED := proto/params.schema.json proto/events.schema.json $(wildcard proto/openapi.yaml)
# the web app (smd_app.c): web/ and the npm libraries it loads
APP_EMBEDDED := web/index.html web/app.js web/view.js web/app.css web/favicon.svg \
    $(wildcard node_modules/three/build/three.module.min.js node_modules/three/build/three.core.min.js \
    node_modules/three/examples/jsm/controls/OrbitControls.js node_modules/uplot/dist/uPlot.esm.js \
    node_modules/uplot/dist/uPlot.min.css node_modules/.package-lock.json)
# (npm keeps the packages' own old mtimes; node_modules/.package-lock.json
# is written by every npm ci, so a fresh install rebuilds the embedded app)
SERVER_LIBS := $(HTTP_LIBS) $(PROTO_LIBS) $(CORE_LIBS) -lpq -lpthread

define server_rules
# the PostgreSQL backend (smd_pg*.c) and its test see libpq's header
# (every server file may include smd_pg_node.h, which does not include libpq-fe.h)
build/$(1)/obj/server/smd_pg.o build/$(1)/obj/server/smd_pg_%.o: $(1)_CFLAGS += -I /usr/include/postgresql
build/$(1)/obj/tests/unit/test_server_pg.o: $(1)_CFLAGS += -I /usr/include/postgresql
build/$(1)/gen/server/smd_embedded.c: server/embed.sh $$(SERVER_EMBEDDED)
	@mkdir -p $$(dir $$@)
	server/embed.sh $$@ smd_params_schema proto/params.schema.json smd_openapi_yaml proto/openapi.yaml \
	    smd_events_schema proto/events.schema.json

build/$(1)/obj/gen/server/smd_embedded.o: build/$(1)/gen/server/smd_embedded.c
	@mkdir -p $$(dir $$@)
	$$(CC) $$($(1)_CFLAGS) -c $$< -o $$@

# three's module imports ./three.core.min.js: served as app/three-core.js
build/$(1)/gen/server/smd_app_embedded.c: server/embed.sh $$(APP_EMBEDDED)
	@mkdir -p $$(dir $$@)
	if [ -f node_modules/three/build/three.module.min.js ]; then \
	  sed 's#"\./three\.core\.min\.js"#"./three-core.js"#g' node_modules/three/build/three.module.min.js >$$(dir $$@)three.js; \
	else rm -f $$(dir $$@)three.js; fi
	server/embed.sh $$@ smd_app_index web/index.html smd_app_js web/app.js smd_app_view web/view.js \
	    smd_app_css web/app.css smd_app_favicon web/favicon.svg smd_app_three $$(dir $$@)three.js \
	    smd_app_three_core node_modules/three/build/three.core.min.js \
	    smd_app_orbit node_modules/three/examples/jsm/controls/OrbitControls.js \
	    smd_app_uplot node_modules/uplot/dist/uPlot.esm.js smd_app_uplot_css node_modules/uplot/dist/uPlot.min.css

build/$(1)/obj/gen/server/smd_app_embedded.o: build/$(1)/gen/server/smd_app_embedded.c
	@mkdir -p $$(dir $$@)
	$$(CC) $$($(1)_CFLAGS) -c $$< -o $$@

build/$(1)/libsmserver.a: $$(SERVER_LIB_SRCS:%.c=build/$(1)/obj/%.o) build/$(1)/obj/gen/server/smd_embedded.o build/$(1)/obj/gen/server/smd_app_embedded.o
	@mkdir -p $$(dir $$@)
	rm -f $$@ && ar rcs $$@ $$^

build/$(1)/shapematchd: build/$(1)/obj/server/shapematchd.o build/$(1)/libsmserver.a build/$(1)/libsmjob.a build/$(1)/libsmproto.a build/$(1)/libshapematch.a
	@mkdir -p $$(dir $$@)
	$$(CC) $$($(1)_LDFLAGS) -o $$@ $$^ $$(SERVER_LIBS)

# the worker takes only the spool and input helpers from libsmserver.a: no HTTP
build/$(1)/shapematch-worker: build/$(1)/obj/server/shapematch_worker.o build/$(1)/libsmserver.a build/$(1)/libsmjob.a build/$(1)/libsmproto.a build/$(1)/libshapematch.a
	@mkdir -p $$(dir $$@)
	$$(CC) $$($(1)_LDFLAGS) -o $$@ $$^ $$(PROTO_LIBS) $$(CORE_LIBS)

# server unit tests see the server headers and also link libsmserver.a
# (explicit rules win over the generic pattern of tests/module.mk)
build/$(1)/obj/tests/unit/test_server_%.o: $(1)_CFLAGS += -I server
$$(SERVER_TEST_NAMES:%=build/$(1)/tests/%): build/$(1)/tests/%: build/$(1)/obj/tests/unit/%.o $$(SERVER_TEST_UTIL_SRCS:%.c=build/$(1)/obj/%.o) build/$(1)/libsmserver.a build/$(1)/libsmjob.a build/$(1)/libsmproto.a build/$(1)/libshapematch.a
	@mkdir -p $$(dir $$@)
	$$(CC) $$($(1)_LDFLAGS) -o $$@ $$^ $$(SERVER_LIBS) -lcmocka
endef
$(foreach v,$(VARIANTS),$(eval $(call server_rules,$(v))))
ALL_TARGETS += shapematchd shapematch-worker
INSTALL_PROGRAMS += shapematchd shapematch-worker
