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
# run_one NAME ARGS...: one replay, its console in $out/NAME.log; a run that
# fails stops make replay with its name, exit code (docs/replay.md: 1 a
# write, 2 input, 3 a capacity, 4 figures not drawn) and the end of its log
run_one() {
  name=$1
  shift
  rc=0
  "$bin" run "$data" -c "$cfg" -f "$filter" -p "$particles" $flag -q "$@" -o "$out/$name" \
    > "$out/$name.log" 2>&1 || rc=$?
  if [ "$rc" -ne 0 ]; then
    echo "replay: run $name failed with exit $rc; its log: $out/$name.log" >&2
    tail -n 5 "$out/$name.log" >&2
    exit 1
  fi
}
for filter in ekf fastslam2; do
  for ids in unknown known; do
    flag=""
    [ "$ids" = known ] && flag="--known-ids"
    echo "== 5 robots, $filter, $ids identities"
    run_one "5r_${filter}_${ids}"
    sed -n '1,8p' "$out/5r_${filter}_${ids}.log"
    run_one "5r-nomerge_${filter}_${ids}" --no-merge --no-plots
    for pair in 1,3 1,5 2,3 2,5 3,4 3,5 4,5; do
      plots="--no-plots"
      [ "$pair" = 2,3 ] && plots=""
      run_one "2r-$(echo $pair | tr , -)_${filter}_${ids}" $plots -r "$pair"
    done
  done
done
/usr/bin/python3 tools/replay_table.py "$out" > "$out/summary.md"
cat "$out/summary.md"
echo "replay: $(( $(date +%s) - t0 )) s; figures in $out/5r_*/ and $out/2r-2-3_*/"
