#!/bin/sh
# `make sim`: the main job. Runs the default simulation and writes results
# and figures under out/. Until the simulator lands (issue 5) this is the
# core-only synthetic demo.
set -eu
build=${1:-build}
if [ -x "$build/host/sim/coslam-sim" ]; then
  exec "$build/host/sim/coslam-sim" --out out/sim
fi
"$build/host/demo/coslam-demo" --out out/demo
/usr/bin/python3 tools/plot_run.py out/demo --title "coslam-demo: EKF-SLAM and Fast-SLAM 2.0 on a synthetic loop"
echo "figures: out/demo/paths.png out/demo/errors.png"
