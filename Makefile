# corrtex build. One static library per folder (docs/architecture.md), three programs
# linked from them, Criterion unit tests and end-to-end scripts.
#   make                      release build of every program whose main exists
#   make SANITIZE=address,undefined   the same under sanitizers (build/san)
#   make test | test-asan | check-deps | check-sizes | bench | demo | install PREFIX=...
# `make test` and `make demo` run scripts/setup-deps first (idempotent).

SHELL       := /bin/bash
OPT         ?= -O2 -g
SANITIZE    ?=
PREFIX      ?= /usr/local
V           ?= 0

ifneq ($(SANITIZE),)
CONFIG      ?= san
SANFLAGS    := -fsanitize=$(SANITIZE) -fno-omit-frame-pointer -fno-sanitize-recover=all
OPT         := -O1 -g
else
CONFIG      ?= release
SANFLAGS    :=
endif

BUILD       := build/$(CONFIG)
ifeq ($(CONFIG),release)
BINDIR      := bin
else
BINDIR      := $(BUILD)/bin
endif

# Clang by default: on the tracer's small-struct vector code (vec3 passed in
# SSE registers) it is 10-20 % faster than GCC 12, whose code builds such
# arguments through the stack and stalls on store-to-load forwarding
# (docs/tracer.md, "Performance decisions"). `make CC=gcc` still works.
ifeq ($(origin CC),default)
CC     := $(if $(shell command -v clang 2>/dev/null),clang,cc)
endif
CC_IS_CLANG := $(shell $(CC) --version 2>/dev/null | grep -q clang && echo 1)

WARN   := -Wall -Wextra -Wpedantic -Wshadow -Wstrict-prototypes -Wmissing-prototypes \
          -Wwrite-strings -Werror
# (GCC: -Wno-format-truncation, error and log messages are bounded on purpose.)
ifneq ($(CC_IS_CLANG),1)
WARN   += -Wno-format-truncation
endif
PKGS   := OpenEXR assimp libcjson libpng liblz4 libsodium
PKGCF  := $(shell pkg-config --cflags $(PKGS) 2>/dev/null)
MPICF  := $(shell pkg-config --cflags ompi-c 2>/dev/null)
# -fno-math-errno: nothing reads errno after a math call, and without it a
# sqrtf cannot be vectorized or inlined without a branch.
# ARCH: on x86-64 the F16C half-float conversions (every x86-64 CPU since
# 2012): the master keeps its texels as halves (common/half.h); `make ARCH=`
# builds for older CPUs with the same results by integer arithmetic.
ARCH   ?= $(if $(filter x86_64%,$(shell $(CC) -dumpmachine 2>/dev/null)),-mf16c)
CFLAGS := -std=c11 -D_GNU_SOURCE -fno-math-errno $(ARCH) $(OPT) $(SANFLAGS) $(WARN) -I. $(PKGCF) -MMD -MP
LDFLAGS_BASE := $(SANFLAGS) -pthread

LIBS_COMMON  := -lOpenEXRCore-3_1 -lassimp -lcjson -lpng -lz -lm
LIBS_PROTO   := -llz4 -lsodium
LIBS_EMBREE  := -lembree3
LIBS_MPI     := $(shell pkg-config --libs ompi-c 2>/dev/null)
LIBS_GL      := -lglfw -lX11 -lEGL -lOSMesa -lGL -ldl
LIBS_TEST    := -lcriterion

ifeq ($(V),1)
Q :=
else
Q := @
endif

FOLDERS := common proto tracer radiosity master display
# Sources of a folder: its .c files, one level of subfolders included.
srcs_of = $(sort $(wildcard $(1)/*.c $(1)/*/*.c))
objs_of = $(patsubst %.c,$(BUILD)/%.o,$(call srcs_of,$(1)))

LIB_common := $(BUILD)/libcommon.a
LIB_proto  := $(BUILD)/libproto.a
LIB_tracer := $(BUILD)/libtracer.a
LIB_radiosity := $(BUILD)/libradiosity.a
LIB_master := $(BUILD)/libmaster.a
LIB_display:= $(BUILD)/libdisplay.a

