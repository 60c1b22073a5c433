#!/bin/sh
# coslam-calibrate refuses bad values: exit status 2 and a message naming
# the option, before running any episode.
set -u
# an MPI build: no orted for each singleton start (Open MPI 4), faster
export OMPI_MCA_ess_singleton_isolated=1
BIN=$1
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
[ ! -e /tmp/coslam-cal-cli-never ] || { echo "FAIL: an output folder was created"; fail=1; }
exit $fail
