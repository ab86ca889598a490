# SPDX-License-Identifier: MIT
# mcfd - one top-level Makefile.
#
#   make            build/libmcf.a, build/libmcfapi.a, build/mcf (and build/mcfd once server/ exists)
#   make deps       install missing Debian packages (dpkg -s, then apt-get install -y; sudo when not root),
#                   then the npm packages of package-lock.json (npm ci, when node_modules is missing or stale)
#   make install    mcf, mcfd and their man pages under $(DESTDIR)$(PREFIX) (PREFIX=/usr/local);
#                   make uninstall removes them
#   make test       deps, build, then every unit test binary (build/tests/test_*)
#   make check      the libraries' unit tests only (test_core_*, test_api_*): no daemon,
#                   no package install, no large mesh; one test: build/tests/test_NAME
#   make bench      benchmarks (lab/bench/), ratios against a peer measured in the same run;
#                   make experiments, make quality: the lab's studies (lab/README.md)
#   make SAN=address,undefined test    the same under sanitizers (objects in build-san/)
#   make tsan       the daemon's tests under ThreadSanitizer (build-tsan/, tests/tsan.supp)
#   make WERROR=1 ...                  warnings are errors (CI)
#   make check-deps the one-way dependency server -> api -> core, no exec/setenv in the libraries, the doors -> service.h, includes by name,
#                   nothing outside lab/ includes the lab, an SPDX line atop every source file
#   make check-graph the graph of includes and calls (.ci/depgraph.py): no cycle in server/
#                   or api; the whole server's nodes, edges, levels
#   make image      the container image (docker/Dockerfile, podman); make image-check runs it
#
# Sources are picked up by wildcard: a new core/*.c, api/*.c, api/*.cc or
# tests/test_*.c needs no edit here.

SHARED ?= $(abspath ../shared)
# The large test meshes (armadillo, the dragons, ...): the team's folder when
# it is beside the checkout, else none. The small meshes the tests need are in
# tests/data/meshes; tests that need a large one are skipped without MESHES.
MESHES ?= $(if $(wildcard $(SHARED)/meshes/.),$(SHARED)/meshes,)

include flags.mk
B ?= $(BUILD_DIR)
CPPFLAGS += -I/usr/include/suitesparse -Icore -Iapi

# The serial CHOLMOD (flags.mk says why): Debian's static libcholmod.a,
# its OpenMP calls renamed to core/cholmod_serial/stand_ins.c.
CHOLMOD_A := $(shell $(CC) -print-file-name=libcholmod.a)
LIBS_SRV  := -lmicrohttpd -lhiredis -lpthread
LIBS_TEST := -lcmocka -lcurl -lyaml
# The gRPC door (server/grpc/grpc*.cc): Debian's gRPC C++ 1.51 and protobuf.
# Deferred (=): pkg-config runs once `make deps` has installed them.
GRPC_CFLAGS = $(shell pkg-config --cflags grpc++ protobuf)
LIBS_GRPC   = $(shell pkg-config --libs grpc++ protobuf) -lgrpc++_reflection

# Debian packages: build and test dependencies.
# Debian packages: what building mcf and mcfd needs (DEB_BUILD, listed in
# docker/build-packages, which the image's build stage installs), then the
# tests', fuzzers' and plots'.
DEB_BUILD := $(shell grep -v '^\#' docker/build-packages)
DEB_PKGS := $(DEB_BUILD) clang libclang-rt-14-dev draco libcurl4-openssl-dev \
            libcmocka-dev libyaml-dev gnuplot-nox faketime python3-grpcio grpc-proto \
            chromium python3-protobuf python3-numpy python3-yaml python3-pip python3-venv \
            python3-setuptools python3-wheel curl assimp-utils redis-server
DEB_BENCH := libeigen3-dev libcgal-dev
# make quality's peer: Open3D's filter_smooth_taubin (lab/bench/o3d_taubin.py); its renders:
# matplotlib (lab/bench/render_quality.py)
DEB_QUALITY := python3-open3d python3-numpy python3-matplotlib
# npm's packages (package.json, package-lock.json): `npm ci` below.
NPM_STAMP := node_modules/.package-lock.json
NPM_CI_FLAGS ?=

