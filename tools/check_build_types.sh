#!/usr/bin/env bash
# tools/check_build_types.sh - configure and build the project once per CMake
# build type, each in its own directory, and report which build and how long
# each took (issue 10: every build type a user or a packager picks must
# build; warnings are errors, and -O3 / -Os bring their own warnings).
#
#   tools/check_build_types.sh [TYPE...]
#
# TYPE: Debug Release RelWithDebInfo MinSizeRel, or "default" for no
# CMAKE_BUILD_TYPE at all (the top CMakeLists.txt then picks RelWithDebInfo).
# Without arguments: all five. Environment:
#   BUILD_ROOT   where the build dirs go (default: build-types in the source tree)
#   JOBS         parallel jobs (default: nproc)
#   TARGET       one target instead of all (e.g. coslam-robot) for a quick check
#   CMAKE_ARGS   extra configure arguments (e.g. -DCOSLAM_SANITIZERS=OFF)
# Logs: BUILD_ROOT/<type>.log. Exit status: 0 if every type built, else 1.
# CPU: a full build is ~25 min of two cores on the development machine,
# per type; `make build-types` runs this script (not a CTest test: too long).
set -u
SRC=$(cd "$(dirname "$0")/.." && pwd)
BUILD_ROOT=${BUILD_ROOT:-$SRC/build-types}
JOBS=${JOBS:-$(nproc)}
TARGET=${TARGET:-}
CMAKE_ARGS=${CMAKE_ARGS:-}
if [ $# -eq 0 ]; then
  set -- default Debug Release RelWithDebInfo MinSizeRel
fi
mkdir -p "$BUILD_ROOT"
fail=0
summary=""
for t in "$@"; do
  case "$t" in
    default) type_arg=() ;;
    Debug|Release|RelWithDebInfo|MinSizeRel) type_arg=("-DCMAKE_BUILD_TYPE=$t") ;;
    *) echo "check_build_types: unknown build type '$t'" >&2; exit 2 ;;
  esac
  dir=$BUILD_ROOT/$t
  log=$BUILD_ROOT/$t.log
  start=$(date +%s)
  result=ok
  # shellcheck disable=SC2086  # CMAKE_ARGS is a list of words on purpose
  if ! cmake -S "$SRC" -B "$dir" -DCOSLAM_PROFILE=default "${type_arg[@]}" $CMAKE_ARGS >"$log" 2>&1; then
    result="configure FAILED"
  elif ! cmake --build "$dir" -j"$JOBS" ${TARGET:+--target "$TARGET"} >>"$log" 2>&1; then
    result="build FAILED"
  fi
  secs=$(( $(date +%s) - start ))
  [ "$result" = ok ] || fail=1
  line=$(printf '%-15s %-17s %5d s  %s' "$t" "$result" "$secs" "$log")
  echo "$line"
  summary="$summary$line"$'\n'
  if [ "$result" != ok ]; then
    grep -m 5 -E 'error|Error' "$log" | sed 's/^/    /'
  fi
done
printf '\nbuild types (%s):\n%s' "${TARGET:-all targets}" "$summary"
exit $fail
