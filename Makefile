# The two commands a newcomer needs: `make test` (and, later, `make demo`).
# Debian's python3 first: a pyenv shim on PATH lacks catkin_pkg.
export PATH := /usr/bin:/bin:$(PATH)
SHELL := /bin/bash
MAKEFLAGS += --no-print-directory
# The build lives in .build/ with build/ a link to it: rosrun ignores every executable below
# <package>/build/, and the repository root is the package, so a real build/ would hide our
# tools from `rosrun tabletop_shapes ...` (and from the rostests that use it).
BUILD_DIR ?= build
REAL_BUILD_DIR ?= .build
JOBS ?= $(shell nproc)
CMAKE_ARGS ?= -DPYTHON_EXECUTABLE=/usr/bin/python3 -DPython3_EXECUTABLE=/usr/bin/python3 \
              -DCATKIN_ENABLE_TESTING=ON -DCMAKE_INSTALL_PREFIX=$(abspath $(PREFIX))

.PHONY: deps build install test test-sanitize fuzz soak demo benchmark-accuracy benchmark-speed \
        format clean

deps:
	@scripts/install-deps

# Configures once, then builds incrementally; source $(BUILD_DIR)/devel/setup.bash afterwards.
build: deps
	@if [ "$(BUILD_DIR)" = build ] && [ ! -L build ]; then \
	  if [ -e build ]; then echo "build/ must be a link to $(REAL_BUILD_DIR)/: make clean first"; exit 1; fi; \
	  mkdir -p $(REAL_BUILD_DIR) && ln -s $(REAL_BUILD_DIR) build; fi
	@if [ ! -f $(BUILD_DIR)/CMakeCache.txt ]; then cmake -S . -B $$(realpath $(BUILD_DIR)) $(CMAKE_ARGS); fi
	cmake --build $(BUILD_DIR) -- -j$(JOBS)

# Installs everything a user needs into PREFIX (default .install/ here): the core and nodelet
# libraries, nodelet_plugins.xml, package.xml, launch/, cfg/, rviz/, the messages and the
# command-line tools; `source $(PREFIX)/setup.bash` then makes rosrun / roslaunch use them.
# The default is hidden because roslaunch searches the source package (the repository root)
# for launch files, skipping only hidden folders: an install/ here would give each launch file
# twice. The build is configured for PREFIX when it is first configured; another PREFIX later
# reconfigures it (catkin writes the prefix into generated files) and then rebuilds most of it.
# DESTDIR=<dir> stages the install under <dir>$(PREFIX) without reconfiguring: the staged
# setup.bash finds its own folder, so the staged copy works where it is (test_install uses it).
# Once, a prefix reconfigure was seen to leave devel/include/tabletop_shapes/ empty (the
# generated message and config headers), which the install needs: hence the build after it.
PREFIX ?= .install
install: build
	@prefix=$$(realpath -m $(PREFIX)); \
	if ! grep -qx "CMAKE_INSTALL_PREFIX:PATH=$$prefix" $(BUILD_DIR)/CMakeCache.txt; then \
	  cmake $$(realpath $(BUILD_DIR)) -DCMAKE_INSTALL_PREFIX=$$prefix >/dev/null; \
	  cmake --build $(BUILD_DIR) -- -j$(JOBS) >/dev/null; fi
	DESTDIR=$(DESTDIR) cmake --install $(BUILD_DIR) >/dev/null
	@echo "installed $$(wc -l <$(BUILD_DIR)/install_manifest.txt) files into $(DESTDIR)$$(realpath -m $(PREFIX));" \
	  "use them with: source $(DESTDIR)$$(realpath -m $(PREFIX))/setup.bash"

# Builds the tests and runs them all through ctest, which exits non-zero on any failure
# (unlike `catkin_make run_tests`).
test: build
	cmake --build $(BUILD_DIR) --target tests -- -j$(JOBS)
	cd $(BUILD_DIR) && ctest --output-on-failure