CORE_SRC := $(wildcard core/*.c)
API_SRC  := $(wildcard api/*.c)
API_CXX  := $(wildcard api/*.cc)
CLI_SRC  := $(wildcard cli/*.c)
# What the programs (mcf, mcfd) do first in main (prog/prog.h): theirs,
# not the libraries'.
PROG_SRC := $(wildcard prog/*.c)
# server/: the daemon's process at the top, one folder per module below
# (README's Layout); SRV_DIRS lists them, SRV_INC says what each may see.
SRV_DIRS := server server/service server/sandbox server/store server/store/redis \
            server/rest server/grpc server/grpc/h2gate
SRV_SRC  := $(wildcard $(SRV_DIRS:%=%/*.c))
SRV_CXX  := $(wildcard $(SRV_DIRS:%=%/*.cc))
SRV_ALL  := $(wildcard $(SRV_DIRS:%=%/*.[ch]) $(SRV_DIRS:%=%/*.cc))
TEST_SRC := $(wildcard tests/test_*.c)
TESTLIB  := $(wildcard tests/testlib.c)

CORE_OBJ := $(CORE_SRC:%.c=$(B)/%.o)
API_OBJ  := $(API_SRC:%.c=$(B)/%.o) $(API_CXX:%.cc=$(B)/%.o)
CLI_OBJ  := $(CLI_SRC:%.c=$(B)/%.o)
PROG_OBJ := $(PROG_SRC:%.c=$(B)/%.o)
SRV_OBJ  := $(SRV_SRC:%.c=$(B)/%.o) $(SRV_CXX:%.cc=$(B)/%.o)
TESTLIB_OBJ := $(TESTLIB:%.c=$(B)/%.o)
TEST_BIN := $(TEST_SRC:tests/%.c=$(B)/tests/%)
# Python test runners (tests/test_*.py on Debian's /usr/bin/python3, whose
# grpcio the gRPC tests use) and node ones (tests/test_*.mjs, the page's
# browser test with puppeteer-core): each gets an executable wrapper in
# $(B)/tests, run and counted by `make test` like the cmocka binaries.
TEST_PY  := $(wildcard tests/test_*.py)
TEST_BIN += $(TEST_PY:tests/%.py=$(B)/tests/%)
TEST_MJS := $(wildcard tests/test_*.mjs)
TEST_BIN += $(TEST_MJS:tests/%.mjs=$(B)/tests/%)
# The lab's tests (lab/tests/test_*.c, e.g. its flow studies end to end):
# built by lab/Makefile, run and counted here.
LAB_TEST_BIN := $(patsubst lab/tests/%.c,$(B)/lab/tests/%,$(wildcard lab/tests/test_*.c))
TEST_BIN += $(LAB_TEST_BIN)

PROGS := $(B)/mcf
ifneq ($(SRV_SRC),)
PROGS += $(B)/mcfd
endif

.PHONY: all deps deps-build test check bench run check-deps check-graph clean asan fuzz image image-check
.DEFAULT_GOAL := all

all: $(B)/libmcf.a $(B)/libmcfapi.a $(CHOLMOD_SERIAL) $(PROGS)

$(B)/libmcf.a: $(CORE_OBJ)
	@mkdir -p $(@D)
	rm -f $@ && ar rcs $@ $^

# The OpenMP entry points CHOLMOD uses (GOMP_parallel, omp_get_num_threads,
# omp_get_thread_num, nothing else: `nm -u`), the clock of its BLAS
# timing statistics and its dpotrf/dtrsm calls (small ones as loops, the
# rest to the BLAS) become the stand-ins'; the stand-ins join the archive
# so that any link order resolves them.
$(B)/libcholmod_serial.a: $(CHOLMOD_A) core/cholmod_serial/stand_ins.c
	@mkdir -p $(@D)/cholmod_serial
	$(CC) $(WARN) $(CFLAGS) -c core/cholmod_serial/stand_ins.c -o $(@D)/cholmod_serial/stand_ins.o
	objcopy --redefine-sym GOMP_parallel=mcf__omp_parallel \
	  --redefine-sym omp_get_num_threads=mcf__omp_get_num_threads \
	  --redefine-sym omp_get_thread_num=mcf__omp_get_thread_num \
	  --redefine-sym SuiteSparse_time=mcf__suitesparse_time \
	  --redefine-sym dtrsm_=mcf__dtrsm --redefine-sym dpotrf_=mcf__dpotrf $(CHOLMOD_A) $@.tmp
	! nm -u $@.tmp | grep -E ' (GOMP_|omp_|GOACC_)' || \
	  { echo "libcholmod_serial.a: $(CHOLMOD_A) calls more of OpenMP than the stand-ins cover"; rm -f $@.tmp; exit 1; }
	ar rs $@.tmp $(@D)/cholmod_serial/stand_ins.o && mv $@.tmp $@

$(B)/libmcfapi.a: $(API_OBJ)
	@mkdir -p $(@D)
	rm -f $@ && ar rcs $@ $^

$(PROG_OBJ) $(CLI_OBJ) $(B)/server/main.o: CPPFLAGS += -Iprog

# Which headers a server/ file sees, by folder: every one the daemon's
# (server/: srv.h, service.h, door.h) and its own folder's; the service its
# store and sandbox as well; the Redis store the store's contract; main.c
# the two doors and the sandbox. A door has no -I to store/, service/ or
# sandbox/, so the compiler refuses a door that includes their headers.
SRV_INC_server               := -Iserver
SRV_INC_server/service       := -Iserver/service -Iserver/store -Iserver/sandbox
SRV_INC_server/sandbox       := -Iserver/sandbox
SRV_INC_server/store         := -Iserver/store
SRV_INC_server/store/redis   := -Iserver/store -Iserver/store/redis
SRV_INC_server/rest          := -Iserver/rest
SRV_INC_server/grpc          := -Iserver/grpc -Iserver/grpc/h2gate
SRV_INC_server/grpc/h2gate   := -Iserver/grpc/h2gate
SRV_INC_MAIN                 := -Iserver/rest -Iserver/grpc -Iserver/sandbox
# $(call srv_inc,BUILD-DIR): each server object under BUILD-DIR gets its folder's.
srv_inc = $(foreach f,$(SRV_SRC) $(SRV_CXX),$(eval $(1)/$(basename $(f)).o: \
  CPPFLAGS += -Iserver $(SRV_INC_$(patsubst %/,%,$(dir $(f))))))
$(call srv_inc,$(B))
$(B)/server/main.o: CPPFLAGS += $(SRV_INC_MAIN)

$(B)/mcf: $(CLI_OBJ) $(PROG_OBJ) $(B)/libmcfapi.a $(B)/libmcf.a $(CHOLMOD_SERIAL)
	$(CXX) $(LDFLAGS) -o $@ $(CLI_OBJ) $(PROG_OBJ) $(B)/libmcfapi.a $(B)/libmcf.a $(LIBS_API) $(LIBS_CORE)

$(B)/mcfd: $(SRV_OBJ) $(PROG_OBJ) $(B)/libmcfapi.a $(B)/libmcf.a $(CHOLMOD_SERIAL)
	$(CXX) $(LDFLAGS) -o $@ $(SRV_OBJ) $(PROG_OBJ) $(B)/libmcfapi.a $(B)/libmcf.a $(LIBS_SRV) $(LIBS_GRPC) $(LIBS_API) $(LIBS_CORE)

# ---- the in-process door for Python (pyext/mcfpy.c; clients/python's
# `mcf` module loads it with ctypes): libmcf and libmcfapi inside one
# shared library that exports mcfpy_* alone (pyext/mcfpy.map), from their
# own position-independent objects in $(B)/pic/ (the programs' stay as
# they are). Built by `make pylib`, `make test` and `pip install
# ./clients/python`, not by `make`. CHOLMOD is Debian's shared libcholmod
# (flags.mk's serial copy is Debian's libcholmod.a, whose objects are not
# position-independent: 278 absolute 32-bit relocations cannot go into a
# shared object); the module sets OMP_NUM_THREADS=1 before loading it.
# The same mesh as mcf to rounding, not the same bytes: Debian's
# libcholmod calls OpenBLAS's dpotrf/dtrsm where mcf's serial copy runs
# small ones as loops (tests/test_pymcf.py states the tolerance).
PIC := $(B)/pic
PYEXT_SRC := $(wildcard pyext/*.c)
PIC_OBJ := $(CORE_SRC:%.c=$(PIC)/%.o) $(API_SRC:%.c=$(PIC)/%.o) $(API_CXX:%.cc=$(PIC)/%.o) \
           $(PYEXT_SRC:%.c=$(PIC)/%.o)
$(PIC)/core/%.o: core/%.c
	@mkdir -p $(@D)
	$(CC) $(WARN) $(CPPFLAGS) $(CFLAGS) -fPIC -MMD -MP -c $< -o $@
$(PIC)/%.o: %.c
	@mkdir -p $(@D)
	$(CC) $(WARN) -D_POSIX_C_SOURCE=200809L $(CPPFLAGS) $(CFLAGS) -fPIC -MMD -MP -c $< -o $@
$(PIC)/%.o: %.cc
	@mkdir -p $(@D)
	$(CXX) $(CXXWARN) -I/usr/include/draco $(CPPFLAGS) $(CXXFLAGS) -fPIC -MMD -MP -c $< -o $@
$(B)/libmcfpy.so: $(PIC_OBJ) pyext/mcfpy.map
	$(CXX) $(LDFLAGS) -shared -Wl,--version-script=pyext/mcfpy.map -Wl,-z,defs \
	  -o $@ $(PIC_OBJ) $(LIBS_API) $(patsubst $(CHOLMOD_SERIAL),-lcholmod,$(LIBS_CORE))
pylib: $(B)/libmcfpy.so
.PHONY: pylib
-include $(PIC_OBJ:.o=.d)

# ---- the gRPC contract: api/mcfd.proto -> $(B)/gen/mcfd{,.grpc}.pb.{cc,h}
# (protoc + grpc_cpp_plugin, Debian's protobuf-compiler-grpc). Generated
# code is compiled without our warning flags (it is not ours to fix) and
# included with -isystem, so the bridge keeps -Werror on its own lines.
GEN := $(B)/gen
GEN_CC := $(GEN)/mcfd.pb.cc $(GEN)/mcfd.grpc.pb.cc
GEN_OBJ := $(GEN_CC:.cc=.o)
ifneq ($(SRV_CXX),)
SRV_OBJ += $(GEN_OBJ)
$(B)/mcfd: $(GEN_OBJ)
endif

$(GEN_CC) $(GEN_CC:.cc=.h) &: api/mcfd.proto
	@mkdir -p $(GEN)
	protoc -Iapi --cpp_out=$(GEN) --grpc_out=$(GEN) \
	  --plugin=protoc-gen-grpc=$$(command -v grpc_cpp_plugin) $<

$(GEN)/%.o: $(GEN)/%.cc
	$(CXX) -std=c++17 $(GRPC_CFLAGS) $(CXXFLAGS) -MMD -MP -c $< -o $@

$(SRV_CXX:%.cc=$(B)/%.o): $(B)/%.o: %.cc $(GEN_CC:.cc=.h)
	@mkdir -p $(@D)
	$(CXX) $(CXXWARN) -isystem $(GEN) $(GRPC_CFLAGS) $(CPPFLAGS) $(CXXFLAGS) -MMD -MP -c $< -o $@

$(LAB_TEST_BIN): $(B)/libmcf.a $(B)/libmcfapi.a $(CHOLMOD_SERIAL) $(TESTLIB_OBJ) FORCE
	$(MAKE) -C lab B=$(abspath $(B)) $(abspath $@)

FORCE:

# A Python test: a wrapper that runs tests/NAME.py with Debian's python3.
$(B)/tests/%: tests/%.py
	@mkdir -p $(@D)
	printf '#!/bin/sh\nexec /usr/bin/python3 %s "$$@"\n' '$(abspath $<)' > $@ && chmod +x $@

# A node test: a wrapper that runs tests/NAME.mjs with the machine's node.
$(B)/tests/%: tests/%.mjs $(NPM_STAMP)
	@mkdir -p $(@D)
	printf '#!/bin/sh\nexec node %s "$$@"\n' '$(abspath $<)' > $@ && chmod +x $@

# core/ is strict C11 with no POSIX; api/, cli/, server/ and tests/ get POSIX.
$(B)/core/%.o: core/%.c
	@mkdir -p $(@D)
	$(CC) $(WARN) $(CPPFLAGS) $(CFLAGS) -MMD -MP -c $< -o $@

$(B)/%.o: %.c
	@mkdir -p $(@D)
	$(CC) $(WARN) -D_POSIX_C_SOURCE=200809L $(CPPFLAGS) $(CFLAGS) -MMD -MP -c $< -o $@

$(B)/%.o: %.cc
	@mkdir -p $(@D)
	$(CXX) $(CXXWARN) -I/usr/include/draco $(CPPFLAGS) $(CXXFLAGS) -MMD -MP -c $< -o $@

$(B)/tests/%: $(B)/tests/%.o $(TESTLIB_OBJ) $(B)/libmcfapi.a $(B)/libmcf.a $(CHOLMOD_SERIAL)
	$(CXX) $(LDFLAGS) -o $@ $< $(TESTLIB_OBJ) $(B)/libmcfapi.a $(B)/libmcf.a $(LIBS_TEST) $(LIBS_API) $(LIBS_CORE) -lpthread

# The Redis store's tests: its client (server/store/redis/rds.c) and store
# (server/store/redis/rstore*.c) against a real redis-server (Debian's, DEB_PKGS) that
# tests/redisd.c starts and stops.
REDIS_TESTS := $(B)/tests/test_redis $(B)/tests/test_rstore
RSTORE_OBJ := $(patsubst %.c,$(B)/%.o,$(wildcard server/store/redis/r*.c))
REDIS_OBJ := $(B)/tests/redisd.o $(RSTORE_OBJ) $(B)/server/fsio.o
$(REDIS_TESTS): $(B)/tests/%: $(B)/tests/%.o $(REDIS_OBJ) $(TESTLIB_OBJ) $(B)/libmcfapi.a $(B)/libmcf.a $(CHOLMOD_SERIAL)
	$(CXX) $(LDFLAGS) -o $@ $< $(REDIS_OBJ) $(TESTLIB_OBJ) $(B)/libmcfapi.a $(B)/libmcf.a $(LIBS_TEST) $(LIBS_API) $(LIBS_CORE) -lhiredis -lpthread

-include $(CORE_OBJ:.o=.d) $(API_OBJ:.o=.d) $(CLI_OBJ:.o=.d) $(PROG_OBJ:.o=.d) $(SRV_OBJ:.o=.d) $(TEST_SRC:tests/%.c=$(B)/tests/%.d) $(TESTLIB_OBJ:.o=.d) $(B)/tests/srvlib.d $(B)/tests/redisd.d

# ---- set-up: install what is missing, nothing else
deps:
	@missing=""; for p in $(DEB_PKGS) $(EXTRA_PKGS); do \
	  dpkg -s $$p >/dev/null 2>&1 || missing="$$missing $$p"; done; \
	if [ -n "$$missing" ]; then \
	  echo "make deps: installing$$missing"; \
	  SUDO=""; [ "$$(id -u)" = 0 ] || SUDO=sudo; \
	  $$SUDO apt-get update -qq && \
	  DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq $$missing; \
	fi
	@$(MAKE) --no-print-directory $(NPM_STAMP)

# ---- npm: package.json + package-lock.json (three for the page, and the
# test tools), `npm ci` into node_modules/ when it is missing or older than
# them. Debian's nodejs and npm are installed when there is no npm (a
# machine's own node, e.g. NodeSource's, which bundles npm, is kept).
# NPM_CI_FLAGS=--omit=dev: three only (the image's build).
$(NPM_STAMP): package.json package-lock.json
	@command -v npm >/dev/null 2>&1 || $(MAKE) --no-print-directory deps DEB_PKGS="nodejs npm"
	npm ci --ignore-scripts --no-audit --no-fund $(NPM_CI_FLAGS)
	@touch $@

# Only what building mcf and mcfd needs (the container's build stage).
deps-build:
	$(MAKE) deps DEB_PKGS="$(DEB_BUILD)"

# ---- tests: every binary, MESHES passed through the environment
# A test that needs a large mesh MESHES does not have is skipped by name
# (cmocka's SKIPPED) with the reason, and logged to $(B)/tests/skipped.log;
# the last line counts them and says how to run them. Two lanes, one per
# core: the tests that start no daemon (core's and api's unit tests, the
# CLI's, the lab's) beside the rest (daemons on ports the kernel picks);
# each binary's output is printed whole when it ends.
TEST_LANE1 = $(CHECK_BIN) $(filter $(B)/tests/test_cli $(LAB_TEST_BIN),$(TEST_BIN))
test: deps
	$(MAKE) all $(TEST_BIN) $(if $(SAN),,$(B)/libmcfpy.so)
	$(MAKE) check-deps check-graph
	@rm -f $(B)/tests/skipped.log $(B)/tests/*.out; \
	run() { for t in "$$@"; do \
	  { OPENBLAS_NUM_THREADS=1 OMP_THREAD_LIMIT=1 MCF_MESHES=$(MESHES) \
	    MCF_TESTDATA=$(CURDIR)/tests/data MCF_SKIP_LOG=$(abspath $(B))/tests/skipped.log \
	    MCF_IMAGE=$(IMAGE) MCF_BUILD=$(B) MCF_SAN=$(SAN) $$t > $$t.out 2>&1; echo $$? > $$t.rc; }; \
	  rc=$$(cat $$t.rc); rm -f $$t.rc; \
	  if [ "$$rc" != 0 ]; then \
	    grep -q '^\[  FAILED  \] [0-9]* test(s), listed below' $$t.out || \
	      echo "[  FAILED  ] 1 test(s), listed below: $$t exited with status $$rc" >> $$t.out; fi; \
	  flock $(B)/tests/.print sh -c 'echo "== $$1"; cat "$$1.out"' sh $$t; \
	done; }; \
	run $(TEST_LANE1) & run $(filter-out $(TEST_LANE1),$(TEST_BIN)); wait; \
	count() { cat $(TEST_BIN:%=%.out) | sed -n "s/^\[  $$1 *\] \([0-9]*\) test(s).*/\1/p" | \
	  awk '{ n += $$1 } END { print n + 0 }'; }; \
	passed=$$(count PASSED); failed=$$(count FAILED); skipped=$$(count SKIPPED); \
	if [ -s $(B)/tests/skipped.log ]; then \
	  echo "make test: the skipped tests (SKIPPED above, each with its reason) need:" \
	    "$$(cut -f1 $(B)/tests/skipped.log | sort -u | tr '\n' ' ')"; \
	  echo "  a mesh file there is a large scan kept out of the repository (tests/data/meshes/SOURCES.md);" \
	    "anything else is what the machine or the build lacks (the reason says)"; \
	  echo "make test: $$passed passed, $$failed failed, $$skipped skipped;" \
	    "run the mesh ones with: make test MESHES=/path/to/meshes (the team's: ../shared/meshes)"; \
	else echo "make test: $$passed passed, $$failed failed, $$skipped skipped (MESHES=$(or $(MESHES),unset))"; fi; \
	[ "$$failed" = 0 ] && ! grep -q '^\[  FAILED  \]' $(TEST_BIN:%=%.out)

asan:
	$(MAKE) SAN=address,undefined test

# ---- make check: core's and api's unit tests (tests/test_core_*.c,
# test_api_*.c) with MESHES unset and MCF_QUICK set, so those that need a
# large mesh and the long studies (tl_long) skip by name; no daemon, no `make deps`, nothing installed. Each binary's output
# is kept in $(B)/tests/NAME.check; the last line counts them.
CHECK_BIN := $(filter $(B)/tests/test_core_% $(B)/tests/test_api_%,$(TEST_BIN))
check: $(CHECK_BIN)
	@fail=0; for t in $(CHECK_BIN); do \
	  OPENBLAS_NUM_THREADS=1 OMP_THREAD_LIMIT=1 MCF_MESHES= MCF_QUICK=1 MCF_TESTDATA=$(CURDIR)/tests/data \
	    $$t > $$t.check 2>&1 || { fail=1; cat $$t.check; }; \
	  echo "$$t: $$(sed -n 's/^\[  \([A-Z]*\) *\] \([0-9]*\) test(s).*/\2 \1/p' $$t.check | tr '\n' ' ')"; \
	done; \
	count() { cat $(CHECK_BIN:%=%.check) | sed -n "s/^\[  $$1 *\] \([0-9]*\) test(s).*/\1/p" | \
	  awk '{ n += $$1 } END { print n + 0 }'; }; \
	echo "make check: $$(count PASSED) passed, $$(count FAILED) failed, $$(count SKIPPED) skipped" \
	  "(the skipped need MESHES or are long studies: make test MESHES=... runs them)"; exit $$fail

# ---- ThreadSanitizer on the daemon (build-tsan/): test_service (the job
# service in-process) and test_server* against TSan builds of mcfd (the job
# service, the REST door, the sandbox), with
# tests/tsan.supp. Fails on any report; they are kept in build-tsan/tsan/
# (one file per process that had one). TSAN_GRPC=1 adds test_grpc: not
# clean yet, gRPC's libraries are not instrumented and TSan cannot see the
# order gRPC gives a call's reactions (tests/tsan.supp says what is left).
TSAN_OPTS = halt_on_error=0 second_deadlock_stack=1 \
  suppressions=$(CURDIR)/tests/tsan.supp log_path=$(CURDIR)/build-tsan/tsan/report
tsan: deps
	$(MAKE) SAN=thread B=build-tsan build-tsan/mcfd build-tsan/mcf \
	  $(SERVER_TEST_NAMES:%=build-tsan/tests/%) build-tsan/tests/test_service
	@rm -rf build-tsan/tsan; mkdir -p build-tsan/tsan; fail=0; \
	for t in test_service $(SERVER_TEST_NAMES); do \
	  OPENBLAS_NUM_THREADS=1 OMP_THREAD_LIMIT=1 MCF_MESHES=$(MESHES) \
	  MCF_TESTDATA=$(CURDIR)/tests/data MCF_BUILD=build-tsan TSAN_OPTIONS="$(TSAN_OPTS)" \
	  build-tsan/tests/$$t || fail=1; done; \
	[ "$(TSAN_GRPC)" != 1 ] || OPENBLAS_NUM_THREADS=1 OMP_THREAD_LIMIT=1 MCF_MESHES=$(MESHES) \
	  MCF_TESTDATA=$(CURDIR)/tests/data MCF_BUILD=build-tsan TSAN_OPTIONS="$(TSAN_OPTS)" \
	  /usr/bin/python3 tests/test_grpc.py || fail=1; \
	if [ -n "$$(ls build-tsan/tsan)" ]; then fail=1; \
	  echo "make tsan: ThreadSanitizer reports in build-tsan/tsan/:"; \
	  grep -h '^SUMMARY' build-tsan/tsan/* | sort | uniq -c; fi; \
	echo "make tsan: $$([ $$fail = 0 ] && echo clean || echo FAILED)"; exit $$fail

.PHONY: tsan

# ---- the attacks of issues 9 and 17 on a real mcfd (loopback), one test
# each, with the figures they measure (worker release, floods, slowloris,
# followers, queued memory, uploads in flight; for the gRPC door:
# connection floods, descriptors, header blocks, abandoned streams, rapid
# reset, compressed messages); the README's reliability section quotes
# them. ATTACKS are in test_server*.c and test_service.c, ATTACKS_GRPC in
# test_grpc.py.
ATTACKS := test_multipart_unnamed test_multipart_duplicates test_hangup_and_budgets \
  test_http_small_things test_transfer_framing test_query_flood test_spool_failures test_spool_quota test_spool_full \
  test_descriptor_exhaustion test_readonly_outcomes test_step_log_memory test_events_memory test_spool_damage \
  test_followers_and_per_ip test_per_ip_busy test_header_deadline test_queued_inputs_on_disk \
  test_cancel_survives_shutdown test_quantization_cap test_draco_sandbox \
  test_memory_admission test_body_timeout test_clock_jumps test_uploads_in_flight test_cpu_budget \
  test_cpu_budget_counts_job_threads
ATTACKS_GRPC := test_connection_flood_leaves_the_doors_working \
  test_no_descriptors_makes_the_daemon_unhealthy test_header_blocks_are_bounded \
  test_abandoned_streams_are_bounded test_rapid_reset_is_paced \
  test_compressed_messages_are_refused test_uploads_in_flight_fit_the_memory_budget \
  test_open_and_cancel_thousands_of_calls test_unread_answer_is_cancelled
# issue 28's, in tests/test_store_trust.py and tests/test_redis_network.py
# (a real redis-server) and tests/test_upload_limits.py; the C ones are in
# ATTACKS
ATTACKS_PY := test_evicting_redis_is_refused test_what_a_restart_loses \
  test_readyz_while_redis_refuses_writes test_unqueueable_job_is_not_acknowledged \
  test_garbage_request_record_is_quarantined test_multipart_300mb_over_default_max_upload \
  test_chunked_multipart_over_max_upload test_refused_at_decode_leaves_its_input_off_the_spool \
  test_latency_drops_and_partition
attack: deps
	$(MAKE) all $(SERVER_TESTS) $(B)/tests/test_service
	@fail=0; for t in $(ATTACKS) $(ATTACKS_GRPC) $(ATTACKS_PY); do \
	  case " $(ATTACKS_GRPC) $(ATTACKS_PY) " in \
	    *" $$t "*) run="/usr/bin/python3 $$(grep -l "^def $$t(" tests/test_*.py)";; \
	    *) run=$$(grep -l "^static void $$t(" $(SERVER_TEST_NAMES:%=tests/%.c) tests/test_service.c | \
	          sed 's|^tests/|$(B)/tests/|; s|\.c$$||');; esac; \
	  OPENBLAS_NUM_THREADS=1 OMP_THREAD_LIMIT=1 MCF_MESHES=$(MESHES) \
	    MCF_TESTDATA=$(CURDIR)/tests/data MCF_BUILD=$(B) MCF_TEST_FILTER=$$t \
	    $$run > $(B)/tests/attack.out 2>&1 || fail=1; \
	  grep -E '^\[ *(OK|FAILED|SKIP) *\]|^    ' $(B)/tests/attack.out | grep -v ' test(s)'; \
	done; rm -f $(B)/tests/attack.out; exit $$fail

.PHONY: attack

# ---- the daemon: `make run`, and the OpenAPI document embedded in mcfd
# api/openapi.yaml becomes a byte array (od + sed: coreutils only, so the
# Docker build stage needs nothing extra) linked into build/mcfd, which
# serves it at /openapi.yaml; no file has to ship next to the binary.
ifneq ($(SRV_SRC),)
OPENAPI_OBJ := $(B)/server/openapi_yaml.o
SRV_OBJ += $(OPENAPI_OBJ)
$(B)/mcfd: $(OPENAPI_OBJ)
endif

# rest_internal.h declares the names it defines: a build made before a
# rename regenerates it.
$(B)/server/openapi_yaml.c: api/openapi.yaml server/rest/rest_internal.h
	@mkdir -p $(@D)
	{ echo '/* generated from api/openapi.yaml by make: do not edit */'; \
	  echo '#include <stddef.h>'; \
	  echo 'extern const unsigned char rest_openapi_yaml[];'; \
	  echo 'extern const size_t rest_openapi_yaml_len;'; \
	  echo 'const unsigned char rest_openapi_yaml[] = {'; \
	  od -An -v -tx1 $< | sed 's/\([0-9a-f][0-9a-f]\)/0x\1,/g'; \
	  echo '0x00};'; \
	  echo "const size_t rest_openapi_yaml_len = $$(wc -c < $<);"; } > $@.tmp && mv $@.tmp $@

$(B)/server/openapi_yaml.o: $(B)/server/openapi_yaml.c
	$(CC) $(WARN) $(CFLAGS) -c $< -o $@

# The page (server/rest/ui.c): web/'s files and three.js (node_modules, `npm ci`
# above) embedded by web/embed.sh as build/server/ui_assets.c. The addon's
# bare `from 'three'` becomes a relative import: the page needs no import
# map (an inline script its Content-Security-Policy forbids).
UI_WEB := $(filter-out web/index.html,$(wildcard web/*.js web/*.css web/*.svg))
THREE := node_modules/three
ifneq ($(SRV_SRC),)
SRV_OBJ += $(B)/server/ui_assets.o
$(B)/mcfd: $(B)/server/ui_assets.o
endif

$(B)/server/ui_assets.c: web/embed.sh web/index.html $(UI_WEB) $(NPM_STAMP)
	@mkdir -p $(@D) $(B)/ui
	sed "s#from 'three'#from './three.module.js'#" \
	  $(THREE)/examples/jsm/controls/OrbitControls.js > $(B)/ui/OrbitControls.js
	web/embed.sh $@ /=web/index.html $(foreach f,$(UI_WEB),/ui/$(notdir $f)=$f) \
	  /ui/three.module.js=$(THREE)/build/three.module.js \
	  /ui/three.core.js=$(THREE)/build/three.core.js \
	  /ui/OrbitControls.js=$(B)/ui/OrbitControls.js

$(B)/server/ui_assets.o: $(B)/server/ui_assets.c server/rest/ui_assets.h
	$(CC) $(WARN) -Iserver/rest $(CFLAGS) -c $< -o $@

# ---- make install: the two programs, their man pages (made from their
# --help, so they cannot drift), the licence and the API contracts.
#   make install [PREFIX=/usr/local] [DESTDIR=]   make uninstall (the same variables)
PREFIX ?= /usr/local
BINDIR ?= $(PREFIX)/bin
MANDIR ?= $(PREFIX)/share/man/man1
DOCDIR ?= $(PREFIX)/share/doc/mcfd
MANPAGES := $(B)/man/mcf.1 $(if $(SRV_SRC),$(B)/man/mcfd.1)

# A man page from a program's --help output: NAME, SYNOPSIS and the help
# text preformatted (roff's own escapes neutralised); mcf's has every
# command's --help in turn. Coreutils and sed only.
define manpage
{ printf '.TH %s 1 "" "mcfd %s" "User Commands"\n.SH NAME\n%s \\- %s\n' \
    $(1) "$$(sed -n 's/^#define API_VERSION "\(.*\)"/\1/p' api/api.h)" $(1) "$(2)"; \
  for c in SYNOPSIS $(3); do \
    printf '.SH "%s"\n.nf\n' "$$(echo "$(1) $$c" | sed 's/^.* SYNOPSIS$$/SYNOPSIS/')"; \
    $(B)/$(1) $$(echo $$c | sed 's/^SYNOPSIS$$//') --help | \
      sed -e 's/\\/\\e/g' -e "s/^[.']/\\\\\&&/"; \
    printf '.fi\n'; \
  done; \
  printf '.SH "SEE ALSO"\nThe README of the mcfd repository; %s/openapi.yaml and %s/mcfd.proto.\n' \
    $(DOCDIR) $(DOCDIR); } > $@.tmp && mv $@.tmp $@
endef

$(B)/man/mcf.1: $(B)/mcf api/api.h
	@mkdir -p $(@D)
	$(call manpage,mcf,smooth meshes by mean curvature flow,smooth info schemes params convert)

$(B)/man/mcfd.1: $(B)/mcfd api/api.h
	@mkdir -p $(@D)
	$(call manpage,mcfd,the mesh-smoothing daemon (REST and gRPC),)

install: $(PROGS) $(MANPAGES)
	install -d $(DESTDIR)$(BINDIR) $(DESTDIR)$(MANDIR) $(DESTDIR)$(DOCDIR)
	install -m 755 $(PROGS) $(DESTDIR)$(BINDIR)/
	install -m 644 $(MANPAGES) $(DESTDIR)$(MANDIR)/
	install -m 644 LICENSE api/openapi.yaml api/mcfd.proto $(DESTDIR)$(DOCDIR)/
	install -m 644 $(THREE)/LICENSE $(DESTDIR)$(DOCDIR)/three.js-LICENSE

uninstall:
	rm -f $(DESTDIR)$(BINDIR)/mcf $(DESTDIR)$(BINDIR)/mcfd \
	  $(DESTDIR)$(MANDIR)/mcf.1 $(DESTDIR)$(MANDIR)/mcfd.1 \
	  $(DESTDIR)$(DOCDIR)/LICENSE $(DESTDIR)$(DOCDIR)/openapi.yaml $(DESTDIR)$(DOCDIR)/mcfd.proto \
	  $(DESTDIR)$(DOCDIR)/three.js-LICENSE
	-rmdir $(DESTDIR)$(DOCDIR)

# ---- the Python client's gRPC stubs (committed: clients/python/gen_stubs.sh
# says why); after a change to api/mcfd.proto: make python-stubs, and commit.
python-stubs:
	clients/python/gen_stubs.sh

.PHONY: install uninstall python-stubs

# Builds (after deps) on every core and runs the daemon in the foreground
# with its embedded defaults: 127.0.0.1:8080, one worker per core, spool
# ./var/mcfd. Ctrl-C stops it (it holds 8080 and 50051).
NPROC := $(shell nproc 2>/dev/null || echo 2)
run: deps
	@echo "make run: building build/mcf and build/mcfd, $(NPROC) compiles at a time" \
	  "(the first build: about 4 minutes of CPU, some 2-3 minutes on 2 idle cores; later ones only what changed)"
	@$(MAKE) --no-print-directory -j$(NPROC) all
	@echo "make run: starting build/mcfd on 127.0.0.1:8080 (gRPC 50051), the page at" \
	  "http://127.0.0.1:8080/; Ctrl-C stops it and frees the ports"
	exec $(B)/mcfd

# ---- the container image: docker/Dockerfile built with Debian's podman
#   make image              builds $(IMAGE) (installs podman, runc, buildah, debootstrap)
#   make image BASE=IMG     on that base image instead. Default: debian:bookworm-slim when
#                           a registry answers, else a `debootstrap --variant=minbase
#                           bookworm` imported as localhost/mcfd-base:bookworm (kept: the
#                           next build reuses it)
#   make image-check        runs it as CI does: HEALTHCHECK, POST /smooth and gRPC Smooth
#                           through published 127.0.0.1 ports (the same bytes), a non-root
#                           user, `podman stop` exits 0, the size
# docker/image.sh holds what podman needs on these machines (runc, lower ulimits) and why.
IMAGE ?= mcfd:latest
BASE ?=
IMAGE_PKGS := podman runc buildah debootstrap

image:
	$(MAKE) deps DEB_PKGS="$(IMAGE_PKGS)"
	docker/image.sh build $(IMAGE) $(BASE)

image-check:
	$(MAKE) deps DEB_PKGS="$(DEB_BUILD) $(IMAGE_PKGS) curl procps python3-grpcio"
	$(MAKE) $(B)/mcf
	docker/image.sh check $(IMAGE) $(B)/mcf

# Every source of the product and its tests (all but lab/), and the lab's
# header names as one regular expression (lab.h|study.h|...).
PRODUCT_SRC := $(wildcard core/*.[ch] api/*.[ch] api/*.cc cli/*.[ch] prog/*.[ch] tests/*.[ch] tests/fuzz/*.[ch]) \
               $(SRV_ALL)
empty :=
LAB_HEADERS_RE := $(subst $(empty) $(empty),|,$(subst .,\.,$(notdir $(wildcard lab/*.h lab/*/*.h))))

