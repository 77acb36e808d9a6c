# The two commands a newcomer needs: `make test` (and, later, `make demo`).
# Debian's python3 first: a pyenv shim on PATH lacks catkin_pkg.
export PATH := /usr/bin:/bin:$(PATH)
SHELL := /bin/bash
MAKEFLAGS += --no-print-directory
BUILD_DIR ?= build
JOBS ?= $(shell nproc)
CMAKE_ARGS ?= -DPYTHON_EXECUTABLE=/usr/bin/python3 -DPython3_EXECUTABLE=/usr/bin/python3 \
              -DCATKIN_ENABLE_TESTING=ON

.PHONY: deps build test benchmark-accuracy format clean

deps:
	@scripts/install-deps

# Configures once, then builds incrementally; source $(BUILD_DIR)/devel/setup.bash afterwards.
build: deps
	@if [ ! -f $(BUILD_DIR)/CMakeCache.txt ]; then cmake -S . -B $(BUILD_DIR) $(CMAKE_ARGS); fi
	cmake --build $(BUILD_DIR) -- -j$(JOBS)

# Builds the tests and runs them all through ctest, which exits non-zero on any failure
# (unlike `catkin_make run_tests`).
test: build
	cmake --build $(BUILD_DIR) --target tests -- -j$(JOBS)
	cd $(BUILD_DIR) && ctest --output-on-failure

# The paper's Tables 2-3 / Fig. 12 on rendered scenes and segmentation scores on real OSD
# scenes (../shared/data when present, else the copies in test/data); plots in benchmark-output/.
OSD_DIR ?= $(firstword $(wildcard ../shared/data/osd-learn) test/data)
benchmark-accuracy: build
	$(BUILD_DIR)/devel/lib/tabletop_shapes/benchmark_accuracy --osd $(OSD_DIR) --out benchmark-output

format:
	clang-format -i $$(git ls-files '*.h' '*.cpp')

clean:
	rm -rf $(BUILD_DIR)
