# shapematch — one entry point: deps, all, test, demo, bench, fuzz, lint, install, clean.
#
# Two build variants live side by side:
#   build/release  -O2, what users run and what `make bench` measures
#   build/asan     AddressSanitizer + UndefinedBehaviorSanitizer, for tests
# Each top-level part (core, proto, server, client, tests, bench) adds its
# targets through a small `module.mk` fragment, so a part can grow without
# editing this file.

SHELL := /bin/bash
.DEFAULT_GOAL := all

PREFIX ?= /usr/local
# where `make install` puts the systemd unit: nowhere unless given
# (UNITDIR=/etc/systemd/system), so that an install stays under PREFIX
UNITDIR ?=
VERSION := 0.1.0

# Debian packages the build, the tests, the demo and the benchmarks need
# (python3-numpy: the Python package's arrays, tests/python; man-db and
# groff-base: man -l in tests/build/install.sh).
DEB_PACKAGES := gcc make pkg-config libc6-dev \
  libsuitesparse-dev libopenblas0-pthread zlib1g-dev libcmocka-dev libjansson-dev \
  libmicrohttpd-dev libgnutls28-dev libcurl4-openssl-dev curl gmsh wrk jq systemd python3 python3-yaml strace \
  libdeflate-dev pmccabe clang libclang-rt-14-dev libomp-14-dev nodejs chromium postgresql libpq-dev \
  libhypre-dev mpi-default-dev python3-numpy man-db groff-base python3-meshio
# templates meshed from a surface or a label map (core/sm_template_mesh.c):
# Netgen's nglib (LGPL-2.1; its C++ header needs g++ for the shim,
# core/mesh/sm_nglib.cc; docs/your-data.md)
DEB_PACKAGES += g++ libnglib-dev
# the label-map tests and bench: scipy's distance transform as an independent oracle
DEB_PACKAGES += python3-scipy
# tests/cli/image_out.sh (nibabel reads the NIfTI images `sdf --image` writes)
# and tests/cli/image_frame.sh (a NIfTI written by nibabel itself, RAS)
DEB_PACKAGES += python3-nibabel

# The part of them `make release` and `make install` need (the Dockerfile's
# build stage: `make deps-build`); tests/deploy/ checks it is a subset.
DEB_BUILD_PACKAGES := gcc make pkg-config libc6-dev libsuitesparse-dev libopenblas0-pthread \
  zlib1g-dev libdeflate-dev libcmocka-dev libjansson-dev libmicrohttpd-dev libgnutls28-dev libcurl4-openssl-dev libpq-dev \
  libhypre-dev mpi-default-dev python3-numpy man-db groff-base g++ libnglib-dev

CC ?= cc
# hypre (BoomerAMG, the iterative solver of large templates) is built with
# MPI in Debian: its headers need MPI's; -isystem keeps their warnings out.
MPI_PC := $(shell pkg-config --cflags-only-I mpi-c 2>/dev/null)
HYPRE_CFLAGS := -isystem /usr/include/hypre $(MPI_PC:-I%=-isystem %)
HYPRE_LIBS := -lHYPRE $(shell pkg-config --libs mpi-c 2>/dev/null)
# -fPIC: one set of objects for the archives and the shared libraries
# (libshapematch.so, libshapematch_job.so); -fno-semantic-interposition keeps
# calls inside them direct, as in the executables (Debian's gcc builds PIE).
BASE_CFLAGS := -std=c11 -D_DEFAULT_SOURCE -D_GNU_SOURCE -Wall -Wextra -Werror -fopenmp \
  -fPIC -fno-semantic-interposition \
  -Wno-missing-field-initializers -g -I core/include -I proto -I /usr/include/suitesparse \
  -DSM_VERSION='"$(VERSION)"' $(HYPRE_CFLAGS)
RELEASE_CFLAGS := $(BASE_CFLAGS) -O2
ASAN_CFLAGS := $(BASE_CFLAGS) -O1 -fno-omit-frame-pointer \
  -fsanitize=address,undefined -fno-sanitize-recover=all
RELEASE_LDFLAGS := -fopenmp
ASAN_LDFLAGS := -fopenmp -fsanitize=address,undefined

CORE_LIBS := -fopenmp -lcholmod $(HYPRE_LIBS) -llapack -lblas -ldeflate -lz -lm
PROTO_LIBS := -ljansson
HTTP_LIBS := -lmicrohttpd -lgnutls
# libcurl is opened at run time (client/curl_api.h), not linked
CURL_LIBS := -ldl

