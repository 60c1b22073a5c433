#!/bin/sh
# Merging on real data, the table of issue 8: MRCLAM Datasets 6 and 1, all
# robots, unknown identities, EKF-SLAM and Fast-SLAM 2.0 (PARTICLES, 300),
# each with and without merging; maps scored after the best rigid fit to the
# landmark truth (Dataset 1 has no robot truth: pose "n/a"). Parameters:
# host/replay/mrclam6.ini, chosen on Dataset 6 only (docs/replay.md).
#   tools/merge_table.sh [BUILD] [OUT]     -> OUT/merge_table.md
# BUILD: a host-profile build (default build-host, as `make replay` makes:
# 300 particles need more than the default profile's 100).
# Environment: COSLAM_DATA_DIR (folder holding mrclam/), PARTICLES, SEEDS,
# CONFIG (another replay configuration, default host/replay/mrclam6.ini).
# SEEDS (e.g. "1 2 3 4 5 6"): Fast-SLAM 2.0 is random and on this data one
# robot's figures change from seed to seed by more than most merge changes
# do, so the table then also runs it with each particle seed (merge and
# alone) and counts, per robot, the seeds that miss each goal.
# A run that fails (or a missing coslam-replay) fails the script: exit 1,
# the run and its log named; no table is written from partial runs.
set -eu
build=${1:-build-host}
out=${2:-out/merge_table}
data=${COSLAM_DATA_DIR:-../shared/data}/mrclam
particles=${PARTICLES:-300}
config=${CONFIG:-host/replay/mrclam6.ini}
bin="$build/host/replay/coslam-replay"
if [ ! -x "$bin" ]; then
  echo "merge_table: no $bin: build it first (make replay, or cmake --build $build --target coslam-replay)" >&2
  exit 1
fi
for d in 6 1; do
  if [ ! -d "$data/MRCLAM_Dataset$d" ]; then
    echo "merge_table: SKIPPED, no $data/MRCLAM_Dataset$d (set COSLAM_DATA_DIR)"
    exit 0
  fi
done
mkdir -p "$out"
run() { # dataset filter merge-flag [particle-seed]
  tag="d$1_$2${4:+_s$4}${3:+_alone}"
  rc=0
  "$bin" run "$data/MRCLAM_Dataset$1" -c "$config" -f "$2" -p "$particles" ${4:+--seed "$4"} $3 \
    -q --no-plots -o "$out/$tag" > "$out/$tag.txt" 2>&1 || rc=$?
  if [ $rc -ne 0 ]; then
    echo "merge_table: run $tag failed (exit $rc), its log: $out/$tag.txt" >&2
    return 1
  fi
}
. "$(dirname "$0")/wait_jobs.sh"
for d in 6 1; do
  (run $d ekf "" && run $d ekf --no-merge) &
  p1=$!
  (run $d fastslam2 "" && run $d fastslam2 --no-merge) &
  wait_jobs merge_table $p1 $!
done
seeds=${SEEDS:-}
for s in $seeds; do
  for d in 6 1; do
    run $d fastslam2 "" "$s" &
    p1=$!
    run $d fastslam2 --no-merge "$s" &
    wait_jobs merge_table $p1 $!
  done
done
# (the table to a file first: through a pipe to tee, its exit status would be lost)
/usr/bin/python3 tools/merge_table.py "$out" $seeds > "$out/merge_table.md"
cat "$out/merge_table.md"
