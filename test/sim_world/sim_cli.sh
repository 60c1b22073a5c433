#!/bin/sh
# coslam-sim on bad input: a clear error naming the file (and line, key),
# exit 2 for a bad option or scenario (an impossible world: a self-crossing
# arena, a landmark outside it, a negative explore_s, a robot started in a
# wall, a fault of no length, a zero resend period, a wall that is a point);
# a fault a shortened run does not reach is said so, not printed as
# -1.0 s; a run without a merge says "no merge" and writes first_merge_s
# null, not -1; a full disk or an output file that cannot be opened is an
# error naming the file and the OS's reason, exit 1.
set -u
BIN=$1
PAPER=$2
WORK=$3
fail=0
rm -rf "$WORK"
mkdir -p "$WORK"
# expect_error WHAT RC NEEDLE ARGS...: exit status RC and a line with NEEDLE
expect_error() {
  what=$1
  want=$2
  needle=$3
  shift 3
  out=$("$BIN" --quiet "$@" 2>&1); rc=$?
  if [ $rc -ne "$want" ] || ! echo "$out" | grep -qF -- "$needle"; then
    echo "FAIL: $what: exit $rc (want $want): $(echo "$out" | tail -3)"; fail=1
  else
    echo "ok: $what -> exit $rc: $(echo "$out" | grep -F -- "$needle" | head -1)"
  fi
}
# scenario KEY_LINE_SED NAME: a copy of the paper scenario edited with sed
scenario() {
  sed "$1" "$PAPER" > "$WORK/$2.toml"
}
# with_fault NAME AT_S DURATION_S: a copy of the paper scenario with a
# laser_unplug fault of robot 1 appended
with_fault() {
  cp "$PAPER" "$WORK/$1.toml"
  printf '\n[[fault]]\nrobot = 1\nkind = "laser_unplug"\nat_s = %s\nduration_s = %s\n' "$2" "$3" >> "$WORK/$1.toml"
}
# refused WHAT NEEDLE NAME: $WORK/NAME.toml is refused (exit 2) with NEEDLE
refused() {
  expect_error "$1" 2 "$2" --scenario "$WORK/$3.toml" --out "$WORK/never"
}
expect_error "a directory" 2 "$WORK: is a directory, not a scenario file" --scenario "$WORK" --out "$WORK/never"
expect_error "a bad option value" 2 "--seed" --seed -3 --out "$WORK/never"
with_fault late 500 5
line=$(grep -n '^at_s = 500' "$WORK/late.toml" | cut -d: -f1)
expect_error "a fault after the end" 2 \
  "$WORK/late.toml: line $line: fault[0].at_s: at_s 500 is at or after the run's end (duration_s 120 s)" \
  --scenario "$WORK/late.toml" --out "$WORK/never"
# impossible worlds
scenario 's/^arena = .*/arena = [[-4.5, -3.5], [4.5, 3.5], [4.5, -3.5], [-4.5, 3.5]]/' bowtie
expect_error "a self-crossing arena" 2 \
  "$WORK/bowtie.toml: line 24: world.arena: edge 0 (-4.5, -3.5)-(4.5, 3.5) and edge 2 (4.5, -3.5)-(-4.5, 3.5) cross" \
  --scenario "$WORK/bowtie.toml" --out "$WORK/never"
scenario 's/^arena = .*/arena = [[-4.5, -3.5], [4.5, -3.5], [4.5, -3.5], [4.5, 3.5], [-4.5, 3.5]]/' repeated
expect_error "a repeated arena corner" 2 "world.arena: corners 1 and 2 are the same point (4.5, -3.5)" \
  --scenario "$WORK/repeated.toml" --out "$WORK/never"
scenario 's/{ pos = \[3.75, 3.48\], signature = 1 }/{ pos = [3.75, 9.0], signature = 1 }/' lm_out
expect_error "a landmark outside the arena" 2 "world.landmarks[5].pos: (3.75, 9) is outside the arena" \
  --scenario "$WORK/lm_out.toml" --out "$WORK/never"
scenario 's/^explore_s = 50.0 .*/explore_s = -5/' explore_neg
expect_error "a negative behaviour.explore_s" 2 "line 89: behaviour.explore_s: value -5 outside [0, 1e+06]" \
  --scenario "$WORK/explore_neg.toml" --out "$WORK/never"
scenario 's/^radius_m = 0.19$/radius_m = 0.19\nexplore_s = -1/' robot_explore_neg
expect_error "a negative robot explore_s" 2 "robot[0].explore_s: value -1 outside [0, 1e+06]" \
  --scenario "$WORK/robot_explore_neg.toml" --out "$WORK/never"