VARIANTS := release asan
release_DIR := build/release
asan_DIR := build/asan
release_CFLAGS := $(RELEASE_CFLAGS)
asan_CFLAGS := $(ASAN_CFLAGS)
release_LDFLAGS := $(RELEASE_LDFLAGS)
asan_LDFLAGS := $(ASAN_LDFLAGS)

# Filled by the module fragments: programs built in every variant, and
# programs built in the release variant only (the benchmarks).
ALL_TARGETS :=
RELEASE_ONLY_TARGETS :=

# A quiet build: one line per step ("  CC   core/sm_match.c", the variant
# in brackets when it is not release); `make V=1` prints the commands.
# A recipe line starts with $(call show,STEP,WHAT,VARIANT) (or $(Q) for a
# step not worth a line), which expands to the @printf of that line.
ifeq ($(V),1)
show =
Q =
else
show = @printf '  %-4s %s%s\n' '$(1)' '$(2)' '$(if $(filter-out release,$(3)), [$(3)])';
Q = @
endif

# compile rule for every variant: build/<variant>/obj/<path>.o
define variant_rules
build/$(1)/obj/%.o: %.c
	@mkdir -p $$(dir $$@)
	$$(call show,CC,$$<,$(1))$$(CC) $$($(1)_CFLAGS) -MMD -MP -c $$< -o $$@
endef
$(foreach v,$(VARIANTS),$(eval $(call variant_rules,$(v))))

include $(wildcard core/module.mk proto/module.mk web/module.mk server/module.mk \
  client/module.mk tests/module.mk bench/module.mk docs/module.mk)

.PHONY: all deps check-deps test demo lint install clean release asan
all: $(foreach v,$(VARIANTS),$(ALL_TARGETS:%=build/$(v)/%)) $(RELEASE_ONLY_TARGETS:%=build/release/%)
release: $(ALL_TARGETS:%=build/release/%) $(RELEASE_ONLY_TARGETS:%=build/release/%)
asan: $(ALL_TARGETS:%=build/asan/%)

# The Debian packages of $(1) that dpkg does not list as installed, as
# shell words (for a recipe: `missing="$(call missing_debs,...)"`).
missing_debs = $$(for p in $(1); do dpkg-query -W -f='$${Status}' $$p 2>/dev/null | \
  grep -q "install ok installed" || printf '%s ' $$p; done)
# The npm packages of the tests are missing or older than package-lock.json.
npm_stale = ! command -v npm >/dev/null || [ ! -f node_modules/.package-lock.json ] || \
  [ package-lock.json -nt node_modules/.package-lock.json ]

# The installer (root): the Debian packages that are missing, npm, and the
# npm packages of the tests from package-lock.json.  Idempotent: only
# touches apt when something is missing.
deps:
	@missing="$(call missing_debs,$(DEB_PACKAGES))"; \
	if [ -n "$$missing" ]; then \
	  echo "deps: installing $$missing"; \
	  if [ "$$(id -u)" != 0 ]; then echo "deps: run as root (or install:$$missing)" >&2; exit 1; fi; \
	  apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends $$missing; \
	else echo "deps: all Debian packages present"; fi
	@# npm: Debian's package, unless the nodejs installed brings its own
	@command -v npm >/dev/null || { echo "deps: installing npm"; \
	  DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends npm; }
	@# npm packages of the tests, from package-lock.json (again when it changes)
	@if $(npm_stale); then \
	  echo "deps: npm ci"; npm ci --no-audit --no-fund --ignore-scripts; \
	else echo "deps: npm packages present"; fi

# The prerequisite check of test, demo, bench and fuzz: reads dpkg's list
# and node_modules, and does nothing more when everything is there.  On a
# clean machine (CI's) it names what is missing and runs the installer
# (`make deps`), which installs only that.
check-deps:
	@missing="$(call missing_debs,$(DEB_PACKAGES))"; \
	if [ -z "$$missing" ] && ! { $(npm_stale); }; then \
	  echo "check-deps: every prerequisite is present"; \
	else \
	  npm=""; if $(npm_stale); then npm="npm packages"; fi; \
	  echo "check-deps: missing:" $$missing $$npm "- installing them (make deps)"; \
	  $(MAKE) --no-print-directory deps; \
	fi

