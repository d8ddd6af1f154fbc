# The two commands of the README. Both install missing Debian packages first.
#   make demo   build, then run the main job and write demo-out/
#   make test   build everything and run every test and the Python package's tests
#   make test-asan   the parsers, cameras and scene readers and their tests under ASan + UBSan
#               with the fuzz targets run briefly (a second build, with clang; CI runs it)
#   make test-gpu-build   the same build against PyPI's LibTorch 2.x with the CUDA code compiled,
#               and the tests whose code can differ between the versions (scripts/gpu/build.sh,
#               tests/pypi_build.list; tests that need a GPU skip themselves without one)
JOBS ?= $(shell nproc)
# Threads per test while JOBS tests run at once: more would oversubscribe the cores, and
# the tests that keep a time budget would miss it.
TEST_THREADS ?= $(shell echo $$(( $$(nproc) / $(JOBS) > 1 ? $$(nproc) / $(JOBS) : 1 )))
BUILD ?= build
SAN_BUILD ?= build-asan
GPU_BUILD ?= build-gpu
SHARED ?= ../shared

FUZZ_SECONDS ?= 60
# Each step says how long it took (CI's log shows where its time went).
TIMED = $(CURDIR)/scripts/timed.sh

.PHONY: all deps build demo test test-main san-build test-asan test-python python test-gpu-build fuzz bench clean

all: build

deps:
	@bash scripts/install-deps.sh

build: deps
	@cmake -S . -B $(BUILD) -G Ninja -DCMAKE_BUILD_TYPE=Release > /dev/null
	@$(TIMED) build cmake --build $(BUILD) -j $(JOBS)

demo: build
	@bash scripts/demo.sh $(BUILD)/instainpaint

# The sanitizer build is not part of it: a second build of the torch-free code (2-3 minutes on
# 2 cores) whose tests are the same as the main build's, under the sanitizers. CI runs it
# (.ci/run); a user's first `make test` is spared it (docs/benchmarks.md, "CI on a fresh machine").
test: test-main test-python

test-main: build
	@cd $(BUILD) && OMP_NUM_THREADS=$(TEST_THREADS) $(TIMED) test-main ctest --output-on-failure -j $(JOBS)

# Parsers, cameras and scene readers under AddressSanitizer + UndefinedBehaviorSanitizer,
# built with clang so that the same build holds the libFuzzer targets (each runs briefly).
san-build: deps
	@cmake -S . -B $(SAN_BUILD) -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER=clang++ \
	  -DINSTAINPAINT_SANITIZE=ON > /dev/null
	@$(TIMED) san-build cmake --build $(SAN_BUILD) -j $(JOBS)

test-asan: san-build
	@cd $(SAN_BUILD) && ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1 \
	  $(TIMED) test-asan ctest --output-on-failure -j $(JOBS)

# The Python package (pip install . into the project-local .venv-py) and its tests.
python: build
	@BUILD=$(BUILD) bash scripts/python-package.sh

test-python: build
	@BUILD=$(BUILD) OMP_NUM_THREADS=$(TEST_THREADS) $(TIMED) test-python bash scripts/python-package.sh --test

# PyPI's torch + NVIDIA's CUDA compiler in the project-local .venv-gpu (pinned in
# scripts/gpu/requirements.txt), everything compiled with the CUDA code, the tests whose code can
# differ between the LibTorch versions run (tests/pypi_build.list) with the Python package's.
test-gpu-build: deps
	@JOBS=$(JOBS) $(TIMED) test-gpu-build bash scripts/gpu/build.sh --build $(GPU_BUILD) --test

# Every parser's fuzz target for FUZZ_SECONDS each (scripts/fuzz.sh --help).
fuzz: san-build
	@bash scripts/fuzz.sh --build $(SAN_BUILD) --seconds $(FUZZ_SECONDS)

bench: build
	@$(BUILD)/instainpaint bench

clean:
	rm -rf $(BUILD) $(SAN_BUILD) $(GPU_BUILD) build-pip demo-out fuzz-findings .venv-py
