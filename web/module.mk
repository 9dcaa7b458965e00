# The web app (web/ and the npm libraries it loads), embedded into the
# daemon as C arrays by server/embed.sh; server/api/smd_app.c serves them.
# Included before server/module.mk, which links WEB_APP_OBJ into libsmserver.a.
APP_EMBEDDED := web/index.html web/app.js web/view.js web/target.js web/align.js web/warp.js web/batch.js \
    web/app.css web/favicon.svg \
    $(wildcard node_modules/three/build/three.module.min.js node_modules/three/build/three.core.min.js \
    node_modules/three/examples/jsm/controls/OrbitControls.js node_modules/uplot/dist/uPlot.esm.js \
    node_modules/uplot/dist/uPlot.min.css node_modules/.package-lock.json)
# (npm keeps the packages' own old mtimes; node_modules/.package-lock.json
# is written by every npm ci, so a fresh install rebuilds the embedded app)
# the object, per variant: $(call WEB_APP_OBJ,<variant>)
WEB_APP_OBJ = build/$(1)/obj/gen/web/smd_app_embedded.o

define web_rules
# three's module imports ./three.core.min.js: served as app/three-core.js
build/$(1)/gen/web/smd_app_embedded.c: server/embed.sh $$(APP_EMBEDDED)
	@mkdir -p $$(dir $$@)
	$$(Q)if [ -f node_modules/three/build/three.module.min.js ]; then \
	  sed 's#"\./three\.core\.min\.js"#"./three-core.js"#g' node_modules/three/build/three.module.min.js >$$(dir $$@)three.js; \
	else rm -f $$(dir $$@)three.js; fi
	$$(call show,GEN,$$@,$(1))server/embed.sh $$@ smd_app_index web/index.html smd_app_js web/app.js smd_app_view web/view.js smd_app_target web/target.js \
	    smd_app_align web/align.js smd_app_warp web/warp.js smd_app_batch web/batch.js \
	    smd_app_css web/app.css smd_app_favicon web/favicon.svg smd_app_three $$(dir $$@)three.js \
	    smd_app_three_core node_modules/three/build/three.core.min.js \
	    smd_app_orbit node_modules/three/examples/jsm/controls/OrbitControls.js \
	    smd_app_uplot node_modules/uplot/dist/uPlot.esm.js smd_app_uplot_css node_modules/uplot/dist/uPlot.min.css

build/$(1)/obj/gen/web/smd_app_embedded.o: build/$(1)/gen/web/smd_app_embedded.c
	@mkdir -p $$(dir $$@)
	$$(call show,CC,$$<,$(1))$$(CC) $$($(1)_CFLAGS) -c $$< -o $$@
endef
$(foreach v,$(VARIANTS),$(eval $(call web_rules,$(v))))
