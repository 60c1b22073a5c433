#!/bin/sh
# `make replay`: full replays of MRCLAM Dataset 6 (docs/replay.md) with the
# per-robot calibration host/replay/mrclam6.ini:
#   - five robots together, with and without merging;
#   - every pair of robots that meets (1-3, 1-5, 2-3, 2-5, 3-4, 3-5, 4-5);
# each with EKF-SLAM and Fast-SLAM 2.0, unknown and known identities.
# Outputs under out/replay/<run>/, the summary table in out/replay/summary.md.
# Environment: COSLAM_DATA_DIR (folder holding mrclam/), PARTICLES (1000).
set -eu
build=${1:-build}
data=${COSLAM_DATA_DIR:-../shared/data}/mrclam/MRCLAM_Dataset6
particles=${PARTICLES:-1000}
bin="$build/host/replay/coslam-replay"
cfg=host/replay/mrclam6.ini
out=out/replay
if [ ! -d "$data" ]; then
  echo "replay: SKIPPED, no MRCLAM Dataset 6 at $data (set COSLAM_DATA_DIR)"
  exit 0
fi
mkdir -p "$out"
t0=$(date +%s)
for filter in ekf fastslam2; do
  for ids in unknown known; do
    flag=""
    [ "$ids" = known ] && flag="--known-ids"
    echo "== 5 robots, $filter, $ids identities"
    "$bin" run "$data" -c "$cfg" -f "$filter" -p "$particles" $flag -q -o "$out/5r_${filter}_${ids}" 2>/dev/null \
      | sed -n '1,8p'
    "$bin" run "$data" -c "$cfg" -f "$filter" -p "$particles" $flag -q --no-merge --no-plots \
      -o "$out/5r-nomerge_${filter}_${ids}" > /dev/null 2>&1
    for pair in 1,3 1,5 2,3 2,5 3,4 3,5 4,5; do
      plots="--no-plots"
      [ "$pair" = 2,3 ] && plots=""
      "$bin" run "$data" -c "$cfg" -f "$filter" -p "$particles" $flag -q $plots -r "$pair" \
        -o "$out/2r-$(echo $pair | tr , -)_${filter}_${ids}" > /dev/null 2>&1
    done
  done
done
/usr/bin/python3 tools/replay_table.py "$out" > "$out/summary.md"
cat "$out/summary.md"
echo "replay: $(( $(date +%s) - t0 )) s; figures in $out/5r_*/ and $out/2r-2-3_*/"
