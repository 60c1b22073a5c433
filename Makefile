# coslam front door. CMake does the build; these targets set it up.
#   make          build everything (installs missing Debian packages first)
#   make test     build and run every test through CTest
#   make sim      build and run the main job, results under out/
#   make bench    build and run the benchmarks (figures in out/bench/)
#   make replay   replay MRCLAM Dataset 6 (2 and 5 robots, both filters), out/replay/
#   make calibrate  noise calibration (coslam-calibrate, docs/calibration.md), out/calibrate/
#   make calibrate-figures  paper Figs. 4, 5 and 10 from out/calibrate/synth_paper (after make calibrate)
#   make bench-mrpt  install MRPT, then coslam vs MRPT EKF-SLAM on MRCLAM and on
#                    the large world's stream (out/bench/)
#   make deps     install the Debian packages the build needs
#   make robot    coslam-robot for the host ($(BUILD)) and for aarch64 ($(CROSS_BUILD))
#   make cross    the aarch64 robot-side build and its tests under qemu-aarch64
#   make package  Debian packages of coslam-robot (amd64, arm64) in out/package/
#   make fuzz     run every libFuzzer target FUZZ_SECONDS each, corpus in out/fuzz/ (docs/fuzzing.md)
#   make build-types  configure and build every CMake build type (BUILD_TYPES), each in
#                 build-types/<type> (tools/check_build_types.sh; ~25 min of 2 cores per type)
#   make build-profiles  configure every capacity profile (PROFILES) and build the core, app,
#                 link, robot, replay and simulator of each in build-profiles/<profile>
#                 (tools/check_profiles.sh)
# Variables: BUILD (build dir), JOBS, PROFILE (default|large|host: the capacity
#   profile of every binary of the build, README "Profiles"), TEST_LEVEL (ci|full),
#   CROSS_BUILD (aarch64 build dir), CROSS_CTEST_ARGS (ctest arguments of `make cross`),
#   SANITIZE=1 (every target with ASan+UBSan, in build-san unless BUILD is given),
#   FUZZ_SECONDS (per target, `make fuzz`), FUZZ_TARGETS (a subset, `make fuzz`),
#   BUILD_TYPES (`make build-types`: default Debug Release RelWithDebInfo MinSizeRel),
#   PROFILES (`make build-profiles`: default large host)

SANITIZE   ?= 0
ifeq ($(SANITIZE),1)
BUILD      ?= build-san
SAN_ARGS   := -DCOSLAM_SANITIZE=ON
# halt at the first report, with a stack (CTest passes the environment on)
export UBSAN_OPTIONS ?= print_stacktrace=1:halt_on_error=1
export ASAN_OPTIONS ?= detect_leaks=1
else
SAN_ARGS   := -DCOSLAM_SANITIZE=OFF
endif
# Host tools at scale: bench, replay, calibrate, calibrate-figures and
# bench-mrpt build with PROFILE=host (2048 landmarks, 1000 particles, 64
# sightings per frame) in their own build directory (build-host), so that
# `make`, `make test` and `make sim` keep the robot's default profile and
# stay fast. PROFILE=... and BUILD=... on the command line override both.
HOST_TARGETS := bench replay calibrate calibrate-figures bench-mrpt
$(HOST_TARGETS): PROFILE = host
$(HOST_TARGETS): BUILD = $(if $(filter default,$(PROFILE)),build,build-$(PROFILE))
FUZZ_SECONDS ?= 300
FUZZ_TARGETS ?=
FUZZ_OUT   ?= out/fuzz
BUILD      ?= build
JOBS       ?= $(shell nproc 2>/dev/null || echo 2)
PROFILE    ?= default
TEST_LEVEL ?= ci
CMAKE_ARGS ?=
CROSS_BUILD ?= build-aarch64
# the cross tests run under qemu, ~10x slower: the long randomized ones
# (label long) are left out unless CROSS_CTEST_ARGS= is given
CROSS_CTEST_ARGS ?= -LE long
BUILD_TYPES ?= default Debug Release RelWithDebInfo MinSizeRel
PROFILES   ?= default large host

