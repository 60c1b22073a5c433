#!/bin/sh
# coslam-sim on bad input: a clear error naming the file (and line, key),
# a non-zero exit; a fault a shortened run does not reach is said so, not
# printed as -1.0 s; a full disk is an error naming the file.
set -u
BIN=$1
PAPER=$2
WORK=$3
fail=0
rm -rf "$WORK"
mkdir -p "$WORK"
expect_error() {
  what=$1
  needle=$2
  shift 2
  out=$("$BIN" --quiet "$@" 2>&1); rc=$?
  if [ $rc -eq 0 ] || ! echo "$out" | grep -qF -- "$needle"; then
    echo "FAIL: $what: exit $rc: $(echo "$out" | tail -3)"; fail=1
  else
    echo "ok: $what -> $(echo "$out" | grep -F -- "$needle" | head -1)"
  fi
}
expect_error "a directory" "$WORK: is a directory, not a scenario file" --scenario "$WORK" --out "$WORK/never"
cp "$PAPER" "$WORK/late.toml"
printf '\n[[fault]]\nrobot = 1\nkind = "laser_unplug"\nat_s = 500\nduration_s = 5\n' >> "$WORK/late.toml"
line=$(grep -n '^at_s = 500' "$WORK/late.toml" | cut -d: -f1)
expect_error "a fault after the end" \
  "$WORK/late.toml: line $line: fault[0].at_s: at_s 500 is at or after the run's end (duration_s 120 s)" \
  --scenario "$WORK/late.toml" --out "$WORK/never"
[ ! -e "$WORK/never" ] || { echo "FAIL: an output folder was made"; fail=1; }
# --duration shortens the run below the fault's start
cp "$PAPER" "$WORK/fault.toml"
printf '\n[[fault]]\nrobot = 1\nkind = "laser_unplug"\nat_s = 100\nduration_s = 5\n' >> "$WORK/fault.toml"
out=$("$BIN" --quiet --camera oracle --duration 2 --scenario "$WORK/fault.toml" --out "$WORK/short" 2>&1); rc=$?
if [ $rc -ne 0 ] || ! echo "$out" | grep -qF "fault laser_unplug on robot1: not reached (at 100.0 s, the run ended at 2.0 s)" ||
   echo "$out" | grep -qF -- "-1.0 s" || ! grep -q '"reached": false' "$WORK/short/metrics.json"; then
  echo "FAIL: a fault not reached: exit $rc: $out"; fail=1
else
  echo "ok: $(echo "$out" | grep 'fault laser_unplug')"
fi
# a full disk
if [ -e /dev/full ]; then
  mkdir -p "$WORK/full"
  ln -s /dev/full "$WORK/full/metrics.json"
  expect_error "a full disk" "cannot write $WORK/full/metrics.json" --camera oracle --duration 1 --out "$WORK/full"
fi
exit $fail