# Only what building needs (no test tools, no npm): the Dockerfile's build stage.
.PHONY: deps-build
deps-build:
	@missing="$(call missing_debs,$(DEB_BUILD_PACKAGES))"; \
	if [ -n "$$missing" ]; then \
	  echo "deps-build: installing $$missing"; \
	  apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends $$missing; \
	else echo "deps-build: all Debian packages present"; fi

# The Dockerfile built without a Docker engine (tests/deploy/): fresh
# debian:bookworm roots made by mmdebstrap, its RUN steps in them, the
# built daemon run from the runtime root against a 2D job.  Root, network
# to the Debian archive; ~10 min.  Not part of `make test`; CI runs it.
.PHONY: test-deploy
test-deploy:
	@command -v mmdebstrap >/dev/null || { echo "test-deploy: installing mmdebstrap"; \
	  apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends mmdebstrap; }
	tests/deploy/docker_build.sh

test: check-deps
	$(MAKE) -j$$(nproc) all fuzz-build
	tests/run.sh

# `make bench` and its parts: bench/module.mk.

# Where the house is crowded: the longest files and the longest and most
# complex functions (pmccabe) against the size guide in tests/lint.sh.  Informative,
# never fails.
lint:
	@tests/lint.sh

# only the three programs the demo runs (not the tests and benchmarks of
# `make release`): a first demo is built in well under a minute on two cores
demo: check-deps
	@$(MAKE) --no-print-directory -j$$(nproc) $(INSTALL_PROGRAMS:%=build/release/%)
	examples/demo.sh

