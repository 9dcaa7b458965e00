# libsmjob: the one job runner of `shapematch run` and `shapematch-worker`
# (inputs read and checked, the run, its thread policy, the result set and
# its summary).  Stands on the wire contract (libsmproto) and the core:
# users link libsmjob.a before libsmproto.a and libshapematch.a, plus
# $(PROTO_LIBS) and -lz.  Its headers are included as "job/sm_job_*.h".
JOB_SRCS := proto/job/sm_job_inputs.c proto/job/sm_job_warnings.c proto/job/sm_job_runner.c \
  proto/job/sm_job_threads.c proto/job/sm_job_results.c proto/job/sm_job_align.c
define job_rules
build/$(1)/libsmjob.a: $$(JOB_SRCS:%.c=build/$(1)/obj/%.o)
	@mkdir -p $$(dir $$@)
	rm -f $$@ && ar rcs $$@ $$^
endef
$(foreach v,$(VARIANTS),$(eval $(call job_rules,$(v))))
ALL_TARGETS += libsmjob.a
