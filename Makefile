# Convenience front end: every target sets up (apt-get, only what is missing) and builds first.
#   make run        run the default scene, frames in out/smoke_sheets/
#   make test       build and run the unit/validation tests (skips the "long" and "blender" labels)
#   make test-long  the long cases only
#   make test-blender  install Debian's blender (setup.sh --blender) and run the "blender" label
#   make bench      the solver benchmark
#   make sanitize   an ASan + UBSan build in build-sanitize/ and its test run (skips "long")
#   make pictures   regenerate the pictures docs/*.png (scripts/make_pictures.sh, ~12 min)
#   make figures    the paper's Figs. 1-6 as frame sequences, docs/figures/ (scripts/paper_figures.sh)
BUILD ?= build
# ccache (when present) rewrites absolute paths under base_dir as relative ones, so two clones
# of the repository (a fresh one per CI run, a worktree beside this one) share their objects.
export CCACHE_BASEDIR ?= /
JOBS ?= $(shell nproc)
SCENE ?= data/scenes/smoke_sheets.json
OUT ?= out/smoke_sheets

SAN_BUILD ?= build-sanitize
# Leaks that PETSc / Open MPI / hwloc make at start-up are suppressed (scripts/lsan.supp);
# huge allocations must throw std::bad_alloc (the hostile-input tests), not abort.
# Open MPI unloads its components at MPI_Finalize, which leaves their frames unnamed: keep
# them loaded, and unwind mallocs fully so that the PetscInitialize / MPI_Init frames match.
SAN_ENV = OMPI_MCA_mca_base_component_disable_dlclose=1 \
  ASAN_OPTIONS=allocator_may_return_null=1:detect_leaks=1:abort_on_error=0:fast_unwind_on_malloc=0 \
  LSAN_OPTIONS=suppressions=$(CURDIR)/scripts/lsan.supp:print_suppressions=0:fast_unwind_on_malloc=0 \
  UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1

.PHONY: setup configure build run test test-long test-all test-blender bench sanitize format clean pictures figures

setup:
	@bash scripts/setup.sh

configure: setup
	@if [ ! -f $(BUILD)/CMakeCache.txt ]; then \
	  gen=""; command -v ninja >/dev/null && gen="-G Ninja"; \
	  cmake -S . -B $(BUILD) $$gen -DCMAKE_BUILD_TYPE=Release; fi

build: configure
	@cmake --build $(BUILD) -j $(JOBS)

run: build
	$(BUILD)/cli/tetfsi run $(SCENE) --out $(OUT)

# "blender" (Blender headless on an exported run) needs blender, which only test-blender installs.
test: build
	cd $(BUILD) && ctest --output-on-failure --no-tests=error -j $(JOBS) -LE 'long|blender'

test-long: build
	cd $(BUILD) && ctest --output-on-failure --no-tests=error -j $(JOBS) -L long

test-all: build
	cd $(BUILD) && ctest --output-on-failure --no-tests=error -j $(JOBS) -LE blender

test-blender: build
	@bash scripts/setup.sh --blender
	cd $(BUILD) && ctest --output-on-failure --no-tests=error -L blender

pictures: build
	BUILD=$(BUILD) bash scripts/make_pictures.sh

figures: build
	@bash scripts/setup.sh --blender
	BUILD=$(BUILD) bash scripts/paper_figures.sh

bench: build
	$(BUILD)/cli/tetfsi bench solvers --n 250000

sanitize: setup
	@if [ ! -f $(SAN_BUILD)/CMakeCache.txt ]; then \
	  gen=""; command -v ninja >/dev/null && gen="-G Ninja"; \
	  cmake -S . -B $(SAN_BUILD) $$gen -DCMAKE_BUILD_TYPE=RelWithDebInfo -DTETFSI_SANITIZE=ON; fi
	@cmake --build $(SAN_BUILD) -j $(JOBS)
	cd $(SAN_BUILD) && $(SAN_ENV) ctest --output-on-failure --no-tests=error -j $(JOBS) -LE 'long|blender'

format:
	@clang-format -i $$(git ls-files '*.cpp' '*.hpp')

clean:
	rm -rf $(BUILD)
