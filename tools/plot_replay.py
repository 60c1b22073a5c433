#!/usr/bin/python3
"""Figures of a coslam-replay run folder (docs/replay.md):

  robot<k>_map.png  per robot, like the paper's Figs. 6 and 10: the true and
                    estimated path in the robot's map frame, landmark
                    estimates with 2-sigma ellipses and the true landmarks;
                    left the merge that added the most landmarks (map before
                    the merge in blue, after in red), right the end of the run.
  errors.png        like Fig. 7: position error, heading error, landmark RMSE
                    and landmark count over time for every robot, merges
                    marked (dashed lines in the receiver's colour).

Reads the outputs written by coslam-replay (robot<k>_path.tum,
robot<k>_truth_path.tum, robot<k>_map*.csv, robot<k>_truth_map.csv,
errors.csv, map_errors.csv, merge_events.csv). Reuses the readers of
plot_run.py.

usage: plot_replay.py RUN_DIR [--title TEXT]
"""
import argparse
import csv
import glob
import json
import math
import os
import re
import sys

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from plot_run import ellipse, read_map, read_tum  # noqa: E402


def read_csv(path):
    if not os.path.exists(path):
        return []
    with open(path) as f:
        return [{k: float(v) for k, v in r.items()} for r in csv.DictReader(f)]


def draw_map(ax, path, color, label=None):
    if not os.path.exists(path):
        return
    lms = read_map(path)
    for lm in lms:
        ellipse(ax, lm, color)
    if lms:
        ax.plot([lm["x"] for lm in lms], [lm["y"] for lm in lms], "+", color=color, ms=5,
                label=label and "%s (%d)" % (label, len(lms)))


def robot_figure(d, k, metrics, title):
    base = os.path.join(d, "robot%d" % k)
    est = read_tum(base + "_path.tum")
    tru = read_tum(base + "_truth_path.tum") if os.path.exists(base + "_truth_path.tum") else np.zeros((0, 4))
    truth_map = read_csv(base + "_truth_map.csv")
    t_merge = None
    for r in metrics.get("robots", []):
        # shown_merge_t_s is null (None) for a robot that never merged
        if r["id"] == k and r.get("shown_merge_t_s") is not None and os.path.exists(base + "_map_before_merge.csv"):
            t_merge = r["shown_merge_t_s"]
            added = r["shown_merge_added"]
    panels = [("merge at t = %.0f s (+%d landmarks)" % (t_merge, added), t_merge)] if t_merge is not None else []
    panels.append(("end of run", None))
    fig, axs = plt.subplots(1, len(panels), figsize=(7.5 * len(panels), 7.5), squeeze=False)
    for ax, (name, t_cut) in zip(axs[0], panels):
        e = est if t_cut is None else est[est[:, 0] <= t_cut]
        g = tru if t_cut is None else tru[tru[:, 0] <= t_cut]
        if len(g):
            ax.plot(g[:, 1], g[:, 2], "k-", lw=0.7, label="true path")
        if len(e):
            ax.plot(e[:, 1], e[:, 2], "-", color="tab:green", lw=0.7, label="estimated path")
            ax.plot(e[-1, 1], e[-1, 2], "o", color="tab:green", ms=6)
        if t_cut is not None:
            draw_map(ax, base + "_map_before_merge.csv", "tab:blue", "map before merge")
            draw_map(ax, base + "_map_after_merge.csv", "tab:red", "map after merge")
        else:
            draw_map(ax, base + "_map.csv", "tab:red", "final map")
        if truth_map:
            ax.plot([p["x"] for p in truth_map], [p["y"] for p in truth_map], "kx", ms=6, label="true landmarks")
        ax.set_aspect("equal")
        ax.set_xlabel("x [m] (robot %d map frame)" % k)
        ax.set_ylabel("y [m]")
        ax.set_title("robot %d, %s" % (k, name))
        ax.grid(True, lw=0.3)
        ax.legend(loc="best", fontsize=8)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(base + "_map.png", dpi=110)
    plt.close(fig)


def error_figure(d, robots, merges, title):
    errs = read_csv(os.path.join(d, "errors.csv"))
    maps = read_csv(os.path.join(d, "map_errors.csv"))
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    fig, axs = plt.subplots(4, 1, figsize=(10, 10), sharex=True)
    for i, k in enumerate(robots):
        c = colors[i % len(colors)]
        e = np.array([(r["t"], r["pos_err_m"], r["heading_err_rad"]) for r in errs if int(r["robot"]) == k])
        m = np.array([(r["t"], r["rmse_m"], r["n_estimated"], r["n_spurious"]) for r in maps if int(r["robot"]) == k])
        if len(e):
            axs[0].plot(e[:, 0], e[:, 1], color=c, lw=0.8, label="robot %d" % k)
            axs[1].plot(e[:, 0], np.degrees(e[:, 2]), color=c, lw=0.8)
        if len(m):
            axs[2].plot(m[:, 0], m[:, 1], color=c, lw=1.0)
            axs[3].plot(m[:, 0], m[:, 2], color=c, lw=1.0)
            axs[3].plot(m[:, 0], m[:, 3], color=c, lw=0.8, ls=":")
        for ev in merges:
            if int(ev["robot"]) == k and int(ev["status"]) == 0:
                for ax in axs:
                    ax.axvline(ev["t"], color=c, ls="--", lw=0.7)
    axs[0].set_ylabel("position error [m]")
    axs[1].set_ylabel("heading error [deg]")
    axs[2].set_ylabel("landmark RMSE [m]")
    axs[3].set_ylabel("landmarks (solid)\nspurious (dotted)")
    axs[3].set_xlabel("t [s] (dashed: merges, receiver's colour)")
    axs[0].legend(fontsize=8, ncol=len(robots))
    for ax in axs:
        ax.grid(True, lw=0.3)
    if title:
        axs[0].set_title(title)
    fig.tight_layout()
    fig.savefig(os.path.join(d, "errors.png"), dpi=110)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("run_dir")
    ap.add_argument("--title", default="")
    a = ap.parse_args()
    d = a.run_dir
    robots = sorted(int(re.match(r"robot(\d+)_path\.tum", os.path.basename(p)).group(1))
                    for p in glob.glob(os.path.join(d, "robot*_path.tum"))
                    if re.match(r"robot(\d+)_path\.tum", os.path.basename(p)))
    if not robots:
        print("plot_replay: no robot<k>_path.tum in %s" % d, file=sys.stderr)
        return 1
    merges = read_csv(os.path.join(d, "merge_events.csv"))
    metrics = {}
    if os.path.exists(os.path.join(d, "metrics.json")):
        with open(os.path.join(d, "metrics.json")) as f:
            metrics = json.load(f)
    for k in robots:
        robot_figure(d, k, metrics, a.title)
    error_figure(d, robots, merges, a.title)
    return 0


if __name__ == "__main__":
    sys.exit(main())
