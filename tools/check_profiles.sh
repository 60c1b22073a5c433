#!/usr/bin/env bash
# tools/check_profiles.sh - configure the project once per capacity profile
# (coslam/config.h: default, large, host), each in its own directory, and
# build the parts whose sizes follow the profile: the core, the robot app,
# the link (Cyclone DDS backend and authentication decorator, where the
# compile-time assertions tie the largest map message to the link payload),
# coslam-robot and, unless TARGETS says otherwise, the host tools.
#
#   tools/check_profiles.sh [PROFILE...]      (default: default large host)
#
# Environment:
#   BUILD_ROOT  where the build dirs go (default: build-profiles in the source tree)
#   JOBS        parallel jobs (default: nproc)
#   TARGETS     the targets to build (default below; a target this build
#               does not have, e.g. the DDS link without Cyclone, is skipped)
#   CMAKE_ARGS  extra configure arguments
# Logs: BUILD_ROOT/<profile>.log. Exit status 0 if every profile built.
set -u
SRC=$(cd "$(dirname "$0")/.." && pwd)
BUILD_ROOT=${BUILD_ROOT:-$SRC/build-profiles}
JOBS=${JOBS:-$(nproc)}
TARGETS=${TARGETS:-coslam_core coslam_app coslam_hal_link_auth coslam_hal_link_dds coslam-robot coslam-replay coslam-sim}
CMAKE_ARGS=${CMAKE_ARGS:-}
if [ $# -eq 0 ]; then
  set -- default large host
fi
mkdir -p "$BUILD_ROOT"
fail=0
summary=""
for p in "$@"; do
  case "$p" in
    default|large|host) ;;
    *) echo "check_profiles: unknown profile '$p'" >&2; exit 2 ;;
  esac
  dir=$BUILD_ROOT/$p
  log=$BUILD_ROOT/$p.log
  start=$(date +%s)
  result=ok
  built=""
  # shellcheck disable=SC2086  # CMAKE_ARGS is a list of words on purpose
  if ! cmake -S "$SRC" -B "$dir" -DCOSLAM_PROFILE="$p" -DCOSLAM_SANITIZERS=OFF $CMAKE_ARGS >"$log" 2>&1; then
    result="configure FAILED"
  else
    have=$(cmake --build "$dir" --target help 2>/dev/null | sed -n 's/^\.\.\. \([^ ]*\).*/\1/p')
    for t in $TARGETS; do
      if ! printf '%s\n' "$have" | grep -qx "$t"; then
        echo "  $p: no target $t in this build, skipped" >>"$log"
        continue
      fi
      if ! cmake --build "$dir" -j"$JOBS" --target "$t" >>"$log" 2>&1; then
        result="build of $t FAILED"
        break
      fi
      built="$built $t"
    done
  fi
  secs=$(( $(date +%s) - start ))
  [ "$result" = ok ] || fail=1
  line=$(printf '%-8s %-30s %5d s  %s' "$p" "$result" "$secs" "$log")
  echo "$line"
  echo "         built:$built"
  summary="$summary$line"$'\n'
  if [ "$result" != ok ]; then
    grep -m 5 -E 'error|Error' "$log" | sed 's/^/    /'
  fi
done
printf '\nprofiles:\n%s' "$summary"
exit $fail
