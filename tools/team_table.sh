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
set -eu
build=${1:-build-host}
out=${2:-out/team_table}
filter=${3:-ekf}
seeds=${4:-$(seq 1 10)}
particles=${PARTICLES:-100}
config=${CONFIG:-host/replay/synth/arena.ini}
bin="$build/host/replay/coslam-replay"
gen="$build/host/eval/coslam-eval-worlds"
mkdir -p "$out"
run() { # seed merge-flag
  tag="$filter/s$1${2:+_alone}"
  mkdir -p "$out/$filter"
  "$bin" run "$out/log$1" -c "$config" -f "$filter" -p "$particles" --seed "$1" $2 \
    -q --no-plots -o "$out/$tag" > "$out/$tag.txt" 2>&1
}
for s in $seeds; do
  [ -d "$out/log$s" ] || "$gen" --world arena --seed0 "$s" --robots 5 --write-log "$out/log$s" 2>/dev/null
  run "$s" "" &
  run "$s" --no-merge &
  wait
done
/usr/bin/python3 tools/team_table.py "$out/$filter" $seeds | tee "$out/team_table_$filter.md"