scenario 's/^radius_m = 0.19$/radius_m = 0/' radius0
expect_error "a zero robot radius" 2 "robot[0].radius_m: value 0 outside [0.01, 10]" \
  --scenario "$WORK/radius0.toml" --out "$WORK/never"
scenario 's/^duration_s = .*/duration_s = 0/' duration0
expect_error "a zero duration_s" 2 "duration_s: value 0 outside" --scenario "$WORK/duration0.toml" --out "$WORK/never"
scenario 's/^boxes = \[/walls = [ { from = [1.0, -1.0], to = [1.0, 1.0] } ]\nboxes = [/' in_wall
expect_error "a robot started in a wall" 2 "robot[1].start (1, 0): the body overlaps wall 0 (1, -1)-(1, 1)" \
  --scenario "$WORK/in_wall.toml" --out "$WORK/never"
scenario 's/^start = \[1.0, 0.0, 0.0\] .*/start = [6.0, 0.0, 0.0]/' start_out
expect_error "a robot started outside the arena" 2 "robot[1].start (6, 0): outside the arena" \
  --scenario "$WORK/start_out.toml" --out "$WORK/never"
# values the robot could not act on (accepted before): a fault of no
# length, a map resent at every step, a period the robot's microseconds
# cannot hold, a wall that is a point
with_fault fault0 50 0
line=$(grep -n '^duration_s = 0$' "$WORK/fault0.toml" | cut -d: -f1)
refused "a fault of duration 0" \
  "line $line: fault[0].duration_s: duration_s 0 s is shorter than one physics step (timing.physics_dt_ms 1 ms)" fault0
scenario 's/^resend_s = 1.0$/resend_s = 0/' resend0
refused "a zero meeting.resend_s" "line 99: meeting.resend_s: value 0 outside [0.001, 4000]" resend0
scenario 's/^meeting_gap_s = 5.0$/meeting_gap_s = 5000/' gap_big
refused "a meeting.meeting_gap_s beyond 4000 s" "meeting.meeting_gap_s: value 5000 outside [0, 4000]" gap_big
scenario 's/^boxes = \[/walls = [ { from = [1.0, 2.0], to = [1.0, 2.0] } ]\nboxes = [/' wall0
refused "a wall of length 0" "world.walls[0].to: (1, 2) is the same point as from: a wall needs a length" wall0
[ ! -e "$WORK/never" ] || { echo "FAIL: an output folder was made"; fail=1; }
# --duration shortens the run below the fault's start (and below any merge)
with_fault fault 100 5
out=$("$BIN" --quiet --camera oracle --duration 2 --scenario "$WORK/fault.toml" --out "$WORK/short" 2>&1); rc=$?
if [ $rc -ne 0 ] || ! echo "$out" | grep -qF "fault laser_unplug on robot1: not reached (at 100.0 s, the run ended at 2.0 s)" ||
   echo "$out" | grep -qF -- "-1.0 s" || ! grep -q '"reached": false' "$WORK/short/metrics.json"; then
  echo "FAIL: a fault not reached: exit $rc: $out"; fail=1
else
  echo "ok: $(echo "$out" | grep 'fault laser_unplug')"
fi
# no merge in 2 s: null in metrics.json (never -1), "no merge" in the summary
if [ "$(grep -c '"first_merge_s": null' "$WORK/short/metrics.json")" -ne 2 ] ||
   grep -q '"first_merge_s": -' "$WORK/short/metrics.json" ||
   [ "$(echo "$out" | grep -cE '^  robot[01] .* no merge ')" -ne 2 ]; then
  echo "FAIL: no merge: $(grep first_merge_s "$WORK/short/metrics.json") / $(echo "$out" | grep -E '^  robot[01] ')"; fail=1
else
  echo "ok: no merge -> first_merge_s null; $(echo "$out" | grep -E '^  robot0 ')"
fi
# an output file that cannot be opened: the OS's reason (the grid had none)
mkdir -p "$WORK/grid/robot0_grid.pgm"
expect_error "a grid file that cannot be opened" 1 "cannot write $WORK/grid/robot0_grid.pgm: Is a directory" \
  --camera oracle --duration 1 --out "$WORK/grid"
# a full disk
if [ -e /dev/full ]; then
  mkdir -p "$WORK/full"
  ln -s /dev/full "$WORK/full/metrics.json"
  expect_error "a full disk" 1 "cannot write $WORK/full/metrics.json: No space left on device" \
    --camera oracle --duration 1 --out "$WORK/full"
fi
exit $fail
