# coslam front door. CMake does the build; these targets set it up.
#   make          build everything (installs missing Debian packages first)
#   make test     build and run every test through CTest
#   make sim      build and run the main job, results under out/
#   make bench    build and run the benchmarks (figures in out/bench/)
#   make replay   replay MRCLAM Dataset 6 (2 and 5 robots, both filters), out/replay/
#   make bench-mrpt  install MRPT, then coslam vs MRPT EKF-SLAM on MRCLAM (out/bench/)
#   make deps     install the Debian packages the build needs
# Variables: BUILD (build dir), JOBS, PROFILE (default|large), TEST_LEVEL (ci|full)

BUILD      ?= build
JOBS       ?= $(shell nproc 2>/dev/null || echo 2)
PROFILE    ?= default
TEST_LEVEL ?= ci
CMAKE_ARGS ?=

.PHONY: all deps build configure test sim bench replay bench-mrpt clean distclean

all: build

deps:
	@tools/deps.sh install

configure: deps
	@cmake -S . -B $(BUILD) -DCOSLAM_PROFILE=$(PROFILE) -DCOSLAM_TEST_LEVEL=$(TEST_LEVEL) $(CMAKE_ARGS) >/dev/null

build: configure
	@cmake --build $(BUILD) -j$(JOBS)

test: build
	@cd $(BUILD) && ctest --output-on-failure -j$(JOBS)

sim: build
	@tools/run_sim.sh $(BUILD)

bench: build
	@tools/run_bench.sh $(BUILD)

replay: build
	@tools/run_replay.sh $(BUILD)

bench-mrpt:
	@tools/deps.sh install
	@tools/deps.sh install mrpt
	@cmake -S . -B $(BUILD) -DCOSLAM_PROFILE=$(PROFILE) -DCOSLAM_TEST_LEVEL=$(TEST_LEVEL) $(CMAKE_ARGS) >/dev/null
	@cmake --build $(BUILD) -j$(JOBS) --target coslam-bench-mrclam
	@$(BUILD)/host/replay/coslam-bench-mrclam -c host/replay/mrclam6.ini --mrpt-grid --repeats 3 --out out/bench

clean:
	@cmake --build $(BUILD) --target clean 2>/dev/null || true

distclean:
	rm -rf $(BUILD) out
