#!/bin/sh
# test/replay/team_log_smoke.sh - the arena's team logs (coslam-eval-worlds
# --world arena --robots N --write-log) replayed by coslam-replay with
# merging, and scored by tools/team_table.py (tools/team_table.sh's path):
# every robot's log and truth is written, the robots sight each other (R
# records) so that meetings happen and maps are merged, each robot is
# evaluated against its truth, and the table counts every robot-run. A team
# outside the arena, of 0 or 10 robots, or without --write-log is refused
# with exit code 2.
#
#   team_log_smoke.sh EVAL_WORLDS_BIN REPLAY_BIN PYTHON SOURCE_DIR WORK_DIR
set -u
EVAL=$1
REPLAY=$2
PY=$3
SRC=$4
WORK=$5
rm -rf "$WORK"
mkdir -p "$WORK"
fail() { echo "team_log_smoke: FAIL: $*"; exit 1; }
"$EVAL" --world arena --seed0 3 --robots 3 --write-log "$WORK/log3" > "$WORK/eval.txt" 2>&1 || fail "--write-log"
for k in 1 2 3; do
    [ -s "$WORK/log3/robot$k.log" ] && [ -s "$WORK/log3/robot${k}_truth.txt" ] || fail "robot $k's log or truth missing"
    grep -q '^R ' "$WORK/log3/robot$k.log" || fail "robot $k never sights another robot"
done
[ "$(wc -l < "$WORK/log3/landmarks_truth.txt")" -eq 15 ] || fail "not 15 landmarks"
[ ! -e "$WORK/log3/robot4.log" ] || fail "a fourth robot was written"
for m in "" --no-merge; do
    out="$WORK/s3${m:+_alone}"
    "$REPLAY" run "$WORK/log3" -c "$SRC/host/replay/synth/arena.ini" -f ekf $m -q --no-plots -o "$out" \
        > "$out.txt" 2>&1 || fail "replay $m exit $?: $(tail -3 "$out.txt")"
done
merged=$(sed -n 's/^merges: \([0-9]*\).*/\1/p' "$WORK/s3.txt")
[ -n "$merged" ] && [ "$merged" -gt 0 ] || fail "no merge in the team run ($(grep '^merges' "$WORK/s3.txt"))"
"$PY" "$SRC/tools/team_table.py" "$WORK" 3 > "$WORK/table.md" 2>&1 || fail "team_table.py: $(tail -3 "$WORK/table.md")"
grep -q '^3 robot-runs: ' "$WORK/table.md" || fail "the table does not count 3 robot-runs: $(tail -2 "$WORK/table.md")"
[ "$(grep -c '^| 3 | [123] |' "$WORK/table.md")" -eq 3 ] || fail "not one row per robot"
grep -q '^pose RMSE in the fitted map alone / merged [0-9.]* / [0-9.]* m' "$WORK/table.md" ||
    fail "no pose in the fitted map: $(tail -1 "$WORK/table.md")"
for bad in "--world loop --robots 2" "--world arena --robots 0" "--world arena --robots 10" "--world arena --robots x"; do
    # shellcheck disable=SC2086
    "$EVAL" $bad --seed0 1 --write-log "$WORK/bad" > "$WORK/bad.txt" 2>&1
    rc=$?
    [ "$rc" -eq 2 ] || fail "'$bad' exit $rc, not 2"
done
# a team without --write-log: the runs are one robot's, so it is refused
"$EVAL" --world arena --robots 3 --seeds 1 > "$WORK/bad.txt" 2>&1
rc=$?
[ "$rc" -eq 2 ] || fail "--robots without --write-log: exit $rc, not 2"
grep -q -- '--robots is for --write-log' "$WORK/bad.txt" || fail "no message for --robots without --write-log"
echo "team_log_smoke: ok ($merged merges; $(grep '^3 robot-runs: ' "$WORK/table.md"))"