.PHONY: calibrate calibrate-figures
.PHONY: all deps build configure test sim bench replay bench-mrpt clean distclean robot cross package fuzz build-types
.PHONY: build-profiles

all: build

deps:
	@tools/deps.sh install

configure: deps
	@echo "coslam: profile $(PROFILE) in $(BUILD)"
	@cmake -S . -B $(BUILD) -DCOSLAM_PROFILE=$(PROFILE) -DCOSLAM_TEST_LEVEL=$(TEST_LEVEL) $(SAN_ARGS) $(CMAKE_ARGS) >/dev/null

build: configure
	@cmake --build $(BUILD) -j$(JOBS)

test: build
	@cd $(BUILD) && ctest --output-on-failure -j$(JOBS)

# Every build type a user or packager may pick must build (warnings are
# errors; -O3 and -Os bring warnings of their own). Not a CTest test: one
# full build per type is far beyond a test's budget.
build-types: deps
	@JOBS=$(JOBS) CMAKE_ARGS="$(CMAKE_ARGS)" tools/check_build_types.sh $(BUILD_TYPES)

# Every capacity profile must build: the compile-time assertions that tie the
# largest map message to the link payload run in each (docs/map-message.md).
build-profiles: deps
	@JOBS=$(JOBS) CMAKE_ARGS="$(CMAKE_ARGS)" tools/check_profiles.sh $(PROFILES)

# Each libFuzzer target for FUZZ_SECONDS with a persistent corpus under
# $(FUZZ_OUT)/<target>; a summary table (executions, cov, ft) at the end.
# Needs clang and libclang-rt-14-dev (the configure step skips the targets
# without them: apt-get install clang-14 libclang-rt-14-dev).
fuzz: configure
	@cmake --build $(BUILD) -j$(JOBS) --target fuzz_all
	@test/fuzz/run_fuzz.sh long $(BUILD) $(FUZZ_OUT) $(FUZZ_SECONDS) $(FUZZ_TARGETS)

sim: build
	@tools/run_sim.sh $(BUILD)

# (bench and replay build only their programs in the host-profile tree)
bench: configure
	@cmake --build $(BUILD) -j$(JOBS) --target coslam-benches
	@tools/run_bench.sh $(BUILD)

replay: configure
	@cmake --build $(BUILD) -j$(JOBS) --target coslam-replay
	@tools/run_replay.sh $(BUILD)

# Noise calibration (docs/calibration.md): simulated worlds (train seeds 1-16,
# held-out 101-116), then MRCLAM Dataset 6 robots 1-3 (held-out 4-5, map
# score on Dataset 1), EKF-SLAM. CAL_ARGS adds options to both. The data:
# COSLAM_DATA_DIR (the folder holding mrclam/; environment or command line),
# else ../shared/data beside the checkout, as tools/run_replay.sh reads it;
# checked before the first run, not after the synthetic one.
CAL_ARGS ?=
CAL_DATA = $(if $(strip $(COSLAM_DATA_DIR)),$(COSLAM_DATA_DIR),../shared/data)/mrclam
calibrate: configure
	@for d in $(CAL_DATA)/MRCLAM_Dataset6 $(CAL_DATA)/MRCLAM_Dataset1; do test -d "$$d" || \
	  { echo "calibrate: $$d: no such folder (set COSLAM_DATA_DIR to the folder holding mrclam/)" >&2; exit 2; }; done
	@cmake --build $(BUILD) -j$(JOBS) --target coslam-calibrate
	@$(BUILD)/host/calibrate/coslam-calibrate --train-seeds 1-16 --test-seeds 101-116 --evals 301 \
	  --lambda 10 -o out/calibrate/synth_paper $(CAL_ARGS)
	@$(BUILD)/host/calibrate/coslam-calibrate --source mrclam -c host/replay/mrclam6.ini --evals 301 \
	  --lambda 10 --data $(CAL_DATA)/MRCLAM_Dataset6 --map-data $(CAL_DATA)/MRCLAM_Dataset1 \
	  -o out/calibrate/mrclam6_ekf $(CAL_ARGS)