# The job service's files (service/, with its sandbox/ and store/): they
# alone include svc_internal.h (spool.c, the local store, sees only store.h).
SRV_SERVICE := $(wildcard server/service.h server/service/*.[ch] server/sandbox/*.[ch] server/store/*.[ch] server/store/redis/*.[ch])
# The doors: each reaches jobs through service.h alone and never includes
# the other door's headers (the -I flags above enforce the first).
REST_DOOR := $(wildcard server/rest/*.[ch])
# The gRPC door's C++ (the only C++ in server/), sharing grpc_internal.h.
GRPC_CXX := $(wildcard server/grpc/*.cc)
GRPC_DOOR := $(wildcard server/grpc/*.cc server/grpc/*.h server/grpc/h2gate/*.[ch])
# The leaves that broke the cycles of issue 32 (the REST door's request
# accessors, the service's table and wake-up, the codecs' shared steps,
# the gRPC door's state, the Redis store's keys and commands):
# called by their module's files, they call none of them.
LEAVES := $(wildcard server/rest/request.c server/service/svc_table.c api/api_codec.c api/api_gltf_write.c server/grpc/grpc_state.cc server/store/redis/rstore_cmd.c)
# The code whose include-and-call graph has no cycle (make check-graph,
# .ci/depgraph.py over the objects: a file that calls back up fails it):
# the whole daemon and the api layer.
ACYCLIC := server api

# The daemon's integration tests (test_server*.c, one concern each) share
# tests/srvlib.c.
SRVLIB_OBJ := $(B)/tests/srvlib.o
SERVER_TEST_NAMES := $(patsubst tests/%.c,%,$(wildcard tests/test_server*.c))
SERVER_TESTS := $(SERVER_TEST_NAMES:%=$(B)/tests/%)
$(SERVER_TESTS): $(B)/tests/%: $(B)/tests/%.o $(SRVLIB_OBJ) $(TESTLIB_OBJ) $(B)/libmcfapi.a $(B)/libmcf.a $(CHOLMOD_SERIAL)
	$(CXX) $(LDFLAGS) -o $@ $< $(SRVLIB_OBJ) $(TESTLIB_OBJ) $(B)/libmcfapi.a $(B)/libmcf.a $(LIBS_TEST) $(LIBS_API) $(LIBS_CORE) -lpthread

# test_service drives the job service in-process: its objects (the service,
# its store and sandbox, the log and metrics it reports to, fsio.c), no door.
SVC_TEST_OBJ := $(patsubst %.c,$(B)/%.o,$(filter %.c,$(SRV_SERVICE)) server/log.c server/metrics.c server/fsio.c)
$(B)/tests/test_service.o: CPPFLAGS += -Iserver -Iserver/sandbox
$(B)/tests/test_service: $(B)/tests/test_service.o $(SVC_TEST_OBJ) $(TESTLIB_OBJ) $(B)/libmcfapi.a $(B)/libmcf.a $(CHOLMOD_SERIAL)
	$(CXX) $(LDFLAGS) -o $@ $< $(SVC_TEST_OBJ) $(TESTLIB_OBJ) $(B)/libmcfapi.a $(B)/libmcf.a $(LIBS_TEST) $(LIBS_API) $(LIBS_CORE) -lhiredis -lpthread

# the files that carry an SPDX line (LICENSE is MIT; issue 20)
SPDX_FILES := '*.c' '*.h' '*.cc' '*.cpp' '*.proto' '*.py' '*.mjs' '*.js' '*.sh' '*.gp' \
  '*.css' '*.html' '*.yaml' '*.toml' '*.mk' Makefile '*/Makefile' .ci/run docker/Dockerfile \
  docker/build-packages

# The graph of includes and calls (.ci/depgraph.py, from the sources and
# nm of the objects): nodes, edges, levels, cycles; fails on a cycle in
# $(ACYCLIC). make test runs it.
check-graph: $(SRV_OBJ) $(API_OBJ)
	@python3 .ci/depgraph.py --build $(B) --fail-on-cycle $(ACYCLIC)
	@python3 .ci/depgraph.py --build $(B) server

check-deps:
	@! grep -nE '#include *[<"](microhttpd|cjson/cJSON|cJSON|curl/curl|api)\.h' core/*.c core/*.h || \
	  { echo "check-deps: core/ must not include api, JSON or HTTP headers"; exit 1; }
	@! grep -nE '#include *[<"]microhttpd\.h' api/*.c api/*.cc api/*.h || \
	  { echo "check-deps: api/ must not include microhttpd.h"; exit 1; }
	@! grep -nE '\b(exec[lv]p?e?|setenv|putenv|fork)[[:space:]]*\(' core/*.[ch] api/*.[ch] api/*.cc || \
	  { echo "check-deps: the libraries leave the process to the programs: no exec, fork or setenv in core/ or api/ (prog/ has what mcf and mcfd do first)"; exit 1; }
	@! grep -nE '#include *[<"](grpc[a-z+]*/|google/protobuf/)|mcfd(\.grpc)?\.pb\.h' core/*.[ch] api/*.c api/*.cc api/*.h $(filter-out $(GRPC_CXX) server/grpc/grpc_internal.h,$(SRV_ALL)) || \
	  { echo "check-deps: only the server's gRPC bridge ($(GRPC_CXX), server/grpc/grpc_internal.h) includes gRPC or protobuf"; exit 1; }
	@[ -z "$(filter-out $(GRPC_CXX),$(wildcard $(SRV_DIRS:%=%/*.cc) $(SRV_DIRS:%=%/*.cpp)))" ] || \
	  { echo "check-deps: $(GRPC_CXX) are the only C++ in server/"; exit 1; }
	@! grep -nE '#include *[<"]grpc_internal\.h' $(filter-out $(GRPC_CXX),$(wildcard core/*.[ch] api/*.[ch] api/*.cc cli/*.[ch] tests/*.[ch]) $(SRV_ALL)) || \
	  { echo "check-deps: grpc_internal.h is the gRPC door's own ($(GRPC_CXX)); others use grpc_door.h"; exit 1; }
	@! grep -nE '#include *[<"][^>"]*\.\./' $(wildcard core/*.[ch] api/*.c api/*.cc api/*.h cli/*.[ch] prog/*.[ch]) $(SRV_ALL) || \
	  { echo "check-deps: include a layer's header by name (\"api.h\"), not by a relative path: the -I flags say which layers a file may see"; exit 1; }
	@! grep -nE '#include *[<"](microhttpd|http)\.h' $(SRV_SERVICE) || \
	  { echo "check-deps: the job service (service.h) must not know the REST door or libmicrohttpd"; exit 1; }
	@! grep -nE '#include *[<"]svc_internal\.h' $(filter-out $(SRV_SERVICE),$(SRV_ALL)) || \
	  { echo "check-deps: outside the job service, use service.h, not svc_internal.h"; exit 1; }
	@! grep -nE '#include *[<"](svc_internal|svc_admit|store|sandbox|rstore[a-z_]*|rds)\.h' $(REST_DOOR) $(GRPC_DOOR) || \
	  { echo "check-deps: a door includes service.h, never the service's own headers (svc_internal.h, svc_admit.h, store.h, rstore.h, rds.h, sandbox.h)"; exit 1; }
	@! grep -nE '#include *[<"](grpc_door|h2gate[a-z_]*)\.h' $(REST_DOOR) || \
	  { echo "check-deps: the REST door does not include the gRPC door's headers"; exit 1; }
	@! grep -nE '#include *[<"](http|rest_door|rest_internal)\.h' $(GRPC_DOOR) || \
	  { echo "check-deps: the gRPC door does not include the REST door's headers"; exit 1; }
	@! grep -nE '#include *[<"]http\.h' $(filter-out server/rest/http.c server/rest/rest_door.c,$(SRV_ALL)) || \
	  { echo "check-deps: only rest_door.c includes the router's http.h: the door's other files are called by http.c and never call it back (rest_internal.h)"; exit 1; }
	@! grep -HnE '#include *"' $(LEAVES) | grep -vE ':[0-9]+:#include *"(rest_internal|svc_internal|api_internal|grpc_internal|rstore_internal)\.h"' || \
	  { echo "check-deps: the leaves $(LEAVES) include their module's internal header alone (they call no other file of it: make check-graph)"; exit 1; }
	@! grep -nE '#include *[<"]([^>"]*/)?(lab/|$(LAB_HEADERS_RE))' $(PRODUCT_SRC) || \
	  { echo "check-deps: nothing outside lab/ includes the lab's headers: the lab is a client of the product, never a part"; exit 1; }
	@missing=$$(git ls-files -- $(SPDX_FILES) 2>/dev/null | grep -v -e '^tests/fuzz/corpus' -e '^tests/data/' | \
	  while read -r f; do head -5 "$$f" | grep -q 'SPDX-License-Identifier: MIT' || echo "$$f"; done); \
	  [ -z "$$missing" ] || { echo "check-deps: no 'SPDX-License-Identifier: MIT' in the first 5 lines of:" $$missing; exit 1; }
	@echo "check-deps: server -> api -> core holds; the doors -> service.h; nothing includes lab/; every source file carries its SPDX line"

clean:
	rm -rf build build-san build-tsan build-fuzz

# ---- fuzzing: libFuzzer with Debian clang, ASan + UBSan, in build-fuzz/
#   make fuzz FUZZ_TIME=30    builds every tests/fuzz/fuzz_*.c and runs each
#                             for FUZZ_TIME seconds; fails if one crashes.
# Seeds come from tests/fuzz/corpus_<name>/ (read only); new inputs go to
# build-fuzz/corpus/<name>/, crashes to build-fuzz/artifacts/. A target
# uses tests/fuzz/<name>.dict when present (params and query: json.dict).
FUZZ_TIME ?= 30
# Inputs that reach libdraco (Draco, glTF, the round trip) get 120 s, the others 10 s. libdraco 1.5.5's
# portable texcoord predictor loops over an int32 orientation count read
# from the stream (MeshPredictionSchemeTexCoordsPortableDecoder): a
# 251-byte file costs 4.6 s of CPU (7 s under ASan), and the largest count
# (2^31) about 8x that; the header counts check_counts bounds are tiny there.
# The daemon decodes Draco in a sandbox with CPU and memory limits
# (server/sandbox/sandbox.c: such a file is a 422 there); the fuzzers call the codec
# directly, hence the long timeout. Crashes, leaks and UB still fail the
# run at once.
FUZZ_DRACO_TIMEOUT ?= 120
FZ := build-fuzz
FUZZ_CC  ?= clang
FUZZ_CXX ?= clang++
FUZZ_SAN := -fsanitize=address,undefined -fno-sanitize-recover=all
# FUZZING_BUILD_MODE_UNSAFE_FOR_PRODUCTION: api_limits_default's counts at
# the fuzzers' scale (api/api_limits.c)
FUZZ_CFLAGS := -O1 -g -fno-omit-frame-pointer -fsanitize=fuzzer-no-link $(FUZZ_SAN) \
               -DFUZZING_BUILD_MODE_UNSAFE_FOR_PRODUCTION
FUZZ_SRC := $(wildcard tests/fuzz/fuzz_*.c)
FUZZ_NAMES := $(FUZZ_SRC:tests/fuzz/fuzz_%.c=%)
FUZZ_BIN := $(FUZZ_NAMES:%=$(FZ)/fuzz_%)
# The server's pure parts, for fuzz_h2gate: the gRPC door's frame parser
# and its accounting (h2gate_parser.h, h2gate_limits.h: no sockets, threads or clock).
FUZZ_SRVOBJ := $(FZ)/server/grpc/h2gate/h2gate_parser.o $(FZ)/server/grpc/h2gate/h2gate_limits.o
FUZZ_LIBOBJ := $(CORE_SRC:%.c=$(FZ)/%.o) $(API_SRC:%.c=$(FZ)/%.o) \
               $(API_CXX:%.cc=$(FZ)/%.o) $(FUZZ_SRVOBJ)

$(FZ)/core/%.o: core/%.c
	@mkdir -p $(@D)
	$(FUZZ_CC) $(WARN) $(CPPFLAGS) $(FUZZ_CFLAGS) -MMD -MP -c $< -o $@

$(FZ)/api/%.o: api/%.c
	@mkdir -p $(@D)
	$(FUZZ_CC) $(WARN) -D_POSIX_C_SOURCE=200809L $(CPPFLAGS) $(FUZZ_CFLAGS) -MMD -MP -c $< -o $@

$(FZ)/api/%.o: api/%.cc
	@mkdir -p $(@D)
	$(FUZZ_CXX) $(CXXWARN) -I/usr/include/draco $(CPPFLAGS) $(FUZZ_CFLAGS) -MMD -MP -c $< -o $@

$(call srv_inc,$(FZ))
$(FZ)/server/%.o: server/%.c
	@mkdir -p $(@D)
	$(FUZZ_CC) $(WARN) -D_POSIX_C_SOURCE=200809L $(CPPFLAGS) $(FUZZ_CFLAGS) -MMD -MP -c $< -o $@

$(FZ)/tests/fuzz/fuzz_h2gate.o: CPPFLAGS += -Iserver/grpc/h2gate
$(FZ)/tests/fuzz/%.o: tests/fuzz/%.c
	@mkdir -p $(@D)
	$(FUZZ_CC) $(WARN) -D_POSIX_C_SOURCE=200809L $(CPPFLAGS) $(FUZZ_CFLAGS) -MMD -MP -c $< -o $@

$(FZ)/fuzz_%: $(FZ)/tests/fuzz/fuzz_%.o $(FUZZ_LIBOBJ) $(CHOLMOD_SERIAL)
	$(FUZZ_CXX) -fsanitize=fuzzer $(FUZZ_SAN) -o $@ $< $(FUZZ_LIBOBJ) $(LIBS_API) $(LIBS_CORE)

-include $(FUZZ_LIBOBJ:.o=.d) $(FUZZ_NAMES:%=$(FZ)/tests/fuzz/fuzz_%.d)

# Objects of chained pattern rules would otherwise be deleted as
# intermediate files after each link.
.SECONDARY: $(FUZZ_LIBOBJ) $(FUZZ_NAMES:%=$(FZ)/tests/fuzz/fuzz_%.o)

fuzz-build: $(FUZZ_BIN)

fuzz: $(FUZZ_BIN)
	@mkdir -p $(FZ)/artifacts
	@fail=""; for n in $(FUZZ_NAMES); do \
	  mkdir -p $(FZ)/corpus/$$n; \
	  dict=tests/fuzz/$$n.dict; \
	  case $$n in params|query) dict=tests/fuzz/json.dict;; esac; \
	  [ -f $$dict ] && dopt=-dict=$$dict || dopt=; \
	  seeds=tests/fuzz/corpus_$$n; [ -d $$seeds ] || seeds=; \
	  case $$n in draco|roundtrip|gltf) to=$(FUZZ_DRACO_TIMEOUT);; *) to=10;; esac; \
	  echo "== fuzz_$$n for $(FUZZ_TIME) s"; \
	  $(FZ)/fuzz_$$n -max_total_time=$(FUZZ_TIME) -timeout=$$to -rss_limit_mb=2048 \
	    -print_final_stats=1 -artifact_prefix=$(FZ)/artifacts/$$n- $$dopt \
	    $(FZ)/corpus/$$n $$seeds > $(FZ)/fuzz_$$n.log 2>&1 \
	    || { fail="$$fail $$n"; tail -40 $(FZ)/fuzz_$$n.log; }; \
	  grep -E '^stat::number_of_executed_units|^stat::new_units_added' $(FZ)/fuzz_$$n.log; \
	done; \
	if [ -n "$$fail" ]; then echo "fuzz: FAILED:$$fail (inputs in $(FZ)/artifacts/)"; exit 1; fi; \
	echo "fuzz: no crash in$(FUZZ_NAMES:%= fuzz_%)"

