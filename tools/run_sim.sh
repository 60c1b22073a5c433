#!/bin/sh
# `make sim`: the main job. Runs the default simulation and writes results
# and figures under out/. Until the simulator lands (issue 5) this is the
# core-only synthetic demo.
set -eu
build=${1:-build}
if [ -x "$build/host/sim/coslam-sim" ]; then
  exec "$build/host/sim/coslam-sim" --out out/sim "$@"
fi
exec "$build/host/demo/coslam-demo" --out out/demo
