# Convenience front end: every target sets up (apt-get, only what is missing) and builds first.
#   make run        run the default scene, frames in out/smoke_sheets/
#   make test       build and run the unit/validation tests (skips the "long" label)
#   make test-long  the long cases only
#   make bench      the solver benchmark
BUILD ?= build
JOBS ?= $(shell nproc)
SCENE ?= data/scenes/smoke_sheets.json
OUT ?= out/smoke_sheets

.PHONY: setup configure build run test test-long test-all bench format clean

setup:
	@bash scripts/setup.sh

configure: setup
	@if [ ! -f $(BUILD)/CMakeCache.txt ]; then \
	  gen=""; command -v ninja >/dev/null && gen="-G Ninja"; \
	  cmake -S . -B $(BUILD) $$gen -DCMAKE_BUILD_TYPE=Release; fi

build: configure
	@cmake --build $(BUILD) -j $(JOBS)

run: build
	$(BUILD)/tools/tetfsi run $(SCENE) --out $(OUT)

test: build
	cd $(BUILD) && ctest --output-on-failure --no-tests=error -j $(JOBS) -LE long

test-long: build
	cd $(BUILD) && ctest --output-on-failure --no-tests=error -j $(JOBS) -L long

test-all: build
	cd $(BUILD) && ctest --output-on-failure --no-tests=error -j $(JOBS)

bench: build
	$(BUILD)/tools/tetfsi bench solvers --n 250000

format:
	@clang-format -i $$(git ls-files '*.cpp' '*.hpp')

clean:
	rm -rf $(BUILD)
