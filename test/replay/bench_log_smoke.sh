#!/bin/sh
# test/replay/bench_log_smoke.sh - coslam-bench-mrclam on a landmark log (the
# way `make bench-mrpt` runs issue 13's large stream): a small generated
# world, coslam's EKF-SLAM and Fast-SLAM 2.0 only (no MRPT needed). The
# report must be written under the name asked for, name the data folder,
# hold both methods, and EKF-SLAM must track the path (pose RMSE < 0.5 m on
# this seed; it gets about 0.2 m). An unknown method is refused. A report
# that cannot be written (a full disk) is an error naming it, exit 1.
#
#   bench_log_smoke.sh EVAL_WORLDS_BIN BENCH_BIN WORK_DIR
set -u
EVAL=$1
BENCH=$2
WORK=$3
rm -rf "$WORK"
mkdir -p "$WORK"
fail() { echo "bench_log_smoke: FAIL: $*"; exit 1; }
"$EVAL" --world paper --seed0 1 --write-log "$WORK/smoke_log" > "$WORK/eval.txt" 2>&1 || fail "eval-worlds --write-log"
"$BENCH" --data "$WORK/smoke_log" --methods ekf,fs2 -p 20 --report smoke -o "$WORK/out" > "$WORK/bench.txt" 2>&1 ||
    fail "bench exit $? ($(tail -3 "$WORK/bench.txt"))"
md="$WORK/out/smoke.md"
[ -f "$md" ] && [ -f "$WORK/out/smoke.json" ] || fail "no $md / smoke.json"
head -1 "$md" | grep -q '^smoke_log, each robot alone' || fail "the report does not name the data folder: $(head -1 "$md")"
grep -q '^| coslam Fast-SLAM 2.0 (20 particles) |' "$md" || fail "no Fast-SLAM 2.0 row"
rmse=$(awk -F'|' '/^\| coslam EKF-SLAM/ { gsub(/ /, "", $3); print $3; exit }' "$md")
[ -n "$rmse" ] || fail "no EKF-SLAM row"
awk -v r="$rmse" 'BEGIN { exit !(r + 0 < 0.5) }' || fail "EKF-SLAM pose RMSE $rmse m >= 0.5 m"
if "$BENCH" --data "$WORK/smoke_log" --methods ekf,nosuch -o "$WORK/out2" > "$WORK/bad.txt" 2>&1; then
    fail "an unknown method was accepted"
fi
if [ -e /dev/full ]; then
    mkdir -p "$WORK/full"
    ln -s /dev/full "$WORK/full/smoke.json"
    "$BENCH" --data "$WORK/smoke_log" --methods ekf --report smoke -o "$WORK/full" > "$WORK/full.txt" 2>&1
    rc=$?
    [ $rc -eq 1 ] && grep -q "^coslam-bench-mrclam: cannot write $WORK/full/smoke.json: No space left on device" \
        "$WORK/full.txt" || fail "a full disk: exit $rc ($(tail -2 "$WORK/full.txt"))"
fi
echo "bench_log_smoke: ok (EKF-SLAM pose RMSE $rmse m)"