# Programs: bin/corrtex (offline tools), bin/corrtex-render (MPI job),
# bin/corrtex-display (display client). Built when their main exists.
PROG_corrtex_SRCS         := $(sort $(wildcard cli/corrtex/*.c))
PROG_corrtex_render_SRCS  := $(sort $(wildcard cli/render/*.c))
PROG_corrtex_display_SRCS := $(sort $(wildcard cli/display/*.c))

PROGS :=
ifneq ($(PROG_corrtex_SRCS),)
PROGS += $(BINDIR)/corrtex
endif
ifneq ($(PROG_corrtex_render_SRCS),)
PROGS += $(BINDIR)/corrtex-render
endif
ifneq ($(PROG_corrtex_display_SRCS),)
PROGS += $(BINDIR)/corrtex-display
endif

# Scene generators (scenes/gen/*.c): standalone programs, run by `make scenes`.
GEN_SRCS  := $(sort $(wildcard scenes/gen/*.c))
GEN_BINS  := $(patsubst scenes/gen/%.c,$(BUILD)/gen/%,$(GEN_SRCS))

UNIT_SRCS := $(sort $(wildcard tests/unit/test_*.c))
UNIT_BINS := $(patsubst tests/unit/%.c,$(BUILD)/tests/%,$(UNIT_SRCS))
TEST_SUPPORT := $(patsubst %.c,$(BUILD)/%.o,$(sort $(wildcard tests/support/*.c)))

ALL_LIBS := $(LIB_display) $(LIB_master) $(LIB_radiosity) $(LIB_tracer) $(LIB_proto) $(LIB_common)

.PHONY: all test test-asan unit-bins e2e check-deps check-sizes bench demo install man clean scenes fuzz setup
.DEFAULT_GOAL := all

all: $(PROGS) scenes

# Objects depend on the compiler and its flags: a build folder made with
# another CC or OPT is rebuilt rather than mixed.
FLAGS_STAMP := $(BUILD)/flags.stamp
FLAGS_NOW   := $(CC) $(CFLAGS) $(LDFLAGS_BASE)
$(FLAGS_STAMP): FORCE
	@mkdir -p $(dir $@)
	@[ "$$(cat $@ 2>/dev/null)" = '$(FLAGS_NOW)' ] || echo '$(FLAGS_NOW)' > $@
FORCE:

# The git commit a build came from, for --version (common/version.h): a
# header written only when the commit changes, so that a new commit
# recompiles common/version.c alone. Outside a git checkout (a tarball, or
# git missing) it is "unknown"; .git is looked for here, not in a folder
# above, whose repository would not be this tree's.
GIT_COMMIT  := $(or $(if $(wildcard .git),$(shell git rev-parse --short=7 HEAD 2>/dev/null)),unknown)
COMMIT_H    := $(BUILD)/version/ct_commit.h
COMMIT_LINE := \#define CT_GIT_COMMIT "$(GIT_COMMIT)"
$(COMMIT_H): FORCE
	@mkdir -p $(dir $@)
	@[ "$$(cat $@ 2>/dev/null)" = '$(COMMIT_LINE)' ] || echo '$(COMMIT_LINE)' > $@
$(BUILD)/common/version.o: $(COMMIT_H)
$(BUILD)/common/version.o: CFLAGS += -I$(BUILD)/version

$(BUILD)/%.o: %.c $(FLAGS_STAMP)
	@mkdir -p $(dir $@)
	@[ "$(V)" = 1 ] || echo "  CC      $<"
	$(Q)$(CC) $(CFLAGS) $(if $(filter master/% proto/%,$<),$(MPICF)) -c $< -o $@

lib_objs = $(or $(call objs_of,$(1)),$(BUILD)/empty.o)
# A library also depends on the list of its objects, so that a source file
# moved out of a folder leaves its archive (which would still hold it).
define LIBRULE
$$(BUILD)/lib$(1).objs: FORCE
	@mkdir -p $$(dir $$@)
	@[ "$$$$(cat $$@ 2>/dev/null)" = '$$(call lib_objs,$(1))' ] || echo '$$(call lib_objs,$(1))' > $$@
$$(LIB_$(1)): $$(call lib_objs,$(1)) $$(BUILD)/lib$(1).objs
	@mkdir -p $$(dir $$@)
	@[ "$(V)" = 1 ] || echo "  AR      $$@"
	$(Q)rm -f $$@ && $(AR) rcs $$@ $$(call lib_objs,$(1))
endef
$(foreach f,$(FOLDERS),$(eval $(call LIBRULE,$(f))))

# An empty folder still yields a valid (empty) archive.
$(BUILD)/empty.o:
	@mkdir -p $(dir $@)
	$(Q)echo 'typedef int ct_empty_unit;' | $(CC) -x c -c - -o $@

$(BINDIR)/corrtex: $(patsubst %.c,$(BUILD)/%.o,$(PROG_corrtex_SRCS)) $(LIB_master) $(LIB_radiosity) $(LIB_tracer) $(LIB_proto) $(LIB_common)
	@mkdir -p $(dir $@)
	@[ "$(V)" = 1 ] || echo "  LD      $@"
	$(Q)$(CC) $(LDFLAGS_BASE) -o $@ $^ $(LIBS_EMBREE) $(LIBS_PROTO) $(LIBS_COMMON)

$(BINDIR)/corrtex-render: $(patsubst %.c,$(BUILD)/%.o,$(PROG_corrtex_render_SRCS)) $(LIB_master) $(LIB_radiosity) $(LIB_tracer) $(LIB_proto) $(LIB_common)
	@mkdir -p $(dir $@)
	@[ "$(V)" = 1 ] || echo "  LD      $@"
	$(Q)$(CC) $(LDFLAGS_BASE) -o $@ $^ $(LIBS_EMBREE) $(LIBS_MPI) $(LIBS_PROTO) $(LIBS_COMMON)

$(BINDIR)/corrtex-display: $(patsubst %.c,$(BUILD)/%.o,$(PROG_corrtex_display_SRCS)) $(LIB_display) $(LIB_proto) $(LIB_common)
	@mkdir -p $(dir $@)
	@[ "$(V)" = 1 ] || echo "  LD      $@"
	$(Q)$(CC) $(LDFLAGS_BASE) -o $@ $^ $(LIBS_GL) $(LIBS_PROTO) $(LIBS_COMMON)

$(BUILD)/gen/%: scenes/gen/%.c $(wildcard scenes/gen/*.h)
	@mkdir -p $(dir $@)
	@[ "$(V)" = 1 ] || echo "  GEN     $@"
	$(Q)$(CC) -std=c11 -D_GNU_SOURCE -O2 $(WARN) -o $@ $< -lm

# Generated scene meshes (not in git): each generator writes its scene folder.
scenes: $(GEN_BINS)
	@for g in $(GEN_BINS); do n=$$(basename $$g); \
	  stamp=scenes/$$n/.generated; \
	  if [ ! -f $$stamp ] || [ $$g -nt $$stamp ]; then \
	    echo "  SCENE   scenes/$$n"; $$g scenes/$$n && touch $$stamp || exit 1; fi; done

$(BUILD)/tests/%: tests/unit/%.c $(TEST_SUPPORT) $(ALL_LIBS)
	@mkdir -p $(dir $@)
	@[ "$(V)" = 1 ] || echo "  TEST-LD $@"
	$(Q)$(CC) $(CFLAGS) -o $@ $< $(TEST_SUPPORT) $(ALL_LIBS) $(LDFLAGS_BASE) \
	  $(LIBS_TEST) $(LIBS_GL) $(LIBS_EMBREE) $(LIBS_MPI) $(LIBS_PROTO) $(LIBS_COMMON)

# Benchmark programs (tests/bench/*.c), run by scripts/bench-*; built with the tests.
BENCH_SRCS := $(sort $(wildcard tests/bench/*.c))
BENCH_BINS := $(patsubst tests/bench/%.c,$(BUILD)/bench/%,$(BENCH_SRCS))
$(BUILD)/bench/%: tests/bench/%.c $(ALL_LIBS)
	@mkdir -p $(dir $@)
	@[ "$(V)" = 1 ] || echo "  BENCH-LD $@"
	$(Q)$(CC) $(CFLAGS) -o $@ $< $(ALL_LIBS) $(LDFLAGS_BASE) \
	  $(LIBS_GL) $(LIBS_EMBREE) $(LIBS_MPI) $(LIBS_PROTO) $(LIBS_COMMON)

# Test tools (tests/tools/*.c): programs the end-to-end tests run, such as
# peers that send what the real programs never would; built with the tests.
TOOL_SRCS := $(sort $(wildcard tests/tools/*.c))
TOOL_BINS := $(patsubst tests/tools/%.c,$(BUILD)/tools/%,$(TOOL_SRCS))
$(BUILD)/tools/%: tests/tools/%.c $(LIB_proto) $(LIB_common)
	@mkdir -p $(dir $@)
	@[ "$(V)" = 1 ] || echo "  TOOL-LD $@"
	$(Q)$(CC) $(CFLAGS) -o $@ $< $(LIB_proto) $(LIB_common) $(LDFLAGS_BASE) $(LIBS_PROTO) $(LIBS_COMMON)
# tracer_script is a master scripted against a real tracer rank: it links
# the tracer, Embree and MPI as well.
$(BUILD)/tools/tracer_script: tests/tools/tracer_script.c $(LIB_tracer) $(LIB_proto) $(LIB_common)
	@mkdir -p $(dir $@)
	@[ "$(V)" = 1 ] || echo "  TOOL-LD $@"
	$(Q)$(CC) $(CFLAGS) -o $@ $< $(LIB_tracer) $(LIB_proto) $(LIB_common) $(LDFLAGS_BASE) \
	  $(LIBS_EMBREE) $(LIBS_MPI) $(LIBS_PROTO) $(LIBS_COMMON)

setup:
	@scripts/setup-deps

# The whole suite: unit tests then end-to-end tests, one summary line at the end.
test: setup
	@$(MAKE) --no-print-directory all
	@$(MAKE) --no-print-directory unit-bins
	@CORRTEX_BIN=$(BINDIR) CORRTEX_BUILD=$(BUILD) scripts/run-tests $(UNIT_BINS) -- $(sort $(wildcard tests/e2e/*.sh))

unit-bins: $(UNIT_BINS) $(BENCH_BINS) $(TOOL_BINS)

test-asan: setup
	@$(MAKE) --no-print-directory SANITIZE=address,undefined test

check-deps:
	@scripts/check-deps

check-sizes:
	@scripts/check-sizes

bench: all
	@for b in scripts/bench-*; do echo "== $$b"; $$b || exit 1; done

demo: setup
	@$(MAKE) --no-print-directory all
	@scripts/demo

# The programs, the walkthrough launcher (scripts/corrtex-walk) and its report
# tool, a man page per program made from its --help, the scenes and the guides.
install: all
	install -d $(PREFIX)/bin $(PREFIX)/share/corrtex $(PREFIX)/share/man/man1 $(PREFIX)/share/doc/corrtex
	install -m 0755 $(PROGS) scripts/corrtex-walk $(PREFIX)/bin/
	install -m 0755 scripts/walk-report $(PREFIX)/bin/corrtex-walk-report
	@scripts/gen-man $(PREFIX)/share/man/man1 $(PROGS) scripts/corrtex-walk
	cp -r scenes $(PREFIX)/share/corrtex/
	install -m 0644 docs/*.md $(PREFIX)/share/doc/corrtex/

# docs/man/*.1 from the programs' --help (scripts/gen-man).
man: all
	@scripts/gen-man docs/man $(PROGS) scripts/corrtex-walk

clean:
	rm -rf build bin

-include $(shell find build -name '*.d' 2>/dev/null)

# libFuzzer targets (tests/fuzz/fuzz_*.c, clang): `make fuzz` builds each
# with the proto sources instrumented and runs it FUZZ_SECONDS seconds from
# its generated seeds plus tests/fuzz/corpus/<name>/.
FUZZ_SECONDS ?= 20
FUZZ_CC      ?= clang
FUZZ_SRCS    := $(sort $(wildcard tests/fuzz/fuzz_*.c))
FUZZ_BINS    := $(patsubst tests/fuzz/fuzz_%.c,build/fuzz/fuzz_%,$(FUZZ_SRCS))
# The MPI link and the MPI tracer port are not fuzzed (they decode nothing
# of their own) and need MPI.
FUZZ_DEPS    := $(filter-out proto/mpi_link.c proto/tport_mpi.c,$(call srcs_of,proto)) tests/support/proto_fixtures.c

build/fuzz/fuzz_%: tests/fuzz/fuzz_%.c $(FUZZ_DEPS) $(wildcard proto/*.h tests/support/*.h) $(LIB_common)
	@mkdir -p $(dir $@)
	@[ "$(V)" = 1 ] || echo "  FUZZ-LD $@"
	$(Q)$(FUZZ_CC) -std=c11 -D_GNU_SOURCE -O1 -g -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=all \
	  -I. $(PKGCF) -o $@ $< $(FUZZ_DEPS) $(LIB_common) $(LIBS_PROTO) $(LIBS_COMMON)

# The .ctmesh decoder is instrumented too (it lives in libcommon).
build/fuzz/fuzz_ctmesh: FUZZ_DEPS += common/radmesh_io.c common/radmesh.c

fuzz: $(FUZZ_BINS)
	@for b in $(FUZZ_BINS); do n=$${b##*/fuzz_}; c=build/fuzz/corpus/$$n; mkdir -p $$c; \
	  FUZZ_WRITE_SEEDS=$$c $$b >/dev/null 2>&1; \
	  [ -d tests/fuzz/corpus/$$n ] && cp tests/fuzz/corpus/$$n/* $$c/ 2>/dev/null; \
	  echo "  FUZZ    $$n ($(FUZZ_SECONDS) s)"; \
	  $$b -max_total_time=$(FUZZ_SECONDS) -max_len=65536 -timeout=10 -rss_limit_mb=2048 \
	    -artifact_prefix=build/fuzz/$$n- $$c >build/fuzz/$$n.log 2>&1 \
	    || { echo "fuzz: $$n failed; see build/fuzz/$$n.log and build/fuzz/$$n-*"; tail -n 30 build/fuzz/$$n.log; exit 1; }; \
	  grep -E '^(Done|#[0-9]+.*DONE)' build/fuzz/$$n.log | tail -n 1; done