# Figs. 4 and 5 (hand-tuned against calibrated on the held-out seeds) and the
# particle-count curve (Fig. 10) with the calibrated weights; about 10 min.
calibrate-figures: configure
	@cmake --build $(BUILD) -j$(JOBS) --target coslam-calibrate
	@$(BUILD)/host/calibrate/coslam-calibrate --figures out/calibrate/synth_paper/calibrated.ini \
	  --test-seeds 101-116 -o out/calibrate/figures
	@$(BUILD)/host/calibrate/coslam-calibrate --sweep-particles 5,10,20,50,100,200,500,1000 \
	  --sweep-filters fs1,fs2 --test-seeds 101-116 -c out/calibrate/synth_paper/calibrated.ini \
	  -o out/calibrate/particles
	@/usr/bin/python3 tools/plot_calibration_figs.py out/calibrate/figures
	@/usr/bin/python3 tools/plot_particles.py out/calibrate/particles

bench-mrpt:
	@tools/deps.sh install
	@tools/deps.sh install mrpt
	@echo "coslam: profile $(PROFILE) in $(BUILD)"
	@cmake -S . -B $(BUILD) -DCOSLAM_PROFILE=$(PROFILE) -DCOSLAM_TEST_LEVEL=$(TEST_LEVEL) $(CMAKE_ARGS) >/dev/null
	@cmake --build $(BUILD) -j$(JOBS) --target coslam-bench-mrclam coslam-eval-worlds
	@$(BUILD)/host/replay/coslam-bench-mrclam -c host/replay/mrclam6.ini --mrpt-grid --repeats 3 --out out/bench
	@# issue 13's large stream: the large world (1,024 landmarks, seed 101) as a landmark log, coslam and
	@# MRPT (NN only: about 25 min; its JCBB is slower still). MRPT gets the generator's bearing sd
	@# (2 deg) and its range sd at 3 m (0.1 m; MRPT's range noise is constant). docs/scale.md
	@$(BUILD)/host/eval/coslam-eval-worlds --world large --seed0 101 --write-log out/bench/large_world_log
	@$(BUILD)/host/replay/coslam-bench-mrclam --data out/bench/large_world_log -c host/replay/synth/large_world.ini \
	  --methods ekf,fs2,mrpt --mrpt-assoc nn --mrpt-sd-range 0.1 --mrpt-sd-bearing 0.035 \
	  --report large_world_mrpt --out out/bench

# The robot build and its Debian packages (docs/packaging.md).
robot: configure
	@cmake --build $(BUILD) -j$(JOBS) --target coslam-robot
	@file $(BUILD)/firmware/port/linux/coslam-robot
	@tools/deps.sh install cross
	@JOBS=$(JOBS) PROFILE=$(PROFILE) TEST_LEVEL=$(TEST_LEVEL) tools/cross_aarch64.sh robot $(CROSS_BUILD)

cross:
	@tools/deps.sh install
	@tools/deps.sh install cross
	@JOBS=$(JOBS) PROFILE=$(PROFILE) TEST_LEVEL=$(TEST_LEVEL) CTEST_ARGS="$(CROSS_CTEST_ARGS)" \
	  tools/cross_aarch64.sh test $(CROSS_BUILD)

package: robot
	@cpack --config $(BUILD)/CPackConfig.cmake -B $(BUILD)/package >/dev/null
	@JOBS=$(JOBS) PROFILE=$(PROFILE) TEST_LEVEL=$(TEST_LEVEL) tools/cross_aarch64.sh package $(CROSS_BUILD) >/dev/null
	@mkdir -p out/package && rm -f out/package/*.deb
	@cp $(BUILD)/package/*.deb $(CROSS_BUILD)/package/*.deb out/package/
	@ls -l out/package/*.deb

clean:
	@cmake --build $(BUILD) --target clean 2>/dev/null || true

distclean:
	rm -rf $(BUILD) $(CROSS_BUILD) out
