#!/bin/sh
# `make sim`: the main job. Runs the default simulation scenario
# (sim/scenarios/paper.toml: two robots, their firmware on the simulated
# devices, meeting and map merge) and writes results and figures under
# out/sim/. Falls back to the core-only synthetic demo if the simulator was
# not built.
set -eu
build=${1:-build}
if [ -x "$build/host/sim/coslam-sim" ]; then
  "$build/host/sim/coslam-sim" --out out/sim
  /usr/bin/python3 tools/plot_sim.py out/sim >/dev/null
  /usr/bin/python3 tools/plot_run.py out/sim --title "coslam-sim: paths and landmark estimates (world frame)"
  echo "figures: out/sim/fig6_paths_maps.png out/sim/fig7_errors.png out/sim/paths.png out/sim/errors.png"
  exit 0
fi
"$build/host/demo/coslam-demo" --out out/demo
/usr/bin/python3 tools/plot_run.py out/demo --title "coslam-demo: EKF-SLAM and Fast-SLAM 2.0 on a synthetic loop"
echo "figures: out/demo/paths.png out/demo/errors.png"