.PHONY: fuzz-build

# ---- the lab (lab/Makefile, lab/README.md): flow studies, benchmarks
# against peers and the scan-quality study live there, never in `make`;
# these targets build what they need and delegate (variables given on the
# command line, e.g. REPS=3 or QUALITY_ARGS=..., pass through).
#   make experiments [EXP_DIR=DIR]   every flow study -> lab/results/experiments/
#   make exp-sweep-spot ...          one of them (lab/Makefile lists them)
#   make bench                       benchmarks, ratios against a peer measured in the same run
#                                    (bench-core, bench-server, bench-grpc, bench-store, bench-peers,
#                                    bench-scale: one part; SCALE=1 adds the 7M row)
#   make bench-ui [UI_MESH=dragon_vrip.drc] [UI_REPS=3]   the page on a large scan, headless chromium
#   make quality [QUALITY_ARGS="--models out --rho 0.25 --list spot.obj"] [QUALITY_OUT=DIR]
#                                    the scan-quality study -> build/lab/quality/ (lab/README.md)
LAB = $(MAKE) -C lab B=$(abspath $(B)) MESHES=$(MESHES) $(if $(EXP_DIR),EXP_DIR=$(abspath $(EXP_DIR))) \
      $(if $(QUALITY_OUT),QUALITY_OUT=$(abspath $(QUALITY_OUT))) $(if $(QUALITY_BASELINE),QUALITY_BASELINE=$(abspath $(QUALITY_BASELINE)))
LAB_LIBS := $(B)/libmcf.a $(B)/libmcfapi.a $(CHOLMOD_SERIAL)
LAB_TARGETS := experiments bench bench-core bench-server bench-grpc bench-store bench-peers bench-scale bench-ui quality

experiments: deps
	$(MAKE) $(LAB_LIBS)
	$(LAB) $@

exp-%: deps
	$(MAKE) $(LAB_LIBS)
	$(LAB) $@

bench bench-core bench-server bench-grpc bench-store bench-peers bench-scale: deps
	$(MAKE) EXTRA_PKGS="$(DEB_BENCH) $(DEB_QUALITY)" deps
	$(MAKE) all
	$(LAB) $@

bench-ui: deps
	$(MAKE) all
	$(LAB) $@

quality: deps
	$(MAKE) EXTRA_PKGS="$(DEB_QUALITY)" deps
	$(MAKE) $(LAB_LIBS)
	$(LAB) $@

.PHONY: $(LAB_TARGETS)
