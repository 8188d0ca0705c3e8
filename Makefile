# gissar front door. `make demo` and `make test` each install what is
# missing (Debian packages), build, and run.
BUILD_DIR ?= build
JOBS ?= $(shell nproc)

# `make test-sanitize`: the whole suite built with ASan + UBSan.
SANITIZE_DIR ?= build-asan
# Optimisation and debug info of the sanitized build: -O1 without -g compiles
# in about 55 % of RelWithDebInfo's time (-O2 -g: 90 s against 50 s for
# geo/thin_plate_spline.cc), which is what lets CI's sanitizer job fit; the
# reports still name every function (symbol table). For file:line in the
# stacks: `make test-sanitize SANITIZE_OPT="-O1 -g"` (docs/robustness.md).
SANITIZE_OPT ?= -O1
SANITIZE_CONFIGURE = -DCMAKE_BUILD_TYPE=Sanitize -DCMAKE_CXX_FLAGS_SANITIZE="$(SANITIZE_OPT) -DNDEBUG" \
  -DCMAKE_C_FLAGS_SANITIZE="$(SANITIZE_OPT) -DNDEBUG" -DGISSAR_SANITIZE=ON -DGISSAR_BUILD_BENCH=OFF
# `make fuzz FUZZ_SECONDS=600`: each libFuzzer harness for that long.
FUZZ_DIR ?= build-fuzz
FUZZ_SECONDS ?= 60
FUZZERS ?=

.PHONY: all deps configure build install install-python docs-numbers test test-sanitize test-sanitize-ci fuzz demo bench clean

all: build

# Ninja for a new build tree: it compiles a library's objects while the
# libraries below it are still linking, so both cores stay busy (make's
# generator waits at every library: 157 % CPU against 195 %, measured on the
# demo's build). A tree configured before keeps its own generator.
GENERATOR = $(if $(wildcard $(1)/CMakeCache.txt),,-G Ninja)

deps:
	@bash scripts/install-deps.sh

configure: deps
	@cmake -S . -B $(BUILD_DIR) $(call GENERATOR,$(BUILD_DIR)) -DCMAKE_BUILD_TYPE=Release > /dev/null

build: configure
	@cmake --build $(BUILD_DIR) -j$(JOBS)

# `make install PREFIX=$HOME/.local`: the gissar binary into PREFIX/bin, the
# Python module into PREFIX/lib/python3/dist-packages.
PREFIX ?= /usr/local
install: build
	@cmake --install $(BUILD_DIR) --prefix $(PREFIX)

# `make install-python`: the Python package into the virtual environment
# $(VENV) (made with --system-site-packages for Debian's NumPy/GDAL; reuses
# the build tree, offline): then `$(VENV)/bin/python -c "import gissar"`
# works from any directory.
VENV ?= .venv
install-python: build
	@test -x $(VENV)/bin/python || /usr/bin/python3 -m venv --system-site-packages $(VENV)
	@GISSAR_BUILD_DIR=$(CURDIR)/$(BUILD_DIR) $(VENV)/bin/python -m pip install -q --no-build-isolation --no-index .
	@echo "install-python: gissar installed into $(VENV) ($(VENV)/bin/python)"

# Rewrites the figures docs/tutorial.md quotes from a fresh run of the
# tutorial (scripts/docs_numbers.py; the docs_tutorial test compares them).
docs-numbers: build
	@PYTHONPATH=$(BUILD_DIR)/python /usr/bin/python3 scripts/options_table.py --out docs/options.md
	@mkdir -p out/tutorial
	@PYTHONPATH=$(BUILD_DIR)/python /usr/bin/python3 examples/tutorial.py --out out/tutorial | tee out/tutorial/printed.txt
	@/usr/bin/python3 scripts/docs_numbers.py --results out/tutorial/results.json \
	  --output out/tutorial/printed.txt --update docs/tutorial.md

test: build
	@cd $(BUILD_DIR) && ctest --output-on-failure -j$(JOBS)

# Sanitizer run-time options (docs/robustness.md): leaks of the uninstrumented
# system libraries are suppressed, every UBSan finding is fatal.
test-sanitize: export ASAN_OPTIONS = detect_leaks=1:detect_stack_use_after_return=0:check_initialization_order=1:strict_init_order=1
test-sanitize: export LSAN_OPTIONS = suppressions=$(CURDIR)/scripts/sanitizer/lsan.supp:print_suppressions=0
test-sanitize: export UBSAN_OPTIONS = print_stacktrace=1:halt_on_error=1
test-sanitize: deps
	@cmake -S . -B $(SANITIZE_DIR) $(call GENERATOR,$(SANITIZE_DIR)) $(SANITIZE_CONFIGURE) > /dev/null
	@cmake --build $(SANITIZE_DIR) -j$(JOBS)
	@cd $(SANITIZE_DIR) && ctest --output-on-failure -j$(JOBS) --timeout 1500

# CI's subset under ASan + UBSan (time budget): the unit tests of the library
# modules below the CLI (util, geo, scene, material, sensor, render, mvg) and
# the whole bad-input catalogue through the sanitized binary.
SANITIZE_CI_TESTS = util_test geo_test scene_test material_test sensor_test render_test mvg_test
SANITIZE_CI_TARGETS = $(SANITIZE_CI_TESTS) gissar bad_inputs_driver
SANITIZE_CI_LABELS = $(SANITIZE_CI_TESTS) bad_inputs
test-sanitize-ci: export ASAN_OPTIONS = detect_leaks=1:detect_stack_use_after_return=0:check_initialization_order=1:strict_init_order=1
test-sanitize-ci: export LSAN_OPTIONS = suppressions=$(CURDIR)/scripts/sanitizer/lsan.supp:print_suppressions=0
test-sanitize-ci: export UBSAN_OPTIONS = print_stacktrace=1:halt_on_error=1
test-sanitize-ci: deps
	@cmake -S . -B $(SANITIZE_DIR) $(call GENERATOR,$(SANITIZE_DIR)) $(SANITIZE_CONFIGURE) > /dev/null
	@cmake --build $(SANITIZE_DIR) -j$(JOBS) $(addprefix --target ,$(SANITIZE_CI_TARGETS))
	@cd $(SANITIZE_DIR) && ctest --output-on-failure -j$(JOBS) --timeout 1500 \
	  -L '^($(subst $(eval) ,|,$(strip $(SANITIZE_CI_LABELS))))$$'

fuzz: build
	@bash scripts/fuzz.sh $(FUZZ_DIR) $(FUZZ_SECONDS) $(BUILD_DIR) $(FUZZERS)

# The demo prints one line per product; the build's own output goes to
# $(BUILD_DIR)/build.log (its tail is shown if the build fails). It builds
# only what it runs, the gissar binary (`make build` and `make test` build
# the Python package, the tests and the benchmarks).
DEMO_TARGETS = gissar
demo: configure
	@echo "demo: building $(DEMO_TARGETS) (log: $(BUILD_DIR)/build.log)"
	@cmake --build $(BUILD_DIR) -j$(JOBS) $(addprefix --target ,$(DEMO_TARGETS)) > $(BUILD_DIR)/build.log 2>&1 \
	  || (tail -40 $(BUILD_DIR)/build.log; exit 1)
	@bash scripts/demo.sh $(BUILD_DIR)
	@echo "demo: see it on a map: $(BUILD_DIR)/bin/gissar view out/demo/andorra_h0  (Ctrl-C stops; docs/view.md)"

bench: build
	@bash scripts/bench.sh $(BUILD_DIR)

clean:
	@rm -rf $(BUILD_DIR) out
