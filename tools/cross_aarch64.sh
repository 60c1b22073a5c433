#!/bin/sh
# The aarch64 (arm64) cross build of the robot side: coslam-robot and the C
# tests of core, drivers, HAL Linux backends, app and port/linux, built with
# Debian's aarch64-linux-gnu-gcc against arm64 multiarch libraries and run
# under qemu-aarch64 (docs/packaging.md).
#   tools/cross_aarch64.sh <step> [build-dir]      (build-dir: build-aarch64)
# Steps, each doing the ones before it:
#   configure  cmake -DCMAKE_TOOLCHAIN_FILE=cmake/toolchain-aarch64.cmake
#              -DCOSLAM_ROBOT_ONLY=ON (no sanitizers: ASan does not run under qemu-user)
#   robot      build coslam-robot only; print `file` of it
#   test       build everything of the robot-only build; ctest under qemu
#   package    build coslam-robot, then cpack: coslam-robot_<version>_arm64.deb
# Environment: JOBS (default 2), PROFILE (default), TEST_LEVEL (ci),
# CTEST_ARGS (more ctest arguments, e.g. "-LE long").
# Needs `tools/deps.sh install cross` (make robot / make cross do it).
set -eu
cd "$(dirname "$0")/.."
step=${1:-test}
dir=${2:-build-aarch64}
JOBS=${JOBS:-2}
PROFILE=${PROFILE:-default}
TEST_LEVEL=${TEST_LEVEL:-ci}

if ! tools/deps.sh check cross; then
  echo "cross_aarch64: run 'tools/deps.sh install cross' (as root) first" >&2
  exit 1
fi

configure() {
  cmake -S . -B "$dir" -DCMAKE_TOOLCHAIN_FILE="$PWD/cmake/toolchain-aarch64.cmake" \
    -DCOSLAM_ROBOT_ONLY=ON -DCOSLAM_SANITIZERS=OFF -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCOSLAM_PROFILE="$PROFILE" -DCOSLAM_TEST_LEVEL="$TEST_LEVEL" >/dev/null
}

robot() {
  configure
  cmake --build "$dir" -j"$JOBS" --target coslam-robot
  bin="$dir/firmware/port/linux/coslam-robot"
  file "$bin"
  # the target runs: print its usage line under the emulator
  qemu-aarch64 -L / "$bin" --help | head -n 1
}

case "$step" in
  configure) configure ;;
  robot) robot ;;
  test)
    configure
    cmake --build "$dir" -j"$JOBS"
    # Emulation changes timing (system calls are slower, clock reads are
    # not vDSO): a timing-sensitive test gets a second run; failing twice fails.
    # shellcheck disable=SC2086 # CTEST_ARGS is a list of arguments
    (cd "$dir" && ctest --output-on-failure -j"$JOBS" --repeat until-pass:2 ${CTEST_ARGS:-})
    ;;
  package)
    robot
    rm -f "$dir"/package/*.deb
    cpack --config "$dir/CPackConfig.cmake" -B "$dir/package" >/dev/null
    ls "$dir"/package/*.deb
    ;;
  *) echo "usage: $0 configure|robot|test|package [build-dir]" >&2; exit 2 ;;
esac