# make install PREFIX=... DESTDIR=...: the programs, the libraries
# (libshapematch.so.MAJOR with its archive, libshapematch_job.so.MAJOR), the
# headers (<shapematch.h>, <shapematch/...>, <shapematch_job.h>),
# shapematch.pc, the man pages, the Python package and the license files
# (LICENSE, THIRD-PARTY in share/doc/shapematch), all under PREFIX.
# Nothing goes elsewhere unless UNITDIR is given: the systemd unit then goes
# there with its program path rewritten to $(PREFIX)/bin
# (UNITDIR=/etc/systemd/system).
LIBDIR = $(PREFIX)/lib
INCLUDEDIR = $(PREFIX)/include
MANDIR = $(PREFIX)/share/man
DOCDIR = $(PREFIX)/share/doc/shapematch
# Debian's python3 searches it for PREFIX=/usr; for /usr/local give
# PYTHONDIR=/usr/local/lib/python3.X/dist-packages (docs/python.md)
PYTHONDIR = $(PREFIX)/lib/python3/dist-packages
PYTHON_FILES := $(wildcard python/shapematch/*.py)
SM_LIBS := libshapematch libshapematch_job

install: release
	install -d $(DESTDIR)$(PREFIX)/bin $(DESTDIR)$(LIBDIR)/pkgconfig $(DESTDIR)$(INCLUDEDIR)/shapematch \
	  $(DESTDIR)$(MANDIR)/man1 $(DESTDIR)$(MANDIR)/man8 $(DESTDIR)$(PYTHONDIR)/shapematch \
	  $(DESTDIR)$(DOCDIR)
	install -m 755 $(INSTALL_PROGRAMS:%=build/release/%) $(DESTDIR)$(PREFIX)/bin/
	for l in $(SM_LIBS); do \
	  install -m 755 build/release/$$l.so.$(SM_SOVERSION) $(DESTDIR)$(LIBDIR)/$$l.so.$(VERSION) && \
	  ln -sf $$l.so.$(VERSION) $(DESTDIR)$(LIBDIR)/$$l.so.$(SM_SOVERSION) && \
	  ln -sf $$l.so.$(SM_SOVERSION) $(DESTDIR)$(LIBDIR)/$$l.so || exit 1; done
	install -m 644 build/release/libshapematch.a $(DESTDIR)$(LIBDIR)/
	@# the Netgen shim, opened by the template mesher from ../lib of the programs
	install -m 755 build/release/libshapematch_nglib.so.0 $(DESTDIR)$(LIBDIR)/
	install -m 644 build/release/include/shapematch.h proto/job/shapematch_job.h $(DESTDIR)$(INCLUDEDIR)/
	install -m 644 $(CORE_PUBLIC_HEADERS) $(DESTDIR)$(INCLUDEDIR)/shapematch/
	sed -e 's|@PREFIX@|$(PREFIX)|' -e 's|@VERSION@|$(VERSION)|' -e 's|@LIBS_PRIVATE@|$(CORE_LIBS)|' \
	  core/shapematch.pc.in >$(DESTDIR)$(LIBDIR)/pkgconfig/shapematch.pc
	install -m 644 build/release/man/shapematch.1 $(DESTDIR)$(MANDIR)/man1/
	install -m 644 build/release/man/shapematchd.8 $(DESTDIR)$(MANDIR)/man8/
	install -m 644 $(PYTHON_FILES) $(DESTDIR)$(PYTHONDIR)/shapematch/
	install -m 644 LICENSE THIRD-PARTY $(DESTDIR)$(DOCDIR)/
	@# bytecode now: an installed folder users cannot write would otherwise
	@# be compiled at every import (~10-20 ms of a 2D match's 0.4 s)
	@if [ -x /usr/bin/python3 ]; then /usr/bin/python3 -m compileall -q \
	  -d $(PYTHONDIR)/shapematch $(DESTDIR)$(PYTHONDIR)/shapematch >/dev/null; fi
	@if [ -n "$(UNITDIR)" ]; then \
	  install -d $(DESTDIR)$(UNITDIR) && \
	  sed 's|/usr/local/bin/|$(PREFIX)/bin/|g' deploy/systemd/shapematchd.service \
	    >$(DESTDIR)$(UNITDIR)/shapematchd.service.tmp && \
	  chmod 644 $(DESTDIR)$(UNITDIR)/shapematchd.service.tmp && \
	  mv $(DESTDIR)$(UNITDIR)/shapematchd.service.tmp $(DESTDIR)$(UNITDIR)/shapematchd.service && \
	  echo "installed; start the daemon with: systemctl daemon-reload && systemctl enable --now shapematchd"; \
	else echo "installed under $(PREFIX); the systemd unit with UNITDIR=/etc/systemd/system"; fi

.PHONY: uninstall
uninstall:
	rm -f $(INSTALL_PROGRAMS:%=$(DESTDIR)$(PREFIX)/bin/%) \
	  $(foreach l,$(SM_LIBS),$(DESTDIR)$(LIBDIR)/$(l).so.$(VERSION) $(DESTDIR)$(LIBDIR)/$(l).so.$(SM_SOVERSION) $(DESTDIR)$(LIBDIR)/$(l).so) \
	  $(DESTDIR)$(LIBDIR)/libshapematch.a $(DESTDIR)$(LIBDIR)/pkgconfig/shapematch.pc \
	  $(DESTDIR)$(LIBDIR)/libshapematch_nglib.so.0 \
	  $(DESTDIR)$(INCLUDEDIR)/shapematch.h $(DESTDIR)$(INCLUDEDIR)/shapematch_job.h \
	  $(CORE_PUBLIC_HEADERS:core/include/%=$(DESTDIR)$(INCLUDEDIR)/%) \
	  $(DESTDIR)$(MANDIR)/man1/shapematch.1 $(DESTDIR)$(MANDIR)/man8/shapematchd.8 \
	  $(PYTHON_FILES:python/%=$(DESTDIR)$(PYTHONDIR)/%) \
	  $(DESTDIR)$(DOCDIR)/LICENSE $(DESTDIR)$(DOCDIR)/THIRD-PARTY
	rm -rf $(DESTDIR)$(PYTHONDIR)/shapematch/__pycache__
	-rmdir $(DESTDIR)$(INCLUDEDIR)/shapematch $(DESTDIR)$(PYTHONDIR)/shapematch $(DESTDIR)$(DOCDIR) 2>/dev/null
	$(if $(UNITDIR),rm -f $(DESTDIR)$(UNITDIR)/shapematchd.service)

clean:
	rm -rf build demo-out

# The compilers' dependency files (-MMD), named from the sources: every
# module lists its sources in a variable whose name ends in _SRCS.
DEP_SRCS := $(sort $(filter %.c,$(foreach v,$(filter %_SRCS,$(.VARIABLES)),$($(v)))))
-include $(wildcard $(foreach d,$(VARIANTS:%=build/%/obj) $(FUZZ_DIR)/obj,$(DEP_SRCS:%.c=$(d)/%.d)))
