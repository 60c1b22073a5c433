#!/bin/sh
# coslam-calibrate refuses bad values: exit status 2 and a message naming
# the option, before running any episode.
set -u
# an MPI build: no orted for each singleton start (Open MPI 4), faster
export OMPI_MCA_ess_singleton_isolated=1
BIN=$1
# the shared data: COSLAM_DATA_DIR overrides the build's folder (argument 2)
DATA=${COSLAM_DATA_DIR:-${2:-}}
fail=0
check() {
  out=$("$BIN" "$@" -o /tmp/coslam-cal-cli-never 2>&1); rc=$?
  if [ $rc -ne 2 ] || [ -z "$out" ]; then
    echo "FAIL: '$*' gave exit $rc: $out"; fail=1
  else
    echo "ok: '$*' -> $(echo "$out" | head -1)"
  fi
}
check --evals -5
check --evals 0
check --evals 5
check --evals nan
check --evals abc
check --sigma0 nan
check --sigma0 -1
check --sigma0 inf
check --factor 1
check --factor nan
check --stop-error -1
check --stop-error nan
check --penalty 0.5
check --duration -3
check --jobs 0
check --lambda 2
check --repeats 0
check --particles 0
check --world moon
check --optimiser simplex
check --source mars
check --train-seeds 5-1
check --train-seeds x
check --train-seeds 1-4 --test-seeds 3-6
check --fixed w9
check --source mrclam --train-robots 1,2 --test-robots 2
check -c /nonexistent.ini
check --no-such-option
# options of the other source would be ignored: refused, the option named
check_says() {
  needle=$1
  shift
  out=$("$BIN" "$@" -o /tmp/coslam-cal-cli-never 2>&1); rc=$?
  if [ $rc -ne 2 ] || ! echo "$out" | grep -qF -- "$needle"; then
    echo "FAIL: '$*' gave exit $rc: $out"; fail=1
  else
    echo "ok: '$*' -> $(echo "$out" | grep -F -- "$needle" | head -1)"
  fi
}
check_says "--train-robots does not apply to --source synth" --source synth --train-robots 1
check_says "--data does not apply to --source synth" --source synth --data /tmp
check_says "--duration does not apply to --source synth" --source synth --duration 10
check_says "--train-seeds does not apply to --source mrclam" --source mrclam --train-seeds 1
check_says "--world does not apply to --source mrclam" --source mrclam --world loop
# -f/-p with mrclam were silently ignored: the replay's [filter] decides
check_says "--filter does not apply to --source mrclam (it would be ignored); the replay's filter and particles come from the configuration: [filter] type" \
  --source mrclam -f fs2
check_says "--particles does not apply to --source mrclam" --source mrclam -p 50
# Dataset 1 has no robot ground truth: nothing to score a robot's path by
D1=$DATA/mrclam/MRCLAM_Dataset1
if [ -n "$DATA" ] && [ -d "$D1" ]; then
  check_says "robot 1 has no ground truth (Dataset 1: use --map-data)" --source mrclam --data "$D1"
else
  echo "skip: no $D1"
fi
# the data folder comes from COSLAM_DATA_DIR when it is set (it was the
# build's folder only): a missing one is named; the real one, reached through
# another path, is read (a robot not in it is refused naming that path)
W=$(mktemp -d)
out=$(COSLAM_DATA_DIR="$W/missing" "$BIN" --source mrclam -o /tmp/coslam-cal-cli-never 2>&1); rc=$?
if [ $rc -ne 2 ] || ! echo "$out" | grep -qF "$W/missing/mrclam/MRCLAM_Dataset6: no such folder"; then
  echo "FAIL: COSLAM_DATA_DIR at a missing folder gave exit $rc: $out"; fail=1
else
  echo "ok: COSLAM_DATA_DIR missing -> $(echo "$out" | grep -F "$W/missing" | head -1)"
fi
if [ -n "$DATA" ] && [ -d "$DATA/mrclam/MRCLAM_Dataset6" ]; then
  ln -s "$(cd "$DATA" && pwd)/mrclam" "$W/mrclam"
  out=$(COSLAM_DATA_DIR="$W" "$BIN" --source mrclam --train-robots 9 -o /tmp/coslam-cal-cli-never 2>&1); rc=$?
  if [ $rc -ne 2 ] || ! echo "$out" | grep -qF -- "--data $W/mrclam/MRCLAM_Dataset6: robot 9 is not in the dataset"; then
    echo "FAIL: COSLAM_DATA_DIR at the data gave exit $rc: $out"; fail=1
  else
    echo "ok: COSLAM_DATA_DIR at the data -> $(echo "$out" | grep -F "robot 9" | head -1)"
  fi
else
  echo "skip: no $DATA/mrclam/MRCLAM_Dataset6"
fi
rm -rf "$W"
# a full disk: the report is an error naming the file, not exit 0
if [ -e /dev/full ]; then
  W=$(mktemp -d)
  ln -s /dev/full "$W/report.txt"
  out=$("$BIN" --train-seeds 1 --test-seeds 101 --evals 5 --lambda 4 -j 2 -q -o "$W" 2>&1); rc=$?
  if [ $rc -eq 0 ] || ! echo "$out" | grep -q "cannot write $W/report.txt"; then
    echo "FAIL: a full disk gave exit $rc: $(echo "$out" | tail -2)"; fail=1
  else
    echo "ok: full disk -> $(echo "$out" | tail -1)"
  fi
  rm -rf "$W"
fi
[ ! -e /tmp/coslam-cal-cli-never ] || { echo "FAIL: an output folder was created"; fail=1; }
exit $fail