# The core's unit tests and the estimate_shapes command tests, built with gcc's AddressSanitizer
# and UndefinedBehaviorSanitizer in a build of their own (SANITIZE_DIR): any report fails.
SANITIZE_DIR ?= .build-sanitize
# Eigen assumes glibc's malloc is 16-byte aligned unless __SANITIZE_ADDRESS__ is defined; then
# it allocates with its own offset header instead. Debian's PCL (no ASan) allocates and frees
# Eigen members with plain malloc, so objects crossing the library boundary (SupervoxelClustering)
# were freed by the other allocator. ASan's malloc is 16-byte aligned too: keep Eigen's choice.
SANITIZE_FLAGS := -fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer
SANITIZE_CXX_FLAGS := $(SANITIZE_FLAGS) -DEIGEN_MALLOC_ALREADY_ALIGNED=1
export ASAN_OPTIONS ?= detect_leaks=1:abort_on_error=1:strict_string_checks=1
export UBSAN_OPTIONS ?= print_stacktrace=1:halt_on_error=1
export LSAN_OPTIONS ?= suppressions=$(CURDIR)/scripts/lsan-suppressions.txt
# Configured every time: a test added since the last run is a target only after configuring
# ("No rule to make target 'test_convex_polygon'" otherwise), and a flag change must reach it.
test-sanitize: deps
	cmake -S . -B $(SANITIZE_DIR) $(CMAKE_ARGS) \
	  -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS="$(SANITIZE_CXX_FLAGS)" \
	  -DCMAKE_EXE_LINKER_FLAGS="$(SANITIZE_FLAGS)" -DCMAKE_SHARED_LINKER_FLAGS="$(SANITIZE_FLAGS)" >/dev/null
	cmake --build $(SANITIZE_DIR) --target sanitize_tests -- -j$(JOBS)
	cd $(SANITIZE_DIR) && ctest --output-on-failure -j$(JOBS) -L sanitize

# libFuzzer targets (test/fuzz) with Debian's clang, ASan and UBSan, in FUZZ_DIR; each runs
# FUZZ_SECONDS from the committed seed corpus. clang comes from a list of its own, so that
# make build / make test do not install it.
FUZZ_DIR ?= .build-fuzz
FUZZ_SECONDS ?= 600
fuzz:
	@DEPS_LIST=scripts/fuzz-packages.txt scripts/install-deps
	@if [ ! -f $(FUZZ_DIR)/CMakeCache.txt ]; then cmake -S test/fuzz -B $(FUZZ_DIR) \
	  -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ >/dev/null; fi
	cmake --build $(FUZZ_DIR) -- -j$(JOBS)
	scripts/fuzz $(FUZZ_DIR) $(FUZZ_SECONDS) $(FUZZ_TARGETS)

# 30 Hz replay through the whole chain for SOAK_SECONDS (default 10 min): RSS at start and
# end, frames in / out / dropped per stage, latency p50 / p99 / max.
SOAK_SECONDS ?= 600
soak: build
	@scripts/soak $(SOAK_SECONDS) $(SOAK_ARGS)

# The paper's Tables 2-3 / Fig. 12 on rendered scenes and segmentation scores on real OSD
# scenes (../shared/data when present, else the copies in test/data); plots in benchmark-output/.
OSD_DIR ?= $(firstword $(wildcard ../shared/data/osd-learn) test/data)
benchmark-accuracy: build
	$(BUILD_DIR)/devel/lib/tabletop_shapes/benchmark_accuracy --osd $(OSD_DIR) --out benchmark-output

# Speed: the core alone (per stage, scaling table, plot in benchmark-output/) and the ROS chain
# in one nodelet manager (PointCloud2 from another process, and the OpenNI2 driver playing an
# .oni in the manager) beside Debian's pcl_ros chain, 300 frames per run (~13 min quiet);
# QUICK=1: a few frames each, a smoke run.
benchmark-speed: build
	scripts/benchmark_speed $(if $(QUICK),--quick) --build $(BUILD_DIR) --osd $(OSD_DIR) --out benchmark-output

# The whole chain on a bundled rendered recording of the paper's four objects; prints the
# objects found beside the true values. RVIZ=1 opens rviz; DEVICE=... uses a live camera.
# One progress line per phase (packages, build, run); the details go to build/demo/*.log.
demo:
	@BUILD_DIR=$(BUILD_DIR) scripts/demo --setup $(if $(RVIZ),--rviz) $(if $(DEVICE),--device $(DEVICE))

format:
	clang-format -i $$(git ls-files '*.h' '*.cpp')

clean:
	rm -rf build $(REAL_BUILD_DIR)
