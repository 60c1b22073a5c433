#!/bin/sh
# `make bench`: every benchmark program, reports under out/bench/.
set -eu
build=${1:-build}
mkdir -p out/bench
for b in "$build"/host/bench/coslam-bench*; do
  [ -x "$b" ] || continue
  echo "== $(basename "$b")"
  "$b" --out out/bench
done
