#!/bin/sh
# Merging in MRCLAM's regime with seeds (issue 8): the arena world's team
# logs (coslam-eval-worlds --world arena --robots 5 --write-log; five robots
# wandering for 600 s among 15 identical landmarks in clusters, noise as
# measured on MRCLAM, docs/consistency.md "The arena world") replayed by
# coslam-replay as MRCLAM is, each robot with and without merging, with
# coslam-replay's MRCLAM model (host/replay/synth/arena.ini). Per robot the
# goals of issue 8: with merging at most 1 spurious landmark and no more
# than alone, landmark RMSE (after the rigid fit) and pose RMSE no worse.
#   tools/team_table.sh [BUILD] [OUT] [FILTER] [SEEDS]  -> OUT/team_table_FILTER.md
# BUILD: a host-profile build (default build-host); FILTER ekf | fastslam2
# (100 particles, PARTICLES to change); SEEDS default "1 2 ... 10"; CONFIG
# another replay configuration (default host/replay/synth/arena.ini).
# A missing binary, or a log or run that fails, fails the script (exit 1,
# what failed and its log named).
set -eu
build=${1:-build-host}
out=${2:-out/team_table}
filter=${3:-ekf}
seeds=${4:-$(seq 1 10)}
particles=${PARTICLES:-100}
config=${CONFIG:-host/replay/synth/arena.ini}
bin="$build/host/replay/coslam-replay"
gen="$build/host/eval/coslam-eval-worlds"
for b in "$bin=coslam-replay" "$gen=coslam-eval-worlds"; do
  if [ ! -x "${b%=*}" ]; then
    echo "team_table: no ${b%=*}: build it first (cmake --build $build --target ${b#*=})" >&2
    exit 1
  fi
done
. "$(dirname "$0")/wait_jobs.sh"
mkdir -p "$out"
run() { # seed merge-flag
  tag="$filter/s$1${2:+_alone}"
  mkdir -p "$out/$filter"
  rc=0
  "$bin" run "$out/log$1" -c "$config" -f "$filter" -p "$particles" --seed "$1" $2 \
    -q --no-plots -o "$out/$tag" > "$out/$tag.txt" 2>&1 || rc=$?
  if [ $rc -ne 0 ]; then
    echo "team_table: run $tag failed (exit $rc), its log: $out/$tag.txt" >&2
    return 1
  fi
}
for s in $seeds; do
  if [ ! -d "$out/log$s" ]; then
    rc=0
    "$gen" --world arena --seed0 "$s" --robots 5 --write-log "$out/log$s" > "$out/log$s.txt" 2>&1 || rc=$?
    if [ $rc -ne 0 ]; then
      echo "team_table: the team log of seed $s failed (exit $rc), its log: $out/log$s.txt" >&2
      rm -rf "$out/log$s" # not taken for a whole log by the next run
      exit 1
    fi
  fi
  run "$s" "" &
  p1=$!
  run "$s" --no-merge &
  wait_jobs team_table $p1 $!
done
/usr/bin/python3 tools/team_table.py "$out/$filter" $seeds > "$out/team_table_$filter.md"
cat "$out/team_table_$filter.md"
