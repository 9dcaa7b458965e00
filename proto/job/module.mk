# libsmjob: the one job runner of `shapematch run` and `shapematch-worker`
# (inputs read and checked, the run, its thread policy, the result set and
# its summary).  Stands on the wire contract (libsmproto) and the core:
# users link libsmjob.a before libsmproto.a and libshapematch.a, plus
# $(PROTO_LIBS) and -lz.  Its headers are included as "job/sm_job_*.h".
JOB_SRCS := proto/job/sm_job_inputs.c proto/job/sm_job_arrays.c proto/job/sm_job_warnings.c proto/job/sm_job_runner.c \
  proto/job/sm_job_threads.c proto/job/sm_job_results.c proto/job/sm_job_api.c \
  proto/job/sm_job_warp.c proto/job/sm_job_warp_api.c proto/job/sm_job_align.c proto/job/sm_job_image.c \
  proto/job/sm_job_model.c proto/job/sm_job_batch.c proto/job/sm_job_batch_list.c \
  proto/job/sm_job_template_from.c \
  proto/job/sm_job_batch_warm.c \
  proto/job/sm_job_template.c proto/job/sm_job_template_json.c
define job_rules
build/$(1)/libsmjob.a: $$(JOB_SRCS:%.c=build/$(1)/obj/%.o)
	@mkdir -p $$(dir $$@)
	$$(call show,AR,$$@,$(1))rm -f $$@ && ar rcs $$@ $$^
endef
$(foreach v,$(VARIANTS),$(eval $(call job_rules,$(v))))
ALL_TARGETS += libsmjob.a

# libshapematch_job.so.MAJOR: the job runner in one call (shapematch_job.h,
# sm_job_api.c, also in libsmjob.a for the unit test) for bindings
# (python/shapematch) and programs: libsmjob and libsmproto inside,
# libshapematch.so beside it (found through $ORIGIN).  It exports the
# sm_run_* functions of shapematch_job.h and nothing else.
define job_so_rules
build/$(1)/libshapematch_job.map: proto/job/module.mk
	@mkdir -p $$(dir $$@)
	@printf 'SHAPEMATCH_JOB_$(SM_SOVERSION) {\n  global:\n    sm_run_*;\n  local: *;\n};\n' >$$@
build/$(1)/libshapematch_job.so.$(SM_SOVERSION): $$(JOB_SRCS:%.c=build/$(1)/obj/%.o) $$(PROTO_SRCS:%.c=build/$(1)/obj/%.o) \
    build/$(1)/libshapematch_job.map build/$(1)/libshapematch.so.$(SM_SOVERSION)
	$$(call show,LD,$$@,$(1))$$(CC) $$($(1)_LDFLAGS) -shared -Wl,-soname,libshapematch_job.so.$(SM_SOVERSION) -Wl,-z,defs \
	  -Wl,--version-script=build/$(1)/libshapematch_job.map -Wl,-rpath,'$$$$ORIGIN' \
	  -o $$@ $$(filter %.o,$$^) -Lbuild/$(1) -l:libshapematch.so.$(SM_SOVERSION) $$(PROTO_LIBS) $$(CORE_LIBS)
	$$(Q)ln -sf libshapematch_job.so.$(SM_SOVERSION) build/$(1)/libshapematch_job.so
endef
$(foreach v,$(VARIANTS),$(eval $(call job_so_rules,$(v))))
ALL_TARGETS += libshapematch_job.so.$(SM_SOVERSION)
